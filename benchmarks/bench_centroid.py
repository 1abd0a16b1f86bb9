"""Centroid speed and agreement: budget.centroid.core against photutils, one run, same windows.

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

and, when SEP is installed, ``sep.winpos`` (windowed positions, Gaussian weight
sigma 1 px) on the same mosaic.

Then one 4096 x 2048 frame with a 5 x 5 star grid through the full-frame path
(``budget.centroid.frames.centroid_frames([frame], reference_xy=ref)``: level and noise from a
row subsample, threshold, labelling of boxes around the references, matching, windows,
CoG), and without the reference list (labelling the whole frame). Beside it, in the
same run, photutils' full-frame path on the same frame: level and noise by
``astropy.stats.sigma_clipped_stats`` on every 16th row, the whole frame thresholded at
5 sigma above the level (values below set to 0), then ``centroid_sources`` (box 11,
``centroid_com``) at the 25 reference positions; and, when SEP is installed, SEP's
background (``sep.Background``) + ``sep.extract`` at 5 sigma on the whole frame (a
detection without a reference list, beside our figure without one).

Printed: time per window (best of N, JIT warmed up), rms position difference to
photutils (0 up to rounding for identical definitions) and rms error to the truth.

The last line is ``RESULT {json}`` with the key figures (read by ``run_all.py``).

Run: ``python benchmarks/bench_centroid.py [--n 10000] [--repeat 5] [--seed 1] [--quick]``
"""

from __future__ import annotations

import os
import sys

import numpy as np
from scipy.special import erf

if not __package__:  # run as a file (python benchmarks/bench_x.py): the repository root on the path
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks._common import (  # noqa: E402
    bench_parser,
    best_of,
    emit_result,
    figure,
    format_table,
    optional_import,
    print_machine,
)

from budget.centroid.core import (  # noqa: E402
    centroid_cog,
    centroid_gaussian_fit,
    centroid_iwcog,
)
from budget.centroid.frames import centroid_frames  # noqa: E402

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
    ap = bench_parser(__doc__)
    ap.add_argument("--n", type=int, default=10_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--n-2dg", type=int, default=200, help="windows for centroid_2dg")
    args = ap.parse_args()
    if args.quick:
        args.n, args.repeat, args.n_2dg = min(args.n, 1000), min(args.repeat, 2), min(args.n_2dg, 10)
    n = args.n
    photutils = optional_import("photutils")
    sep = optional_import("sep")
    bg, thr = 100.0, 50.0          # background (e-) and threshold above it (about 4.5 sigma)
    win, xt, yt = make_windows(n, seed=args.seed)

    print_machine(photutils=photutils.__version__ if photutils else "not installed",
                  sep=sep.__version__ if sep else "not installed")
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

    if photutils is not None:
        from photutils.centroids import centroid_2dg, centroid_com, centroid_sources

        def photutils_loop():
            xs = np.empty(n)
            ys = np.empty(n)
            for q in range(n):
                s = win[q] - bg
                xs[q], ys[q] = centroid_com(np.where(s > thr, s, 0.0))
            return xs, ys

        prepared = np.where(win - bg > thr, win - bg, 0.0)
        mosaic, cx, cy = _mosaic(prepared, SIZE)

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
    if sep is not None:
        mosaic_sep, cx_sep, cy_sep = _mosaic(np.ascontiguousarray(win - bg), SIZE)

        def sep_winpos():
            x, y, _ = sep.winpos(mosaic_sep, cx_sep.astype(float), cy_sep.astype(float),
                                 np.full(n, 1.0))
            return x - (cx_sep - SIZE // 2), y - (cy_sep - SIZE // 2)

        t, _ = best_of(sep_winpos, repeat=max(1, min(args.repeat, 3)), warmup=1)
        x, y = sep_winpos()
        results["SEP winpos (sigma 1 px)"] = (t, x, y)

    ref_name = "photutils centroid_com loop"
    xr, yr = (results[ref_name][1], results[ref_name][2]) if ref_name in results else (None, None)
    rows = []
    for name, (t, x, y) in results.items():
        rows.append([
            name, f"{t / n * 1e6:.3f}",
            f"{np.sqrt(np.nanmean((x - xr) ** 2)):.3e}" if xr is not None else "n/a",
            f"{np.sqrt(np.nanmean((y - yr) ** 2)):.3e}" if yr is not None else "n/a",
            f"{np.sqrt(np.nanmean((x - xt) ** 2)):.5f}", f"{np.sqrt(np.nanmean((y - yt) ** 2)):.5f}",
        ])
    print(format_table(["method", "us/window", "rms dx to photutils com", "rms dy",
                        "rms err x (truth)", "rms err y"], rows))
    if sep is not None:
        _, xi, yi = results["budget IWCoG (sigma_w = 1 px)"]
        _, xs, ys = results["SEP winpos (sigma 1 px)"]
        print(f"IWCoG vs SEP winpos (both iterate a Gaussian-weighted centre, sigma 1 px): rms "
              f"difference {np.sqrt(np.nanmean((xi - xs) ** 2)):.2e} px in x, "
              f"{np.sqrt(np.nanmean((yi - ys) ** 2)):.2e} px in y")
    if photutils is None:
        print("photutils: not installed (its rows and the full-frame peer are missing)")
    if sep is None:
        print("SEP: not installed (sep.winpos and sep.extract rows are missing)")
    ff = full_frame(seed=args.seed, repeat=max(1, min(args.repeat, 3)), photutils=photutils, sep=sep)

    def us(name):
        return results[name][0] / n * 1e6 if name in results else None

    status = None if photutils is not None else "not installed"
    figs = [
        figure("cog_us", "CoG, 11x11 window, given background (us/window)",
               us("budget CoG (given background)"), "us", peer="photutils centroid_sources",
               peer_value=us("photutils centroid_sources"), peer_status=status,
               target=2.0, target_source="project target"),
        figure("cog_border_us", "CoG, 11x11 window, border-median background (us/window)",
               us("budget CoG (border median bg)"), "us", peer="photutils centroid_com loop",
               peer_value=us("photutils centroid_com loop"), peer_status=status,
               target=2.0, target_source="project target"),
        figure("gauss_fit_us", "2-D Gaussian fit, 11x11 window (us/window)",
               us("budget Gaussian LSQ fit"), "us", peer="photutils centroid_2dg",
               peer_value=us(f"photutils centroid_2dg ({min(args.n_2dg, n)})"), peer_status=status),
        figure("full_frame_ref_ms", "full 4096x2048 frame, 25 stars, reference list (ms)",
               ff["ours_ref_s"] * 1e3, "ms", peer="photutils threshold + centroid_sources",
               peer_value=None if ff["photutils_s"] is None else ff["photutils_s"] * 1e3,
               peer_status=status, target=10.0, target_source="project target"),
        figure("full_frame_detect_ms", "full 4096x2048 frame, 25 stars, detection first (ms)",
               ff["ours_detect_s"] * 1e3, "ms", peer="SEP background + extract",
               peer_value=None if ff["sep_s"] is None else ff["sep_s"] * 1e3,
               peer_status=None if sep is not None else "not installed"),
    ]
    figs.insert(2, figure("iwcog_us", "IWCoG (Gaussian weight sigma 1 px), 11x11 window (us/window)",
                          us("budget IWCoG (sigma_w = 1 px)"), "us", peer="SEP winpos (same weight)",
                          peer_value=us("SEP winpos (sigma 1 px)"),
                          peer_status=None if sep is not None else "not installed"))
    emit_result("centroid", figs, quick=args.quick, windows=n,
                photutils=photutils.__version__ if photutils else None,
                sep=sep.__version__ if sep else None)


def _mosaic(windows: np.ndarray, size: int):
    """Tile ``windows`` (n, size, size) into one square image; centres of the tiles."""
    n = windows.shape[0]
    side = int(np.ceil(np.sqrt(n)))
    mosaic = np.zeros((side * size, side * size))
    for q in range(n):
        r, c = divmod(q, side)
        mosaic[r * size:(r + 1) * size, c * size:(c + 1) * size] = windows[q]
    qs = np.arange(n)
    return mosaic, (qs % side) * size + size // 2, (qs // side) * size + size // 2


def full_frame(*, seed: int, repeat: int, photutils=None, sep=None) -> dict:
    """Time the full-frame path on one 4096 x 2048 frame with 25 stars, and its peers."""
    rng = np.random.default_rng(seed + 1)
    rows, cols = 2048, 4096
    level_e, noise_e = 200.0, 5.0
    frame = level_e + rng.normal(0.0, noise_e, (rows, cols))
    gx, gy = np.meshgrid(np.linspace(300, 3800, 5), np.linspace(200, 1850, 5))
    ref = np.column_stack([gx.ravel() + rng.uniform(-.5, .5, 25), gy.ravel() + rng.uniform(-.5, .5, 25)])
    win, wxt, wyt = make_windows(25, seed=seed + 2)
    xt, yt = np.empty(25), np.empty(25)
    for q, ((x, y), w) in enumerate(zip(ref, win)):
        r0, c0 = int(round(y)) - SIZE // 2, int(round(x)) - SIZE // 2
        frame[r0:r0 + SIZE, c0:c0 + SIZE] += w - 100.0
        xt[q], yt[q] = c0 + wxt[q], r0 + wyt[q]

    def rms(x, y):
        return float(np.sqrt(np.nanmean((x - xt) ** 2 + (y - yt) ** 2)))

    t, _ = best_of(lambda: centroid_frames([frame], reference_xy=ref), repeat=repeat, warmup=1)
    t2, _ = best_of(lambda: centroid_frames([frame]), repeat=repeat, warmup=1)
    ours = centroid_frames([frame], reference_xy=ref)
    out = {"ours_ref_s": t, "ours_detect_s": t2, "photutils_s": None, "sep_s": None}
    lines = [["budget centroid_frames, reference list", f"{t * 1e3:.1f}",
              f"{rms(ours['x'].to_numpy(), ours['y'].to_numpy()):.4f}"],
             ["budget centroid_frames, detection first", f"{t2 * 1e3:.1f}", ""]]
    if photutils is not None:
        from astropy.stats import sigma_clipped_stats
        from photutils.centroids import centroid_com, centroid_sources

        def peer():
            _, med, std = sigma_clipped_stats(frame[::16], sigma=3.0)
            img = frame - med
            img[img <= 5.0 * std] = 0.0
            return centroid_sources(img, ref[:, 0], ref[:, 1], box_size=SIZE,
                                    centroid_func=centroid_com)

        tp, _ = best_of(peer, repeat=repeat, warmup=1)
        px, py = peer()
        out["photutils_s"] = tp
        lines.append(["photutils: sigma-clipped level, threshold, centroid_sources",
                      f"{tp * 1e3:.1f}", f"{rms(px, py):.4f}"])
    if sep is not None:
        data = np.ascontiguousarray(frame, dtype=np.float32)

        def sep_path():
            bkg = sep.Background(data)
            return sep.extract(data - bkg, 5.0, err=bkg.globalrms)

        ts, _ = best_of(sep_path, repeat=repeat, warmup=1)
        out["sep_s"] = ts
        objs = sep_path()
        lines.append([f"SEP: Background + extract (5 sigma; {len(objs)} objects)",
                      f"{ts * 1e3:.1f}", ""])
    print(f"\nfull frame {cols}x{rows}, 25 stars, best of {repeat}:")
    print(format_table(["path", "ms", "rms error to truth (px)"], lines))
    return out


if __name__ == "__main__":
    main()
