"""The detector kernels the test suite calls, compiled in a process of their own.

On a cold numba cache (a fresh clone, as in CI) the first test that calls a kernel with a
new signature compiles it: the detector's parallel kernels take 5-8 s each, about 75 s
of a full run for the signatures the suite calls, on one core while the other idles.
``tests/conftest.py`` starts :func:`compile_all` in a child process at the start of a
session when that cache is cold and a second core is free; the child writes numba's
cache, and a test that reaches a kernel after the child compiled it loads it instead.

Each call runs a public function (or, where the tests call one directly, the kernel) on
a tiny block with the argument types a test passes, which compiles the signature that
test calls. The calls run in the reverse of the order in which the suite first meets
them, so that the child and the tests, which compile what they meet where they meet it,
work toward each other rather than compiling the same kernel at the same time (in the
suite's own order they do: the detector tests do little besides calling new signatures,
so once they catch up with the child the two compile side by side, which made five
detector test files slower than no child at all, 154 s against 137 s, where this order
takes 73 s). Nothing
depends on the child: a signature it has not written yet is compiled where it is called,
with the same machine code.
"""

from __future__ import annotations

import numpy as np

#: a tiny two-chip mosaic (the chip boundary inside every block)
CHIP_COLS = 4
MOSAIC_COLS = 2 * CHIP_COLS


def _params(*, adc_bits: int = 16, beta: float = 0.0):
    from simcam.detector import DetectorParams

    return DetectorParams(gain_e_per_dn=(4.0, 6.0), offset_dn=(100.0, 200.0), read_noise_e=(3.0, 4.0),
                          full_well_e=(5e4, 6e4), adc_bits=adc_bits, prnu_rms=0.02, dark_e=20.0,
                          dsnu_rms_e=3.0, hot_pixel_fraction=0.01, hot_pixel_dark_e=400.0,
                          nonlinearity_beta=beta)


def _expose(signal, params, *, quantize=True, maps=None, row0=1, col0=2):
    from simcam.detector import expose

    return expose(signal_e=signal, row0=row0, col0=col0, mosaic_cols=MOSAIC_COLS, chip_cols=CHIP_COLS,
                  params=params, frame_key=1, detector_key=2, quantize=quantize, maps=maps)


def _maps(params, shape):
    from simcam.detector import detector_maps

    return detector_maps(shape=shape, row0=0, col0=0, mosaic_cols=MOSAIC_COLS, params=params, detector_key=2)


def _chain(params):
    from simcam.detector import window_chain

    return window_chain(signal_e=np.full((2, 3, 3), 50.0), row0=[0, 1], col0=[0, 3], mosaic_cols=MOSAIC_COLS,
                        chip_cols=CHIP_COLS, params=params, detector_key=2)


def _fused_centroids() -> None:
    # tests/test_protocols.py: the parallel fused expose-and-centroid kernel
    from budget.starcam.kernels_trial import expose_centroid_chain
    from simcam.rng import child_keys

    chain = _chain(_params())
    expose_centroid_chain(chain, child_keys(np.uint64(1), 2), dark_mean=None, threshold_dn=np.full(2, 3.0),
                          parallel=True)


def _maps_routes() -> None:
    # tests/test_detector_maps.py, test_detector_frame.py: float32 input through maps of
    # the exposed block; float64 through maps of a larger block (their part copied
    # contiguous, simcam.detector._maps_view), to ADC codes and to float DN; the same-block
    # maps to float DN (the thread-count check's child)
    p = _params(beta=0.05)
    same = _maps(p, (2, 6))
    _expose(np.full((2, 6), 50.0, dtype=np.float32), p, maps=same, row0=0, col0=0)
    _expose(np.full((2, 6), 50.0), p, maps=same, row0=0, col0=0, quantize=False)
    larger = _maps(p, (4, 8))
    for quantize in (True, False):
        _expose(np.full((2, 5), 50.0), p, maps=larger, quantize=quantize)


def _window_routes() -> None:
    # tests/test_detector_frame.py: one frame's window kernel; the windows' frames (serial
    # and parallel) to float DN
    from simcam.detector import expose_windows_frames
    from simcam.kernels.detector import noise_adc_window

    mean = np.full((3, 5), 50.0)
    gain, offset, read_noise, full_well = (np.array(v) for v in ([4.0, 6.0], [100.0, 200.0], [3.0, 4.0],
                                                                  [5e4, 6e4]))
    noise_adc_window(mean, np.empty((3, 5)), 0, 2, MOSAIC_COLS, CHIP_COLS, gain, offset, read_noise, full_well,
                     np.uint64(1), 4095.0, np.empty((3, 15), dtype=np.uint64), np.empty(30, dtype=np.int64))
    chain = _chain(_params(beta=0.05))
    for parallel in (False, True):
        expose_windows_frames(chain=chain, frame_keys=[np.uint64(1)], quantize=False, parallel=parallel)


def _block_routes() -> None:
    # tests/test_detector.py: the fused pass to 20-bit codes (uint32), float32 input, the
    # windows (codes and float DN) and the block to float DN and to codes
    from simcam.detector import expose_windows

    p = _params()
    sig = np.full((2, 6), 50.0)
    _expose(sig, _params(adc_bits=20))
    _expose(sig.astype(np.float32), p)
    for quantize in (True, False):
        expose_windows(signal_e=np.full((2, 3, 3), 50.0), row0=[0, 1], col0=[0, 3], mosaic_cols=MOSAIC_COLS,
                       chip_cols=CHIP_COLS, params=p, frame_key=1, detector_key=2, quantize=quantize)
    _expose(sig, p, quantize=False)
    _expose(sig, p)


def _render_routes() -> None:
    # tests/test_cli_simcam.py: a full frame through maps of the whole frame, to codes;
    # the windows' frames (serial and parallel) to codes
    from simcam.detector import expose_windows_frames

    p = _params()
    _expose(np.full((2, 6), 50.0), p, maps=_maps(p, (2, 6)), row0=0, col0=0)
    chain = _chain(p)
    for parallel in (False, True):
        expose_windows_frames(chain=chain, frame_keys=[np.uint64(1)], quantize=True, parallel=parallel)


#: in the reverse of the order in which the suite first calls them (its files run in
#: alphabetical order)
STEPS = (_fused_centroids, _maps_routes, _window_routes, _block_routes, _render_routes)


def compile_all(arg: str = "") -> None:
    """Child target (:mod:`simcam.numba_warm`'s convention, ``arg`` unused): every step
    of :data:`STEPS` in turn."""
    for step in STEPS:
        step()


def warm_studies() -> None:
    """The kernels of a star-camera trial and its truths (the study's own two-process
    :meth:`~budget.runner.capabilities.Warmup.prewarm`, on both cores), then one pointing of the
    attitude study (its sky rendering and solve on top of them): what most of the suite's
    tests call first."""
    from budget.attitude.study import STUDY as ATTITUDE
    from budget.starcam.study import STUDY as STARCAM

    STARCAM.prewarm(STARCAM.load_scenario(None))
    ATTITUDE.trial(ATTITUDE.load_scenario(None), 0, 0)
