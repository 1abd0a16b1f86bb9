"""numba kernel of the Monte Carlo fast path: windows exposed and centroided in one pass.

:func:`expose_centroid_frames` gives, for each (frame, window), exactly what
:func:`simcam.detector.expose_windows_frames` followed by the float64 conversion, the
dark subtraction and :func:`budget.centroid.core.centroid_windows` (thresholded centre of
gravity, border background, given threshold) give, bit for bit: each pixel by
:func:`simcam.kernels.detector.noise_adc_window`, the same value as the windows' pixel
kernel (:func:`simcam.kernels.detector.noise_adc_frames`) in one frame, and the same
per-window centroid (:func:`budget.centroid.kernels.border_cog_one`: the border median of
:func:`budget.centroid.kernels.border_one`, the centre of gravity of
:func:`budget.centroid.kernels.cog_one`). What it saves is memory traffic: a window
lives in a scratch buffer of ``h * w`` doubles instead of passing through a
(frames, windows, h, w) array, its float64 copy and the concatenation of all
conditions. ``tests/test_protocols.py`` checks the equality.

The kernels take arrays and scalars only; :func:`expose_centroid_chain` calls them with
arguments of one type whatever its caller passes (numba compiles each once). The
orchestration is in :func:`budget.starcam.protocols.simulate`.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from budget.centroid.kernels import border_cog_one
from simcam.kernels.detector import noise_adc_window


@njit(cache=True, inline="always")
def _window_scratch(h, w):
    """Scratch of one (h, w) window's exposure and centroid: its mean charge and its pixels,
    the words and index lists of :func:`simcam.kernels.detector.noise_adc_window`, and the
    border of :func:`budget.centroid.kernels.border_one`."""
    return (np.empty((h, w)), np.empty((h, w)), np.empty((3, h * w), dtype=np.uint64),
            np.empty(2 * h * w, dtype=np.int64), np.empty(2 * w + 2 * max(h - 2, 0)))


@njit(cache=True, inline="always")
def _expose_centroid_one(mean, win, words, scratch, buf, k, f, row0, col0, mosaic_cols, chip_cols, gain, offset,
                         read_noise, full_well, frame_key, max_dn, dark_mean, threshold, out_x, out_y, out_flux,
                         out_flag):
    """Window ``k`` in frame ``f`` (key ``frame_key``) from its mean charge ``mean`` (h, w; e-):
    exposed into ``win`` (shot and read noise, quantised), less ``dark_mean[k]`` if given,
    centroided (:func:`budget.centroid.kernels.border_cog_one`: border median background,
    ``threshold[k]`` above it) into ``out_*[f, k]``; the scratch from :func:`_window_scratch`."""
    h, w = win.shape
    noise_adc_window(mean, win, row0[k], col0[k], mosaic_cols, chip_cols, gain, offset, read_noise, full_well,
                     frame_key, max_dn, words, scratch)
    if dark_mean.shape[0]:
        for i in range(h):
            for j in range(w):
                win[i, j] = win[i, j] - dark_mean[k, i, j]
    out_x[f, k], out_y[f, k], out_flux[f, k], out_flag[f, k] = border_cog_one(win, buf, np.float64(col0[k]),
                                                                             np.float64(row0[k]), threshold[k])


@njit(cache=True)
def expose_centroid_frames_serial(mean_e, row0, col0, mosaic_cols, chip_cols, gain, offset, read_noise, full_well,
                                  frame_keys, max_dn, dark_mean, threshold, out_x, out_y, out_flux, out_flag):
    """Expose ``n`` windows in ``F`` frames and centroid each (see module docstring):
    shot and read noise, quantised; border median background, no threshold subtraction,
    no saturation flag. Window by window, frame by frame (:func:`_expose_centroid_one`).

    Parameters
    ----------
    mean_e : float64 (n, h, w)
        Mean charge (e-) from :func:`simcam.detector.window_chain`.
    row0, col0 : int64 (n,)
        Mosaic origins of the windows (the centroid's ``y0``, ``x0``).
    mosaic_cols, chip_cols, gain, offset, read_noise, full_well, max_dn
        The chain's geometry and per-chip constants.
    frame_keys : uint64 (F,)
    dark_mean : float64 (n, h, w) or (0, h, w)
        Mean star-free window (DN) subtracted from every frame; empty: none.
    threshold : float64 (n,)
        Threshold above the background (DN).
    out_x, out_y, out_flux : float64 (F, n)
    out_flag : int64 (F, n)
    """
    n, h, w = mean_e.shape
    mean, win, words, scratch, buf = _window_scratch(h, w)
    for k in range(n):
        for i in range(h):
            for j in range(w):
                mean[i, j] = mean_e[k, i, j]
        for f in range(frame_keys.shape[0]):
            _expose_centroid_one(mean, win, words, scratch, buf, k, f, row0, col0, mosaic_cols, chip_cols, gain,
                                 offset, read_noise, full_well, frame_keys[f], max_dn, dark_mean, threshold, out_x,
                                 out_y, out_flux, out_flag)


@njit(cache=True)
def expose_centroid_drift_serial(mean_e, grad_u, grad_v, drift, row0, col0, mosaic_cols, chip_cols, gain,
                                 offset, read_noise, full_well, frame_keys, max_dn, dark_mean, threshold,
                                 out_x, out_y, out_flux, out_flag):
    """:func:`expose_centroid_frames_serial` for an image that drifts within the condition:
    frame ``f`` of window ``k`` is exposed from its own mean charge
    ``max(mean_e[k] + drift[f, 0] grad_u[k] + drift[f, 1] grad_v[k], 0)``
    (:meth:`simcam.starcam.render.StarCamera.drift_chain`), evaluated with the same
    operations in the same order as numpy's
    ``np.maximum(mean + d_u * G_u + d_v * G_v, 0.0)``, and with that frame's key alone,
    so the result is bit for bit that of one :func:`expose_centroid_frames_serial` call
    per frame (``tests/test_protocols.py``). It saves a Python call, a chain and a mean
    array per frame.
    """
    n, h, w = mean_e.shape
    mean, win, words, scratch, buf = _window_scratch(h, w)
    for k in range(n):
        for f in range(frame_keys.shape[0]):
            du = drift[f, 0]
            dv = drift[f, 1]
            for i in range(h):
                for j in range(w):
                    v = mean_e[k, i, j] + du * grad_u[k, i, j]
                    v = v + dv * grad_v[k, i, j]
                    mean[i, j] = v if v > 0.0 else 0.0
            _expose_centroid_one(mean, win, words, scratch, buf, k, f, row0, col0, mosaic_cols, chip_cols, gain,
                                 offset, read_noise, full_well, frame_keys[f], max_dn, dark_mean, threshold, out_x,
                                 out_y, out_flux, out_flag)


@njit(parallel=True, cache=True)
def expose_centroid_frames(mean_e, row0, col0, mosaic_cols, chip_cols, gain, offset, read_noise, full_well,
                           frame_keys, max_dn, dark_mean, threshold, out_x, out_y, out_flux, out_flag):
    """Threaded twin of :func:`expose_centroid_frames_serial`: windows in parallel, each
    window by the serial kernel on its own one-window arrays (contiguous copies, so the
    serial kernel is called with the types it was compiled for and not compiled again).
    Each (frame, window) result is the same whatever the thread count."""
    n = mean_e.shape[0]
    nf = frame_keys.shape[0]
    for kk in prange(n):
        k = np.int64(kk)
        dm = dark_mean if dark_mean.shape[0] == 0 else np.ascontiguousarray(dark_mean[k:k + 1])
        ox = np.empty((nf, 1))
        oy = np.empty((nf, 1))
        of = np.empty((nf, 1))
        ofl = np.zeros((nf, 1), dtype=np.int64)
        expose_centroid_frames_serial(np.ascontiguousarray(mean_e[k:k + 1]), np.ascontiguousarray(row0[k:k + 1]),
                                      np.ascontiguousarray(col0[k:k + 1]), mosaic_cols, chip_cols, gain, offset,
                                      read_noise, full_well, frame_keys, max_dn, dm,
                                      np.ascontiguousarray(threshold[k:k + 1]), ox, oy, of, ofl)
        for f in range(nf):
            out_x[f, k] = ox[f, 0]
            out_y[f, k] = oy[f, 0]
            out_flux[f, k] = of[f, 0]
            out_flag[f, k] = ofl[f, 0]


def expose_centroid_chain(chain, keys, *, dark_mean, threshold_dn, parallel: bool):
    """The kernels' call for :func:`budget.starcam.protocols._expose_centroid`: a
    :class:`simcam.detector.WindowChain` exposed with the frame ``keys`` (uint64)
    and centroided; x, y, flux, flag as (frames, W)."""
    frames = keys.shape[0]
    W, h, w = chain.mean_e.shape
    out_x, out_y, out_f = np.empty((frames, W)), np.empty((frames, W)), np.empty((frames, W))
    out_flag = np.zeros((frames, W), dtype=np.int64)
    # arguments of one type whatever the caller (a copy is writable and contiguous): numba
    # compiles the kernel once, not once per array flag (a first run compiles every variant)
    dm = np.zeros((0, h, w)) if dark_mean is None else np.array(dark_mean, dtype=np.float64)
    kern = expose_centroid_frames if parallel else expose_centroid_frames_serial
    kern(chain.mean_e, chain.row0, chain.col0, chain.mosaic_cols, chain.chip_cols, chain.gain, chain.offset,
         chain.read_noise, chain.full_well, keys, chain.max_dn, dm, np.array(threshold_dn, dtype=np.float64),
         out_x, out_y, out_f, out_flag)
    return out_x, out_y, out_f, out_flag


def expose_centroid_drift_chain(chain, grad_u, grad_v, drift, keys, *, dark_mean, threshold_dn):
    """:func:`expose_centroid_chain` (serial) for a drifting image (:func:`expose_centroid_drift_serial`):
    ``drift`` (frames, 2) px about the chain's own position, ``grad_u``/``grad_v`` the
    gradients of its mean charge; x, y, flux, flag as (frames, W)."""
    frames = keys.shape[0]
    W, h, w = chain.mean_e.shape
    out_x, out_y, out_f = np.empty((frames, W)), np.empty((frames, W)), np.empty((frames, W))
    out_flag = np.zeros((frames, W), dtype=np.int64)
    dm = np.zeros((0, h, w)) if dark_mean is None else np.array(dark_mean, dtype=np.float64)
    expose_centroid_drift_serial(np.ascontiguousarray(chain.mean_e, dtype=np.float64),
                                 np.ascontiguousarray(grad_u, dtype=np.float64),
                                 np.ascontiguousarray(grad_v, dtype=np.float64),
                                 np.ascontiguousarray(drift, dtype=np.float64), chain.row0, chain.col0,
                                 chain.mosaic_cols, chain.chip_cols, chain.gain, chain.offset, chain.read_noise,
                                 chain.full_well, keys, chain.max_dn, dm,
                                 np.array(threshold_dn, dtype=np.float64), out_x, out_y, out_f, out_flag)
    return out_x, out_y, out_f, out_flag
