"""Interference filters: band-pass transmission curves (raised-cosine or erf edges)."""

from __future__ import annotations

import functools
import math
import statistics

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # colour (and the matplotlib it imports) loads only where a SpectralDistribution is made
    import colour

import numpy as np

from .common import SpectraError, _positive_scalar, _unit_scalar, _wavelengths
from .planck import wavelength_grid_nm
from .tables import array_to_sd

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
