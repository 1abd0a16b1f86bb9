"""Cost of a robustness run (every world effect off, each alone, all together) against a plain validate.

Issue 22's target: robustness of a study with six effects and 200 trials costs at most 8
times its plain ``validate`` (common random numbers, all cases in one worker pool, truths
shared between cases where they do not depend on the effect).

No registered study had six world effects when this was written, so it measures the toy
world study of the tests (``tests/toy_world_study.py``: six effects, truths that depend on
one of them) with a per-trial cost that mimics a real study: ``--trial-ms`` of busy work per
trial (a small matrix iteration, no sleep) and ten times that for the truths. It times, with
``--workers W`` processes (default all cores), each the wall time a user waits (worker
start-up and truths included) and the CPU time of all its processes (the steadier measure
on a shared machine):

* ``validate``: :func:`budget.runner.run.run_study`, 200 trials of the scenario;
* ``robustness``: :func:`budget.runner.robustness.run_robustness`, 8 cases x 200 trials;
* for reference, the same 8 cases as 8 separate validate runs (a pool and the truths each).

The last line is ``RESULT {json}`` (read by ``run_all.py``).

Usage: ``python benchmarks/bench_robustness.py [--trials 200] [--trial-ms 20] [--workers 2] [--quick]``
"""

from __future__ import annotations

import os
import sys
import time

if not __package__:  # run as a file (python benchmarks/bench_x.py): the repository root on the path
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks._common import (  # noqa: E402
    REPO_ROOT,
    bench_parser,
    emit_result,
    figure,
    format_table,
    print_machine,
)

sys.path.insert(0, str(REPO_ROOT / "tests"))  # the toy world study (workers inherit the path)

from budget.runner.executors import default_workers  # noqa: E402
from budget.runner.robustness import build_cases, run_robustness  # noqa: E402
from budget.runner.run import run_study  # noqa: E402
from toy_world_study import ToyWorldStudy, _busy  # noqa: E402


def _calibrate(trial_ms: float) -> int:
    """Iterations of the toy's busy work that take ``trial_ms`` on this machine (best of 3)."""
    n = 200
    best = min(_timed(lambda: _busy(n)) for _ in range(3))
    return max(1, round(n * trial_ms / 1e3 / best))


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def _cpu() -> float:
    """CPU seconds of this process and its ended children (the pool's workers, once joined)."""
    import resource

    me, ch = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + ch.ru_utime + ch.ru_stime


def _timed_cpu(fn) -> tuple[float, float]:
    """Wall and CPU seconds (all processes) of ``fn``: on a shared machine the CPU time is the
    steadier measure of the work, the wall time what a user waits."""
    c0, t0 = _cpu(), time.perf_counter()
    fn()
    return time.perf_counter() - t0, _cpu() - c0


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--trial-ms", type=float, default=20.0, help="busy work per trial (ms)")
    ap.add_argument("--workers", type=int, default=default_workers())
    ap.add_argument("--no-separate", action="store_true", help="skip the 8 separate validate runs")
    args = ap.parse_args()
    if args.quick:
        args.trials, args.trial_ms = min(args.trials, 20), min(args.trial_ms, 2.0)
    study = ToyWorldStudy()
    iters = _calibrate(args.trial_ms)
    data = study.load_scenario().model_dump(mode="json")
    data["busy_work"] = iters
    scn = study.from_dict(data, source="benchmark")
    cases = build_cases(study, scn)
    n_effects = len(scn.world.effects.active())
    t_validate, c_validate = _timed_cpu(lambda: run_study(study, scn, trials=args.trials, seed=1,
                                                          workers=args.workers))
    res = None

    def robust():
        nonlocal res
        res = run_robustness(study, scn, trials=args.trials, seed=1, workers=args.workers)

    t_robust, c_robust = _timed_cpu(robust)
    t_separate = c_separate = None
    if not args.no_separate:
        t_separate, c_separate = _timed_cpu(lambda: [run_study(study, c.scenario, trials=args.trials, seed=1,
                                                               workers=args.workers) for c in cases])
    ratio, cpu_ratio = t_robust / t_validate, c_robust / c_validate
    print_machine(workers=args.workers, busy_iterations_per_trial=iters)
    print(f"toy world study (no registered study had six effects yet): {n_effects} effects, {len(cases)} cases, "
          f"{args.trials} trials each, ~{args.trial_ms:g} ms of busy work per trial, 10x that for the truths "
          f"(own truths in {sum(not c.shares_truths for c in cases)} of {len(cases)} cases)")
    rows = [(f"validate, {args.trials} trials", f"{t_validate:.2f} s", "1.00", f"{c_validate:.2f} s", "1.00"),
            (f"robustness, {len(cases)} cases x {args.trials} trials, one pool", f"{t_robust:.2f} s", f"{ratio:.2f}",
             f"{c_robust:.2f} s", f"{cpu_ratio:.2f}")]
    if t_separate is not None:
        rows.append((f"{len(cases)} separate validate runs (reference)", f"{t_separate:.2f} s",
                     f"{t_separate / t_validate:.2f}", f"{c_separate:.2f} s", f"{c_separate / c_validate:.2f}"))
    print(format_table(["what", "wall", "x validate", "cpu (all processes)", "x validate"], rows))
    emit_result("robustness", [
        figure("robustness_over_validate", f"robustness ({len(cases)} cases) / validate wall time, toy world, "
               f"{n_effects} effects, {args.trials} trials, {args.trial_ms:g} ms/trial", ratio, "x",
               target=8.0, target_source="issue 22"),
        figure("robustness_over_validate_cpu", f"robustness / validate CPU time of all processes, same runs",
               cpu_ratio, "x", target=8.0, target_source="issue 22"),
        figure("robustness_s", f"robustness wall time, {len(cases)} cases x {args.trials} trials (s)", t_robust, "s",
               peer="8 separate validate runs" if t_separate is not None else None, peer_value=t_separate),
        figure("validate_s", f"validate wall time, {args.trials} trials (s)", t_validate, "s"),
    ], quick=args.quick, trials=args.trials, workers=args.workers, trial_ms=args.trial_ms, cases=len(cases))


if __name__ == "__main__":
    main()
