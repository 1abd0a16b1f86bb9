"""Full-frame detector noise chain: simcam's counter-based numba kernel vs plain numpy.

Both do, on a 2048 x 4096 (rows x cols) two-chip mosaic: PRNU (1 + 1 % N(0,1)), dark
signal 2 e- with DSNU 0.5 e- rms and 1e-4 hot pixels, Poisson shot noise, full-well
clip, read noise, per-chip gain/offset ADC to uint16. The expected signal is a 3 e-
background plus 25 Gaussian stars of 1e5 e- each. numpy uses one
``numpy.random.Generator`` per frame (draws the maps every frame, as the kernel does).

Times are best of ``--repeat`` after a warm-up call (JIT / cache load): wall-clock ms per
frame and CPU ms per frame (all threads; steadier on a shared machine). Peak memory is
the tracemalloc peak of one frame (output + temporaries), MB, and the growth of the
process's maximum resident set over the whole run, MB.

Usage: ``python benchmarks/bench_detector_noise.py [--repeat 5]``
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import time

import numba
import numpy as np

_HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, _HERE)
sys.path.insert(1, os.path.dirname(_HERE))  # the repository root, if not installed
from _common import (  # noqa: E402
    best_of_wall_cpu,
    format_table,
    machine_description,
    peak_traced_mb,
)

from simcam.detector import DetectorParams, expose  # noqa: E402
from simcam.rng import key_from_seed  # noqa: E402

ROWS, COLS, CHIP_COLS = 2048, 4096, 2048
PARAMS = DetectorParams(
    gain_e_per_dn=(2.0, 2.1), offset_dn=(100.0, 110.0), read_noise_e=(5.0, 5.5),
    full_well_e=(6.0e4, 6.2e4), adc_bits=16, prnu_rms=0.01, dark_e=2.0, dsnu_rms_e=0.5,
    hot_pixel_fraction=1e-4, hot_pixel_dark_e=200.0,
)


def make_signal(seed: int = 1) -> np.ndarray:
    """3 e- background + 25 Gaussian stars (sigma 1.2 px, 1e5 e- each), float64."""
    rng = np.random.default_rng(seed)
    sig = np.full((ROWS, COLS), 3.0)
    for _ in range(25):
        y0, x0 = rng.uniform(16, ROWS - 16), rng.uniform(16, COLS - 16)
        r, c = int(y0), int(x0)
        yy, xx = np.mgrid[r - 8:r + 9, c - 8:c + 9]
        s2 = 1.2**2
        r2 = (yy - y0) ** 2 + (xx - x0) ** 2
        sig[r - 8:r + 9, c - 8:c + 9] += 1e5 * np.exp(-r2 / (2 * s2)) / (2 * np.pi * s2)
    return sig


def simcam_frame(sig: np.ndarray, frame: int) -> np.ndarray:
    return expose(signal_e=sig, row0=0, col0=0, mosaic_cols=COLS, chip_cols=CHIP_COLS,
                  params=PARAMS, frame_key=key_from_seed(7, 1, frame),
                  detector_key=key_from_seed(7, 0))


def numpy_frame(sig: np.ndarray, frame: int) -> np.ndarray:
    p = PARAMS
    rng = np.random.default_rng(np.random.SeedSequence(7, spawn_key=(1, frame)))
    chip = np.arange(COLS) // CHIP_COLS
    g = np.asarray(p.gain_e_per_dn)[chip]
    off = np.asarray(p.offset_dn)[chip]
    rn = np.asarray(p.read_noise_e)[chip]
    fw = np.asarray(p.full_well_e)[chip]
    lam = rng.standard_normal(sig.shape)
    lam *= p.prnu_rms
    lam += 1.0
    np.maximum(lam, 0.0, out=lam)
    lam *= sig
    dark = rng.standard_normal(sig.shape)
    dark *= p.dsnu_rms_e
    dark += p.dark_e
    np.maximum(dark, 0.0, out=dark)
    dark[rng.random(sig.shape) < p.hot_pixel_fraction] += p.hot_pixel_dark_e
    lam += dark
    del dark
    e = rng.poisson(lam).astype(np.float64)
    del lam
    np.minimum(e, fw, out=e)
    noise = rng.standard_normal(sig.shape)
    noise *= rn
    e += noise
    del noise
    e /= g
    e += off + 0.5
    np.floor(e, out=e)
    np.clip(e, 0, p.max_dn, out=e)
    return e.astype(np.uint16)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="timed repeats (best is reported)")
    args = ap.parse_args(argv)

    info = machine_description()
    print("machine: " + "; ".join(f"{k}={v}" for k, v in info.items()))
    sig = make_signal()
    npix = sig.size
    t0 = time.perf_counter()
    simcam_frame(sig, 0)
    print(f"first simcam call (JIT compile or cache load): {time.perf_counter() - t0:.2f} s")

    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
    rows = []
    max_threads = numba.get_num_threads()
    for n_threads in sorted({max_threads, 1}, reverse=True):
        numba.set_num_threads(n_threads)
        frame = iter(range(1, 10**6))
        wall, cpu = best_of_wall_cpu(lambda: simcam_frame(sig, next(frame)), repeat=args.repeat)
        rows.append(["simcam counter-RNG kernel", n_threads, f"{wall * 1e3:.0f}",
                     f"{cpu * 1e3:.0f}", f"{npix / wall / 1e6:.1f}",
                     f"{peak_traced_mb(lambda: simcam_frame(sig, 0)):.0f}"])
    numba.set_num_threads(max_threads)
    rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
    frame = iter(range(1, 10**6))
    wall, cpu = best_of_wall_cpu(lambda: numpy_frame(sig, next(frame)), repeat=args.repeat)
    rows.append(["numpy Generator (poisson+normal+ADC)", 1, f"{wall * 1e3:.0f}",
                 f"{cpu * 1e3:.0f}", f"{npix / wall / 1e6:.1f}",
                 f"{peak_traced_mb(lambda: numpy_frame(sig, 0)):.0f}"])
    rss2 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
    print(f"full frame {ROWS} x {COLS} = {npix / 1e6:.2f} Mpix, best of {args.repeat}:")
    print(format_table(["method", "threads", "wall ms/frame", "cpu ms/frame", "Mpix/s",
                        "peak MB"], rows))
    print(f"max RSS growth: simcam runs {rss1 - rss0:.0f} MB, then numpy runs {rss2 - rss1:.0f} MB "
          f"(RSS before: {rss0:.0f} MB, includes the 67 MB input)")

    a = simcam_frame(sig, 3).astype(float)
    b = numpy_frame(sig, 3).astype(float)
    bg = sig < 3.5
    print(f"sanity (background pixels, DN): simcam mean {a[bg].mean():.3f} sd {a[bg].std():.3f}; "
          f"numpy mean {b[bg].mean():.3f} sd {b[bg].std():.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
