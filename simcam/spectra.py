"""Spectra and the photon-to-electron chain of the star camera.

Everything here works on a wavelength grid in nanometres (vacuum) and returns plain
``numpy`` arrays for the fast paths; ``*_sd`` variants return
:class:`colour.SpectralDistribution` objects for inspection, plotting and the
colour-science algebra.

Units
-----
* photon spectral radiance: photons s^-1 m^-2 sr^-1 nm^-1
* photon spectral flux density (irradiance) at the entrance pupil:
  photons s^-1 m^-2 nm^-1 (``*_per_nm``)
* detected electron rate density: e- s^-1 nm^-1
* transmissions and quantum efficiencies: dimensionless, 0..1

Models and sources
------------------
* Planck's law in photon units, :func:`planck_photon_radiance`
  (Rybicki & Lightman 1979, *Radiative Processes in Astrophysics*, sec. 1.5, divided by
  the photon energy ``h c / lambda``), CODATA constants from :mod:`scipy.constants`.
* Dwarf effective temperatures, :func:`star_teff_k`: Pecaut & Mamajek (2013, ApJS 208, 9,
  Table 5) as maintained in E. Mamajek's online table (version 2017.10.19), see
  ``simcam/data/spectral_types.csv``.
* Stars are **blackbodies at Teff** (no line blanketing, no Balmer jump): an
  approximation good to roughly 10-20 % in band-integrated photon counts for A-K dwarfs.
* V passband: Bessell (1990, PASP 102, 1181, Table 2), ``simcam/data/bessell_v.csv``,
  read as a response per photon. Bessell & Murphy (2012, PASP 124, 140) read the 1990
  curves as energy responses (photon response proportional to ``S(lambda)/lambda``); that
  reading changes a star's normalisation by -2.4 % (2500 K), +0.2 % (5770 K), +0.9 %
  (9700 K) and +1.5 % (40000 K), well inside the blackbody approximation's error.
* V = 0 zero point: ``f_lambda = 363.1e-11 erg s^-1 cm^-2 A^-1`` (Bessell, Castelli &
  Plez 1998, A&A 333, 231, Table A2), i.e. 3.631e-11 W m^-2 nm^-1, which is
  1.005e8 photons s^-1 m^-2 nm^-1 (about 1005 photons s^-1 cm^-2 A^-1) at 550 nm.
* Lamp: blackbody at the CIE illuminant A temperature 2856 K (CIE 15:2004, sec. 3.1).
"""

from __future__ import annotations

import functools
import math
import pathlib
import re
import statistics
from importlib import resources

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # colour (and the matplotlib it imports) loads only where a SpectralDistribution is made
    import colour
import numpy as np

__all__ = [
    "SpectraError",
    "H_PLANCK_J_S",
    "C_LIGHT_M_S",
    "K_BOLTZMANN_J_K",
    "V_ZERO_POINT_W_M2_NM",
    "SILICON_BANDGAP_EV",
    "CIE_A_TEMPERATURE_K",
    "wavelength_grid_nm",
    "planck_photon_radiance",
    "total_photon_radiance",
    "spectral_type_table",
    "star_teff_k",
    "bessell_v_sd",
    "bessell_v_response",
    "v_band_photon_rate",
    "v_zero_point_photon_rate",
    "star_photon_flux_per_nm",
    "star_photon_flux_sd",
    "bandpass_array",
    "bandpass_sd",
    "cmos_qe_array",
    "cmos_qe_sd",
    "flat_transmission_array",
    "table_sd",
    "read_table_csv",
    "array_to_sd",
    "sd_to_array",
    "circular_aperture_area_m2",
    "detected_electron_rate_per_nm",
    "electrons_per_exposure",
    "trapezoid_weights_nm",
    "normalised_weights",
    "lamp_photon_spectrum_per_nm",
    "lamp_scale_to_match_star",
]

# --------------------------------------------------------------------------------------
# Constants
# --------------------------------------------------------------------------------------

# The SI defining constants (BIPM, The International System of Units, 9th ed. 2019, table 1):
# exact by definition, so written here rather than importing scipy.constants (0.19 s of
# start-up for four numbers); tests/test_spectra.py checks them against scipy.constants.
H_PLANCK_J_S: float = 6.62607015e-34
"""Planck constant, J s (exact in SI 2019)."""
C_LIGHT_M_S: float = 299792458.0
"""Speed of light in vacuum, m s^-1 (exact)."""
K_BOLTZMANN_J_K: float = 1.380649e-23
"""Boltzmann constant, J K^-1 (exact in SI 2019)."""
ELEMENTARY_CHARGE_C: float = 1.602176634e-19
"""Elementary charge, C (exact in SI 2019)."""

V_ZERO_POINT_W_M2_NM: float = 3.631e-11
"""Flux density of a V = 0 star, W m^-2 nm^-1.

Bessell, Castelli & Plez (1998, A&A 333, 231), Table A2: 363.1e-11 erg s^-1 cm^-2 A^-1.
Used as a flat ``f_lambda`` reference spectrum: a V = 0 source gives, through the V
passband, the same photon count as a flat spectrum of this flux density.
"""

SILICON_BANDGAP_EV: float = 1.12
"""Band gap of silicon at 300 K, eV (Sze & Ng 2007, *Physics of Semiconductor Devices*,
3rd ed., table of properties of Si at 300 K). Photons with ``lambda > h c / E_g`` (about 1107 nm) make no
photo-electrons."""

CIE_A_TEMPERATURE_K: float = 2856.0
"""Correlated colour temperature of CIE standard illuminant A (tungsten), K (CIE 15:2004)."""

_NM = 1e-9  # metres per nanometre
_HC_J_M = H_PLANCK_J_S * C_LIGHT_M_S  # J m
_C2_M_K = _HC_J_M / K_BOLTZMANN_J_K  # second radiation constant, m K
_LAMP_REFERENCE_NM = 560.0  # CIE normalisation wavelength of illuminant A


class SpectraError(ValueError):
    """Invalid input to a spectral model: names the parameter and what is wrong."""


# --------------------------------------------------------------------------------------
# Validation helpers
# --------------------------------------------------------------------------------------


def _positive_scalar(value, name: str, *, allow_zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SpectraError(f"{name}: must be a real number (got {value!r})") from None
    if not math.isfinite(v):
        raise SpectraError(f"{name}: must be finite (got {v!r})")
    if allow_zero:
        if v < 0:
            raise SpectraError(f"{name}: must be >= 0 (got {v!r})")
    elif v <= 0:
        raise SpectraError(f"{name}: must be > 0 (got {v!r})")
    return v


def _finite_scalar(value, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SpectraError(f"{name}: must be a real number (got {value!r})") from None
    if not math.isfinite(v):
        raise SpectraError(f"{name}: must be finite (got {v!r})")
    return v


def _unit_scalar(value, name: str) -> float:
    v = _finite_scalar(value, name)
    if not 0.0 <= v <= 1.0:
        raise SpectraError(f"{name}: must lie in [0, 1] (got {v!r})")
    return v


def _float_array(value, name: str) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise SpectraError(f"{name}: must be an array of real numbers") from None
    if not np.all(np.isfinite(a)):
        raise SpectraError(f"{name}: contains NaN or infinite values")
    return a


def _wavelengths(value, name: str = "wavelength_nm", *, grid: bool = False) -> np.ndarray:
    """Validate wavelengths (nm): finite and > 0; with ``grid``, 1-D strictly increasing."""
    a = _float_array(value, name)
    if a.size == 0:
        raise SpectraError(f"{name}: is empty")
    if np.any(a <= 0):
        raise SpectraError(f"{name}: wavelengths must be > 0 nm (min {a.min()!r})")
    if grid:
        if a.ndim != 1 or a.size < 2:
            raise SpectraError(f"{name}: must be a 1-D grid of at least 2 wavelengths")
        if np.any(np.diff(a) <= 0):
            raise SpectraError(f"{name}: must be strictly increasing")
    return a


def _unit_values(value, name: str) -> np.ndarray:
    a = _float_array(value, name)
    if np.any(a < 0) or np.any(a > 1):
        raise SpectraError(
            f"{name}: values must lie in [0, 1] (min {a.min()!r}, max {a.max()!r})"
        )
    return a


def _on_grid(value, name: str, wavelength_nm: np.ndarray, *, unit: bool) -> np.ndarray:
    """Validate a scalar or per-wavelength array and broadcast it to the grid shape."""
    a = _unit_values(value, name) if unit else _float_array(value, name)
    if not unit and np.any(a < 0):
        raise SpectraError(f"{name}: must be >= 0 (min {a.min()!r})")
    if a.ndim not in (0, 1) or (a.ndim == 1 and a.shape != wavelength_nm.shape):
        raise SpectraError(
            f"{name}: must be a scalar or have the shape of wavelength_nm "
            f"{wavelength_nm.shape} (got shape {a.shape})"
        )
    return np.broadcast_to(a, wavelength_nm.shape)


# --------------------------------------------------------------------------------------
# Grid and Planck law
# --------------------------------------------------------------------------------------


def wavelength_grid_nm(*, start_nm: float, end_nm: float, step_nm: float) -> np.ndarray:
    """Uniform wavelength grid including both ends.

    Parameters
    ----------
    start_nm, end_nm : float
        First and last wavelength, nm; ``0 < start_nm < end_nm``.
    step_nm : float
        Spacing, nm; ``end_nm - start_nm`` must be a whole multiple of it (to 1e-9
        relative).

    Returns
    -------
    numpy.ndarray
        ``start_nm + step_nm * arange(n + 1)``, nm, with ``n = (end - start) / step``.

    Raises
    ------
    SpectraError
        Non-finite or non-positive values, ``end_nm <= start_nm``, or a span that is not
        a whole number of steps.
    """
    start = _positive_scalar(start_nm, "start_nm")
    end = _positive_scalar(end_nm, "end_nm")
    step = _positive_scalar(step_nm, "step_nm")
    if end <= start:
        raise SpectraError(f"end_nm: must be > start_nm ({end!r} <= {start!r})")
    n_float = (end - start) / step
    n = int(round(n_float))
    if n < 1 or abs(n - n_float) > 1e-9 * max(n_float, 1.0):
        raise SpectraError(
            f"step_nm: end_nm - start_nm = {end - start!r} is not a whole multiple of "
            f"step_nm = {step!r}"
        )
    return start + step * np.arange(n + 1, dtype=float)


def planck_photon_radiance(*, wavelength_nm, temperature_k) -> np.ndarray:
    """Blackbody photon spectral radiance.

    Planck's law per unit wavelength (Rybicki & Lightman 1979, *Radiative Processes in
    Astrophysics*, sec. 1.5),
    ``B_lambda = 2 h c^2 / lambda^5 / (exp(h c / (lambda k T)) - 1)``, divided by the
    photon energy ``h c / lambda``:

    ``N_lambda = 2 c / lambda^4 / (exp(h c / (lambda k T)) - 1)``  [photons s^-1 m^-2 sr^-1 m^-1],

    returned per nanometre (times 1e-9).

    Parameters
    ----------
    wavelength_nm : array_like
        Vacuum wavelength(s), nm, > 0.
    temperature_k : float or array_like
        Temperature(s), K, > 0; broadcast against ``wavelength_nm``.

    Returns
    -------
    numpy.ndarray
        Photon spectral radiance, photons s^-1 m^-2 sr^-1 nm^-1.
    """
    lam_nm = _wavelengths(wavelength_nm)
    t = _float_array(temperature_k, "temperature_k")
    if np.any(t <= 0):
        raise SpectraError(f"temperature_k: must be > 0 K (min {t.min()!r})")
    lam_m = lam_nm * _NM
    x = _C2_M_K / (lam_m * t)
    with np.errstate(over="ignore"):
        denom = np.expm1(x)
    return 2.0 * C_LIGHT_M_S / lam_m**4 / denom * _NM


def total_photon_radiance(*, temperature_k: float) -> float:
    """Blackbody photon radiance integrated over all wavelengths.

    ``N = integral N_lambda d(lambda) = 4 zeta(3) k^3 T^3 / (h^3 c^2)``, from the
    substitution ``x = h c / (lambda k T)`` in :func:`planck_photon_radiance` and
    ``integral_0^inf x^2 / (e^x - 1) dx = Gamma(3) zeta(3) = 2 zeta(3)`` (Gradshteyn &
    Ryzhik, *Table of Integrals*, 3.411.1). The photon exitance of a blackbody surface
    is ``pi N`` (Lambertian).

    Parameters
    ----------
    temperature_k : float
        Temperature, K, > 0.

    Returns
    -------
    float
        Photon radiance, photons s^-1 m^-2 sr^-1.
    """
    t = _positive_scalar(temperature_k, "temperature_k")
    from scipy.special import zeta  # on first use (0.2 s of start-up)

    zeta3 = float(zeta(3.0, 1.0))
    return 4.0 * zeta3 * (K_BOLTZMANN_J_K * t) ** 3 / (H_PLANCK_J_S**3 * C_LIGHT_M_S**2)


# --------------------------------------------------------------------------------------
# Spectral types
# --------------------------------------------------------------------------------------

_CLASS_OFFSET = {"O": 0.0, "B": 10.0, "A": 20.0, "F": 30.0, "G": 40.0, "K": 50.0, "M": 60.0}
_SPT_RE = re.compile(r"^\s*([OBAFGKM])\s*(\d(?:\.\d+)?)\s*(V|IV|III|II|Ib|Iab|Ia|I)?\s*$")


def _read_data_csv(name: str) -> tuple[list[str], list[list[str]]]:
    text = resources.files("simcam").joinpath("data", name).read_text(encoding="utf-8")
    rows = [ln.strip() for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]
    header = rows[0].split(",")
    return header, [r.split(",") for r in rows[1:]]


@functools.lru_cache(maxsize=1)
def _spectral_table() -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    _, rows = _read_data_csv("spectral_types.csv")
    names = tuple(r[0] for r in rows)
    codes = np.array([_spectral_code(n) for n in names])
    teff = np.array([float(r[1]) for r in rows])
    return names, codes, teff


def _spectral_code(spectral_type: str) -> float:
    m = _SPT_RE.match(spectral_type)
    if m is None:
        raise SpectraError(
            f"spectral_type: {spectral_type!r} is not an MK type such as 'G2V' "
            "(class O, B, A, F, G, K or M, subclass 0-9.5, optional luminosity class V)"
        )
    cls, sub, lum = m.groups()
    if lum is not None and lum != "V":
        raise SpectraError(
            f"spectral_type: {spectral_type!r} has luminosity class {lum}; only dwarfs "
            "(class V) are tabulated"
        )
    subclass = float(sub)
    if subclass >= 10:
        raise SpectraError(f"spectral_type: subclass {sub} of {spectral_type!r} must be < 10")
    return _CLASS_OFFSET[cls] + subclass


def spectral_type_table() -> dict[str, float]:
    """The tabulated dwarf spectral types and their effective temperatures.

    Returns
    -------
    dict
        ``{spectral_type: teff_k}`` in table order (O3V ... M9.5V), from Pecaut &
        Mamajek (2013, ApJS 208, 9, Table 5) / Mamajek's online table, version
        2017.10.19 (``simcam/data/spectral_types.csv``).
    """
    names, _, teff = _spectral_table()
    return dict(zip(names, teff.tolist(), strict=True))


def star_teff_k(*, spectral_type: str) -> float:
    """Effective temperature of a main-sequence star from its MK spectral type.

    Tabulated types return the table value; types between two tabulated ones (e.g.
    ``"G2.5V"``, ``"K8.5V"``) are interpolated linearly in Teff against the numeric
    type code (O0 = 0, B0 = 10, ..., M0 = 60, plus the subclass). A missing luminosity
    class means V.

    Parameters
    ----------
    spectral_type : str
        MK type such as ``"O5V"``, ``"B0V"``, ``"A0V"``, ``"F5V"``, ``"G2V"``,
        ``"K0V"``, ``"M5V"``; range O3V to M9.5V.

    Returns
    -------
    float
        Effective temperature, K (Pecaut & Mamajek 2013, Table 5; Mamajek's online
        table, version 2017.10.19).

    Raises
    ------
    SpectraError
        Not a parseable type, a non-dwarf luminosity class, or outside O3V..M9.5V.
    """
    if not isinstance(spectral_type, str):
        raise SpectraError(f"spectral_type: must be a string (got {spectral_type!r})")
    code = _spectral_code(spectral_type)
    _, codes, teff = _spectral_table()
    if code < codes[0] - 1e-12 or code > codes[-1] + 1e-12:
        raise SpectraError(
            f"spectral_type: {spectral_type!r} is outside the tabulated dwarf range O3V..M9.5V"
        )
    return float(np.interp(code, codes, teff))


# --------------------------------------------------------------------------------------
# V passband and normalisation of stars
# --------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=1)
def _bessell_v_table() -> tuple[np.ndarray, np.ndarray]:
    _, rows = _read_data_csv("bessell_v.csv")
    lam = np.array([float(r[0]) for r in rows])
    resp = np.array([float(r[1]) for r in rows])
    return lam, resp


def bessell_v_response(*, wavelength_nm) -> np.ndarray:
    """Johnson-Cousins V response (Bessell 1990, Table 2), linearly interpolated.

    Parameters
    ----------
    wavelength_nm : array_like
        Wavelength(s), nm.

    Returns
    -------
    numpy.ndarray
        Response per incident photon, normalised to a maximum of 1; zero outside
        470-700 nm.
    """
    lam = _wavelengths(wavelength_nm)
    tab_lam, tab_resp = _bessell_v_table()
    return np.interp(lam, tab_lam, tab_resp, left=0.0, right=0.0)


def bessell_v_sd() -> colour.SpectralDistribution:
    """Bessell (1990) V passband as a colour SpectralDistribution (470-700 nm, 10 nm)."""
    tab_lam, tab_resp = _bessell_v_table()
    return array_to_sd(wavelength_nm=tab_lam, values=tab_resp, name="Bessell (1990) V")


@functools.lru_cache(maxsize=1)
def _v_quadrature() -> tuple[np.ndarray, np.ndarray]:
    """Fine grid (0.1 nm) and trapezoid weights x response over the V band."""
    lam = wavelength_grid_nm(start_nm=470.0, end_nm=700.0, step_nm=0.1)
    return lam, trapezoid_weights_nm(wavelength_nm=lam) * bessell_v_response(wavelength_nm=lam)


def v_band_photon_rate(*, photon_flux_per_nm, wavelength_nm) -> float:
    """Photon rate through the V passband of a tabulated spectrum.

    ``N_V = integral n_lambda(lambda) S_V(lambda) d(lambda)`` (photon-counting synthetic
    photometry, e.g. Bessell & Murphy 2012, PASP 124, 140, appendix, with the
    response read as per photon), with ``n_lambda`` linearly interpolated onto a 0.1 nm grid over
    470-700 nm (zero outside the given grid).

    Parameters
    ----------
    photon_flux_per_nm : array_like
        Photon flux density, photons s^-1 m^-2 nm^-1, on ``wavelength_nm``.
    wavelength_nm : array_like
        Strictly increasing 1-D grid, nm.

    Returns
    -------
    float
        Photons s^-1 m^-2 weighted by the (peak-normalised) V response.
    """
    lam = _wavelengths(wavelength_nm, grid=True)
    flux = _on_grid(photon_flux_per_nm, "photon_flux_per_nm", lam, unit=False)
    qlam, qw = _v_quadrature()
    return float(np.dot(np.interp(qlam, lam, flux, left=0.0, right=0.0), qw))


def v_zero_point_photon_rate() -> float:
    """V-band photon rate of a V = 0 source, photons s^-1 m^-2 (response-weighted).

    The V = 0 reference is the flat ``f_lambda = V_ZERO_POINT_W_M2_NM`` (Bessell,
    Castelli & Plez 1998, Table A2), converted to photons with ``lambda / (h c)``:
    ``N_V0 = integral f_lambda lambda / (h c) S_V d(lambda)``.
    """
    qlam, qw = _v_quadrature()
    photons = V_ZERO_POINT_W_M2_NM * qlam * _NM / _HC_J_M
    return float(np.dot(photons, qw))


def star_photon_flux_per_nm(*, v_mag: float, temperature_k: float, wavelength_nm) -> np.ndarray:
    """Photon flux density of a star of given V magnitude at the top of the telescope.

    The star is a blackbody at ``temperature_k`` (approximation: no lines, no Balmer
    jump), scaled so that its photon rate through the Bessell (1990) V passband equals
    ``10**(-0.4 v_mag)`` times that of the V = 0 reference (flat
    ``f_lambda = 3.631e-11 W m^-2 nm^-1``, Bessell, Castelli & Plez 1998, Table A2):

    ``n_lambda = s N_lambda(T)``, ``s = 10**(-0.4 V) N_V0 / integral N_lambda(T) S_V d(lambda)``,

    with ``N_lambda`` from :func:`planck_photon_radiance` and both band integrals taken
    on a 0.1 nm grid over 470-700 nm (independent of ``wavelength_nm``).
    No atmosphere: a collimated lab source or space.

    Parameters
    ----------
    v_mag : float
        Johnson V magnitude.
    temperature_k : float
        Effective temperature, K (see :func:`star_teff_k`).
    wavelength_nm : array_like
        Wavelengths at which to return the spectrum, nm.

    Returns
    -------
    numpy.ndarray
        Photon flux density, photons s^-1 m^-2 nm^-1, shape of ``wavelength_nm``.
    """
    v = _finite_scalar(v_mag, "v_mag")
    t = _positive_scalar(temperature_k, "temperature_k")
    lam = _wavelengths(wavelength_nm)
    qlam, qw = _v_quadrature()
    band_bb = float(np.dot(planck_photon_radiance(wavelength_nm=qlam, temperature_k=t), qw))
    scale = 10.0 ** (-0.4 * v) * v_zero_point_photon_rate() / band_bb
    return scale * planck_photon_radiance(wavelength_nm=lam, temperature_k=t)


def star_photon_flux_sd(
    *, v_mag: float, temperature_k: float, start_nm: float, end_nm: float, step_nm: float
) -> colour.SpectralDistribution:
    """:func:`star_photon_flux_per_nm` as a colour SpectralDistribution.

    Values in photons s^-1 m^-2 nm^-1 on ``wavelength_grid_nm(start_nm, end_nm, step_nm)``.
    """
    lam = wavelength_grid_nm(start_nm=start_nm, end_nm=end_nm, step_nm=step_nm)
    flux = star_photon_flux_per_nm(v_mag=v_mag, temperature_k=temperature_k, wavelength_nm=lam)
    return array_to_sd(
        wavelength_nm=lam, values=flux, name=f"star V={v_mag} T={temperature_k} K photons"
    )


# --------------------------------------------------------------------------------------
# Interference filters
# --------------------------------------------------------------------------------------

_Z90 = statistics.NormalDist().inv_cdf(0.9)  # 1.2815515655446004 (the standard library's AS 241)


def _ndtr(x):
    """Standard normal CDF, ``0.5 erfc(-x / sqrt 2)`` (``scipy.special.ndtr``'s formula, on the
    standard library's ``math.erfc``: a filter curve is a few hundred points, and importing
    ``scipy.special`` costs 0.2 s of every start)."""
    return np.vectorize(lambda v: 0.5 * math.erfc(-v / math.sqrt(2.0)), otypes=[np.float64])(x)


_RAISED_COSINE_10_90 = (math.acos(-0.8) - math.acos(0.8)) / math.pi  # 0.59033...
_BANDPASS_SHAPES = ("raised_cosine", "erf")


def _bandpass_params(center_nm, width_nm, shape, edge_nm, peak_transmission):
    c = _positive_scalar(center_nm, "center_nm")
    w = _positive_scalar(width_nm, "width_nm")
    e = _positive_scalar(edge_nm, "edge_nm")
    p = _unit_scalar(peak_transmission, "peak_transmission")
    if shape not in _BANDPASS_SHAPES:
        raise SpectraError(f"shape: must be one of {_BANDPASS_SHAPES} (got {shape!r})")
    if shape == "raised_cosine":
        roll = e / _RAISED_COSINE_10_90
        if roll > w:
            raise SpectraError(
                f"edge_nm: a raised-cosine edge of 10-90 % width {e!r} nm needs a "
                f"roll-off of {roll:.4g} nm, wider than width_nm = {w!r}; "
                f"use edge_nm <= {w * _RAISED_COSINE_10_90:.4g}"
            )
    elif e > w:
        raise SpectraError(f"edge_nm: must be <= width_nm ({e!r} > {w!r})")
    if c - w / 2 - 2 * e <= 0:
        raise SpectraError(f"center_nm: the band reaches non-positive wavelengths (center {c!r})")
    return c, w, e, p


@functools.lru_cache(maxsize=256)
def _erf_plateau_width(width_nm: float, sigma_nm: float) -> float:
    """Top-hat width ``a`` whose convolution with N(0, sigma) has FWHM ``width_nm``.

    Profile ``g(x) = Phi((x + a/2)/s) - Phi((x - a/2)/s)``; solve ``g(w/2) = g(0)/2``.
    """
    s = sigma_nm

    def f(a: float) -> float:
        g0 = 2.0 * _ndtr(a / (2 * s)) - 1.0
        gw = _ndtr((width_nm + a) / (2 * s)) - _ndtr((width_nm - a) / (2 * s))
        return gw - 0.5 * g0

    # f < 0 for a -> 0+ (half-max of a Gaussian is at 1.1774 s < w/2 when a is tiny only if
    # w > 2.3548 s, which edge_nm <= width_nm guarantees); f > 0 for a = 2 w.
    lo = 1e-9 * width_nm
    hi = 2.0 * width_nm
    if f(lo) >= 0:  # Gaussian limit already wider than requested
        raise SpectraError(
            f"edge_nm: too wide for width_nm = {width_nm!r}: even a pure Gaussian with "
            f"these edges has FWHM > width_nm"
        )
    from scipy.optimize import brentq  # on first use: scipy.optimize costs 0.2 s of start-up

    return float(brentq(f, lo, hi, xtol=1e-13 * width_nm, rtol=1e-15, maxiter=200))


def bandpass_array(
    *,
    wavelength_nm,
    center_nm: float,
    width_nm: float,
    shape: str = "raised_cosine",
    edge_nm: float = 10.0,
    peak_transmission: float = 1.0,
) -> np.ndarray:
    """Transmission of a flat-top interference filter with smooth edges.

    The FWHM equals ``width_nm`` exactly and the maximum equals ``peak_transmission``.
    ``edge_nm`` is the 10 %-90 % width of each edge. Two edge shapes (parametric
    stand-ins for a filter vendor's curve):

    ``"raised_cosine"``: flat top ``|x| <= w/2 - r/2`` (``x = lambda - center``), then
        ``T = T_peak (1 + cos(pi (|x| - w/2 + r/2) / r)) / 2`` for ``|x| < w/2 + r/2``,
        zero beyond; roll-off ``r = edge_nm / 0.59033`` (the 10-90 % fraction of a
        half cosine period, ``(acos(-0.8) - acos(0.8)) / pi``). ``T(w/2) = T_peak/2``
        by construction. Compact support; requires ``r <= w``.
    ``"erf"``: a top hat of width ``a`` convolved with a Gaussian of
        ``sigma = edge_nm / (2 * 1.28155)`` (``Phi^-1(0.9)``), i.e.
        ``T = T_peak [Phi((x + a/2)/sigma) - Phi((x - a/2)/sigma)] / (2 Phi(a/(2 sigma)) - 1)``,
        with ``a`` solved (Brent) so that ``T(w/2) = T_peak / 2``.

    Parameters
    ----------
    wavelength_nm : array_like
        Wavelengths, nm.
    center_nm, width_nm : float
        Centre and FWHM of the passband, nm.
    shape : {"raised_cosine", "erf"}
        Edge shape.
    edge_nm : float
        10-90 % edge width, nm.
    peak_transmission : float
        Maximum transmission, 0..1.

    Returns
    -------
    numpy.ndarray
        Transmission, 0..1, shape of ``wavelength_nm``.
    """
    lam = _wavelengths(wavelength_nm)
    c, w, e, p = _bandpass_params(center_nm, width_nm, shape, edge_nm, peak_transmission)
    x = np.abs(lam - c)
    if shape == "raised_cosine":
        r = e / _RAISED_COSINE_10_90
        u = np.clip((x - (w / 2 - r / 2)) / r, 0.0, 1.0)
        return p * 0.5 * (1.0 + np.cos(np.pi * u))
    sigma = e / (2.0 * _Z90)
    a = _erf_plateau_width(w, sigma)
    g0 = 2.0 * _ndtr(a / (2 * sigma)) - 1.0
    g = _ndtr((x + a / 2) / sigma) - _ndtr((x - a / 2) / sigma)
    return np.clip(p * g / g0, 0.0, p)


def bandpass_sd(
    *,
    center_nm: float,
    width_nm: float,
    shape: str = "raised_cosine",
    edge_nm: float = 10.0,
    peak_transmission: float = 1.0,
    step_nm: float = 1.0,
) -> colour.SpectralDistribution:
    """:func:`bandpass_array` as a colour SpectralDistribution.

    Sampled every ``step_nm`` over ``center -/+ (width/2 + 3 edge_nm)`` rounded outwards
    to whole steps (transmission there is < 1e-5 of the peak for both shapes).
    See :func:`bandpass_array` for the model; sample it on another grid with
    :func:`sd_to_array` or call :func:`bandpass_array` directly (exact).
    """
    c, w, e, _ = _bandpass_params(center_nm, width_nm, shape, edge_nm, peak_transmission)
    step = _positive_scalar(step_nm, "step_nm")
    half = w / 2 + 3 * e / (_RAISED_COSINE_10_90 if shape == "raised_cosine" else 1.0)
    start = step * math.floor((c - half) / step)
    end = step * math.ceil((c + half) / step)
    start = max(start, step)
    lam = wavelength_grid_nm(start_nm=start, end_nm=end, step_nm=step)
    t = bandpass_array(
        wavelength_nm=lam, center_nm=c, width_nm=w, shape=shape, edge_nm=e,
        peak_transmission=peak_transmission,
    )
    return array_to_sd(wavelength_nm=lam, values=t, name=f"filter {c:g}/{w:g} nm {shape}")


# --------------------------------------------------------------------------------------
# Detector QE, optics transmission, tables
# --------------------------------------------------------------------------------------


def cmos_qe_array(
    *, wavelength_nm, peak_qe: float, peak_nm: float, blue_cutoff_nm: float, red_cutoff_nm: float
) -> np.ndarray:
    """Parametric quantum efficiency of a front-side-illuminated monochrome CMOS sensor.

    A **parametric stand-in, not a vendor curve**: a split (two-sided) Gaussian in
    wavelength that peaks at ``peak_qe`` at ``peak_nm`` and falls to half the peak at
    ``blue_cutoff_nm`` and ``red_cutoff_nm``,

    ``QE = peak_qe exp(-ln 2 ((lambda - peak_nm) / (peak_nm - blue_cutoff_nm))^2)``
    for ``lambda <= peak_nm``, the same with ``red_cutoff_nm - peak_nm`` above,

    and zero beyond the silicon band-gap wavelength
    ``h c / E_g = 1107 nm`` (``E_g = 1.12 eV``, Sze & Ng 2007). The curve is C1 at the
    peak; its integral over all wavelengths (ignoring the band-gap cut) is
    ``peak_qe sqrt(pi / ln 2) / 2 (red_cutoff_nm - blue_cutoff_nm)``.

    Parameters
    ----------
    wavelength_nm : array_like
        Wavelengths, nm.
    peak_qe : float
        Peak QE, electrons per photon, in (0, 1].
    peak_nm : float
        Wavelength of the peak, nm.
    blue_cutoff_nm, red_cutoff_nm : float
        Half-maximum wavelengths, nm, ``blue_cutoff_nm < peak_nm < red_cutoff_nm``.

    Returns
    -------
    numpy.ndarray
        QE, 0..1, shape of ``wavelength_nm``.
    """
    lam = _wavelengths(wavelength_nm)
    q = _unit_scalar(peak_qe, "peak_qe")
    if q == 0:
        raise SpectraError("peak_qe: must be > 0")
    pk = _positive_scalar(peak_nm, "peak_nm")
    b = _positive_scalar(blue_cutoff_nm, "blue_cutoff_nm")
    r = _positive_scalar(red_cutoff_nm, "red_cutoff_nm")
    if not b < pk:
        raise SpectraError(f"blue_cutoff_nm: must be < peak_nm ({b!r} >= {pk!r})")
    if not r > pk:
        raise SpectraError(f"red_cutoff_nm: must be > peak_nm ({r!r} <= {pk!r})")
    gap_nm = _HC_J_M / (SILICON_BANDGAP_EV * ELEMENTARY_CHARGE_C) / _NM
    if pk >= gap_nm:
        raise SpectraError(f"peak_nm: must be below the silicon cut-off {gap_nm:.1f} nm")
    half_width = np.where(lam <= pk, pk - b, r - pk)
    qe = q * np.exp(-math.log(2.0) * ((lam - pk) / half_width) ** 2)
    return np.where(lam <= gap_nm, qe, 0.0)


def cmos_qe_sd(
    *,
    peak_qe: float,
    peak_nm: float,
    blue_cutoff_nm: float,
    red_cutoff_nm: float,
    start_nm: float = 300.0,
    end_nm: float = 1100.0,
    step_nm: float = 1.0,
) -> colour.SpectralDistribution:
    """:func:`cmos_qe_array` as a colour SpectralDistribution on a uniform grid (nm)."""
    lam = wavelength_grid_nm(start_nm=start_nm, end_nm=end_nm, step_nm=step_nm)
    qe = cmos_qe_array(
        wavelength_nm=lam, peak_qe=peak_qe, peak_nm=peak_nm,
        blue_cutoff_nm=blue_cutoff_nm, red_cutoff_nm=red_cutoff_nm,
    )
    return array_to_sd(wavelength_nm=lam, values=qe, name="FSI CMOS QE (parametric)")


def flat_transmission_array(*, wavelength_nm, transmission: float) -> np.ndarray:
    """Wavelength-independent optics transmission (0..1) on a grid (nm)."""
    lam = _wavelengths(wavelength_nm)
    t = _unit_scalar(transmission, "transmission")
    return np.full(lam.shape, t)


def array_to_sd(*, wavelength_nm, values, name: str = "") -> colour.SpectralDistribution:
    """Wrap a sampled curve into a colour SpectralDistribution.

    Parameters
    ----------
    wavelength_nm : array_like
        Strictly increasing 1-D grid, nm.
    values : array_like
        Finite values, same shape.
    name : str
        Name of the distribution.
    """
    lam = _wavelengths(wavelength_nm, grid=True)
    v = _float_array(values, "values")
    if v.shape != lam.shape:
        raise SpectraError(f"values: shape {v.shape} differs from wavelength_nm {lam.shape}")
    import colour

    return colour.SpectralDistribution(dict(zip(lam.tolist(), v.tolist(), strict=True)), name=name)


def sd_to_array(*, sd: colour.SpectralDistribution, wavelength_nm, fill: float = 0.0) -> np.ndarray:
    """Sample a SpectralDistribution on a grid by linear interpolation.

    Linear interpolation (``numpy.interp``) between the SD's samples keeps values within
    the range of the samples (no spline overshoot), so a transmission stays in [0, 1].
    Outside the SD's domain the value is ``fill``.

    Parameters
    ----------
    sd : colour.SpectralDistribution
        Distribution with wavelengths in nm.
    wavelength_nm : array_like
        Wavelengths to sample, nm.
    fill : float
        Value outside the SD's wavelength range.

    Returns
    -------
    numpy.ndarray
        Sampled values, shape of ``wavelength_nm``.
    """
    import colour

    if not isinstance(sd, colour.SpectralDistribution):
        raise SpectraError(f"sd: must be a colour.SpectralDistribution (got {type(sd).__name__})")
    lam = _wavelengths(wavelength_nm)
    f = _finite_scalar(fill, "fill")
    return np.interp(lam, np.asarray(sd.wavelengths, float), np.asarray(sd.values, float),
                     left=f, right=f)


def table_sd(*, wavelength_nm, value, name: str = "table") -> colour.SpectralDistribution:
    """A user table (wavelength_nm, value in [0, 1]) as a SpectralDistribution.

    For measured optics transmission, filter curves or QE. Wavelengths must be strictly
    increasing and positive, values within [0, 1].
    """
    v = _unit_values(value, "value")
    return array_to_sd(wavelength_nm=wavelength_nm, values=v, name=name)


def read_table_csv(*, path) -> colour.SpectralDistribution:
    """Read a two-column CSV table ``wavelength_nm,value`` (0..1) into a SpectralDistribution.

    Lines starting with ``#`` are comments; a first row that is not numeric is taken as a
    header and must read ``wavelength_nm,value``.
    """
    p = pathlib.Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as err:
        raise SpectraError(f"path: cannot read {str(p)!r}: {err.strerror}") from None
    rows = [ln.strip() for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if rows and not re.match(r"^[-+0-9.]", rows[0]):
        header = [h.strip() for h in rows[0].split(",")]
        if header != ["wavelength_nm", "value"]:
            raise SpectraError(f"{p}: header must be 'wavelength_nm,value' (got {rows[0]!r})")
        rows = rows[1:]
    lam, val = [], []
    for i, r in enumerate(rows, start=1):
        parts = [s.strip() for s in r.split(",")]
        if len(parts) != 2:
            raise SpectraError(f"{p}: data row {i}: expected 2 columns (got {len(parts)})")
        try:
            lam.append(float(parts[0]))
            val.append(float(parts[1]))
        except ValueError:
            raise SpectraError(f"{p}: data row {i}: not a number in {r!r}") from None
    if len(lam) < 2:
        raise SpectraError(f"{p}: needs at least 2 data rows")
    try:
        return table_sd(wavelength_nm=lam, value=val, name=p.stem)
    except SpectraError as err:
        raise SpectraError(f"{p}: {err}") from None


# --------------------------------------------------------------------------------------
# The chain: photons -> electrons
# --------------------------------------------------------------------------------------


def circular_aperture_area_m2(*, diameter_mm: float, obstruction_diameter_mm: float = 0.0) -> float:
    """Collecting area of a circular aperture with an optional central obstruction, m^2.

    ``A = pi / 4 (D^2 - d^2)``.
    """
    d = _positive_scalar(diameter_mm, "diameter_mm")
    o = _positive_scalar(obstruction_diameter_mm, "obstruction_diameter_mm", allow_zero=True)
    if o >= d:
        raise SpectraError(f"obstruction_diameter_mm: must be < diameter_mm ({o!r} >= {d!r})")
    return math.pi / 4.0 * (d**2 - o**2) * 1e-6


def detected_electron_rate_per_nm(
    *, photon_flux_per_nm, aperture_area_m2: float, transmission, filter_transmission, qe,
    wavelength_nm,
) -> np.ndarray:
    """Photo-electron rate density at the detector.

    ``r(lambda) = n_lambda(lambda) A tau_optics(lambda) tau_filter(lambda) QE(lambda)``
    i.e. the integrand of the photon-counting signal equation
    ``N_e = t integral n_lambda A tau QE d(lambda)`` (QE in electrons per incident
    photon; the photon-counting synthetic-photometry integral of Bessell & Murphy 2012,
    PASP 124, 140, appendix, with the camera's throughput as the response).

    Parameters
    ----------
    photon_flux_per_nm : array_like
        Photon flux density at the entrance pupil, photons s^-1 m^-2 nm^-1, >= 0, on
        ``wavelength_nm``.
    aperture_area_m2 : float
        Collecting area, m^2.
    transmission, filter_transmission, qe : float or array_like
        Optics transmission, filter transmission and QE, 0..1, scalars or arrays on
        ``wavelength_nm`` (use ``filter_transmission=1.0`` for no filter).
    wavelength_nm : array_like
        1-D strictly increasing grid, nm.

    Returns
    -------
    numpy.ndarray
        Electron rate density, e- s^-1 nm^-1, shape of ``wavelength_nm``.
    """
    lam = _wavelengths(wavelength_nm, grid=True)
    flux = _on_grid(photon_flux_per_nm, "photon_flux_per_nm", lam, unit=False)
    area = _positive_scalar(aperture_area_m2, "aperture_area_m2")
    tau = _on_grid(transmission, "transmission", lam, unit=True)
    filt = _on_grid(filter_transmission, "filter_transmission", lam, unit=True)
    q = _on_grid(qe, "qe", lam, unit=True)
    return flux * area * tau * filt * q


def trapezoid_weights_nm(*, wavelength_nm) -> np.ndarray:
    """Trapezoid-rule weights (nm) of a 1-D grid: ``integral f = sum w_i f_i``.

    ``w_0 = (l_1 - l_0)/2``, ``w_i = (l_{i+1} - l_{i-1})/2``, ``w_{n-1} = (l_{n-1} - l_{n-2})/2``.
    """
    lam = _wavelengths(wavelength_nm, grid=True)
    d = np.diff(lam)
    w = np.empty_like(lam)
    w[0] = d[0] / 2
    w[-1] = d[-1] / 2
    w[1:-1] = (d[:-1] + d[1:]) / 2
    return w


def electrons_per_exposure(*, electron_rate_per_nm, wavelength_nm, exposure_s: float) -> float:
    """Photo-electrons collected in an exposure (trapezoid rule over the grid).

    ``N_e = t_exp integral r(lambda) d(lambda)``.

    Parameters
    ----------
    electron_rate_per_nm : array_like
        e- s^-1 nm^-1 on ``wavelength_nm`` (from :func:`detected_electron_rate_per_nm`).
    wavelength_nm : array_like
        1-D strictly increasing grid, nm.
    exposure_s : float
        Exposure time, s, >= 0.

    Returns
    -------
    float
        Expected number of electrons (mean, before shot noise), e-.
    """
    lam = _wavelengths(wavelength_nm, grid=True)
    rate = _on_grid(electron_rate_per_nm, "electron_rate_per_nm", lam, unit=False)
    t = _positive_scalar(exposure_s, "exposure_s", allow_zero=True)
    return float(t * np.dot(rate, trapezoid_weights_nm(wavelength_nm=lam)))


def normalised_weights(*, electron_rate_per_nm, wavelength_nm) -> np.ndarray:
    """Per-sample weights of a polychromatic PSF, summing to 1.

    ``w_i = r_i W_i / sum_j r_j W_j`` with ``W`` the trapezoid weights of the grid, so
    that ``sum_i w_i PSF(lambda_i)`` is the trapezoid estimate of the
    electron-weighted mean PSF.

    Parameters
    ----------
    electron_rate_per_nm : array_like
        e- s^-1 nm^-1 (any positive scale) on ``wavelength_nm``, >= 0, not all zero.
    wavelength_nm : array_like
        1-D strictly increasing grid, nm.

    Returns
    -------
    numpy.ndarray
        Weights, >= 0, summing to 1.
    """
    lam = _wavelengths(wavelength_nm, grid=True)
    rate = _on_grid(electron_rate_per_nm, "electron_rate_per_nm", lam, unit=False)
    w = rate * trapezoid_weights_nm(wavelength_nm=lam)
    total = w.sum()
    if not total > 0:
        raise SpectraError("electron_rate_per_nm: is zero everywhere; no weights to normalise")
    return w / total


# --------------------------------------------------------------------------------------
# Lamp
# --------------------------------------------------------------------------------------


def lamp_photon_spectrum_per_nm(*, temperature_k: float = CIE_A_TEMPERATURE_K, wavelength_nm) -> np.ndarray:
    """Relative photon spectrum of a tungsten (blackbody) lamp.

    ``n(lambda) = N_lambda(lambda, T) / N_lambda(560 nm, T)``, the Planck photon
    radiance (:func:`planck_photon_radiance`) normalised to 1 at 560 nm, the
    normalisation wavelength of CIE illuminant A (CIE 15:2004; A is a 2856 K
    Planckian radiator). Multiply by :func:`lamp_scale_to_match_star` to get photons
    s^-1 m^-2 nm^-1 at the entrance pupil.

    Parameters
    ----------
    temperature_k : float
        Lamp (filament colour) temperature, K; default 2856 K.
    wavelength_nm : array_like
        Wavelengths, nm.

    Returns
    -------
    numpy.ndarray
        Relative photon spectral flux (1 at 560 nm), dimensionless.
    """
    t = _positive_scalar(temperature_k, "temperature_k")
    lam = _wavelengths(wavelength_nm)
    ref = planck_photon_radiance(wavelength_nm=_LAMP_REFERENCE_NM, temperature_k=t)
    return planck_photon_radiance(wavelength_nm=lam, temperature_k=t) / ref


def lamp_scale_to_match_star(
    *,
    v_mag: float,
    star_temperature_k: float,
    lamp_temperature_k: float = CIE_A_TEMPERATURE_K,
    wavelength_nm,
    transmission,
    qe,
) -> float:
    """Scale of the lamp spectrum that gives the same signal as a star.

    Returns ``k`` such that the lamp ``k * lamp_photon_spectrum_per_nm(...)`` seen
    through the camera's unfiltered band yields the same electrons per exposure as the
    star ``star_photon_flux_per_nm(v_mag, star_temperature_k)``:

    ``k = sum_i n_star,i tau_i QE_i W_i / sum_i n_lamp,i tau_i QE_i W_i``

    (trapezoid weights ``W`` on ``wavelength_nm``; aperture and exposure cancel).
    Seed 000: "target brightness matched to the camera (better than Mv 7.5)".

    Parameters
    ----------
    v_mag : float
        V magnitude of the star to match.
    star_temperature_k : float
        Star effective temperature, K.
    lamp_temperature_k : float
        Lamp temperature, K (default 2856 K, CIE illuminant A).
    wavelength_nm : array_like
        1-D strictly increasing grid, nm.
    transmission, qe : float or array_like
        Optics transmission and QE on the grid, 0..1.

    Returns
    -------
    float
        Scale, photons s^-1 m^-2 nm^-1 per unit of the relative lamp spectrum.
    """
    lam = _wavelengths(wavelength_nm, grid=True)
    star = star_photon_flux_per_nm(v_mag=v_mag, temperature_k=star_temperature_k, wavelength_nm=lam)
    lamp = lamp_photon_spectrum_per_nm(temperature_k=lamp_temperature_k, wavelength_nm=lam)
    kw = dict(aperture_area_m2=1.0, transmission=transmission, filter_transmission=1.0, qe=qe,
              wavelength_nm=lam)
    e_star = electrons_per_exposure(
        electron_rate_per_nm=detected_electron_rate_per_nm(photon_flux_per_nm=star, **kw),
        wavelength_nm=lam, exposure_s=1.0,
    )
    e_lamp = electrons_per_exposure(
        electron_rate_per_nm=detected_electron_rate_per_nm(photon_flux_per_nm=lamp, **kw),
        wavelength_nm=lam, exposure_s=1.0,
    )
    if not e_lamp > 0:
        raise SpectraError("qe: transmission x QE is zero over the grid; the lamp gives no signal")
    return e_star / e_lamp
