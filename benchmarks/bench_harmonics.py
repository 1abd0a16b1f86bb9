"""Benchmark: full seed-001 calibration trials per second (budget.inductosyn.validate).

One trial = draw the polygon face errors and four passes of noise (24-face raw and
verification, 23-face raw and verification: 94 points), simulate the lab tables, fit
eq 7, compensate, fit eq 8 (in sequence) and the joint fit, and verify both
compensations against the truth over 3600 points of the circle (every 0.1 deg):
3 sigma and max |residual|.

The last line is ``RESULT {json}`` (read by ``run_all.py``).

Run: ``python benchmarks/bench_harmonics.py [--trials 10000] [--repeats 5] [--quick]``.
"""

from __future__ import annotations

import os
import statistics
import sys
import time


if not __package__:  # run as a file (python benchmarks/bench_x.py): the repository root on the path
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks._common import bench_parser, emit_result, figure, print_machine  # noqa: E402


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--trials", type=int, default=10000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    if args.quick:
        args.repeats = min(args.repeats, 2)

    from budget.inductosyn.validate import prepare, run_trials
    from simcam.encoder.inductosyn import default

    sc = default()
    t0 = time.perf_counter()
    p = prepare(scenario=sc, dense_step_deg=0.1)
    t_prep = time.perf_counter() - t0
    run_trials(prepared=p, trials=100, seed=args.seed)  # warm-up (imports, BLAS threads)
    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        run_trials(prepared=p, trials=args.trials, seed=args.seed)
        times.append(time.perf_counter() - t0)
    print_machine()
    print(f"scenario preparation (truth on {p.truth.n} points, face expansions, "
          f"pseudo-inverses): {t_prep:.3f} s")
    print(f"{args.trials} full calibration trials (24+24+23+23 points, in-sequence and joint "
          f"fits, verification over {p.truth.n} points): best {min(times):.3f} s, "
          f"median {statistics.median(times):.3f} s over {args.repeats} runs")
    emit_result("harmonics", [
        figure("trials_s", f"{args.trials} full inductosyn calibration trials (s, best)", min(times), "s",
               target=2.0 * args.trials / 10000, target_source="project target"),
    ], quick=args.quick, trials=args.trials)


if __name__ == "__main__":
    main()
