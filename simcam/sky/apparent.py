"""Apparent directions of catalogue stars seen from a spacecraft, through astropy (ERFA).

:func:`apparent_directions` takes catalogue stars (ICRS, epoch J1991.25) to unit vectors in
the GCRS axes as seen by an observer at a geocentric position and velocity: space motion
to the epoch of observation (proper motion, parallax as distance, radial velocity taken as
zero), then ICRS -> GCRS with ``obsgeoloc``/``obsgeovel``, which applies the annual
aberration of the Earth's barycentric velocity plus the observer's geocentric velocity
(relativistically), the parallax from the observer's barycentric position, and light
deflection by the Sun (IERS Conventions 2010; astropy's ``GCRS`` frame via ERFA
``apcs``/``atciqz``).

Switches say what a simplified model leaves out (to show what ignoring an effect costs):
without ``aberration`` the same chain stops before ERFA's ``ab`` (the direction from the
observer's barycentric position, light deflection included); without ``parallax`` the
star is at infinite distance; without ``proper_motion`` the catalogue epoch's position is
used.

:func:`aberration_first_order` is the classical first-order formula
``u' = u + v/c - (u . v / c) u`` (Seidelmann 1992, Explanatory Supplement, eq. 3.252-1,
to first order in v/c), kept for tests and for estimators that model aberration themselves.
"""

from __future__ import annotations

import numpy as np

from simcam.sky.catalogue import EPOCH_JYEAR, Catalogue
from simcam.units import C_LIGHT_KM_S

__all__ = ["aberration_first_order", "apparent_directions", "observer_barycentric_velocity_km_s"]

#: parallax given to stars whose catalogue parallax is <= this (mas): 1 Gpc, effectively infinite
_MIN_PARALLAX_MAS = 1e-6


def aberration_first_order(u, velocity_km_s) -> np.ndarray:
    """Directions ``u`` (..., 3) seen by an observer moving at ``velocity_km_s`` (3,) or (..., 3).

    First order in v/c: ``u' = u + v/c - (u . v/c) u``, renormalised to unit length.
    """
    u = np.asarray(u, dtype=float)
    b = np.asarray(velocity_km_s, dtype=float) / C_LIGHT_KM_S
    out = u + b - np.sum(u * b, axis=-1, keepdims=True) * u
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def _skycoord(cat: Catalogue, *, proper_motion: bool, parallax: bool):
    import astropy.units as u
    from astropy.coordinates import Distance, SkyCoord
    from astropy.time import Time

    plx = np.where(cat.parallax_mas > _MIN_PARALLAX_MAS, cat.parallax_mas, _MIN_PARALLAX_MAS)
    if not parallax:
        plx = np.full_like(plx, _MIN_PARALLAX_MAS)
    pm_ra = cat.pm_ra_mas_yr if proper_motion else np.zeros_like(cat.pm_ra_mas_yr)
    pm_de = cat.pm_dec_mas_yr if proper_motion else np.zeros_like(cat.pm_dec_mas_yr)
    return SkyCoord(ra=cat.ra_rad * u.rad, dec=cat.dec_rad * u.rad,
                    distance=Distance(parallax=plx * u.mas),
                    pm_ra_cosdec=pm_ra * u.mas / u.yr, pm_dec=pm_de * u.mas / u.yr,
                    radial_velocity=np.zeros_like(plx) * u.km / u.s,
                    obstime=Time(EPOCH_JYEAR, format="jyear", scale="tcb"), frame="icrs")


def apparent_directions(cat: Catalogue, time, *, observer_position_km=None, observer_velocity_km_s=None,
                        proper_motion: bool = True, parallax: bool = True,
                        aberration: bool = True) -> np.ndarray:
    """(N, 3) unit vectors (GCRS axes) of the stars of ``cat`` seen from the observer at ``time``.

    Parameters
    ----------
    cat : Catalogue
        The stars.
    time : astropy.time.Time
        Epoch of observation (scalar).
    observer_position_km, observer_velocity_km_s : array-like (3,), optional
        The observer's geocentric position (km) and velocity (km/s) in GCRS axes (default:
        the geocentre at rest).
    proper_motion, parallax, aberration : bool
        Which effects to apply (see the module docstring).
    """
    import warnings

    import astropy.units as u
    import erfa
    from astropy.coordinates import GCRS, CartesianRepresentation
    from astropy.coordinates.erfa_astrom import erfa_astrom

    pos = np.zeros(3) if observer_position_km is None else np.asarray(observer_position_km, float)
    vel = np.zeros(3) if observer_velocity_km_s is None else np.asarray(observer_velocity_km_s, float)
    sc = _skycoord(cat, proper_motion=proper_motion, parallax=parallax)
    frame = GCRS(obstime=time, obsgeoloc=CartesianRepresentation(pos * u.km),
                 obsgeovel=CartesianRepresentation(vel * u.km / u.s))
    with warnings.catch_warnings():
        # ERFA warns about "dubious year" for epochs beyond its leap-second table: harmless here
        warnings.simplefilter("ignore", erfa.ErfaWarning)
        if proper_motion:
            sc = sc.apply_space_motion(new_obstime=time)
        # the observer's astrometry parameters exactly as astropy's ICRS -> GCRS uses them
        astrom = erfa_astrom.get().apcs(frame)
    # ERFA's atciqz without the bias-precession-nutation (identity for GCRS), one step at a
    # time so that aberration can be left out: parallax from the observer's barycentric
    # position (pmpx with the space motion already applied), light deflection by the Sun
    # (ldsun), then aberration (ab)
    ra = sc.icrs.ra.to_value(u.rad)
    dec = sc.icrs.dec.to_value(u.rad)
    px_arcsec = sc.icrs.distance.to(u.arcsec, equivalencies=u.parallax()).value
    zero = np.zeros_like(ra)
    pco = erfa.pmpx(ra, dec, zero, zero, px_arcsec, zero, 0.0, astrom["eb"])
    pnat = erfa.ldsun(pco, astrom["eh"], astrom["em"])
    xyz = erfa.ab(pnat, astrom["v"], astrom["em"], astrom["bm1"]) if aberration else pnat
    return xyz / np.linalg.norm(xyz, axis=1, keepdims=True)


def observer_barycentric_velocity_km_s(time, observer_velocity_km_s=None) -> np.ndarray:
    """The observer's barycentric velocity (km/s): the Earth's (astropy ephemeris) plus the
    observer's geocentric one (Galilean sum, enough for the first-order formula)."""
    from astropy.coordinates import get_body_barycentric_posvel

    _, v = get_body_barycentric_posvel("earth", time)
    extra = np.zeros(3) if observer_velocity_km_s is None else np.asarray(observer_velocity_km_s, float)
    return v.xyz.to_value("km/s") + extra
