"""Tests of the detector chain :mod:`simcam.detector` against its analytic model.

References: the photon-transfer / EMVA 1288 moments (mean DN = (S g + d)/K + offset,
variance DN^2 = (S g + d + sigma_read^2)/K^2 + 1/12), scipy.stats distributions and
the rectified-normal moments for the clipped DSNU map. Monte Carlo assertions use fixed
seeds and allow 5 standard errors of the statistic (derivations next to each test).
"""

from __future__ import annotations

import dataclasses

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from simcam.infra.errors import ScenarioError
from simcam.detector import (
    DetectorParameterError,
    DetectorParams,
    dsnu_map,
    expose,
    expose_windows,
    prnu_map,
)
from simcam import rng as rng_mod
from simcam import rng_poisson
from simcam.rng import key_from_seed

Z = 5.0
MOSAIC_COLS = 4096
CHIP_COLS = 2048
SEED = 8675309
DET_KEY = key_from_seed(SEED, 0)
FRAME_KEY = key_from_seed(SEED, 1, 0)


def _params(**kw):
    base = dict(gain_e_per_dn=(4.0, 6.0), offset_dn=(100.0, 200.0), read_noise_e=(3.0, 4.0),
                full_well_e=(5e4, 6e4), adc_bits=16, prnu_rms=0.05, dark_e=20.0,
                dsnu_rms_e=3.0, hot_pixel_fraction=0.0, hot_pixel_dark_e=0.0)
    base.update(kw)
    return DetectorParams(**base)


def _expose(sig, row0, col0, params, frame_key=FRAME_KEY, **kw):
    return expose(signal_e=sig, row0=row0, col0=col0, mosaic_cols=MOSAIC_COLS,
                  chip_cols=CHIP_COLS, params=params, frame_key=frame_key,
                  detector_key=DET_KEY, **kw)


def _signal(shape, seed=0, level=60.0):
    """A smooth star-like signal plus background (e-), the same for every call."""
    h, w = shape
    y, x = np.mgrid[0:h, 0:w]
    star = 4e3 * np.exp(-((y - h / 2) ** 2 + (x - w / 3) ** 2) / (2 * 2.0**2))
    return level + star + np.random.default_rng(seed).uniform(0, 10, shape)


def _model(sig, row0, col0, params):
    """Model mean and variance (DN, DN^2) of each pixel, and the electron mean."""
    h, w = sig.shape
    g = prnu_map(shape=(h, w), row0=row0, col0=col0, mosaic_cols=MOSAIC_COLS, params=params,
                 detector_key=DET_KEY)
    d = dsnu_map(shape=(h, w), row0=row0, col0=col0, mosaic_cols=MOSAIC_COLS, params=params,
                 detector_key=DET_KEY)
    chip = (col0 + np.arange(w)) // CHIP_COLS
    k = np.asarray(params.gain_e_per_dn)[chip]
    off = np.asarray(params.offset_dn)[chip]
    rn = np.asarray(params.read_noise_e)[chip]
    lam = sig * g + d
    return lam / k + off, (lam + rn**2) / k**2 + 1 / 12, lam, k, off, rn


# ---------------------------------------------------------------------- parameters


@pytest.mark.parametrize(
    "field,value",
    [
        ("gain_e_per_dn", (0.0, 1.0)),
        ("gain_e_per_dn", (-2.0, 1.0)),
        ("gain_e_per_dn", (np.nan, 1.0)),
        ("offset_dn", (-1.0, 0.0)),
        ("offset_dn", (70000.0, 0.0)),
        ("read_noise_e", (-0.1, 1.0)),
        ("read_noise_e", (1.0,)),
        ("full_well_e", (0.0, 1.0)),
        ("full_well_e", "abc"),
        ("adc_bits", 7),
        ("adc_bits", 33),
        ("adc_bits", 12.5),
        ("prnu_rms", -0.01),
        ("dark_e", -1.0),
        ("dark_e", np.inf),
        ("dsnu_rms_e", -1.0),
        ("hot_pixel_fraction", 1.5),
        ("hot_pixel_dark_e", -5.0),
    ],
)
def test_params_reject_bad_values_naming_the_field(field, value):
    with pytest.raises(DetectorParameterError, match=field):
        _params(**{field: value})


def test_params_are_frozen_keyword_only_and_typed():
    p = _params(adc_bits=20)
    assert issubclass(DetectorParameterError, ScenarioError)
    assert issubclass(DetectorParameterError, ValueError)
    assert p.n_chips == 2 and p.max_dn == 2**20 - 1 and p.output_dtype == np.uint32
    assert _params().output_dtype == np.uint16
    assert p.gain_e_per_dn == (4.0, 6.0) and isinstance(p.gain_e_per_dn, tuple)
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.prnu_rms = 0.1
    with pytest.raises(TypeError):
        DetectorParams((1.0,), (0.0,), (1.0,), (1e4,))
    q = dataclasses.replace(p, read_noise_e=[1.0, 2.0])
    assert q.read_noise_e == (1.0, 2.0)


def test_expose_rejects_bad_arguments_naming_them():
    p = _params()
    sig = np.ones((4, 4))
    bad = [
        (dict(signal_e=-sig), "signal_e"),
        (dict(signal_e=sig * np.nan), "signal_e"),
        (dict(signal_e=sig * 1e13), "signal_e"),
        (dict(signal_e=np.ones(4)), "signal_e"),
        (dict(row0=-1), "row0"),
        (dict(col0=4094), "col0"),
        (dict(col0=1.5), "col0"),
        (dict(chip_cols=1024), "chip_cols"),
        (dict(frame_key=-1), "frame_key"),
        (dict(detector_key=2**64), "detector_key"),
        (dict(params="p"), "params"),
    ]
    for change, name in bad:
        args = dict(signal_e=sig, row0=0, col0=0, mosaic_cols=MOSAIC_COLS, chip_cols=CHIP_COLS,
                    params=p, frame_key=1, detector_key=2)
        args.update(change)
        with pytest.raises(DetectorParameterError, match=name):
            expose(**args)
    with pytest.raises(DetectorParameterError, match="row0"):
        expose_windows(signal_e=np.ones((2, 3, 3)), row0=[0], col0=[0, 1],
                       mosaic_cols=MOSAIC_COLS, chip_cols=CHIP_COLS, params=p, frame_key=1,
                       detector_key=2)
    with pytest.raises(TypeError):
        expose(sig, 0, 0, MOSAIC_COLS, CHIP_COLS, p, 1, 2)  # keyword-only


# ---------------------------------------------------------------------- identity


def test_windows_equal_the_full_block_exactly():
    p = _params(hot_pixel_fraction=0.01, hot_pixel_dark_e=500.0)
    row0, col0 = 100, 2010  # straddles the chip boundary at column 2048
    sig = _signal((48, 80))
    full = _expose(sig, row0, col0, p)
    full_f = _expose(sig, row0, col0, p, quantize=False)
    origins = [(0, 0), (5, 30), (40, 70), (5, 33), (20, 38), (41, 0)]  # overlapping too
    h, w = 7, 10
    r0 = np.array([row0 + a for a, _ in origins])
    c0 = np.array([col0 + b for _, b in origins])
    cut = np.stack([sig[a:a + h, b:b + w] for a, b in origins])
    win = expose_windows(signal_e=cut, row0=r0, col0=c0, mosaic_cols=MOSAIC_COLS,
                         chip_cols=CHIP_COLS, params=p, frame_key=FRAME_KEY,
                         detector_key=DET_KEY)
    win_f = expose_windows(signal_e=cut, row0=r0, col0=c0, mosaic_cols=MOSAIC_COLS,
                           chip_cols=CHIP_COLS, params=p, frame_key=FRAME_KEY,
                           detector_key=DET_KEY, quantize=False)
    assert win.dtype == np.uint16 and win_f.dtype == np.float64
    for k, (a, b) in enumerate(origins):
        assert np.array_equal(win[k], full[a:a + h, b:b + w])
        assert np.array_equal(win_f[k], full_f[a:a + h, b:b + w])
        single = _expose(cut[k], int(r0[k]), int(c0[k]), p)
        assert np.array_equal(single, full[a:a + h, b:b + w])
    # float32 input gives the same pixels as float64 holding the same values
    sig32 = sig.astype(np.float32)
    assert np.array_equal(_expose(sig32, row0, col0, p),
                          _expose(sig32.astype(float), row0, col0, p))


@settings(max_examples=25, deadline=None)
@given(r=st.integers(0, 40), c=st.integers(0, 60), h=st.integers(1, 8), w=st.integers(1, 12),
       quantize=st.booleans())
def test_any_window_equals_the_full_block(r, c, h, w, quantize):
    # property: a window of any size at any origin inside the block reproduces the
    # block's pixels bit for bit (block straddles the chip boundary)
    p = _params(hot_pixel_fraction=0.01, hot_pixel_dark_e=500.0)
    row0, col0 = 1000, 2000
    sig = _signal((48, 72), level=8.0)
    full = _expose(sig, row0, col0, p, quantize=quantize)
    win = _expose(np.ascontiguousarray(sig[r:r + h, c:c + w]), row0 + r, col0 + c, p,
                  quantize=quantize)
    assert np.array_equal(win, full[r:r + h, c:c + w])


def test_results_do_not_depend_on_thread_count():
    if numba.config.NUMBA_NUM_THREADS < 2:
        # one core (numba's thread pool is sized at import from the core count): run this
        # test again in a process whose pool has 4 threads (numba runs more threads than
        # cores, time-sliced), so that the comparison is made on every machine
        import os
        import subprocess
        import sys

        run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                              f"{__file__}::test_results_do_not_depend_on_thread_count"],
                             env=dict(os.environ, NUMBA_NUM_THREADS="4"), capture_output=True, text=True,
                             timeout=600, check=False)
        assert run.returncode == 0 and "1 passed" in run.stdout, run.stdout[-3000:] + run.stderr[-2000:]
        return
    p = _params(hot_pixel_fraction=0.01, hot_pixel_dark_e=500.0)
    sig = _signal((64, 96))
    cut = np.stack([sig[i:i + 9, 2 * i:2 * i + 9] for i in range(8)])
    rows = 300 + np.arange(8)
    cols = 2000 + 2 * np.arange(8)
    before = numba.get_num_threads()
    results = []
    try:
        for n in (1, min(4, numba.config.NUMBA_NUM_THREADS)):
            numba.set_num_threads(n)
            results.append((
                _expose(sig, 300, 2000, p),
                expose_windows(signal_e=cut, row0=rows, col0=cols, mosaic_cols=MOSAIC_COLS,
                               chip_cols=CHIP_COLS, params=p, frame_key=FRAME_KEY,
                               detector_key=DET_KEY),
                prnu_map(shape=(64, 96), row0=300, col0=2000, mosaic_cols=MOSAIC_COLS,
                         params=p, detector_key=DET_KEY),
            ))
    finally:
        numba.set_num_threads(before)
    for a, b in zip(*results):
        assert np.array_equal(a, b)


def test_maps_depend_on_detector_key_noise_on_frame_key():
    p = _params()
    sig = _signal((16, 16))
    quiet = dict(shot_noise=False, read_noise=False)
    k1, k2 = key_from_seed(SEED, 1, 1), key_from_seed(SEED, 1, 2)
    assert np.array_equal(_expose(sig, 0, 0, p, k1, **quiet), _expose(sig, 0, 0, p, k2, **quiet))
    assert not np.array_equal(_expose(sig, 0, 0, p, k1), _expose(sig, 0, 0, p, k2))


def _reference_chain(sig, row0, col0, params, frame_key, *, quantize):
    """The chain rebuilt in numpy from the rng primitives (slot layout of the kernel)."""
    h, w = sig.shape
    rows, cols = np.mgrid[row0:row0 + h, col0:col0 + w]
    pix = (rows * MOSAIC_COLS + cols).astype(np.uint64)
    ctr = pix << np.uint64(16)
    z_prnu = rng_mod.normal_array(key=DET_KEY, counter=ctr | np.uint64(0 << 12))
    z_dsnu = rng_mod.normal_array(key=DET_KEY, counter=ctr | np.uint64(1 << 12))
    u_hot = rng_mod.uniform_array(key=DET_KEY, counter=ctr | np.uint64(2 << 12))
    g = np.maximum(0.0, 1.0 + params.prnu_rms * z_prnu)
    d = np.maximum(0.0, params.dark_e + params.dsnu_rms_e * z_dsnu)
    d = d + np.where(u_hot < params.hot_pixel_fraction, params.hot_pixel_dark_e, 0.0)
    assert np.array_equal(g, prnu_map(shape=(h, w), row0=row0, col0=col0,
                                      mosaic_cols=MOSAIC_COLS, params=params,
                                      detector_key=DET_KEY))
    assert np.array_equal(d, dsnu_map(shape=(h, w), row0=row0, col0=col0,
                                      mosaic_cols=MOSAIC_COLS, params=params,
                                      detector_key=DET_KEY))
    lam = sig * g + d
    n = rng_poisson.poisson_array(lam=lam, key=frame_key, counter=ctr | np.uint64(1 << 12))
    chip = cols // CHIP_COLS
    e = np.minimum(n.astype(float), np.asarray(params.full_well_e)[chip])
    e = e + np.asarray(params.read_noise_e)[chip] * rng_mod.normal_array(
        key=frame_key, counter=ctr | np.uint64(0 << 12))
    v = e / np.asarray(params.gain_e_per_dn)[chip] + np.asarray(params.offset_dn)[chip]
    if quantize:
        return np.clip(np.floor(v + 0.5), 0, params.max_dn)
    return v


@pytest.mark.parametrize("adc_bits", [16, 20])
def test_kernel_equals_composition_of_rng_primitives(adc_bits):
    # the fused numba chain against the same model assembled in numpy from the public
    # generator functions: catches any drift of the kernel from the documented model
    p = _params(adc_bits=adc_bits, hot_pixel_fraction=0.05, hot_pixel_dark_e=300.0,
                full_well_e=(2e3, 3e3))
    row0, col0 = 33, 2030
    sig = _signal((24, 40), level=5.0)  # Poisson means on both sides of 10, saturation
    for quantize in (True, False):
        out = _expose(sig, row0, col0, p, quantize=quantize)
        ref = _reference_chain(sig, row0, col0, p, FRAME_KEY, quantize=quantize)
        if quantize:
            assert out.dtype == p.output_dtype
            assert np.array_equal(out, ref.astype(out.dtype))
        else:
            assert np.allclose(out, ref, rtol=1e-14, atol=1e-12)


# ---------------------------------------------------------------------- moments


def test_per_pixel_mean_and_variance_over_frames_match_the_model():
    # 400 frames of a 32 x 64 block straddling both chips, temporal noise keyed by frame,
    # maps fixed by the detector key.
    p = _params()
    n_frames, row0, col0 = 400, 500, 2016
    sig = _signal((32, 64), level=60.0)
    sig[sig > 2e3] = 2e3  # stay well below the full well
    frames = np.stack([
        _expose(sig, row0, col0, p, key_from_seed(SEED, 2, f)).astype(float)
        for f in range(n_frames)
    ])
    mean_dn, var_dn, lam, k, _, _ = _model(sig, row0, col0, p)
    n_pix = mean_dn.size
    # means: z = (xbar - mu) / sqrt(var / n) is N(0, 1) per pixel; max over 2048
    # pixels below 5.5 (false alarm 2048 * 3.8e-8), average within 5 / sqrt(n_pix)
    z = (frames.mean(0) - mean_dn) / np.sqrt(var_dn / n_frames)
    assert np.abs(z).max() < 5.5
    assert abs(z.mean()) < Z / np.sqrt(n_pix)
    # variances: R = s^2 / var has mean 1 and variance 2/(n-1) + kappa4 / (var^2 n)
    # (standard error of a sample variance), with the fourth cumulant of DN
    # kappa4 = lam / K^4 (Poisson) - 1/120 (uniform quantisation error)
    r = frames.var(0, ddof=1) / var_dn
    kappa4 = lam / k**4 - 1 / 120
    var_r = 2 / (n_frames - 1) + kappa4 / (var_dn**2 * n_frames)
    se = np.sqrt(var_r.mean() / n_pix)
    assert abs(r.mean() - 1.0) < Z * se
    # the test resolves the 1/12 DN^2 quantisation term: without it the model is off
    r_noq = frames.var(0, ddof=1) / (var_dn - 1 / 12)
    assert abs(r_noq.mean() - 1.0) > 3 * se


def test_prnu_map_rms_equals_prnu_rms():
    p = _params(prnu_rms=0.02)
    m = prnu_map(shape=(512, 512), row0=1000, col0=1800, mosaic_cols=MOSAIC_COLS, params=p,
                 detector_key=DET_KEY)
    n = m.size
    # mean SE sigma/sqrt(n); sample std SE sigma/sqrt(2(n-1))
    assert abs(m.mean() - 1.0) < Z * 0.02 / np.sqrt(n)
    assert abs(m.std(ddof=1) - 0.02) < Z * 0.02 / np.sqrt(2 * (n - 1))
    assert stats.kstest((m.ravel() - 1.0) / 0.02, stats.norm.cdf).pvalue > 1e-4
    # neighbouring pixels are independent: correlation SE 1/sqrt(n)
    assert abs(np.corrcoef(m[:, :-1].ravel(), m[:, 1:].ravel())[0, 1]) < Z / np.sqrt(n)
    assert abs(np.corrcoef(m[:-1].ravel(), m[1:].ravel())[0, 1]) < Z / np.sqrt(n)
    # switched off: exactly 1 (a design property: no PRNU leaves the signal bit-identical)
    assert np.all(prnu_map(shape=(8, 8), row0=0, col0=0, mosaic_cols=MOSAIC_COLS,
                           params=_params(prnu_rms=0.0), detector_key=DET_KEY) == 1.0)


def test_dsnu_map_rms_and_independence_from_prnu():
    p = _params(dark_e=100.0, dsnu_rms_e=5.0)
    kw = dict(shape=(512, 512), row0=0, col0=1900, mosaic_cols=MOSAIC_COLS, params=p,
              detector_key=DET_KEY)
    d = dsnu_map(**kw)
    g = prnu_map(**kw)
    n = d.size
    assert abs(d.mean() - 100.0) < Z * 5.0 / np.sqrt(n)
    assert abs(d.std(ddof=1) - 5.0) < Z * 5.0 / np.sqrt(2 * (n - 1))
    assert stats.kstest((d.ravel() - 100.0) / 5.0, stats.norm.cdf).pvalue > 1e-4
    # PRNU and DSNU use different streams of the detector key: uncorrelated (SE 1/sqrt(n))
    assert abs(np.corrcoef(d.ravel(), g.ravel())[0, 1]) < Z / np.sqrt(n)


def test_dsnu_clipped_at_zero_is_a_rectified_normal():
    # dark_e = 0: max(0, sigma z) has P(0) = 1/2 and mean sigma / sqrt(2 pi)
    p = _params(dark_e=0.0, dsnu_rms_e=2.0)
    d = dsnu_map(shape=(256, 512), row0=7, col0=0, mosaic_cols=MOSAIC_COLS, params=p,
                 detector_key=DET_KEY)
    n = d.size
    assert d.min() == 0.0
    assert abs((d == 0).mean() - 0.5) < Z * 0.5 / np.sqrt(n)
    mean_ref = 2.0 / np.sqrt(2 * np.pi)
    sd_ref = 2.0 * np.sqrt(0.5 - 1 / (2 * np.pi))  # sd of the rectified normal
    assert abs(d.mean() - mean_ref) < Z * sd_ref / np.sqrt(n)


def test_hot_pixels_fraction_and_level():
    p = _params(dark_e=10.0, dsnu_rms_e=0.0, hot_pixel_fraction=0.01, hot_pixel_dark_e=300.0)
    d = dsnu_map(shape=(512, 512), row0=0, col0=0, mosaic_cols=MOSAIC_COLS, params=p,
                 detector_key=DET_KEY)
    # levels are dark_e (+ hot_pixel_dark_e): one addition, at most one rounding
    hot = np.isclose(d, 310.0, rtol=2 * np.finfo(float).eps, atol=0)
    assert np.all(hot | np.isclose(d, 10.0, rtol=2 * np.finfo(float).eps, atol=0))
    n = d.size
    # binomial count: SE sqrt(n f (1 - f))
    assert abs(hot.sum() - 0.01 * n) < Z * np.sqrt(n * 0.01 * 0.99)


# ---------------------------------------------------------------------- chain terms


def test_flags_remove_exactly_their_term():
    p = _params(hot_pixel_fraction=0.02, hot_pixel_dark_e=200.0)
    row0, col0 = 64, 2000
    sig = _signal((64, 96))
    sig[sig > 3e3] = 3e3
    mean_dn, _, lam, k, off, rn = _model(sig, row0, col0, p)

    def run(shot, read, quant=False):
        return _expose(sig, row0, col0, p, shot_noise=shot, read_noise=read, quantize=quant)

    none = run(False, False)
    # no temporal noise, no ADC: the model mean (same operations, so equal to rounding)
    assert np.allclose(none, mean_dn, rtol=1e-14, atol=0)
    # read noise alone adds (rn / K) * z with z ~ N(0, 1), identical with or without shot
    read_only = run(False, True) - none
    shot_only = run(True, False)
    both = run(True, True)
    assert np.allclose(both - shot_only, read_only, rtol=0, atol=1e-9)
    z = (read_only * k / rn).ravel()
    assert stats.kstest(z, stats.norm.cdf).pvalue > 1e-4
    # shot noise alone: (DN - offset) K is an integer count; standardised sum and sum of
    # squares of (count - lam): E = 0 and sum(lam), SE sqrt(sum lam) and
    # sqrt(sum(lam + 2 lam^2)) (Poisson fourth central moment lam + 3 lam^2)
    counts = (shot_only - off) * k
    assert np.allclose(counts, np.round(counts), rtol=0, atol=1e-6)
    dev = np.round(counts) - lam
    assert abs(dev.sum()) < Z * np.sqrt(lam.sum())
    assert abs((dev**2).sum() - lam.sum()) < Z * np.sqrt((lam + 2 * lam**2).sum())
    # quantisation alone: exactly floor(x + 1/2) of the float output, clipped
    for shot, read in ((False, False), (True, True)):
        q = run(shot, read, True)
        assert q.dtype == np.uint16
        ref = np.clip(np.floor(run(shot, read) + 0.5), 0, p.max_dn)
        assert np.array_equal(q, ref.astype(np.uint16))


def test_full_well_saturation():
    p = _params(prnu_rms=0.01)
    sig = np.full((8, 8), 1e6)
    col0 = 2044  # both chips
    out = _expose(sig, 0, col0, p, read_noise=False, quantize=False)
    chip = (col0 + np.arange(8)) // CHIP_COLS
    fw = np.asarray(p.full_well_e)[chip]
    g = np.asarray(p.gain_e_per_dn)[chip]
    off = np.asarray(p.offset_dn)[chip]
    # clipped at full well then fw / g + off: two roundings in the code and in the reference
    np.testing.assert_allclose(out, np.broadcast_to(fw / g + off, out.shape), rtol=4 * np.finfo(float).eps, atol=0)
    # quantised DN are integers, far (>= 0.1 DN) from a rounding boundary here: exact
    q = _expose(sig, 0, col0, p, read_noise=False)
    assert np.array_equal(q, np.broadcast_to(np.floor(fw / g + off + 0.5), q.shape))
    # read noise is added after the full-well clip (output amplifier): saturated pixels
    # scatter around fw/K + offset with sd read/K
    noisy = _expose(np.full((64, 64), 1e6), 0, 0, p, quantize=False)
    zs = (noisy - (5e4 / 4.0 + 100.0)) / (3.0 / 4.0)
    assert abs(zs.mean()) < Z / 64 and abs(zs.std() - 1) < Z / np.sqrt(2 * 4095)


def test_adc_clips_to_code_range_and_output_types():
    # 8-bit ADC: a bright pixel clips at 255
    p8 = _params(adc_bits=8, offset_dn=(10.0, 10.0), full_well_e=(1e6, 1e6))
    out = _expose(np.full((4, 4), 1e5), 0, 0, p8)
    assert out.dtype == np.uint16 and np.all(out == 255)
    # zero offset and large read noise: negative values clip at code 0
    p0 = _params(offset_dn=(0.0, 0.0), read_noise_e=(40.0, 40.0), dark_e=0.0, dsnu_rms_e=0.0)
    out0 = _expose(np.zeros((32, 32)), 0, 0, p0)
    assert out0.min() == 0 and (out0 == 0).mean() > 0.4
    # 20-bit ADC gives uint32 codes above 65535
    p20 = _params(adc_bits=20, gain_e_per_dn=(0.1, 0.1), full_well_e=(1e6, 1e6))
    out20 = _expose(np.full((4, 4), 2e4), 0, 0, p20, shot_noise=False, read_noise=False)
    assert out20.dtype == np.uint32 and out20.min() > 65535
