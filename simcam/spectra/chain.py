"""The chain photons -> electrons: aperture area, detected electron rate density (the
photon-counting signal equation, Bessell & Murphy 2012, PASP 124, 140, appendix),
trapezoid-rule integration over the grid, electrons per exposure and spectral weights."""

from __future__ import annotations

import math

import numpy as np

from .common import SpectraError, _on_grid, _positive_scalar, _wavelengths


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
