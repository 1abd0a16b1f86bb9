"""Cost of Monte Carlo validation trials on the embedded seed-000 scenario.

* one full protocol trial (TE + HSFE + chromatic + distortion: 20,460 star-windows with
  the default plans, centroided and through the published and improved estimators), on
  one core (numba serial kernels), after warm-up, best and median of ``--repeat``; its CPU
  time (best), and that of the same trials in the ideal world and with the exact stamp
  route (``render.stamp_route = "exact"``);
  with the time split into rendering, centroiding and estimating;
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

    numba.set_num_threads(1)
    scn = default()
    warnings.simplefilter("ignore")
    V.run_trial(scn, 0, 0)
    times = []
    for k in range(1, args.repeat + 1):
        t0 = time.perf_counter()
        V.run_trial(scn, 0, k)
        times.append(time.perf_counter() - t0)
    # the same trial's CPU time (each trial new: its hexapod errors and drift render new
    # scenes), in the ideal world (no world effects) and with the exact stamp route
    # (render.stamp_route = "exact": the wavelengths summed for every scene)
    from budget.runner.cli import ideal_world_scenario
    from simcam.starcam.scenario import with_updates

    cpu = {}
    for name, s in (("realistic", scn), ("ideal", ideal_world_scenario(STUDY, scn, source="embedded default")),
                    ("exact", with_updates(scn, {"render.stamp_route": "exact"}))):
        V.run_trial(s, 0, 0)
        ts = []
        for k in range(1, args.repeat + 1):
            t0 = time.process_time()
            V.run_trial(s, 0, 100 + k)
            ts.append(time.process_time() - t0)
        cpu[name] = min(ts)
    from budget.starcam.protocols import make_plan
    from simcam.starcam.targets import calibration_grid

    w_star = scn.lab.target.rows * scn.lab.target.cols
    w_cal = calibration_grid(scn).n_stars
    n_windows = sum(c.frames * (w_cal if c.target == "calibration_grid" else w_star)
                    for p in ("te", "hsfe", "chromatic", "distortion") for c in make_plan(p, scn).conditions)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
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
            (f"{res.trials} trials, {args.workers} worker process(es), wall (truth included)", f"{total:.1f} s"),
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
        figure("trials_total_s", f"{res.trials} trials, {args.workers} workers, truth included (s)",
               total, "s", target=120.0 if res.trials == 1000 else None,
               target_source="project target, 1000 trials" if res.trials == 1000 else None),
    ], quick=args.quick, trials=res.trials, workers=args.workers)


if __name__ == "__main__":
    main()
