"""Star centroiding: background removal, detection, windows, centre of gravity.

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
* **Detection** on a full frame: pixels above threshold, connected components
  (``scipy.ndimage.label``, 8-connectivity), peak pixel of each component.
* **Matching** across frames: each reference star takes the nearest detection within
  ``match_radius_px``.
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
import math
import warnings
from collections.abc import Mapping, Sequence
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
    "detect_stars",
    "extract_windows",
    "match_stars",
    "centroid_cog",
    "centroid_iwcog",
    "centroid_gaussian_fit",
    "centroid_windows",
    "centroid_frames",
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


# ---------------------------------------------------------------- full-frame steps


#: pixels of the regular subsample behind a frame's level and noise: the median's standard
#: error is 1.25 sigma / sqrt(n) = 0.005 sigma, the MAD sigma's relative one 1.65 / sqrt(n) = 0.6 %
LEVEL_SAMPLES = 1 << 16


def _subsample(frame: np.ndarray, dark: np.ndarray | None = None, *, max_samples: int = LEVEL_SAMPLES) -> np.ndarray:
    """Evenly spaced whole rows of ``frame - dark`` (at most about ``max_samples`` pixels), float64.

    Whole rows are read contiguously (a pixel-strided sample of a large frame costs a
    cache miss per pixel)."""
    img = np.asarray(frame)
    rows = img.shape[0] if img.ndim == 2 else 1
    img2 = img.reshape(rows, -1)
    row_step = max(1, -(-rows * img2.shape[1] // max_samples))
    sample = img2[::row_step].astype(np.float64).ravel()
    if dark is not None:
        sample -= np.asarray(dark, dtype=np.float64).reshape(rows, -1)[::row_step].ravel()
    return sample


def _frame_level_and_noise(frame: np.ndarray, *, max_samples: int = LEVEL_SAMPLES) -> tuple[float, float]:
    """Median and MAD sigma of a frame, from evenly spaced rows (:func:`_subsample`)."""
    sample = _subsample(frame, max_samples=max_samples)
    finite = sample[np.isfinite(sample)]
    if finite.size == 0:
        raise UserInputError("frame: no finite pixel")
    med = float(np.median(finite))
    mad = float(np.median(np.abs(finite - med))) * 1.482602218505602
    return med, mad


def detect_stars(
    frame: Any,
    *,
    threshold_sigma: float = 5.0,
    threshold_dn: float | None = None,
    background_dn: float | None = None,
    noise_dn: float | None = None,
    min_pixels: int = 3,
) -> pd.DataFrame:
    """Coarse detection: threshold and 8-connected components, peak pixel of each.

    Parameters
    ----------
    frame : array (rows, cols)
        Frame (DN), background/dark already removed or not (see ``background_dn``).
    threshold_sigma : float
        Threshold in units of ``noise_dn`` above ``background_dn`` (ignored when
        ``threshold_dn`` is given).
    threshold_dn : float, optional
        Absolute threshold above the background (DN).
    background_dn, noise_dn : float, optional
        Background level and noise (DN); default: median and MAD-based sigma of a
        regular subsample of the frame (at most about 1e6 pixels).
    min_pixels : int
        Smallest component kept (pixels above threshold); the default 3 rejects single
        noise excursions and hot pixels (a 5-sigma threshold passes about 2 single
        noise pixels on a 4096 x 2048 frame).

    Returns
    -------
    pandas.DataFrame
        Columns ``x_peak``, ``y_peak`` (int, mosaic px), ``peak_dn`` (above background),
        ``npix``; sorted by ``y_peak`` then ``x_peak``.
    """
    img = np.asarray(frame, dtype=np.float64)
    if img.ndim != 2:
        raise UserInputError(f"frame: expected a 2-D array, got shape {img.shape}")
    if background_dn is None or (threshold_dn is None and noise_dn is None):
        level, noise = _frame_level_and_noise(img)
    bg = level if background_dn is None else float(background_dn)
    if threshold_dn is not None:
        thr = float(threshold_dn)
    else:
        nz = noise if noise_dn is None else float(noise_dn)
        if not nz > 0:
            raise UserInputError(
                "noise_dn: frame noise is zero or unknown; give threshold_dn or noise_dn > 0"
            )
        thr = float(threshold_sigma) * nz
    sig = img - bg
    mask = np.isfinite(sig) & (sig > thr)
    from scipy import ndimage  # on first use (a window-only run never labels a frame)

    labels, n = ndimage.label(mask, structure=np.ones((3, 3), dtype=bool))
    if n == 0:
        return pd.DataFrame({"x_peak": np.array([], dtype=np.int64),
                             "y_peak": np.array([], dtype=np.int64),
                             "peak_dn": np.array([], dtype=np.float64),
                             "npix": np.array([], dtype=np.int64)})
    # peak of each component from the above-threshold pixels only (no full-frame sort)
    flat = np.flatnonzero(mask)
    lab = labels.ravel()[flat]
    val = sig.ravel()[flat]
    order = np.lexsort((-val, lab))                  # by label, brightest first
    lab_sorted = lab[order]
    first = order[np.r_[True, lab_sorted[1:] != lab_sorted[:-1]]]
    rows_, cols_ = np.divmod(flat[first], img.shape[1])
    npix = np.bincount(lab, minlength=n + 1)[1:].astype(np.int64)
    out = pd.DataFrame({"x_peak": cols_.astype(np.int64), "y_peak": rows_.astype(np.int64),
                        "peak_dn": val[first], "npix": npix})
    out = out[out["npix"] >= int(min_pixels)]
    return out.sort_values(["y_peak", "x_peak"], kind="stable").reset_index(drop=True)


def _detect_near(raw: np.ndarray, dark, ref: np.ndarray, *, background_dn: float, noise_dn: float,
                 search_px: int, match_radius_px: float, threshold_sigma: float, threshold_dn: float | None,
                 min_pixels: int) -> pd.DataFrame | None:
    """:func:`detect_stars` restricted to boxes of half-side ``search_px`` around the references.

    Gives the detections :func:`match_stars` can match (every component whose peak lies
    within the match radius of a reference), as the whole-frame labelling would. A component
    cut by a box's side is left out unless its peak in the box lies within the match radius
    of a reference; then this returns ``None`` and the caller labels the whole frame (a
    component whose true peak is within the radius of a reference is either whole in that
    reference's box or cut with that same peak inside it). A component seen from two
    overlapping boxes is counted once.
    """
    rows, cols = raw.shape
    thr = float(threshold_dn) if threshold_dn is not None else float(threshold_sigma) * float(noise_dn)
    if not thr > 0 and threshold_dn is None:
        raise UserInputError("noise_dn: frame noise is zero or unknown; give threshold_dn or noise_dn > 0")
    from scipy import ndimage  # on first use (a window-only run never labels a frame)

    structure = np.ones((3, 3), dtype=bool)
    peaks: dict[tuple[int, int], tuple[float, int]] = {}
    boxes = []   # (r0, c0, labels, cut labels) of each box
    doubtful = []  # peaks of cut components within the match radius of a reference
    for xr, yr in np.rint(ref).astype(np.int64):
        r0, r1 = max(yr - search_px, 0), min(yr + search_px + 1, rows)
        c0, c1 = max(xr - search_px, 0), min(xr + search_px + 1, cols)
        if r0 >= r1 or c0 >= c1:
            continue
        box = raw[r0:r1, c0:c1].astype(np.float64)
        if dark is not None:
            box -= dark[r0:r1, c0:c1]
        sig = box - background_dn
        mask = np.isfinite(sig) & (sig > thr)
        if not mask.any():
            continue
        labels, n = ndimage.label(mask, structure=structure)
        # peak of each component (brightest pixel, first in raster order on ties) and its
        # size, as detect_stars finds them
        flat = np.flatnonzero(mask)
        lab = labels.ravel()[flat]
        val = sig.ravel()[flat]
        order = np.lexsort((-val, lab))
        ls = lab[order]
        first = order[np.r_[True, ls[1:] != ls[:-1]]]
        npix = np.bincount(lab, minlength=n + 1)[1:]
        # a component on a side of the box that is not the frame's edge may go on outside:
        # its size and peak here are not the whole component's
        sides = [e for e, inside in ((labels[0, :], r0 > 0), (labels[-1, :], r1 < rows),
                                     (labels[:, 0], c0 > 0), (labels[:, -1], c1 < cols)) if inside]
        cut = set(np.unique(np.concatenate(sides)).tolist()) - {0} if sides else set()
        boxes.append((r0, c0, labels, cut))
        w = c1 - c0
        for f in first:
            k = int(lab[f])
            pr, pc = divmod(int(flat[f]), w)
            y_pk, x_pk = pr + r0, pc + c0
            if k in cut:
                # harmless unless the whole-frame labelling could match it
                if np.any(np.hypot(ref[:, 0] - x_pk, ref[:, 1] - y_pk) <= match_radius_px + 1e-9):
                    doubtful.append((y_pk, x_pk))
                continue
            peaks[(y_pk, x_pk)] = (float(val[f]), int(npix[k - 1]))
    for y_pk, x_pk in doubtful:
        # fine if another box holds that pixel in a whole component (found there, exactly)
        whole = False
        for r0, c0, labels, cut in boxes:
            i, j = y_pk - r0, x_pk - c0
            if 0 <= i < labels.shape[0] and 0 <= j < labels.shape[1]:
                lab = int(labels[i, j])
                if lab and lab not in cut:
                    whole = True
                    break
        if not whole:
            return None
    if not peaks:
        keys, vals = [], []
    else:
        keys, vals = zip(*peaks.items())
    out = pd.DataFrame({"x_peak": np.array([k[1] for k in keys], dtype=np.int64),
                        "y_peak": np.array([k[0] for k in keys], dtype=np.int64),
                        "peak_dn": np.array([v[0] for v in vals], dtype=np.float64),
                        "npix": np.array([v[1] for v in vals], dtype=np.int64)})
    out = out[out["npix"] >= int(min_pixels)]
    return out.sort_values(["y_peak", "x_peak"], kind="stable").reset_index(drop=True)


def extract_windows(
    frame: Any, *, x_center: Any, y_center: Any, size_px: int = 11
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Cut ``size_px`` x ``size_px`` windows centred on integer pixel positions.

    Parts of a window outside the frame are NaN and flagged `CentroidFlag.EDGE`.

    Parameters
    ----------
    frame : array (rows, cols)
    x_center, y_center : array-like of int (n,)
        Mosaic pixel (column, row) at the window centre.
    size_px : int
        Odd window side (px).

    Returns
    -------
    windows : float64 array (n, size_px, size_px)
    x0, y0 : float64 arrays (n,)
        Mosaic position of each window's pixel ``[0, 0]``.
    flag : int64 array (n,)
    """
    img = np.asarray(frame)  # windows are float64; the frame is not copied whole
    if img.ndim != 2:
        raise UserInputError(f"frame: expected a 2-D array, got shape {img.shape}")
    if size_px < 3 or size_px % 2 != 1:
        raise UserInputError(f"size_px: must be an odd integer >= 3, got {size_px}")
    xc = np.asarray(x_center, dtype=np.int64).ravel()
    yc = np.asarray(y_center, dtype=np.int64).ravel()
    half = size_px // 2
    n = xc.size
    rows, cols = img.shape
    out = np.full((n, size_px, size_px), np.nan)
    flag = np.zeros(n, dtype=np.int64)
    x0 = (xc - half).astype(np.float64)
    y0 = (yc - half).astype(np.float64)
    for q in range(n):
        r0, c0 = yc[q] - half, xc[q] - half
        ra, rb = max(r0, 0), min(r0 + size_px, rows)
        ca, cb = max(c0, 0), min(c0 + size_px, cols)
        if ra >= rb or ca >= cb:
            flag[q] |= CentroidFlag.EDGE
            continue
        if ra != r0 or ca != c0 or rb != r0 + size_px or cb != c0 + size_px:
            flag[q] |= CentroidFlag.EDGE
        out[q, ra - r0:rb - r0, ca - c0:cb - c0] = img[ra:rb, ca:cb]
    return out, x0, y0, flag


def match_stars(
    *, x: Any, y: Any, x_ref: Any, y_ref: Any, match_radius_px: float = 3.0
) -> np.ndarray:
    """Match each reference star to the nearest detection within a radius.

    Parameters
    ----------
    x, y : array-like (m,)
        Detected positions (mosaic px).
    x_ref, y_ref : array-like (n,)
        Reference positions (mosaic px).
    match_radius_px : float

    Returns
    -------
    numpy.ndarray of int64 (n,)
        Index into the detections for each reference star, ``-1`` when none lies within
        the radius or when a closer reference star already took that detection.
    """
    det = np.column_stack([np.asarray(x, float).ravel(), np.asarray(y, float).ravel()])
    ref = np.column_stack([np.asarray(x_ref, float).ravel(), np.asarray(y_ref, float).ravel()])
    out = np.full(ref.shape[0], -1, dtype=np.int64)
    if det.shape[0] == 0 or ref.shape[0] == 0:
        return out
    from scipy.spatial import cKDTree  # on first use: 0.16 s of start-up

    dist, idx = cKDTree(det).query(ref, k=1, distance_upper_bound=float(match_radius_px))
    ok = np.isfinite(dist)
    # a detection claimed by several references goes to the closest one only
    order = np.argsort(np.where(ok, dist, np.inf), kind="stable")
    taken: set[int] = set()
    for r in order:
        if not ok[r]:
            continue
        d = int(idx[r])
        if d in taken:
            continue
        taken.add(d)
        out[r] = d
    return out


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


def _warn_flags(flag: np.ndarray, star: np.ndarray, frame: np.ndarray, *, stacklevel: int = 3) -> None:
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


def _table_columns(
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


def _centroid_arrays(windows: Any, *, x0: Any, y0: Any, method: str, **options: Any) -> tuple:
    """x, y, flux and flag of each window of a batch by ``method`` (the columns
    :func:`centroid_windows` tabulates)."""
    w = _as_windows(windows)
    return _METHODS[_method(method)](w, x0=x0, y0=y0, **options)


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
    x, y, f, flag = _centroid_arrays(windows, x0=x0, y0=y0, method=method, **options)
    cols = _table_columns(star=np.arange(x.size) if star is None else star, frame=frame, x=x, y=y,
                          flux=f, flag=flag, flux_column=flux_column, extra_columns=extra_columns)
    _warn_flags(cols["flag"], cols["star"], cols["frame"])
    return pd.DataFrame(cols)


def centroid_frames(
    frames: Any,
    *,
    dark: Any = None,
    reference_xy: Any = None,
    frame_ids: Sequence[int] | None = None,
    window_size_px: int = 11,
    threshold_sigma: float = 5.0,
    threshold_dn: float | None = None,
    noise_dn: float | None = None,
    min_pixels: int = 3,
    match_radius_px: float = 3.0,
    method: str = "cog",
    background: Any = "border",
    saturation_dn: float | None = None,
    adc_max_dn: float | None = None,
    extra_columns: Mapping[str, Any] | None = None,
    flux_column: str = "flux_dn",
    **method_options: Any,
) -> pd.DataFrame:
    """Detect, window and centroid the stars of a sequence of full frames.

    Parameters
    ----------
    frames : array (n, rows, cols) or sequence of 2-D arrays
        Frames (DN).
    dark : array (rows, cols) or (k, rows, cols), optional
        Star-free frame(s) subtracted first (:func:`subtract_dark`).
    reference_xy : array (W, 2), optional
        Reference star positions (mosaic px); star ``j`` is row ``j``. Default: the
        detections of the first frame.
    frame_ids : sequence of int, optional
        Frame numbers (default ``0..n-1``).
    window_size_px : int
        Window side (px, odd).
    threshold_sigma, threshold_dn, noise_dn
        Detection threshold above the frame's median (noise from the frame MAD unless
        given); the same threshold is used in the windows.
    min_pixels : int
    match_radius_px : float
    method : {'cog', 'iwcog', 'gauss'}
    background : {'border', 'none'} or float
        Background in the windows.
    saturation_dn, adc_max_dn : float, optional
    extra_columns : mapping, optional
        Scalar columns passed through (``condition``, ``filter_nm``, ``field``).
    flux_column : str
    **method_options
        Extra options of the centroid method (e.g. ``weight_sigma_px`` for IWCoG,
        ``sigma_start_px`` for the Gaussian fit).

    Returns
    -------
    pandas.DataFrame
        One row per reference star and frame: ``star, frame, x, y, <flux>, flag`` plus
        the extra columns; a star without a detection in a frame gets
        ``UNMATCHED | LOST`` and NaN position.
    """
    _method(method)
    stack = list(frames)            # references only; each frame is converted in turn
    if not stack:
        raise UserInputError("frames: no frame given")
    shape = np.shape(stack[0])
    for q, f in enumerate(stack):
        if np.ndim(f) != 2 or np.shape(f) != shape:
            raise UserInputError(f"frames[{q}]: shape {np.shape(f)} differs from {shape}")
    if dark is not None:
        dark = np.asarray(dark, dtype=np.float64)
        dark = dark.mean(axis=0) if dark.ndim == 3 else dark

    def prepared(f: Any) -> np.ndarray:
        return subtract_dark(f, dark=dark) if dark is not None else np.asarray(f, dtype=np.float64)

    ids = list(range(len(stack))) if frame_ids is None else [int(v) for v in frame_ids]
    if len(ids) != len(stack):
        raise UserInputError(f"frame_ids: {len(ids)} ids for {len(stack)} frames")
    det_opts = dict(threshold_sigma=threshold_sigma, threshold_dn=threshold_dn,
                    min_pixels=min_pixels)
    if reference_xy is None:
        d0 = detect_stars(prepared(stack[0]), noise_dn=noise_dn, **det_opts)
        if d0.empty:
            raise UserInputError("frames[0]: no star above threshold to use as reference")
        ref = d0[["x_peak", "y_peak"]].to_numpy(dtype=np.float64)
    else:
        ref = np.asarray(reference_xy, dtype=np.float64)
        if ref.ndim != 2 or ref.shape[1] != 2 or not np.isfinite(ref).all():
            raise UserInputError("reference_xy: expected finite positions of shape (W, 2)")
    n_ref = ref.shape[0]
    tables = []
    for fid, raw in zip(ids, stack):
        raw = np.asarray(raw)
        # level and noise from a regular subsample: the same numbers as from the whole
        # dark-subtracted frame, without making it (a full float64 copy costs 20-30 ms)
        level, noise = _frame_level_and_noise(_subsample(raw, dark))
        if noise_dn is not None:
            noise = float(noise_dn)
        det = None
        if reference_xy is not None:
            det = _detect_near(raw, dark, ref, background_dn=level, noise_dn=noise,
                               search_px=int(math.ceil(match_radius_px)) + window_size_px // 2 + 2,
                               match_radius_px=match_radius_px, **det_opts)
        if det is None:  # no reference list, or a component larger than a search box: whole frame
            det = detect_stars(prepared(raw), background_dn=level, noise_dn=noise, **det_opts)
        m = match_stars(x=det["x_peak"], y=det["y_peak"], x_ref=ref[:, 0], y_ref=ref[:, 1],
                        match_radius_px=match_radius_px)
        found = m >= 0
        xc = np.rint(ref[:, 0]).astype(np.int64)
        yc = np.rint(ref[:, 1]).astype(np.int64)
        xc[found] = det["x_peak"].to_numpy()[m[found]]
        yc[found] = det["y_peak"].to_numpy()[m[found]]
        win, x0, y0, eflag = extract_windows(raw, x_center=xc, y_center=yc, size_px=window_size_px)
        if dark is not None:
            win -= extract_windows(dark, x_center=xc, y_center=yc, size_px=window_size_px)[0]
        thr = float(threshold_dn) if threshold_dn is not None else float(threshold_sigma) * noise
        opts = dict(background=background, threshold_dn=thr, saturation_dn=saturation_dn,
                    adc_max_dn=adc_max_dn, **method_options)
        x, y, f, flag = _METHODS[method](win, x0=x0, y0=y0, **opts)
        flag |= eflag
        flag[~found] |= CentroidFlag.UNMATCHED | CentroidFlag.LOST
        x[~found] = np.nan
        y[~found] = np.nan
        f[~found] = np.nan
        tables.append(pd.DataFrame(_table_columns(star=np.arange(n_ref), frame=fid, x=x, y=y, flux=f, flag=flag,
                                                  flux_column=flux_column, extra_columns=extra_columns)))
    table = pd.concat(tables, ignore_index=True)
    _warn_flags(table["flag"].to_numpy(), table["star"].to_numpy(), table["frame"].to_numpy())
    return table


_METHODS = {"cog": centroid_cog, "iwcog": centroid_iwcog, "gauss": centroid_gaussian_fit}


def _method(method: str) -> str:
    if method not in _METHODS:
        raise UserInputError(f"method: expected one of {', '.join(_METHODS)}, got {method!r}")
    return method
