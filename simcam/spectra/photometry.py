"""V passband and the V = 0 zero point.

* V passband: Bessell (1990, PASP 102, 1181, Table 2), ``simcam/data/bessell_v.csv``, read
  as a response per photon (Bessell & Murphy 2012, PASP 124, 140, read the 1990 curves as
  energy responses; that reading changes a star's normalisation by -2.4 % (2500 K), +0.2 %
  (5770 K), +0.9 % (9700 K) and +1.5 % (40000 K), well inside the blackbody approximation's
  error).
* V = 0 zero point: ``f_lambda = 363.1e-11 erg s^-1 cm^-2 A^-1`` (Bessell, Castelli & Plez
  1998, A&A 333, 231, Table A2), i.e. 3.631e-11 W m^-2 nm^-1.
"""

from __future__ import annotations

import functools

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # colour (and the matplotlib it imports) loads only where a SpectralDistribution is made
    import colour

import numpy as np

from .chain import trapezoid_weights_nm
from .common import _on_grid, _read_data_csv, _wavelengths
from .constants import _HC_J_M, _NM, V_ZERO_POINT_W_M2_NM
from .planck import wavelength_grid_nm
from .tables import array_to_sd


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
