"""Lamp: a blackbody at the CIE illuminant A temperature 2856 K (CIE 15:2004, sec. 3.1),
and its scale to give the signal of a star."""

from __future__ import annotations

import numpy as np

from .chain import detected_electron_rate_per_nm, electrons_per_exposure
from .common import SpectraError, _positive_scalar, _wavelengths
from .constants import CIE_A_TEMPERATURE_K
from .planck import planck_photon_radiance
from .stars import star_photon_flux_per_nm

_LAMP_REFERENCE_NM = 560.0  # CIE normalisation wavelength of illuminant A


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
