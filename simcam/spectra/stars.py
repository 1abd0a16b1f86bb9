"""Stars: dwarf effective temperatures by spectral type (Pecaut & Mamajek 2013, ApJS 208, 9,
Table 5, as maintained in E. Mamajek's online table, version 2017.10.19:
``simcam/data/spectral_types.csv``) and the photon flux of a star of given V and Teff, a
**blackbody at Teff** normalised through the V passband (:mod:`.photometry`): no line
blanketing, no Balmer jump, good to roughly 10-20 % in band-integrated photon counts for
A-K dwarfs."""

from __future__ import annotations

import functools
import re

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # colour (and the matplotlib it imports) loads only where a SpectralDistribution is made
    import colour

import numpy as np

from .common import SpectraError, _finite_scalar, _positive_scalar, _read_data_csv, _wavelengths
from .photometry import _v_quadrature, v_zero_point_photon_rate
from .planck import planck_photon_radiance, wavelength_grid_nm
from .tables import array_to_sd

_CLASS_OFFSET = {"O": 0.0, "B": 10.0, "A": 20.0, "F": 30.0, "G": 40.0, "K": 50.0, "M": 60.0}
_SPT_RE = re.compile(r"^\s*([OBAFGKM])\s*(\d(?:\.\d+)?)\s*(V|IV|III|II|Ib|Iab|Ia|I)?\s*$")


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
