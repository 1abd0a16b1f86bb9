"""Throughput of design-trade sweeps, and the cost of a point as its trial count grows.

What it measures is the sweep machinery (processes, Dask, the store), on points that do
every class's work at a light HSFE truth. Since the HSFE truth became the expected centroid's static error, the HSFE truth of the default
scenario exposes ``validation.hsfe_truth_frames`` noisy frames at each of 64 sub-pixel phases
(2000 before the control variate made 400 enough: 15-18 s of a point's work on one core), so 24 points on 1 and 2 processes,
twice, took far longer than a benchmark should (the run was killed). The points here set
``validation.hsfe_truth_frames`` to ``--hsfe-truth-frames`` (default 100: the same route,
its standard error sqrt(20) = 4.5x larger, about 2.1-2.3 s a point), so the figures are those of
the machinery on points of a few seconds; one point with the scenario's own 2000 frames is
timed once and printed, so the cost of a full-truth point is in the same run. Every point
keeps one camera's pixel maps for every trial (``validation.new_maps_per_trial = false``):
with the maps drawn per trial (the default) TE's and HSFE's truths are each trial's own, so a
truth-mode point would compute neither and the figures would not be those of the points
described here.

* points per second of a truth-mode sweep of the embedded seed-000 scenario (PSF width x
  PRNU, ``--points`` points, each a new camera: scenes, stamps and every class's truth)
  on 1 and 2 local worker processes (``budget sweep --workers W``), and optionally on a
  Dask LocalCluster (``--dask``). Two rates per run: end to end (wall time of
  ``run_sweep``: reading and checking the sweep, starting the processes, importing,
  warming the JIT, writing the store) and steady state: every task of the run counted,
  the pieces of the points' truths (which the runner computes first, spread over the
  workers) as well as the points' own tasks, the pipeline full once as many tasks have
  finished as there are workers (about one each: start-up, imports and JIT warm-up
  behind), and the rate the points finished after that (a point when its last task is)
  over the time from then to the last point. So the steady ratio of 2 processes to 1 is
  the throughput of all of a point's work, not of its own task alone (which in truth
  mode is little more than writing the truths its pieces gave). Each configuration runs
  ``--repeat`` times into a fresh store; best and range are printed;
* one validation point (``evaluate = "validate"``) of the default scenario (with the same
  light HSFE truth) with K trials, in this process on one numba thread (as in a worker), K
  in ``--trials-list``, best of ``--repeat``; a least-squares line gives the fixed cost
  (truths) and the cost per trial; then one point with the scenario's own HSFE truth.

About 3 minutes on 2 cores (3.5 with ``--dask``; measured at load 1.2-1.3). The last line is ``RESULT {json}``
(read by ``run_all.py``).

Usage: ``python benchmarks/bench_sweep.py [--points 16] [--repeat 2] [--dask]
[--trials-list 2,4,8,16] [--hsfe-truth-frames 100] [--quick]``
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
import time
from contextlib import contextmanager

if not __package__:  # run as a file (python benchmarks/bench_x.py): the repository root on the path
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks._common import (  # noqa: E402
    bench_parser,
    emit_result,
    figure,
    format_table,
    print_machine,
)


def _grid_file(d: str, points: int, hsfe_truth_frames: int) -> str:
    n_psf = max(1, points // 2)
    path = os.path.join(d, "bench.toml")
    with open(path, "w") as fh:
        fh.write(f"""name = "bench: HSFE vs PSF width and PRNU"
kind = "starcam"
seed = 1
evaluate = "truth"
[fixed]
"validation.hsfe_truth_frames" = {hsfe_truth_frames}
"validation.new_maps_per_trial" = false
[parameters]
"optics.psf.sigma0_px" = {{start = 0.6, stop = 1.4, num = {n_psf}}}
"detector.prnu_rms" = [0.0, 0.01]
""")
    return path


@contextmanager
def _task_log():
    """Record every finished task of a sweep (truth pieces and points alike) as
    ``(time, is_point, workers)``: :meth:`budget.sweeps.execute.SweepRunner.run` wrapped
    for the ``with`` body (the runner yields each task's result as it finishes)."""
    from budget.sweeps.execute import SweepRunner
    from budget.sweeps.evaluate import TruthPartTask

    log: list = []
    orig = SweepRunner.run

    def run(self, tasks):
        for res in orig(self, tasks):
            log.append((time.perf_counter(), not isinstance(res, TruthPartTask), self.workers))
            yield res

    SweepRunner.run = run
    try:
        yield log
    finally:
        SweepRunner.run = orig


def _rates(rep, log) -> tuple[float, float]:
    """(end-to-end points/s, steady-state points/s) of a run.

    Steady state counts all of a point's work, its truth's pieces included (the runner
    computes every truth, split into pieces, before the points that use it): the pipeline
    is full once ``W`` tasks of any kind have finished (``W`` workers: about one each, so
    process start-up, imports and JIT warm-up are behind), and the rate is the points
    finished after that over the time from then to the last point (a point is finished
    when its last task is; every truth piece comes before its point's own task).
    """
    n = len(rep.completed)
    e2e = n / rep.wall_s
    workers = log[0][2] if log else 1
    if len(log) <= workers:
        return e2e, float("nan")
    t_ready = log[workers - 1][0]
    after = [t for t, is_point, _ in log if is_point and t > t_ready]
    steady = len(after) / (max(after) - t_ready) if after else float("nan")
    return e2e, steady


def _throughput(path: str, d: str, repeat: int, configs) -> list:
    from budget.sweeps.run import run_sweep

    rows = []
    for label, kw in configs:
        e2e, steady, cost, cpu = [], [], [], []
        for r in range(repeat):
            out = os.path.join(d, f"store-{label.replace(' ', '_')}-{r}")
            with _task_log() as log:
                rep = run_sweep(path, out, **kw)
            a, b = _rates(rep, log)
            e2e.append(a)
            steady.append(b)
            cost.extend(rep.compute_s)
            cpu.extend(rep.cpu_s)
            shutil.rmtree(out)
        cost.sort()
        cpu.sort()
        rows.append((label, e2e, steady, cost[len(cost) // 2], cpu[len(cpu) // 2]))
        print(f"  {label}: end-to-end {max(e2e):.3f} points/s, steady {max(steady):.3f} points/s", flush=True)
    return rows


def _trial_cost(trials_list, repeat, hsfe_truth_frames, *, full_point: bool = True):
    import numpy as np

    from budget.sweeps.evaluate import PointTask, evaluate_point
    from budget.runner.executors import worker_setup
    from budget.starcam.study import STUDY
    from simcam.starcam.scenario import default, with_updates

    worker_setup(STUDY.worker_init)  # one numba thread, as in a worker process
    full = with_updates(default(), {"validation.new_maps_per_trial": False})  # the run's TE and HSFE truths
    base = with_updates(full, {"validation.hsfe_truth_frames": hsfe_truth_frames})
    evaluate_point(PointTask("grid", 0, "starcam", "validate", base, 1, trials=2))  # warm-up (JIT)
    rows = []
    n = 0
    for k in trials_list:
        ts = []
        for r in range(repeat):
            # a new scenario (detector seed) each time, as every point of a sweep is: no cached
            # camera, scenes or stamps
            n += 1
            scn = with_updates(base, {"seed": base.seed + n})
            t0 = time.perf_counter()
            evaluate_point(PointTask("grid", 0, "starcam", "validate", scn, 100 + n, trials=k))
            ts.append(time.perf_counter() - t0)
        rows.append((k, min(ts), max(ts)))
        print(f"  {k} trials: best {min(ts):.2f} s", flush=True)
    k = np.array([r[0] for r in rows], float)
    t = np.array([r[1] for r in rows])
    b, a = np.polyfit(k, t, 1)
    if not full_point:
        return rows, a, b, None
    # one point with the scenario's own HSFE truth, for scale (timed once)
    k_full = trials_list[0]
    scn = with_updates(full, {"seed": full.seed + n + 1})
    t0 = time.perf_counter()
    evaluate_point(PointTask("grid", 0, "starcam", "validate", scn, 100 + n + 1, trials=k_full))
    t_full = time.perf_counter() - t0
    print(f"  {k_full} trials, HSFE truth of {full.validation.hsfe_truth_frames} frames per phase "
          f"(the scenario's own), once: {t_full:.2f} s", flush=True)
    return rows, a, b, (k_full, full.validation.hsfe_truth_frames, t_full)


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--points", type=int, default=16)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--dask", action="store_true", help="also a Dask LocalCluster of 2 workers")
    ap.add_argument("--trials-list", default="2,4,8,16")
    ap.add_argument("--hsfe-truth-frames", type=int, default=100,
                    help="validation.hsfe_truth_frames of the timed points (even, >= 4; the scenario's: 400)")
    ap.add_argument("--skip-throughput", action="store_true")
    ap.add_argument("--skip-trials", action="store_true")
    args = ap.parse_args()
    if args.quick:
        args.points, args.repeat, args.trials_list = min(args.points, 4), 1, "2,4"
    figs = []
    print_machine()
    d = tempfile.mkdtemp(prefix="bench_sweep_")
    try:
        if not args.skip_throughput:
            path = _grid_file(d, args.points, args.hsfe_truth_frames)
            configs = [("1 process", {"workers": 1}), ("2 processes", {"workers": 2})]
            if args.dask:
                configs.append(("Dask LocalCluster 2", {"dask_local": 2}))
            print(f"throughput, {args.points} truth-mode points of the default scenario with a light HSFE "
                  f"truth ({args.hsfe_truth_frames} frames per phase; the scenario's 400 make a point "
                  f"far dearer: timed below), {args.repeat} run(s) each:", flush=True)
            rows = _throughput(path, d, args.repeat, configs)
            base_e2e, base_st = max(rows[0][1]), max(rows[0][2])
            print(format_table(
                ["workers", "end-to-end pt/s best [range]", "steady pt/s best [range]", "speed-up (steady)",
                 "median point task wall s", "median point task CPU s"],
                [(lab, f"{max(e):.3f} [{min(e):.3f}-{max(e):.3f}]", f"{max(s):.3f} [{min(s):.3f}-{max(s):.3f}]",
                  f"{max(s) / base_st:.2f}x (e2e {max(e) / base_e2e:.2f}x)", f"{c:.2f}", f"{u:.2f}")
                 for lab, e, s, c, u in rows]))
            print("(a point's CPU time is the work; its wall time above its CPU time is waiting for a core: "
                  "other jobs on the machine)")
            by = {lab: (max(e), max(s_)) for lab, e, s_, _, _ in rows}
            light = f" (HSFE truth {args.hsfe_truth_frames} frames/phase)"
            two_e, two_s = by["2 processes"]
            figs += [
                figure("sweep_speedup_steady", f"sweep, {args.points} truth-mode points{light}: steady points/s "
                       "(truth pieces included), 2 processes / 1", two_s / base_st, "x", better="higher", target=1.7,
                       target_source="project target"),
                figure("sweep_speedup_e2e", f"sweep, {args.points} truth-mode points{light}: end-to-end points/s, "
                       "2 processes / 1", two_e / base_e2e, "x", better="higher"),
                figure("sweep_points_per_s", f"sweep, 2 processes{light}, end-to-end points/s", two_e,
                       "points/s", better="higher"),
            ]
            if "Dask LocalCluster 2" in by:
                figs.append(figure("sweep_speedup_dask", "sweep: steady points/s (truth pieces included), "
                                   "Dask LocalCluster 2 / 1 process", by["Dask LocalCluster 2"][1] / base_st, "x",
                                   better="higher", target=1.7, target_source="project target"))
        if not args.skip_trials:
            print(f"cost of one validation point (default scenario, HSFE truth of {args.hsfe_truth_frames} "
                  "frames per phase, one numba thread):", flush=True)
            tl = [int(x) for x in args.trials_list.split(",")]
            rows, a, b, full = _trial_cost(tl, args.repeat, args.hsfe_truth_frames, full_point=not args.quick)
            print(format_table(["trials", "best s", "worst s"], [(k, f"{lo:.2f}", f"{hi:.2f}") for k, lo, hi in rows]))
            print(f"fit: {a:.2f} s + {b:.3f} s per trial")
            if full is not None:
                k_full, n_full, t_full = full
                print(f"one point of {k_full} trials with the scenario's own HSFE truth ({n_full} frames per "
                      f"phase): {t_full:.2f} s, {t_full - (a + b * k_full):.2f} s more than the line")
            figs += [figure("point_fixed_s", f"validation point: fixed cost (truths; HSFE truth of "
                            f"{args.hsfe_truth_frames} frames per phase), s", a, "s"),
                     figure("point_per_trial_s", "validation point: cost per trial, s", b, "s")]
            if full is not None:  # what a point costs at the scenario's own settings (docs/sweeps.md)
                figs.append(figure("point_full_truth_s", f"validation point of {k_full} trials, the scenario's "
                                   f"own HSFE truth ({n_full} frames per phase), s", t_full, "s"))
        print("load after:", " ".join(f"{x:.2f}" for x in os.getloadavg()))
        emit_result("sweep", figs, quick=args.quick, points=args.points,
                    hsfe_truth_frames=args.hsfe_truth_frames)
    finally:
        shutil.rmtree(d, ignore_errors=True)


if __name__ == "__main__":
    main()
