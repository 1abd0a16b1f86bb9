"""Centroid speed and agreement: budget.centroid against photutils, one run, same windows.

10,000 noisy 11x11 windows (pixel-integrated Gaussian PSF, Poisson shot noise and
Gaussian read noise from one ``numpy.random.Generator``) go through

* budget thresholded CoG (numba batch), with a given background and with the border-
  median background,
* budget IWCoG (numba batch),
* budget 2-D Gaussian least-squares fit (numba Levenberg-Marquardt, batch),
* photutils ``centroid_com`` in a per-window loop, on the same background-subtracted,
  thresholded data (so the definition is identical),
* photutils ``centroid_sources`` (box 11, ``centroid_com``) on the windows tiled into
  one image,
* photutils ``centroid_2dg`` (astropy Gaussian fit) on the first ``--n-2dg`` windows
  (it takes milliseconds per window); its time per window is comparable, its rms
  columns refer to that subset.

Then one 4096 x 2048 frame with a 5 x 5 star grid through the full-frame path
(``centroid_frames``: level and noise, threshold, ``ndimage.label``, matching, windows,
CoG).

Printed: time per window (best of N, JIT warmed up), rms position difference to
photutils (0 up to rounding for identical definitions) and rms error to the truth.

Run: ``python benchmarks/bench_centroid.py [--n 10000] [--repeat 5] [--seed 1]``
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np
import photutils
from photutils.centroids import centroid_2dg, centroid_com, centroid_sources
from scipy.special import erf

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import best_of, format_table, machine_description  # noqa: E402

from budget.centroid import (  # noqa: E402
    centroid_cog,
    centroid_frames,
    centroid_gaussian_fit,
    centroid_iwcog,
)

SIZE = 11


def make_windows(n: int, *, seed: int, sigma_px: float = 1.0, flux_e: float = 20000.0,
                 background_e: float = 100.0, read_noise_e: float = 5.0):
    """Noisy windows of a pixel-integrated Gaussian star; returns windows and truth."""
    rng = np.random.default_rng(seed)
    xt = SIZE // 2 + rng.uniform(-0.5, 0.5, n)
    yt = SIZE // 2 + rng.uniform(-0.5, 0.5, n)
    j = np.arange(SIZE)
    s2 = np.sqrt(2.0) * sigma_px

    def prof(c):
        return 0.5 * (erf((j[None, :] + 0.5 - c[:, None]) / s2) - erf((j[None, :] - 0.5 - c[:, None]) / s2))

    clean = flux_e * prof(yt)[:, :, None] * prof(xt)[:, None, :] + background_e
    noisy = rng.poisson(clean).astype(np.float64) + rng.normal(0.0, read_noise_e, clean.shape)
    return noisy, xt, yt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--n-2dg", type=int, default=200, help="windows for centroid_2dg")
    args = ap.parse_args()
    n = args.n
    bg, thr = 100.0, 50.0          # background (e-) and threshold above it (about 4.5 sigma)
    win, xt, yt = make_windows(n, seed=args.seed)

    info = machine_description() | {"photutils": photutils.__version__}
    print("machine: " + ", ".join(f"{k}={v}" for k, v in info.items()))
    print(f"{n} windows {SIZE}x{SIZE}, Gaussian PSF sigma 1 px, 2e4 e-, background {bg} e-, "
          f"read noise 5 e-; threshold {thr} e- above background; best of {args.repeat}\n")

    results: dict[str, tuple[float, np.ndarray, np.ndarray]] = {}

    def ours_cog():
        return centroid_cog(win, x0=0.0, y0=0.0, background=bg, threshold_dn=thr)

    def ours_cog_border():
        return centroid_cog(win, x0=0.0, y0=0.0, background="border", threshold_dn=thr)

    def ours_iwcog():
        return centroid_iwcog(win, x0=0.0, y0=0.0, background=bg, threshold_dn=thr,
                              weight_sigma_px=1.0, psf_sigma_px=1.0)

    def ours_gauss():
        return centroid_gaussian_fit(win, x0=0.0, y0=0.0, background=bg, threshold_dn=thr,
                                     sigma_start_px=1.0)

    for name, fn in (("budget CoG (given background)", ours_cog),
                     ("budget CoG (border median bg)", ours_cog_border),
                     ("budget IWCoG (sigma_w = 1 px)", ours_iwcog),
                     ("budget Gaussian LSQ fit", ours_gauss)):
        t, _ = best_of(fn, repeat=args.repeat, warmup=1)       # warm-up compiles the JIT
        x, y, _, _ = fn()
        results[name] = (t, x, y)

    def photutils_loop():
        xs = np.empty(n)
        ys = np.empty(n)
        for q in range(n):
            s = win[q] - bg
            xs[q], ys[q] = centroid_com(np.where(s > thr, s, 0.0))
        return xs, ys

    prepared = np.where(win - bg > thr, win - bg, 0.0)
    side = int(np.ceil(np.sqrt(n)))
    mosaic = np.zeros((side * SIZE, side * SIZE))
    for q in range(n):
        r, c = divmod(q, side)
        mosaic[r * SIZE:(r + 1) * SIZE, c * SIZE:(c + 1) * SIZE] = prepared[q]
    qs = np.arange(n)
    cx = (qs % side) * SIZE + SIZE // 2
    cy = (qs // side) * SIZE + SIZE // 2

    def photutils_sources():
        x, y = centroid_sources(mosaic, cx, cy, box_size=SIZE, centroid_func=centroid_com)
        return x - (cx - SIZE // 2), y - (cy - SIZE // 2)

    rep_slow = max(1, min(args.repeat, 3))
    for name, fn in (("photutils centroid_com loop", photutils_loop),
                     ("photutils centroid_sources", photutils_sources)):
        t, _ = best_of(fn, repeat=rep_slow, warmup=1)
        x, y = fn()
        results[name] = (t, x, y)

    m2 = min(args.n_2dg, n)

    def photutils_2dg():
        xs = np.full(n, np.nan)
        ys = np.full(n, np.nan)
        for q in range(m2):
            xs[q], ys[q] = centroid_2dg(win[q] - bg)
        return xs, ys

    t, _ = best_of(photutils_2dg, repeat=1, warmup=1)
    t *= n / m2                                     # scaled to n windows for the per-window time
    x, y = photutils_2dg()
    results[f"photutils centroid_2dg ({m2})"] = (t, x, y)

    ref_name = "photutils centroid_com loop"
    _, xr, yr = results[ref_name]
    rows = []
    for name, (t, x, y) in results.items():
        rows.append([
            name, f"{t / n * 1e6:.3f}",
            f"{np.sqrt(np.nanmean((x - xr) ** 2)):.3e}", f"{np.sqrt(np.nanmean((y - yr) ** 2)):.3e}",
            f"{np.sqrt(np.nanmean((x - xt) ** 2)):.5f}", f"{np.sqrt(np.nanmean((y - yt) ** 2)):.5f}",
        ])
    print(format_table(["method", "us/window", "rms dx to photutils com", "rms dy",
                        "rms err x (truth)", "rms err y"], rows))
    t_ours = results["budget CoG (given background)"][0]
    full_frame(seed=args.seed, repeat=rep_slow)
    print(f"\nbudget CoG is {results[ref_name][0] / t_ours:.0f}x faster than the centroid_com loop "
          f"and {results['photutils centroid_sources'][0] / t_ours:.0f}x faster than centroid_sources.")


def full_frame(*, seed: int, repeat: int) -> None:
    """Time the full-frame path on one 4096 x 2048 frame with 25 stars."""
    rng = np.random.default_rng(seed + 1)
    rows, cols = 2048, 4096
    frame = 200.0 + rng.normal(0.0, 5.0, (rows, cols))
    gx, gy = np.meshgrid(np.linspace(300, 3800, 5), np.linspace(200, 1850, 5))
    ref = np.column_stack([gx.ravel() + rng.uniform(-.5, .5, 25), gy.ravel() + rng.uniform(-.5, .5, 25)])
    win, _, _ = make_windows(25, seed=seed + 2)
    for (x, y), w in zip(ref, win):
        r0, c0 = int(round(y)) - SIZE // 2, int(round(x)) - SIZE // 2
        frame[r0:r0 + SIZE, c0:c0 + SIZE] += w - 100.0
    t, _ = best_of(lambda: centroid_frames([frame], reference_xy=ref), repeat=repeat, warmup=1)
    t2, _ = best_of(lambda: centroid_frames([frame]), repeat=repeat, warmup=1)
    print(f"\nfull frame {cols}x{rows}, 25 stars (budget.centroid_frames): {t:.3f} s with a "
          f"reference list, {t2:.3f} s detecting the reference first")


if __name__ == "__main__":
    main()
