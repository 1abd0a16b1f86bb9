"""Tests of the full-frame detector chain (:func:`simcam.detector.expose`, one fused numba
pass per pixel) with the integral non-linearity on: against the window route (another code
path: :func:`simcam.detector.window_chain` + :func:`simcam.detector.expose_windows_frames`),
against the chain rebuilt in numpy from the generator's primitives, against the analytic
photon-transfer moments with the non-linear mean, and across numba thread counts in
separate processes.

References: EMVA 1288 release 4.0 linear camera model with the mean charge replaced by the
non-linear one, ``mu = s (1 - beta min(s, FW) / FW)``, ``s = S g + d``:
mean DN = mu / K + offset, variance DN^2 = (mu + sigma_read^2) / K^2 + 1/12 (the shot noise
is that of the compressed mean, :func:`simcam.detector.apply_nonlinearity`). Monte Carlo
assertions use fixed seeds and allow 5 standard errors of the statistic (derived next to
each test).
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from simcam import rng as rng_mod
from simcam import rng_poisson
from simcam.detector import (
    DetectorParams,
    detector_maps,
    dsnu_map,
    expose,
    expose_windows_frames,
    prnu_map,
    window_chain,
)
from simcam.rng import key_from_seed

Z = 5.0
MOSAIC_COLS = 4096
CHIP_COLS = 2048
SEED = 20261125
DET_KEY = key_from_seed(SEED, 0)
FRAME_KEY = key_from_seed(SEED, 1, 0)


def _params(**kw):
    base = dict(gain_e_per_dn=(4.0, 6.0), offset_dn=(100.0, 200.0), read_noise_e=(3.0, 4.0),
                full_well_e=(5e4, 6e4), adc_bits=16, prnu_rms=0.02, dark_e=20.0, dsnu_rms_e=3.0,
                hot_pixel_fraction=0.01, hot_pixel_dark_e=400.0, nonlinearity_beta=0.05)
    base.update(kw)
    return DetectorParams(**base)


def _expose(sig, row0, col0, params, frame_key=FRAME_KEY, **kw):
    return expose(signal_e=sig, row0=row0, col0=col0, mosaic_cols=MOSAIC_COLS, chip_cols=CHIP_COLS,
                  params=params, frame_key=frame_key, detector_key=DET_KEY, **kw)


def _ramp(shape, lo, hi, seed=0):
    """Signal (e-) spread from ``lo`` to ``hi`` over the block, plus fixed-seed jitter."""
    h, w = shape
    base = np.linspace(lo, hi, h * w).reshape(h, w)
    return base * np.random.default_rng(seed).uniform(0.9, 1.0, shape)


def _model(sig, row0, col0, params):
    """Mean charge (non-linear, e-), and per-pixel K, offset, read noise, full well."""
    h, w = sig.shape
    g = prnu_map(shape=(h, w), row0=row0, col0=col0, mosaic_cols=MOSAIC_COLS, params=params,
                 detector_key=DET_KEY)
    d = dsnu_map(shape=(h, w), row0=row0, col0=col0, mosaic_cols=MOSAIC_COLS, params=params,
                 detector_key=DET_KEY)
    chip = (col0 + np.arange(w)) // CHIP_COLS
    k = np.asarray(params.gain_e_per_dn)[chip]
    off = np.asarray(params.offset_dn)[chip]
    rn = np.asarray(params.read_noise_e)[chip]
    fw = np.asarray(params.full_well_e)[chip]
    s = sig * g + d
    mu = s * (1.0 - params.nonlinearity_beta * np.minimum(s, fw) / fw)
    return mu, k, off, rn, fw


# ------------------------------------------------------------------------------ identity


@pytest.mark.parametrize("quantize", [True, False])
@pytest.mark.parametrize("beta", [0.05, -0.3, 0.0])
def test_full_frame_equals_the_window_route(beta, quantize):
    # a block astride the chip boundary, saturating pixels (small full well), hot pixels: the
    # fused full-frame pass and the window route give the same pixels bit for bit
    p = _params(nonlinearity_beta=beta, full_well_e=(3e3, 4e3))
    row0, col0 = 700, 1990
    sig = _ramp((40, 120), 1.0, 8e3)
    full = _expose(sig, row0, col0, p, quantize=quantize)
    origins = [(0, 0), (3, 50), (29, 109), (10, 55)]
    h, w = 11, 11
    cut = np.stack([sig[a:a + h, b:b + w] for a, b in origins])
    chain = window_chain(signal_e=cut, row0=[row0 + a for a, _ in origins],
                         col0=[col0 + b for _, b in origins], mosaic_cols=MOSAIC_COLS,
                         chip_cols=CHIP_COLS, params=p, detector_key=DET_KEY)
    for parallel in (False, True):
        win = expose_windows_frames(chain=chain, frame_keys=[FRAME_KEY], quantize=quantize,
                                    parallel=parallel)[0]
        for k, (a, b) in enumerate(origins):
            assert np.array_equal(win[k], full[a:a + h, b:b + w])
    # the fixed pattern computed once (detector_maps, here of a larger block) and read by
    # the per-frame pass: the same frame
    maps = detector_maps(shape=(60, 200), row0=row0 - 10, col0=col0 - 30, mosaic_cols=MOSAIC_COLS,
                         params=p, detector_key=DET_KEY)
    assert np.array_equal(_expose(sig, row0, col0, p, quantize=quantize, maps=maps), full)


@pytest.mark.parametrize("quantize", [True, pytest.param(False, marks=pytest.mark.slow)])
@pytest.mark.parametrize("beta", [0.05, -0.3, 0.0])
def test_float32_input_gives_the_pixels_of_float64(beta, quantize):
    # float32 input (used without a copy): the same pixels as float64 holding the same
    # values. Each input and output type is a signature numba compiles on its own (about
    # 5 s of a cold cache): float32 to float DN, which only this check calls, runs with
    # -m slow; float32 to ADC codes in the default suite
    p = _params(nonlinearity_beta=beta, full_well_e=(3e3, 4e3))
    s32 = _ramp((40, 120), 1.0, 8e3).astype(np.float32)
    assert np.array_equal(_expose(s32, 700, 1990, p, quantize=quantize),
                          _expose(s32.astype(np.float64), 700, 1990, p, quantize=quantize))


def test_full_frame_equals_the_chain_rebuilt_from_rng_primitives():
    # the chain in numpy from the public generator functions and the slot layout of
    # simcam.kernels.detector, non-linearity included: catches any drift of the fused kernel
    p = _params(full_well_e=(2e3, 3e3))
    row0, col0 = 33, 2030
    h, w = 24, 40
    sig = _ramp((h, w), 0.5, 4e3)  # means on both sides of the Poisson method switch at 10, saturation
    rows, cols = np.mgrid[row0:row0 + h, col0:col0 + w]
    ctr = (rows * MOSAIC_COLS + cols).astype(np.uint64) << np.uint64(16)
    g = np.maximum(0.0, 1.0 + p.prnu_rms * rng_mod.normal_array(key=DET_KEY, counter=ctr | np.uint64(0 << 12)))
    d = np.maximum(0.0, p.dark_e + p.dsnu_rms_e * rng_mod.normal_array(key=DET_KEY, counter=ctr | np.uint64(1 << 12)))
    d = d + np.where(rng_mod.uniform_array(key=DET_KEY, counter=ctr | np.uint64(2 << 12)) < p.hot_pixel_fraction,
                     p.hot_pixel_dark_e, 0.0)
    chip = cols // CHIP_COLS
    fw = np.asarray(p.full_well_e)[chip]
    s = sig * g + d
    mu = s * (1.0 - p.nonlinearity_beta * np.minimum(s, fw) / fw)
    n = rng_poisson.poisson_array(lam=mu, key=FRAME_KEY, counter=ctr | np.uint64(1 << 12)).astype(float)
    e = np.minimum(n, fw) + np.asarray(p.read_noise_e)[chip] * rng_mod.normal_array(
        key=FRAME_KEY, counter=ctr | np.uint64(0 << 12))
    v = e / np.asarray(p.gain_e_per_dn)[chip] + np.asarray(p.offset_dn)[chip]
    assert np.array_equal(_expose(sig, row0, col0, p), np.clip(np.floor(v + 0.5), 0, p.max_dn).astype(np.uint16))
    # float output: the same operations, so equal up to nothing; allow the last bit anyway
    assert np.allclose(_expose(sig, row0, col0, p, quantize=False), v, rtol=1e-15, atol=0)


def test_one_frame_window_kernel_equals_the_windows_kernel():
    # noise_adc_window (a Monte Carlo trial's windows: one frame, shot and read noise,
    # quantised) gives the pixels noise_adc_frames gives in each frame: a window across the
    # chip boundary, means in every Poisson path (0, table, PTRS just above 10 and far
    # above), over the full well and over the ADC range
    from simcam.kernels.detector import noise_adc_frames, noise_adc_window

    h, w = 11, 13
    row0, col0 = 700, CHIP_COLS - 6
    g = np.random.default_rng(4)
    mean = np.concatenate([np.zeros(5), g.uniform(0.0, 10.0, 60), g.uniform(10.0, 10.5, 40),
                           10.0 ** g.uniform(1.0, 5.5, h * w - 105)])
    g.shuffle(mean)
    mean = mean.reshape(h, w)
    gain, offset, read_noise, full_well = np.array([4.0, 6.0]), np.array([100.0, 200.0]), np.array([3.0, 4.0]), \
        np.array([5e4, 6e4])
    keys = np.array([key_from_seed(SEED, 1, f) for f in range(4)], dtype=np.uint64)
    frames = np.empty((keys.size, h, w))
    noise_adc_frames(mean, frames, row0, col0, MOSAIC_COLS, CHIP_COLS, gain, offset, read_noise, full_well, keys,
                     True, True, True, 4095.0)
    assert (frames == 4095.0).any() and (frames < 4095.0).any()
    win = np.empty((h, w))
    words = np.empty((3, h * w), dtype=np.uint64)
    scratch = np.empty(2 * h * w, dtype=np.int64)
    for f, key in enumerate(keys):
        noise_adc_window(mean, win, row0, col0, MOSAIC_COLS, CHIP_COLS, gain, offset, read_noise, full_well, key,
                         4095.0, words, scratch)
        assert np.array_equal(win, frames[f])


def test_noise_free_frame_is_the_nonlinear_transfer_curve_quantised():
    # without temporal noise the output is the non-linearity's expected curve through the
    # ADC: DN = clip(floor(mu / K + offset + 0.5)), mu from the maps (numpy, independent)
    p = _params(adc_bits=12, offset_dn=(50.0, 60.0))
    row0, col0 = 100, 2000
    sig = _ramp((16, 96), 0.0, 4e4)  # beyond the 12-bit range at K = 4: the top clips at 4095
    mu, k, off, _, fw = _model(sig, row0, col0, p)
    mu_fw = np.minimum(mu, fw)  # the full well clips the (here noiseless) count
    dn = _expose(sig, row0, col0, p, shot_noise=False, read_noise=False, quantize=False)
    assert np.allclose(dn, mu_fw / k + off, rtol=1e-15, atol=1e-12)
    q = _expose(sig, row0, col0, p, shot_noise=False, read_noise=False)
    assert q.dtype == np.uint16
    assert np.array_equal(q, np.clip(np.floor(mu_fw / k + off + 0.5), 0, 4095).astype(np.uint16))
    assert q.max() == 4095 and (q == 4095).sum() > 0
    # the curve is compressed: against the linear camera the deficit is beta s min(s, FW)/FW / K
    lin = _expose(sig, row0, col0, _params(adc_bits=12, offset_dn=(50.0, 60.0), nonlinearity_beta=0.0),
                  shot_noise=False, read_noise=False, quantize=False)
    s, *_ = _model(sig, row0, col0, _params(nonlinearity_beta=0.0))
    assert np.allclose(lin - dn, np.minimum(s, fw) / k - mu_fw / k, rtol=1e-12, atol=1e-9)


# ------------------------------------------------------------------------------ moments


def test_per_pixel_mean_and_variance_over_frames_match_the_nonlinear_model():
    # 300 frames of a 24 x 64 block astride both chips, signals up to 6e4 e- (beta = 0.05
    # with FW = 2e5 compresses the mean by up to 1.5 %), far below the full-well clip
    p = _params(hot_pixel_fraction=0.0, full_well_e=(2e5, 2e5))
    n_frames, row0, col0 = 300, 400, 2016
    sig = _ramp((24, 64), 50.0, 6e4, seed=3)
    frames = np.stack([_expose(sig, row0, col0, p, key_from_seed(SEED, 2, f)).astype(float)
                       for f in range(n_frames)])
    mu, k, off, rn, _ = _model(sig, row0, col0, p)
    mean_dn = mu / k + off
    var_dn = (mu + rn**2) / k**2 + 1 / 12
    n_pix = mean_dn.size
    # means: z = (xbar - mean) / sqrt(var / n) is N(0, 1) per pixel; the largest |z| of 1536
    # pixels stays below 5.5 (false alarm 1536 * 3.8e-8), their average within 5 / sqrt(n_pix)
    z = (frames.mean(0) - mean_dn) / np.sqrt(var_dn / n_frames)
    assert np.abs(z).max() < 5.5
    assert abs(z.mean()) < Z / np.sqrt(n_pix)
    # the test resolves the non-linearity: the linear camera's mean is tens of sigma off at
    # the top of the ramp (225 DN against a standard error of 3.5 DN)
    lin = _params(hot_pixel_fraction=0.0, nonlinearity_beta=0.0, full_well_e=(2e5, 2e5))
    z_lin = (frames.mean(0) - (_model(sig, row0, col0, lin)[0] / k + off)) / np.sqrt(var_dn / n_frames)
    assert np.abs(z_lin).max() > 30
    # variances: R = s^2 / var has mean 1 and variance 2/(n-1) + kappa4 / (var^2 n) per
    # pixel (standard error of a sample variance), kappa4 = mu / K^4 (Poisson) - 1/120
    # (uniform quantisation error); the average of n_pix independent R within 5 standard errors
    r = frames.var(0, ddof=1) / var_dn
    kappa4 = mu / k**4 - 1 / 120
    var_r = 2 / (n_frames - 1) + kappa4 / (var_dn**2 * n_frames)
    assert abs(r.mean() - 1.0) < Z * np.sqrt(var_r.mean() / n_pix)


def test_one_full_frame_standardised_residuals_are_unit_normal():
    # one whole 2048 x 4096 frame (every row block, both chips, all threads): the residual
    # r = (DN - mean) / sd of each pixel against its analytic mean and variance (maps from
    # prnu_map / dsnu_map) has, over N = 8.4e6 pixels, mean 0 +- 5 / sqrt(N) and variance
    # 1 +- 5 sqrt((2 + kappa) / N), kappa the excess kurtosis (below 0.2 here: Poisson 1 / mu,
    # quantisation -1.2 / (12 var)^2 ...), bounded by 1 in the tolerance
    p = _params(hot_pixel_fraction=0.0, nonlinearity_beta=0.008, full_well_e=(5e4, 5e4))
    rows, cols = 2048, 4096
    sig = np.full((rows, cols), 40.0)
    sig[:, ::7] = 2.5e4  # bright columns: the non-linearity matters there (-0.4 %)
    out = _expose(sig, 0, 0, p, key_from_seed(SEED, 3, 0)).astype(float)
    mu, k, off, rn, _ = _model(sig, 0, 0, p)
    r = (out - (mu / k + off)) / np.sqrt((mu + rn**2) / k**2 + 1 / 12)
    n = r.size
    assert abs(r.mean()) < Z / np.sqrt(n)
    assert abs(r.var() - 1.0) < Z * np.sqrt(3.0 / n)
    bright = r[:, ::7]
    assert abs(bright.mean()) < Z / np.sqrt(bright.size)


# ------------------------------------------------------------------------------ threads


_CHILD = r"""
import hashlib, numpy as np, numba
from simcam.detector import DetectorParams, detector_maps, expose
from simcam.rng import key_from_seed
p = DetectorParams(gain_e_per_dn=(4.0, 6.0), offset_dn=(100.0, 200.0), read_noise_e=(3.0, 4.0),
                   full_well_e=(5e4, 6e4), adc_bits=16, prnu_rms=0.02, dark_e=20.0, dsnu_rms_e=3.0,
                   hot_pixel_fraction=0.01, hot_pixel_dark_e=400.0, nonlinearity_beta=0.008)
y, x = np.mgrid[0:256, 0:4096]
sig = 30.0 + 2e4 * np.exp(-((y - 128.3) ** 2 + (x % 97 - 40.2) ** 2) / 8.0)
h = hashlib.sha256()
maps = detector_maps(shape=sig.shape, row0=900, col0=0, mosaic_cols=4096, params=p,
                     detector_key=key_from_seed(5, 0))
for q in (True, False):
    kw = dict(signal_e=sig, row0=900, col0=0, mosaic_cols=4096, chip_cols=2048, params=p,
              frame_key=key_from_seed(5, 1, 2), detector_key=key_from_seed(5, 0), quantize=q)
    out = expose(**kw)
    h.update(out.tobytes())
    # the route through the maps (computed on this thread count too): the same frame
    assert np.array_equal(expose(**kw, maps=maps), out), "maps route differs"
print(numba.get_num_threads(), h.hexdigest())
"""


def test_full_frame_does_not_depend_on_the_thread_count():
    # the same frame in processes whose numba pool has 1 and 2 threads (numba runs more
    # threads than cores, time-sliced, so this holds on a one-core machine too), through
    # the fused chain and through the maps (the child checks the two agree). The digests
    # are compared exactly on purpose: identical pixels whatever the thread count is a
    # property of this code (each pixel's draws depend on its index only), not of numpy
    digests = {}
    for n in (1, 2):
        run = subprocess.run([sys.executable, "-c", _CHILD], env=dict(os.environ, NUMBA_NUM_THREADS=str(n)),
                             capture_output=True, text=True, timeout=600, check=False)
        assert run.returncode == 0, run.stderr[-3000:]
        threads, digest = run.stdout.split()
        assert int(threads) == n
        digests[n] = digest
    assert digests[1] == digests[2]
