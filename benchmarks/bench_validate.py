"""Cost of Monte Carlo validation trials on the embedded seed-000 scenario.

* one full protocol trial (TE + HSFE + chromatic + distortion: 20,460 star-windows with
  the default plans, centroided and through the published and improved estimators), on
  one core (numba serial kernels), after warm-up, best and median of ``--repeat``; its CPU
  time (best), and that of the same trials in the ideal world, with the exact stamp
  route (``render.stamp_route = "exact"``) and with one camera's pixel maps for every trial
  (``validation.new_maps_per_trial = false``: no TE and HSFE truths of the trial's own
  camera, the trial of earlier runs of this benchmark);
  with the time split into rendering, centroiding and estimating;
* the anatomy of one realistic trial: the window-pixel draws it makes (every star window
  of every frame), the time of its expose-and-centroid kernels (all of them, timed inside
  the trial), and the per-pixel cost of the exact sampler alone on the trial's own mean
  charges (Poisson by table inversion below 10 e-, Hoermann's PTRS at and above, and the
  read-noise normal; :mod:`simcam.rng`), from which the trial's random-number floor
  follows: what no change of orchestration can remove;
* ``--trials K`` trials (default 1000) with ``--workers W`` processes (default all
  cores), wall time, including the truth computation and worker start-up.

The last line is ``RESULT {json}`` (read by ``run_all.py``).

Usage: ``python benchmarks/bench_validate.py [--repeat 10] [--trials 1000] [--workers 2] [--quick]``
"""

from __future__ import annotations

import os
import statistics
import sys
import time
import warnings

if not __package__:  # run as a file (python benchmarks/bench_x.py): the repository root on the path
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks._common import (  # noqa: E402
    bench_parser,
    emit_result,
    figure,
    format_table,
    print_machine,
)

from budget.starcam import validate as V  # noqa: E402
from budget.runner.executors import default_workers  # noqa: E402
from budget.runner.run import run_study  # noqa: E402
from budget.starcam.study import STUDY  # noqa: E402
from simcam.starcam.scenario import default  # noqa: E402


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--repeat", type=int, default=10)
    ap.add_argument("--trials", type=int, default=1000)
    ap.add_argument("--workers", type=int, default=default_workers())
    args = ap.parse_args()
    if args.quick:
        args.repeat, args.trials = min(args.repeat, 3), min(args.trials, 20)
    import numba

    from budget.runner.executors import worker_setup

    blas = worker_setup()  # one numba and one BLAS thread, as in a worker of the runner
    scn = default()
    warnings.simplefilter("ignore")
    V.run_trial(scn, 0, 0, setup=STUDY.prepared(scn))
    times = []
    for k in range(1, args.repeat + 1):
        t0 = time.perf_counter()
        V.run_trial(scn, 0, k, setup=STUDY.prepared(scn))
        times.append(time.perf_counter() - t0)
    # the same trial's CPU time (each trial new: its hexapod errors and drift render new
    # scenes), in the ideal world (no world effects) and with the exact stamp route
    # (render.stamp_route = "exact": the wavelengths summed for every scene)
    from budget.runner.validate_cmd import ideal_world_scenario
    from simcam.starcam.scenario import with_updates

    cpu = {}
    for name, s in (("realistic", scn), ("ideal", ideal_world_scenario(STUDY, scn, source="embedded default")),
                    ("exact", with_updates(scn, {"render.stamp_route": "exact"})),
                    ("shared_maps", with_updates(scn, {"validation.new_maps_per_trial": False}))):
        V.run_trial(s, 0, 0, setup=STUDY.prepared(s))
        ts = []
        for k in range(1, args.repeat + 1):
            t0 = time.process_time()
            V.run_trial(s, 0, 100 + k, setup=STUDY.prepared(s))
            ts.append(time.process_time() - t0)
        cpu[name] = min(ts)
    from budget.starcam.protocols import make_plan
    from simcam.starcam.targets import calibration_grid

    anatomy = trial_anatomy(scn, args.repeat)
    w_star = scn.lab.target.rows * scn.lab.target.cols
    w_cal = calibration_grid(scn).n_stars
    n_windows = sum(c.frames * (w_cal if c.target == "calibration_grid" else w_star)
                    for p in ("te", "hsfe", "chromatic", "distortion") for c in make_plan(p, scn).conditions)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    blas.restore_original_limits()
    t0 = time.perf_counter()
    res = run_study(STUDY, scn, trials=args.trials, seed=1, workers=args.workers)
    total = time.perf_counter() - t0
    print_machine()
    print(format_table(
        ["what", "time"],
        [
            (f"one trial, one core ({n_windows:,} star-windows), best", f"{min(times):.3f} s"),
            ("one trial, one core, median", f"{statistics.median(times):.3f} s"),
            ("one trial, CPU, best", f"{cpu['realistic']:.3f} s"),
            ("one trial, ideal world (--ideal-world), CPU, best", f"{cpu['ideal']:.3f} s"),
            ("one trial, exact stamp route, CPU, best", f"{cpu['exact']:.3f} s"),
            ("one trial, one camera's pixel maps (no own TE/HSFE truths), CPU, best", f"{cpu['shared_maps']:.3f} s"),
            (f"{res.trials} trials, {args.workers} worker process(es), wall (truth included)", f"{total:.1f} s"),
        ],
    ))
    print(format_table(
        ["anatomy of one realistic trial (one core)", "value"],
        [
            ("window-pixel draws (pixels x frames)", f"{anatomy['draws']:,}"),
            ("of which mean >= 10 e- (PTRS)", f"{anatomy['ptrs_fraction']:.1%}"),
            ("expose-and-centroid kernels, CPU per trial", f"{anatomy['kernel_s'] * 1e3:.1f} ms"),
            ("the same per draw", f"{anatomy['kernel_ns']:.1f} ns"),
            ("exact sampler per draw: Poisson (table, mean < 10 e-)", f"{anatomy['table_ns']:.1f} ns"),
            ("exact sampler per draw: Poisson (PTRS, mean >= 10 e-)", f"{anatomy['ptrs_ns']:.1f} ns"),
            ("exact sampler per draw: read-noise normal", f"{anatomy['normal_ns']:.1f} ns"),
            ("random-number floor of the trial (sampler on its draws)", f"{anatomy['floor_s'] * 1e3:.1f} ms"),
            ("numpy Generator, the same draws (Poisson + normal), per draw", f"{anatomy['numpy_ns']:.1f} ns"),
        ],
    ))
    emit_result("validate", [
        figure("trial_s", "one full seed-000 protocol trial, one core, best (s)", min(times), "s",
               target=0.03, target_source="speed target, warm"),
        figure("trial_median_s", "one full seed-000 protocol trial, one core, median (s)",
               statistics.median(times), "s", target=0.03, target_source="speed target, warm"),
        figure("trial_cpu_s", "one full seed-000 protocol trial, CPU time, best (s)", cpu["realistic"], "s"),
        figure("trial_ideal_cpu_s", "the same trial in the ideal world (--ideal-world), CPU time, best (s)",
               cpu["ideal"], "s"),
        figure("trial_exact_stamps_cpu_s", "the same trial with render.stamp_route = exact, CPU time, best (s)",
               cpu["exact"], "s"),
        figure("trial_shared_maps_cpu_s", "the same trial with one camera's pixel maps for every trial "
               "(new_maps_per_trial = false: no TE/HSFE truths of its own), CPU time, best (s)", cpu["shared_maps"], "s"),
        figure("trial_draws", "one realistic trial: window-pixel draws (pixels x frames)", anatomy["draws"], ""),
        figure("trial_kernel_ms", "one realistic trial: its expose-and-centroid kernels, CPU (ms)",
               anatomy["kernel_s"] * 1e3, "ms"),
        figure("sampler_table_ns", "exact Poisson sampler per draw, table inversion (mean < 10 e-), on the trial's means (ns)",
               anatomy["table_ns"], "ns"),
        figure("sampler_ptrs_ns", "exact Poisson sampler per draw, PTRS (mean >= 10 e-), on the trial's means (ns)",
               anatomy["ptrs_ns"], "ns"),
        figure("trial_floor_ms", "one realistic trial: random-number floor, the exact sampler on its draws alone (ms)",
               anatomy["floor_s"] * 1e3, "ms", peer="numpy Generator, the same draws",
               peer_value=anatomy["numpy_ns"] * anatomy["draws"] * 1e-6),
        figure("trials_total_s", f"{res.trials} trials, {args.workers} workers, truth included (s)",
               total, "s", target=120.0 if res.trials == 1000 else None,
               target_source="project target, 1000 trials" if res.trials == 1000 else None),
    ], quick=args.quick, trials=res.trials, workers=args.workers)


def trial_anatomy(scn, repeat: int) -> dict:
    """Where one realistic trial's time goes (one core): the kernels' CPU timed inside the
    trial, and the exact sampler alone (Poisson + read normal per window pixel and frame) on
    the trial's own mean charges, by path. The mean charges are captured from the trial's
    calls of :mod:`budget.starcam.kernels_trial` (the drifting conditions' means at their
    first frame: the drift moves them by hundredths of a pixel, not out of their path)."""
    import numpy as np
    from numba import njit

    import budget.starcam.kernels_trial as KT
    from simcam.rng import std_normal
    from simcam.rng_poisson import poisson

    means: list = []
    spent = [0.0]
    wrapped = {}
    for name in ("expose_centroid_chain", "expose_centroid_drift_chain"):
        orig = getattr(KT, name)

        def timed(chain, *a, _orig=orig, **kw):
            frames = a[-1].shape[0] if _orig is KT.expose_centroid_drift_chain else a[0].shape[0]
            means.append((np.ascontiguousarray(chain.mean_e, dtype=np.float64), frames))
            c0 = time.process_time()
            out = _orig(chain, *a, **kw)
            spent[0] += time.process_time() - c0
            return out

        wrapped[name] = orig
        setattr(KT, name, timed)
    try:
        best = None
        for k in range(max(repeat, 3)):
            means.clear()
            spent[0] = 0.0
            V.run_trial(scn, 0, 500 + k, setup=STUDY.prepared(scn))
            best = spent[0] if best is None else min(best, spent[0])
        kernel_s = best
    finally:
        for name, orig in wrapped.items():
            setattr(KT, name, orig)

    @njit(cache=False)
    def _sample(lam, frames, normal):
        s = 0.0
        for f in range(frames):
            key = np.uint64(0x9E3779B97F4A7C15) * np.uint64(f + 1)
            for i in range(lam.shape[0]):
                c = np.uint64(i) << np.uint64(16)
                s += poisson(lam[i], key, c)
                if normal:
                    s += std_normal(key, c + np.uint64(4096))
        return s

    def per_draw_ns(lam, frames, normal):
        _sample(lam, 1, normal)
        t = []
        for _ in range(5):
            c0 = time.perf_counter()
            _sample(lam, frames, normal)
            t.append(time.perf_counter() - c0)
        return min(t) / (lam.size * frames) * 1e9

    draws = sum(m.size * f for m, f in means)
    lam = np.concatenate([m.ravel() for m, _ in means])
    weights = np.concatenate([np.full(m.size, f, dtype=np.float64) for m, f in means])
    lo, hi = lam[lam < 10.0], lam[lam >= 10.0]
    ptrs_fraction = float(weights[lam >= 10.0].sum() / weights.sum())
    frames = 30
    table_ns = per_draw_ns(np.ascontiguousarray(lo), frames, False) if lo.size else 0.0
    ptrs_ns = per_draw_ns(np.ascontiguousarray(hi), frames, False) if hi.size else 0.0
    both_ns = per_draw_ns(np.ascontiguousarray(lo), frames, True) if lo.size else 0.0
    normal_ns = max(both_ns - table_ns, 0.0)
    floor_s = draws * ((1 - ptrs_fraction) * table_ns + ptrs_fraction * ptrs_ns + normal_ns) * 1e-9
    # the peer: numpy's Generator (PCG64) drawing the same variates, vectorised over the
    # trial's means (its Poisson: multiplication method below 10, PTRS at and above)
    gen = np.random.default_rng(0)
    tile = np.ascontiguousarray(np.tile(lam, 4))
    t = []
    for _ in range(5):
        c0 = time.perf_counter()
        gen.poisson(tile)
        gen.standard_normal(tile.size)
        t.append(time.perf_counter() - c0)
    numpy_ns = min(t) / tile.size * 1e9
    return {"numpy_ns": numpy_ns, "draws": int(draws), "ptrs_fraction": ptrs_fraction, "kernel_s": kernel_s,
            "kernel_ns": kernel_s / draws * 1e9, "table_ns": table_ns, "ptrs_ns": ptrs_ns,
            "normal_ns": normal_ns, "floor_s": floor_s}


if __name__ == "__main__":
    main()
