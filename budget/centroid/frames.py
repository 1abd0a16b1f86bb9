"""Star centroiding on full frames: detection, matching, windows, and the frame pipeline.

* **Detection** on a full frame (:func:`detect_stars`): pixels above threshold, connected
  components (``scipy.ndimage.label``, 8-connectivity), peak pixel of each component; the
  frame's level and noise from a regular subsample of its rows.
* **Matching** across frames (:func:`match_stars`): each reference star takes the nearest
  detection within ``match_radius_px``.
* **Windows** (:func:`extract_windows`): ``size_px`` x ``size_px`` cut-outs around the
  matched peaks, flagged where the frame's edge cuts them.
* **The pipeline** (:func:`centroid_frames`): dark subtraction, detection (in boxes around
  the references when they are given), matching, windows and one of the window centroid
  methods of :mod:`budget.centroid.core`, into one centroid table for a sequence of frames.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from budget.centroid.core import CentroidFlag, centroid_method, subtract_dark, table_columns, warn_flags
from simcam.infra.errors import UserInputError

__all__ = [
    "detect_stars",
    "extract_windows",
    "match_stars",
    "centroid_frames",
]


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
    centroid = centroid_method(method)
    stack = _frame_stack(frames)
    dark = _mean_dark(dark)
    ids = _frame_ids(frame_ids, len(stack))
    det_opts = dict(threshold_sigma=threshold_sigma, threshold_dn=threshold_dn,
                    min_pixels=min_pixels)
    if reference_xy is None:
        ref = _first_frame_stars(stack[0], dark, noise_dn=noise_dn, det_opts=det_opts)
    else:
        ref = _reference_positions(reference_xy)
    n_ref = ref.shape[0]
    tables = []
    for fid, raw in zip(ids, stack):
        raw = np.asarray(raw)
        det, noise = _frame_detections(raw, dark, None if reference_xy is None else ref, noise_dn=noise_dn,
                                       window_size_px=window_size_px, match_radius_px=match_radius_px,
                                       det_opts=det_opts)
        found, win, x0, y0, eflag = _star_windows(raw, dark, ref, det, match_radius_px=match_radius_px,
                                                  window_size_px=window_size_px)
        thr = float(threshold_dn) if threshold_dn is not None else float(threshold_sigma) * noise
        opts = dict(background=background, threshold_dn=thr, saturation_dn=saturation_dn,
                    adc_max_dn=adc_max_dn, **method_options)
        x, y, f, flag = centroid(win, x0=x0, y0=y0, **opts)
        flag |= eflag
        flag[~found] |= CentroidFlag.UNMATCHED | CentroidFlag.LOST
        x[~found] = np.nan
        y[~found] = np.nan
        f[~found] = np.nan
        tables.append(pd.DataFrame(table_columns(star=np.arange(n_ref), frame=fid, x=x, y=y, flux=f, flag=flag,
                                                 flux_column=flux_column, extra_columns=extra_columns)))
    table = pd.concat(tables, ignore_index=True)
    warn_flags(table["flag"].to_numpy(), table["star"].to_numpy(), table["frame"].to_numpy())
    return table


def _frame_stack(frames: Any) -> list:
    """The frames as a list (references only; each frame is converted in turn), all 2-D and
    of one shape."""
    stack = list(frames)
    if not stack:
        raise UserInputError("frames: no frame given")
    shape = np.shape(stack[0])
    for q, f in enumerate(stack):
        if np.ndim(f) != 2 or np.shape(f) != shape:
            raise UserInputError(f"frames[{q}]: shape {np.shape(f)} differs from {shape}")
    return stack


def _mean_dark(dark: Any) -> np.ndarray | None:
    """The star-free frame subtracted from every frame (float64): ``dark``, or the mean of a
    stack of them; ``None`` for none."""
    if dark is not None:
        dark = np.asarray(dark, dtype=np.float64)
        dark = dark.mean(axis=0) if dark.ndim == 3 else dark
    return dark


def _prepared(frame: Any, dark: np.ndarray | None) -> np.ndarray:
    """A whole frame less the dark (float64): what :func:`detect_stars` labels."""
    return subtract_dark(frame, dark=dark) if dark is not None else np.asarray(frame, dtype=np.float64)


def _frame_ids(frame_ids: Sequence[int] | None, n: int) -> list[int]:
    """The frame numbers of ``n`` frames: ``frame_ids``, or ``0..n-1``."""
    ids = list(range(n)) if frame_ids is None else [int(v) for v in frame_ids]
    if len(ids) != n:
        raise UserInputError(f"frame_ids: {len(ids)} ids for {n} frames")
    return ids


def _first_frame_stars(frame: Any, dark: np.ndarray | None, *, noise_dn: float | None,
                       det_opts: dict) -> np.ndarray:
    """Reference positions (W, 2) when none are given: the peaks detected in the first frame."""
    d0 = detect_stars(_prepared(frame, dark), noise_dn=noise_dn, **det_opts)
    if d0.empty:
        raise UserInputError("frames[0]: no star above threshold to use as reference")
    return d0[["x_peak", "y_peak"]].to_numpy(dtype=np.float64)


def _reference_positions(reference_xy: Any) -> np.ndarray:
    """The given reference positions as a finite float64 array (W, 2)."""
    ref = np.asarray(reference_xy, dtype=np.float64)
    if ref.ndim != 2 or ref.shape[1] != 2 or not np.isfinite(ref).all():
        raise UserInputError("reference_xy: expected finite positions of shape (W, 2)")
    return ref


def _frame_detections(raw: np.ndarray, dark: np.ndarray | None, ref: np.ndarray | None, *,
                      noise_dn: float | None, window_size_px: int, match_radius_px: float,
                      det_opts: dict) -> tuple[pd.DataFrame, float]:
    """The detections of one frame (:func:`detect_stars`' table) and its noise (DN): in boxes
    around the given references ``ref`` (:func:`_detect_near`), or in the whole frame when no
    reference list is given or a component is larger than its box."""
    # level and noise from a regular subsample: the same numbers as from the whole
    # dark-subtracted frame, without making it (a full float64 copy costs 20-30 ms)
    level, noise = _frame_level_and_noise(_subsample(raw, dark))
    if noise_dn is not None:
        noise = float(noise_dn)
    det = None
    if ref is not None:
        det = _detect_near(raw, dark, ref, background_dn=level, noise_dn=noise,
                           search_px=int(math.ceil(match_radius_px)) + window_size_px // 2 + 2,
                           match_radius_px=match_radius_px, **det_opts)
    if det is None:  # no reference list, or a component larger than a search box: whole frame
        det = detect_stars(_prepared(raw, dark), background_dn=level, noise_dn=noise, **det_opts)
    return det, noise


def _star_windows(raw: np.ndarray, dark: np.ndarray | None, ref: np.ndarray, det: pd.DataFrame, *,
                  match_radius_px: float, window_size_px: int) -> tuple:
    """The window of each reference star in one frame, centred on its matched detection (on
    the reference's own pixel when unmatched) and less the dark: ``found`` (bool, W), the
    windows, their origins ``x0, y0`` and their edge flags (:func:`extract_windows`)."""
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
    return found, win, x0, y0, eflag
