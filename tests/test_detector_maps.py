"""The detector's fixed-pattern maps computed once (:func:`simcam.detector.detector_maps`) and
read per frame (``expose(..., maps=...)``): the maps against the PRNU factor and dark signal
rebuilt in numpy from the generator's primitives (an independent path), the frames bit for
bit against the fused chain that draws the maps itself, and the key check that keeps a map
from being used for another detector, parameter set or block. No random assertion here:
every comparison is exact (the same functions of the keys and the pixel index).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from simcam import rng as rng_mod
from simcam.detector import (
    DetectorMaps,
    DetectorParameterError,
    DetectorParams,
    detector_maps,
    dsnu_map,
    expose,
    prnu_map,
)
from simcam.rng import key_from_seed

MOSAIC_COLS = 4096
CHIP_COLS = 2048
SEED = 20261126


def _params(**kw):
    base = dict(gain_e_per_dn=(4.0, 6.0), offset_dn=(100.0, 200.0), read_noise_e=(3.0, 4.0),
                full_well_e=(3e3, 4e3), adc_bits=16, prnu_rms=0.02, dark_e=20.0, dsnu_rms_e=3.0,
                hot_pixel_fraction=0.01, hot_pixel_dark_e=400.0, nonlinearity_beta=0.05)
    base.update(kw)
    return DetectorParams(**base)


def _signal(shape, seed=0):
    """Signals from 0 to 8e3 e- (both Poisson methods, saturation at these full wells)."""
    r = np.random.default_rng(seed)
    return r.uniform(0.0, 1.0, shape) ** 3 * 8e3


def _maps(shape, row0, col0, p, dk):
    return detector_maps(shape=shape, row0=row0, col0=col0, mosaic_cols=MOSAIC_COLS, params=p, detector_key=dk)


def _expose(sig, row0, col0, p, fk, dk, **kw):
    return expose(signal_e=sig, row0=row0, col0=col0, mosaic_cols=MOSAIC_COLS, chip_cols=CHIP_COLS,
                  params=p, frame_key=fk, detector_key=dk, **kw)


def test_maps_equal_the_fixed_pattern_rebuilt_from_rng_primitives():
    # g = max(0, 1 + prnu z1), d = max(0, dark + dsnu z2) + hot [u3 < fraction], the slots
    # 0, 1, 2 of the pixel's counter p * 2**16 (simcam.kernels.detector), in numpy
    p = _params()
    dk = key_from_seed(SEED, 0)
    row0, col0, h, w = 37, 2000, 30, 90
    m = _maps((h, w), row0, col0, p, dk)
    rows, cols = np.mgrid[row0:row0 + h, col0:col0 + w]
    ctr = (rows * MOSAIC_COLS + cols).astype(np.uint64) << np.uint64(16)
    g = np.maximum(0.0, 1.0 + p.prnu_rms * rng_mod.normal_array(key=dk, counter=ctr | np.uint64(0 << 12)))
    d = np.maximum(0.0, p.dark_e + p.dsnu_rms_e * rng_mod.normal_array(key=dk, counter=ctr | np.uint64(1 << 12)))
    d = d + np.where(rng_mod.uniform_array(key=dk, counter=ctr | np.uint64(2 << 12)) < p.hot_pixel_fraction,
                     p.hot_pixel_dark_e, 0.0)
    assert np.array_equal(m.gain, g) and np.array_equal(m.dark_e, d)
    assert (m.dark_e > 300).any()  # hot pixels present (1 % of 2700)
    # and the public single-map functions (another kernel) agree
    assert np.array_equal(m.gain, prnu_map(shape=(h, w), row0=row0, col0=col0, mosaic_cols=MOSAIC_COLS,
                                           params=p, detector_key=dk))
    assert np.array_equal(m.dark_e, dsnu_map(shape=(h, w), row0=row0, col0=col0, mosaic_cols=MOSAIC_COLS,
                                             params=p, detector_key=dk))
    assert m.nbytes == 16 * h * w and m.shape == (h, w)
    # without PRNU, DSNU, hot pixels: g = 1, d = dark_e exactly
    flat = _maps((4, 5), 0, 0, _params(prnu_rms=0.0, dsnu_rms_e=0.0, hot_pixel_fraction=0.0), dk)
    assert np.all(flat.gain == 1.0) and np.all(flat.dark_e == 20.0)


@pytest.mark.parametrize("quantize", [True, False])
@pytest.mark.parametrize("beta", [0.05, -0.3, 0.0])
def test_frames_through_maps_equal_the_fused_chain(beta, quantize):
    # several detector and frame keys; the maps of a larger block than the exposed one
    # (every sub-block reads its part); blocks astride the chip boundary
    p = _params(nonlinearity_beta=beta)
    for dseed in (1, 2, 3):
        dk = key_from_seed(SEED, dseed)
        mrow0, mcol0 = 500, 1900
        m = _maps((60, 300), mrow0, mcol0, p, dk)
        for frame, (r, c, h, w) in enumerate([(0, 0, 60, 300), (7, 130, 20, 41), (59, 299, 1, 1),
                                              (3, 0, 40, 148)]):
            sig = _signal((h, w), seed=frame)
            fk = key_from_seed(SEED, 10 + dseed, frame)
            ref = _expose(sig, mrow0 + r, mcol0 + c, p, fk, dk, quantize=quantize)
            got = _expose(sig, mrow0 + r, mcol0 + c, p, fk, dk, quantize=quantize, maps=m)
            assert got.dtype == ref.dtype and np.array_equal(got, ref)


_SWITCHES = [dict(shot_noise=False), dict(read_noise=False), dict(shot_noise=False, read_noise=False, quantize=False)]


def _switch_case():
    p = _params(adc_bits=12, prnu_rms=0.0)
    dk, fk = key_from_seed(SEED, 4), key_from_seed(SEED, 5, 0)
    return p, dk, fk, _signal((16, 64), seed=4), _maps((16, 64), 10, 2020, p, dk)


@pytest.mark.parametrize("switches", _SWITCHES)
def test_noise_switches_through_maps(switches):
    p, dk, fk, sig, m = _switch_case()
    assert np.array_equal(_expose(sig, 10, 2020, p, fk, dk, maps=m, **switches),
                          _expose(sig, 10, 2020, p, fk, dk, **switches))


# float32 to float DN through the maps is a signature numba compiles for this check alone
# (about 8 s of a cold cache): it runs with -m slow, float32 to ADC codes by default
@pytest.mark.parametrize("switches", _SWITCHES[:2] + [pytest.param(_SWITCHES[2], marks=pytest.mark.slow)])
def test_float32_input_through_maps(switches):
    p, dk, fk, sig, m = _switch_case()
    s32 = sig.astype(np.float32)
    assert np.array_equal(_expose(s32, 10, 2020, p, fk, dk, maps=m, **switches),
                          _expose(s32.astype(np.float64), 10, 2020, p, fk, dk, **switches))


def test_maps_of_another_detector_or_block_are_refused():
    p = _params()
    dk = key_from_seed(SEED, 6)
    fk = key_from_seed(SEED, 7, 0)
    m = _maps((20, 20), 100, 100, p, dk)
    sig = _signal((10, 10))
    # another detector key, or any of the five parameters the maps depend on
    with pytest.raises(DetectorParameterError, match="maps"):
        _expose(sig, 100, 100, p, fk, key_from_seed(SEED, 8), maps=m)
    for field, value in (("prnu_rms", 0.03), ("dark_e", 21.0), ("dsnu_rms_e", 2.0),
                         ("hot_pixel_fraction", 0.02), ("hot_pixel_dark_e", 300.0)):
        with pytest.raises(DetectorParameterError, match="maps"):
            _expose(sig, 100, 100, dataclasses.replace(p, **{field: value}), fk, dk, maps=m)
    # another mosaic width (another pixel index), a block the maps do not cover, not maps
    with pytest.raises(DetectorParameterError, match="maps"):
        expose(signal_e=sig, row0=100, col0=100, mosaic_cols=2048, chip_cols=CHIP_COLS, params=p,
               frame_key=fk, detector_key=dk, maps=m)
    for r0, c0 in ((95, 100), (100, 111), (111, 100)):
        with pytest.raises(DetectorParameterError, match="maps: cover"):
            _expose(sig, r0, c0, p, fk, dk, maps=m)
    with pytest.raises(DetectorParameterError, match="maps: must be a DetectorMaps"):
        _expose(sig, 100, 100, p, fk, dk, maps=m.gain)
    # the per-frame parameters (gain, offset, read noise, full well, non-linearity) may change
    p2 = dataclasses.replace(p, gain_e_per_dn=(3.0, 5.0), read_noise_e=(1.0, 2.0), nonlinearity_beta=0.0)
    assert np.array_equal(_expose(sig, 105, 105, p2, fk, dk, maps=m), _expose(sig, 105, 105, p2, fk, dk))
    # an invalid signal is still rejected (the range check rides on the pass)
    bad = sig.copy()
    bad[3, 4] = np.nan
    with pytest.raises(DetectorParameterError, match="signal_e"):
        _expose(bad, 100, 100, p, fk, dk, maps=m)
    assert isinstance(m, DetectorMaps)


def test_star_camera_keeps_its_maps_and_rebuilds_them_when_the_detector_changes():
    from simcam.starcam.render import Placement, StarCamera
    from simcam.starcam.scenario import default
    from simcam.starcam.targets import star_grid

    scn = default()
    cam = StarCamera(scn)
    scene = cam.scene(Placement(layout=star_grid(scn)))
    expected = cam.expected_frame_e(scene)
    rows, cols = cam.mosaic.shape
    frame = cam.render_frame(scene, frame=3, seed=11, expected_e=expected)
    maps = cam.frame_maps()
    assert cam.frame_maps() is maps and maps.shape == (rows, cols)
    key = cam.frame_key(seed=11, condition=scene.placement.condition, frame=3)
    ref = expose(signal_e=expected, row0=0, col0=0, mosaic_cols=cols, chip_cols=cam.mosaic.chip_cols,
                 params=cam.detector_params, frame_key=key, detector_key=cam.detector_key)
    assert np.array_equal(frame, ref)
    # a new detector key or fixed-pattern parameter: new maps, not the stale ones
    cam.detector_key = key_from_seed(99, 0)
    assert cam.frame_maps() is not maps and cam.frame_maps().detector_key == cam.detector_key
    maps2 = cam.frame_maps()
    cam.detector_params = dataclasses.replace(cam.detector_params, dsnu_rms_e=2.5)
    assert cam.frame_maps() is not maps2
    dark = cam.render_frame(scene, frame=0, seed=11, dark=True)
    ref = expose(signal_e=np.zeros((rows, cols)), row0=0, col0=0, mosaic_cols=cols,
                 chip_cols=cam.mosaic.chip_cols, params=cam.detector_params,
                 frame_key=cam.frame_key(seed=11, condition=scene.placement.condition, frame=0, dark=True),
                 detector_key=cam.detector_key)
    assert np.array_equal(dark, ref)
    # not pickled with the camera (a worker rebuilds it)
    assert "_frame_maps" not in cam.__getstate__()


def test_samplers_given_their_first_word_equal_the_generator():
    # the per-frame pass draws the Poisson count and the read-noise normal from a first word
    # computed in a loop of its own: the same variates as simcam.rng_poisson.poisson /
    # simcam.rng.std_normal
    # (exact equality), over means on the table grid and between its levels (j / 16),
    # at 0, near the switch to PTRS at 10, beyond it, NaN, and many counters (the normal's
    # rejections, probability 1.2 %, and the Poisson's second word, up to 6.3 %, occur)
    from numba import njit

    from simcam.rng import random_bits64, std_normal, uniform01
    from simcam.rng import std_normal_from_word as _std_normal_from_word
    from simcam.rng import uniform01_from_word as _uniform01_from_word
    from simcam.rng_poisson import poisson
    from simcam.rng_poisson import poisson_from_word as _poisson_from_word

    @njit
    def both(lam, key, counters, out_p, ref_p, out_z, ref_z):
        for i in range(counters.size):
            c = counters[i]
            w = random_bits64(key, c)
            out_p[i] = _poisson_from_word(lam[i], w, key, c)
            ref_p[i] = poisson(lam[i], key, c)
            out_z[i] = _std_normal_from_word(w, key, c)
            ref_z[i] = std_normal(key, c)
            if _uniform01_from_word(w) != uniform01(key, c):
                out_z[i] = np.nan  # fails the comparison below

    r = np.random.default_rng(5)
    n = 400_000
    special = np.array([0.0, 1e-300, 1 / 16, 0.5, 1.0, 9.9375, 9.999999999, 10.0, 10.5, 1e3, -1.0, np.nan])
    lam = np.concatenate([special, r.uniform(0.0, 12.0, n), np.round(r.uniform(0, 10, 1000) * 16) / 16])
    counters = (np.arange(lam.size, dtype=np.uint64) << np.uint64(16)) | np.uint64(1 << 12)
    out_p, ref_p = np.empty(lam.size, np.int64), np.empty(lam.size, np.int64)
    out_z, ref_z = np.empty(lam.size), np.empty(lam.size)
    for key in (key_from_seed(SEED, 9, 0), key_from_seed(SEED, 9, 1)):
        both(lam, key, counters, out_p, ref_p, out_z, ref_z)
        assert np.array_equal(out_p, ref_p)
        assert np.array_equal(out_z, ref_z)
