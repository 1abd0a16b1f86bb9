"""The camera's spectral response: detector quantum efficiency (a parametric FSI CMOS
stand-in) and a flat optics transmission."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # colour (and the matplotlib it imports) loads only where a SpectralDistribution is made
    import colour

import numpy as np

from .common import SpectraError, _positive_scalar, _unit_scalar, _wavelengths
from .constants import _HC_J_M, _NM, ELEMENTARY_CHARGE_C, SILICON_BANDGAP_EV
from .planck import wavelength_grid_nm
from .tables import array_to_sd


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
