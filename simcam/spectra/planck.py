"""Wavelength grids and Planck's law in photon units (Rybicki & Lightman 1979, *Radiative
Processes in Astrophysics*, sec. 1.5, divided by the photon energy ``h c / lambda``)."""

from __future__ import annotations


import numpy as np

from .common import SpectraError, _float_array, _positive_scalar, _wavelengths
from .constants import _C2_M_K, _NM, C_LIGHT_M_S, H_PLANCK_J_S, K_BOLTZMANN_J_K


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
