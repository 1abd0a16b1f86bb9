"""Star centroiding on windows: background and dark removal, thresholds, the centroid
methods (centre of gravity, IWCoG, Gaussian fit), flags and centroid tables.

The full-frame steps (detection, matching, cutting windows, the frame pipeline) are in
:mod:`budget.centroid.frames`; the numba kernels in :mod:`budget.centroid.kernels`.

What seed 000 does (section 1.2): "inter-frame difference denoising and the centroid
method [10-11], sub-pixel centroid extraction of the star-target image". We implement:

* **Background / dark removal.** A static lab target cancels in the difference of two
  lit frames, so the only inter-frame difference that keeps the star is *lit frame minus
  a star-free frame* (lamp off or shutter closed, same exposure and temperature): that
  removes the dark signal, DSNU, hot pixels and any stray-light pattern pixel by pixel.
  :func:`subtract_dark` subtracts one dark frame, or the mean of ``K`` dark frames, which
  adds ``1/K`` of the dark-frame temporal variance instead of doubling it. The residual
  background level is then removed per window by :func:`window_background` (median of
  the window border, robust to the star's wings), or by a given level.
* **Threshold.** ``threshold_sigma * noise`` above the background (``noise`` given, or
  the border MAD scaled to a standard deviation), or an absolute ``threshold_dn``.
* **Detection** and **matching** on full frames: :mod:`budget.centroid.frames`.
* **Centroid.** Thresholded centre of gravity (the seed's method; its sub-pixel
  "interpolation" is the intensity weighting of pixel centres) in a numba kernel on a
  batch of windows; beside it the iteratively weighted centre of gravity (IWCoG), a
  Gaussian-weighted centroid iterated to its fixed point (K. L. Baker and M. M.
  Moallem, Opt. Express 15, 5147 (2007); A. Vyas, M. B. Roopashree, B. R. Prasad,
  "Performance of centroiding algorithms at low light level conditions in adaptive
  optics", ARTCom 2009), which has a much smaller S-curve and noise sensitivity; and a
  least-squares fit of a pixel-integrated 2-D Gaussian plus background
  (Levenberg-Marquardt in numba; Gaussian fitting as compared by R. C. Stone, AJ 97,
  1227 (1989)).

Flag bits (:class:`CentroidFlag`, column ``flag``; 0 = good):

====  ===============  =====================================================
bit   name             meaning
====  ===============  =====================================================
1     NONFINITE        a NaN/inf pixel in the window (left out of the sums)
2     SATURATED        a pixel at or above the saturation level / ADC maximum
4     LOST             no pixel above threshold: x = y = flux = NaN
8     EDGE             peak on the window border or window cut by the frame edge
16    NOT_CONVERGED    IWCoG or Gaussian fit not converged in ``max_iter``
32    UNMATCHED        no detection within the matching radius in this frame
====  ===============  =====================================================

Every flag set produces one :class:`CentroidWarning` per call naming the stars/frames.
"""

from __future__ import annotations

import enum
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from budget.centroid import kernels as _k
from simcam.infra.errors import UserInputError

__all__ = [
    "CentroidFlag",
    "CentroidWarning",
    "subtract_dark",
    "window_background",
    "centroid_cog",
    "centroid_iwcog",
    "centroid_gaussian_fit",
    "centroid_windows",
]


class CentroidWarning(UserWarning):
    """A star was flagged (lost, saturated, non-finite pixels, unmatched, ...)."""


class CentroidFlag(enum.IntFlag):
    """Bits of the ``flag`` column of a centroid table (0 = good)."""

    NONFINITE = _k.FLAG_NONFINITE
    SATURATED = _k.FLAG_SATURATED
    LOST = _k.FLAG_LOST
    EDGE = _k.FLAG_EDGE
    NOT_CONVERGED = _k.FLAG_NOT_CONVERGED
    UNMATCHED = _k.FLAG_UNMATCHED


_FLAG_TEXT = {
    CentroidFlag.NONFINITE: "non-finite pixels (left out of the centroid)",
    CentroidFlag.SATURATED: "saturated pixels",
    CentroidFlag.LOST: "no pixel above threshold (star lost; x, y = NaN)",
    CentroidFlag.EDGE: "peak on the window border or window cut by the frame edge",
    CentroidFlag.NOT_CONVERGED: "iteration did not converge",
    CentroidFlag.UNMATCHED: "no detection within the matching radius",
}


# --------------------------------------------------------------------------- inputs


def _as_windows(windows: Any) -> np.ndarray:
    arr = np.asarray(windows)
    if arr.ndim == 2:
        arr = arr[None]
    if arr.ndim != 3:
        raise UserInputError(f"windows: expected an array (n, h, w), got shape {arr.shape}")
    if arr.shape[1] < 3 or arr.shape[2] < 3:
        raise UserInputError(f"windows: each window must be at least 3x3, got {arr.shape[1:]}")
    if not np.issubdtype(arr.dtype, np.number):
        raise UserInputError(f"windows: expected numeric pixels, got dtype {arr.dtype}")
    return np.ascontiguousarray(arr, dtype=np.float64)


def _per_window(value: Any, n: int, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise UserInputError(f"{name}: expected a scalar or {n} values, got shape {arr.shape}")
    return np.ascontiguousarray(arr)


def _saturation_level(saturation_dn: float | None, adc_max_dn: float | None) -> float:
    levels = [v for v in (saturation_dn, adc_max_dn) if v is not None]
    for name, v in (("saturation_dn", saturation_dn), ("adc_max_dn", adc_max_dn)):
        if v is not None and not np.isfinite(v):
            raise UserInputError(f"{name}: must be finite, got {v}")
    return float(min(levels)) if levels else np.inf


# ---------------------------------------------------------------- background, dark


def subtract_dark(frames: Any, *, dark: Any) -> np.ndarray:
    """Inter-frame difference: lit frame(s) minus a star-free (dark/background) frame.

    Parameters
    ----------
    frames : array (rows, cols) or (n, rows, cols)
        Lit frames (DN).
    dark : array (rows, cols) or (k, rows, cols)
        One star-free frame or a stack of ``k`` of them (DN), averaged before use so the
        difference carries ``(1 + 1/k)`` times the single-frame temporal variance.

    Returns
    -------
    numpy.ndarray, float64
        ``frames - mean(dark)`` with the shape of ``frames`` (DN).
    """
    f = np.asarray(frames, dtype=np.float64)
    d = np.asarray(dark, dtype=np.float64)
    if d.ndim == 3:
        d = d.mean(axis=0)
    if d.ndim != 2 or f.shape[-2:] != d.shape:
        raise UserInputError(
            f"dark: shape {np.shape(dark)} does not match the frames' {f.shape[-2:]}"
        )
    return f - d


def window_background(windows: Any) -> tuple[np.ndarray, np.ndarray]:
    """Robust local background of each window from its border pixels.

    Parameters
    ----------
    windows : array (n, h, w)

    Returns
    -------
    median, sigma : float64 arrays (n,)
        Border median and ``1.4826 * MAD`` of the border (pixel unit).
    """
    w = _as_windows(windows)
    med = np.empty(w.shape[0])
    sig = np.empty(w.shape[0])
    _k.border_stats(w, med, sig)
    return med, sig


# ---------------------------------------------------------------- window centroids


def _thresholds(
    windows: np.ndarray,
    *,
    background: Any,
    threshold_sigma: float,
    threshold_dn: Any,
    noise_dn: Any,
) -> tuple[np.ndarray, np.ndarray]:
    n = windows.shape[0]
    need_border = isinstance(background, str) or (threshold_dn is None and noise_dn is None)
    if need_border:
        med, sig = window_background(windows)
    if isinstance(background, str):
        if background == "border":
            bg = med
        elif background == "none":
            bg = np.zeros(n)
        else:
            raise UserInputError(
                f"background: expected 'border', 'none', a number or an array, got {background!r}"
            )
    else:
        bg = _per_window(background, n, "background")
    if threshold_dn is not None:
        thr = _per_window(threshold_dn, n, "threshold_dn")
    else:
        noise = sig if noise_dn is None else _per_window(noise_dn, n, "noise_dn")
        thr = float(threshold_sigma) * noise
    return np.ascontiguousarray(bg), np.ascontiguousarray(thr)


def centroid_cog(
    windows: Any,
    *,
    x0: Any,
    y0: Any,
    background: Any = "border",
    threshold_sigma: float = 3.0,
    threshold_dn: Any = None,
    noise_dn: Any = None,
    subtract_threshold: bool = False,
    saturation_dn: float | None = None,
    adc_max_dn: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Thresholded centre of gravity of a batch of windows (seed 000 section 1.2).

    ``x = x0 + sum_ij w_ij j / sum_ij w_ij`` (and ``y`` with ``i``), where
    ``w_ij = s_ij`` if ``s_ij = I_ij - b > t`` else 0 (``s_ij - t`` when
    ``subtract_threshold``).

    Parameters
    ----------
    windows : array (n, h, w)
        Pixel values (DN or e-).
    x0, y0 : scalar or array (n,)
        Mosaic position (px) of each window's pixel ``[0, 0]``.
    background : {'border', 'none'}, float or array (n,)
        Background ``b``: border median, zero, or given level(s).
    threshold_sigma : float
        ``t = threshold_sigma * noise`` (noise = ``noise_dn`` or the border MAD sigma).
    threshold_dn : float or array (n,), optional
        Absolute threshold ``t`` above background (overrides ``threshold_sigma``).
    noise_dn : float or array (n,), optional
    subtract_threshold : bool
    saturation_dn, adc_max_dn : float, optional
        Pixels at or above the smaller of the two are flagged saturated.

    Returns
    -------
    x, y : float64 arrays (n,)
        Mosaic px; NaN when lost.
    flux : float64 array (n,)
        Sum of background-subtracted signal above threshold (pixel unit).
    flag : int64 array (n,)
        `CentroidFlag` bits.
    """
    w = _as_windows(windows)
    n = w.shape[0]
    bg, thr = _thresholds(w, background=background, threshold_sigma=threshold_sigma,
                          threshold_dn=threshold_dn, noise_dn=noise_dn)
    xs, ys = _per_window(x0, n, "x0"), _per_window(y0, n, "y0")
    out_x, out_y, out_f = np.empty(n), np.empty(n), np.empty(n)
    flag = np.zeros(n, dtype=np.int64)
    flag[~np.isfinite(bg) | ~np.isfinite(thr)] |= CentroidFlag.LOST
    _k.thresholded_cog(w, xs, ys, bg, np.where(np.isfinite(thr), thr, np.inf),
                       bool(subtract_threshold), _saturation_level(saturation_dn, adc_max_dn),
                       out_x, out_y, out_f, flag)
    return out_x, out_y, out_f, flag


def centroid_iwcog(
    windows: Any,
    *,
    x0: Any,
    y0: Any,
    weight_sigma_px: float,
    psf_sigma_px: float | None = None,
    background: Any = "border",
    threshold_sigma: float = 3.0,
    threshold_dn: Any = None,
    noise_dn: Any = None,
    max_iter: int = 100,
    tol_px: float = 1e-6,
    saturation_dn: float | None = None,
    adc_max_dn: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Iteratively weighted centre of gravity (Gaussian weight), batch.

    Starts at the thresholded centre of gravity, then iterates the Gaussian-weighted
    centroid (Baker & Moallem 2007, Vyas et al. 2009) on the background-subtracted
    window (no threshold: the weight suppresses the noise far from the star). For a
    Gaussian PSF of variance ``p^2`` and weight variance ``s^2`` the plain iteration
    contracts by ``p^2 / (p^2 + s^2)`` per step; with ``psf_sigma_px`` given the step is
    multiplied by ``gain = (p^2 + 1/12 + s^2) / s^2`` (pixel-integrated PSF), which
    reaches the same fixed point in a few steps.

    Parameters
    ----------
    windows, x0, y0, background, threshold_sigma, threshold_dn, noise_dn,
    saturation_dn, adc_max_dn
        As in :func:`centroid_cog` (the threshold only sets the starting point).
    weight_sigma_px : float
        Standard deviation of the Gaussian weight (px), ideally the PSF's.
    psf_sigma_px : float, optional
        PSF standard deviation (px) for the step gain; plain iteration when omitted.
    max_iter : int
    tol_px : float
        Stop when a step is shorter than this (px).

    Returns
    -------
    x, y, flux, flag
        As in :func:`centroid_cog`; ``flux`` is the background-subtracted window sum.
    """
    if not weight_sigma_px > 0:
        raise UserInputError(f"weight_sigma_px: must be > 0, got {weight_sigma_px}")
    if psf_sigma_px is not None and not psf_sigma_px > 0:
        raise UserInputError(f"psf_sigma_px: must be > 0, got {psf_sigma_px}")
    if max_iter < 1:
        raise UserInputError(f"max_iter: must be >= 1, got {max_iter}")
    w = _as_windows(windows)
    n = w.shape[0]
    xs, ys = _per_window(x0, n, "x0"), _per_window(y0, n, "y0")
    bg, thr = _thresholds(w, background=background, threshold_sigma=threshold_sigma,
                          threshold_dn=threshold_dn, noise_dn=noise_dn)
    sat = _saturation_level(saturation_dn, adc_max_dn)
    cx, cy, _, flag = np.empty(n), np.empty(n), np.empty(n), np.zeros(n, dtype=np.int64)
    _k.thresholded_cog(w, np.zeros(n), np.zeros(n), bg, np.where(np.isfinite(thr), thr, np.inf),
                       False, sat, cx, cy, np.empty(n), flag)
    flag &= ~np.int64(CentroidFlag.EDGE)  # the starting point's edge test is not the result's
    s2 = float(weight_sigma_px) ** 2
    gain = 1.0 if psf_sigma_px is None else (float(psf_sigma_px) ** 2 + 1.0 / 12.0 + s2) / s2
    out_x, out_y, out_f = np.empty(n), np.empty(n), np.empty(n)
    niter = np.zeros(n, dtype=np.int64)
    flag2 = np.zeros(n, dtype=np.int64)
    _k.iterative_weighted_cog(w, xs, ys, bg, cx, cy, float(weight_sigma_px), gain,
                              int(max_iter), float(tol_px), sat, out_x, out_y, out_f, flag2, niter)
    return out_x, out_y, out_f, flag | flag2


def centroid_gaussian_fit(
    windows: Any,
    *,
    x0: Any,
    y0: Any,
    sigma_start_px: float = 1.0,
    background: Any = "border",
    threshold_sigma: float = 3.0,
    threshold_dn: Any = None,
    noise_dn: Any = None,
    max_iter: int = 50,
    tol_px: float = 1e-7,
    saturation_dn: float | None = None,
    adc_max_dn: float | None = None,
    return_details: bool = False,
) -> tuple[np.ndarray, ...]:
    """Least-squares fit of a pixel-integrated circular 2-D Gaussian plus background.

    Model ``F E(j; x, s) E(i; y, s) + B`` with ``E`` the unit Gaussian integrated over
    each pixel; Levenberg-Marquardt on ``(F, x, y, s, B)``, unweighted (the
    maximum-likelihood position for a Gaussian PSF in uniform Gaussian noise; R. C.
    Stone, AJ 97, 1227 (1989)). Start: thresholded CoG, ``sigma_start_px`` and the
    background estimate.

    Parameters
    ----------
    windows, x0, y0, background, threshold_sigma, threshold_dn, noise_dn,
    saturation_dn, adc_max_dn
        As in :func:`centroid_cog` (background and threshold only set the start).
    sigma_start_px : float
        Starting Gaussian width (px).
    max_iter : int
    tol_px : float
        Stop when a step moves the centre by less than this (px).
    return_details : bool
        Also return the fitted width (px) and background.

    Returns
    -------
    x, y, flux, flag [, sigma_px, background]
        Mosaic px, fitted total flux ``F`` (pixel unit), `CentroidFlag` bits.
    """
    if not sigma_start_px > 0:
        raise UserInputError(f"sigma_start_px: must be > 0, got {sigma_start_px}")
    if max_iter < 1:
        raise UserInputError(f"max_iter: must be >= 1, got {max_iter}")
    w = _as_windows(windows)
    n = w.shape[0]
    xs, ys = _per_window(x0, n, "x0"), _per_window(y0, n, "y0")
    bg, thr = _thresholds(w, background=background, threshold_sigma=threshold_sigma,
                          threshold_dn=threshold_dn, noise_dn=noise_dn)
    sat = _saturation_level(saturation_dn, adc_max_dn)
    cx, cy, flag = np.empty(n), np.empty(n), np.zeros(n, dtype=np.int64)
    _k.thresholded_cog(w, np.zeros(n), np.zeros(n), bg, np.where(np.isfinite(thr), thr, np.inf),
                       False, sat, cx, cy, np.empty(n), flag)
    flag &= ~np.int64(CentroidFlag.EDGE)
    out = [np.empty(n) for _ in range(5)]
    flag2 = np.zeros(n, dtype=np.int64)
    niter = np.zeros(n, dtype=np.int64)
    _k.gaussian_fit(w, xs, ys, cx, cy, float(sigma_start_px), np.where(np.isfinite(bg), bg, 0.0),
                    int(max_iter), float(tol_px), sat, *out, flag2, niter)
    x, y, f, sig, b = out
    if return_details:
        return x, y, f, flag | flag2, sig, b
    return x, y, f, flag | flag2


def warn_flags(flag: np.ndarray, star: np.ndarray, frame: np.ndarray, *, stacklevel: int = 3) -> None:
    """One :class:`CentroidWarning` per flag bit set in ``flag``, naming the ``star`` and
    ``frame`` of its first five rows."""
    bits = int(np.bitwise_or.reduce(flag))
    for bit, text in _FLAG_TEXT.items():
        if not bits & int(bit):
            continue
        hit = np.flatnonzero((flag & int(bit)) != 0)
        examples = ", ".join(f"(star={int(star[i])}, frame={int(frame[i])})" for i in hit[:5])
        more = "" if hit.size <= 5 else f" and {hit.size - 5} more"
        warnings.warn(
            f"{hit.size} centroid(s) flagged {bit.name}: {text}: {examples}{more}",
            CentroidWarning, stacklevel=stacklevel,
        )


def table_columns(
    *, star: Any, frame: Any, x: np.ndarray, y: np.ndarray, flux: np.ndarray, flag: np.ndarray,
    flux_column: str, extra_columns: Mapping[str, Any] | None,
) -> dict[str, np.ndarray]:
    """The columns of a centroid table, in table order: ``star, frame, x, y, <flux_column>,
    flag`` and the extra columns (a scalar repeated on every row)."""
    n = x.size
    cols: dict[str, Any] = {
        "star": _per_window(star, n, "star").astype(np.int64),
        "frame": _per_window(frame, n, "frame").astype(np.int64),
        "x": x, "y": y, flux_column: flux, "flag": flag.astype(np.int64),
    }
    for name, value in (extra_columns or {}).items():
        if name in cols:
            raise UserInputError(f"extra_columns: {name!r} clashes with a centroid column")
        arr = np.asarray(value)
        cols[name] = np.repeat(arr, n) if arr.ndim == 0 else arr
        if np.shape(cols[name]) != (n,):
            raise UserInputError(f"extra_columns: {name!r} must be a scalar or {n} values")
    return cols


def centroid_arrays(windows: Any, *, x0: Any, y0: Any, method: str, **options: Any) -> tuple:
    """x, y, flux and flag of each window of a batch by ``method`` (the columns
    :func:`centroid_windows` tabulates)."""
    w = _as_windows(windows)
    return centroid_method(method)(w, x0=x0, y0=y0, **options)


def centroid_windows(
    windows: Any,
    *,
    x0: Any,
    y0: Any,
    star: Any = None,
    frame: Any = 0,
    method: str = "cog",
    extra_columns: Mapping[str, Any] | None = None,
    flux_column: str = "flux_dn",
    **options: Any,
) -> pd.DataFrame:
    """Centroid table of a batch of windows (e.g. the simulator's windows).

    Parameters
    ----------
    windows : array (n, h, w)
    x0, y0 : scalar or array (n,)
        Mosaic position (px) of each window's pixel ``[0, 0]``.
    star : array (n,) of int, optional
        Star ids (default ``0..n-1``).
    frame : int or array (n,)
    method : {'cog', 'iwcog', 'gauss'}
    extra_columns : mapping, optional
        Columns passed through (scalar or ``n`` values), e.g. ``condition``,
        ``filter_nm``, ``field``.
    flux_column : str
        Name of the flux column (``flux_dn`` or ``flux_e`` after the pixel unit).
    **options
        Keyword options of :func:`centroid_cog`, :func:`centroid_iwcog` or
        :func:`centroid_gaussian_fit`.

    Returns
    -------
    pandas.DataFrame
        ``star, frame, x, y, <flux_column>, flag`` and the extra columns. One
        :class:`CentroidWarning` per flag bit that occurs.
    """
    x, y, f, flag = centroid_arrays(windows, x0=x0, y0=y0, method=method, **options)
    cols = table_columns(star=np.arange(x.size) if star is None else star, frame=frame, x=x, y=y,
                          flux=f, flag=flag, flux_column=flux_column, extra_columns=extra_columns)
    warn_flags(cols["flag"], cols["star"], cols["frame"])
    return pd.DataFrame(cols)


_METHODS = {"cog": centroid_cog, "iwcog": centroid_iwcog, "gauss": centroid_gaussian_fit}


def centroid_method(method: str):
    """The window centroid function named ``method``: ``'cog'`` :func:`centroid_cog`,
    ``'iwcog'`` :func:`centroid_iwcog` or ``'gauss'`` :func:`centroid_gaussian_fit`."""
    if method not in _METHODS:
        raise UserInputError(f"method: expected one of {', '.join(_METHODS)}, got {method!r}")
    return _METHODS[method]
