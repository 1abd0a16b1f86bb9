"""A star's signal in the TDI line camera: the spectra chain and the patent's shortcut.

* **Spectra chain** (used by the world): B - V -> effective temperature (Ballesteros 2012,
  EPL 97, 34008, eq. 14: ``T = 4600 K (1/(0.92 (B-V) + 1.7) + 1/(0.92 (B-V) + 0.62))``),
  a blackbody at that temperature scaled to the star's V magnitude through the Bessell V
  passband (:func:`simcam.spectra.star_photon_flux_per_nm`), times aperture area, optics
  transmission and the parametric silicon QE (:func:`simcam.spectra.detected_electron_rate_per_nm`),
  integrated over wavelength: the photo-electron rate ``r`` (e-/s); the star collects
  ``r N T`` electrons in the TDI exposure of ``N`` stages of line period ``T``.
* **The patent's shortcut** (seed 004, step 2): the centre-pixel signal
  ``P = N M I0 2.512^-Mag`` with ``N`` the TDI stages, ``M`` a gain/integration factor
  (here: line period x the fraction of the PSF in the centre pixel) and ``I0`` the
  electron rate of a magnitude-0 star. It ignores the star's colour (and uses 2.512 for
  ``10^0.4 = 2.51189``, 0.003 % per magnitude): :func:`patent_pixel_signal_e` is kept beside
  the chain so that the two can be compared (``docs/linecam.md``).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from simcam import spectra

from .scenario import LineCameraModel

__all__ = ["teff_from_b_v", "electron_rate_v0", "star_electron_rate", "patent_pixel_signal_e",
           "centre_pixel_fraction"]

#: wavelength grid of the photometry, nm (silicon responds from ~300 to ~1100 nm)
_GRID = (300.0, 1100.0, 5.0)
#: temperatures of the tabulated V = 0 electron rate, K
_T_TABLE = np.geomspace(2000.0, 50000.0, 64)


def teff_from_b_v(b_v) -> np.ndarray:
    """Effective temperature (K) from Johnson B - V (Ballesteros 2012, eq. 14).

    ``T = 4600 K (1 / (0.92 (B-V) + 1.7) + 1 / (0.92 (B-V) + 0.62))``; B - V is clipped to
    [-0.4, 2.0], where the formula (a blackbody fit to main-sequence colours) stays sane.
    """
    bv = np.clip(np.asarray(b_v, dtype=float), -0.4, 2.0)
    return 4600.0 * (1.0 / (0.92 * bv + 1.7) + 1.0 / (0.92 * bv + 0.62))


@lru_cache(maxsize=8)
def _rate_table(cam: LineCameraModel) -> np.ndarray:
    lam = spectra.wavelength_grid_nm(start_nm=_GRID[0], end_nm=_GRID[1], step_nm=_GRID[2])
    qe = spectra.cmos_qe_array(wavelength_nm=lam, peak_qe=cam.qe.peak_qe, peak_nm=cam.qe.peak_nm,
                               blue_cutoff_nm=cam.qe.blue_cutoff_nm, red_cutoff_nm=cam.qe.red_cutoff_nm)
    area = spectra.circular_aperture_area_m2(diameter_mm=cam.aperture_mm)
    out = np.empty(_T_TABLE.size)
    for i, t in enumerate(_T_TABLE):
        flux = spectra.star_photon_flux_per_nm(v_mag=0.0, temperature_k=float(t), wavelength_nm=lam)
        rate = spectra.detected_electron_rate_per_nm(photon_flux_per_nm=flux, aperture_area_m2=area,
                                                     transmission=cam.transmission,
                                                     filter_transmission=1.0, qe=qe, wavelength_nm=lam)
        out[i] = spectra.electrons_per_exposure(electron_rate_per_nm=rate, wavelength_nm=lam, exposure_s=1.0)
    return out


def electron_rate_v0(cam: LineCameraModel, temperature_k) -> np.ndarray:
    """Photo-electron rate (e-/s) of a V = 0 blackbody star at ``temperature_k``.

    Interpolated in log T on a 64-point table of the full chain (error < 0.1 %).
    """
    t = np.clip(np.asarray(temperature_k, dtype=float), _T_TABLE[0], _T_TABLE[-1])
    return np.interp(np.log(t), np.log(_T_TABLE), _rate_table(cam))


def star_electron_rate(cam: LineCameraModel, *, v_mag, b_v) -> np.ndarray:
    """Photo-electron rate (e-/s) of stars of Johnson V and B - V: ``r0(T(B-V)) 10^(-0.4 V)``."""
    return electron_rate_v0(cam, teff_from_b_v(b_v)) * 10.0 ** (-0.4 * np.asarray(v_mag, dtype=float))


def centre_pixel_fraction(sigma_px: float) -> float:
    """Fraction of a centred Gaussian PSF (rms ``sigma_px``) in its pixel: ``erf(1/(2 sqrt2 s))^2``."""
    return math.erf(0.5 / (math.sqrt(2.0) * sigma_px)) ** 2


def patent_pixel_signal_e(mag, *, n_stages: int, m: float, i0_e_s: float) -> np.ndarray:
    """The patent's centre-pixel signal ``P = N M I0 2.512^-Mag`` (seed 004, step 2), e-.

    Parameters
    ----------
    mag : array_like
        Star magnitude.
    n_stages : int
        TDI stages N.
    m : float
        Integration factor M, s (line period x centre-pixel fraction of the PSF).
    i0_e_s : float
        Electron rate of a magnitude-0 star, e-/s.
    """
    return n_stages * m * i0_e_s * 2.512 ** (-np.asarray(mag, dtype=float))
