"""Cost of a robustness run (every world effect off, each alone, all together) against a plain validate.

Issue 22's target: robustness of a study with six effects and 200 trials costs at most 8
times its plain ``validate`` (common random numbers, all cases in one worker pool, truths
shared between cases where they do not depend on the effect).

It measures a real study (``--study``, default ``scanmirror``: seven effects, nine cases,
the cheapest trials of the studies with six or more; ``inductosyn`` also has seven) on its
embedded default scenario, in one run, with the same ``--trials`` (default 200), seed and
``--workers`` (default 2) for both:

* ``validate``: :func:`budget.runner.run.run_study`, the default scenario (every effect on);
* ``robustness``: :func:`budget.runner.robustness.run_robustness`, ideal + each effect
  alone + all, each with those trials.

Each is timed as the wall time a user waits (worker start-up and truths included) and the
CPU time of all its processes (this one and its joined workers, ``getrusage``); a small
untimed validate first loads the numba caches, so neither pays compilation. On a machine
shared with other jobs the CPU time is the primary figure (wall time depends on what else
runs); the 1-minute load average before and after is printed beside it. The ratio's floor
is what the cases cannot share: every case runs its own trials, so with ``c`` cases and
trials that dominate, the ratio tends to ``c`` less what the shared truths and the one pool
save.

``--study toy`` measures the toy world study of the tests instead (``tests/toys/toy_world_study.py``:
six effects, truths that depend on one of them, ``--trial-ms`` of busy work per trial, ten
times that for the truths), with the eight cases also run as eight separate validates for
reference.

The last line is ``RESULT {json}`` (read by ``run_all.py``).

Usage: ``python benchmarks/bench_robustness.py [--study scanmirror] [--trials 200] [--workers 2] [--quick]``
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

sys.path.insert(0, str(REPO_ROOT / "tests" / "toys"))  # the toy world study (workers inherit the path)

from budget.runner.robustness import build_cases, run_robustness  # noqa: E402
from budget.runner.run import run_study  # noqa: E402


def _calibrate(trial_ms: float) -> int:
    """Iterations of the toy's busy work that take ``trial_ms`` on this machine (best of 3)."""
    from toy_world_study import _busy

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


def _load1() -> float:
    try:
        return os.getloadavg()[0]
    except OSError:  # pragma: no cover
        return float("nan")


def _study_and_scenario(name: str, trial_ms: float):
    """The study, its scenario and a description of what the benchmark measured."""
    if name == "toy":
        from toy_world_study import ToyWorldStudy

        study = ToyWorldStudy()
        iters = _calibrate(trial_ms)
        data = study.load_scenario().model_dump(mode="json")
        data["busy_work"] = iters
        return study, study.from_dict(data, source="benchmark"), {"busy_iterations_per_trial": iters}
    from budget.runner.registry import get_study

    study = get_study(name)
    return study, study.load_scenario(), {}


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--study", default="scanmirror", help="a registered study with world effects, or 'toy'")
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--trial-ms", type=float, default=20.0, help="busy work per trial of --study toy (ms)")
    ap.add_argument("--separate", action="store_true",
                    help="also run the cases as separate validates (default for --study toy only)")
    args = ap.parse_args()
    if args.quick:
        args.trials, args.trial_ms = min(args.trials, 20), min(args.trial_ms, 2.0)
    study, scn, extra = _study_and_scenario(args.study, args.trial_ms)
    cases = build_cases(study, scn)
    n_effects = len(cases[-1].active)
    own = sum(not c.shares_truths for c in cases)
    # untimed warm-up: numba caches loaded (compiled if cold) in this process and the workers
    run_study(study, scn, trials=2, seed=args.seed, workers=args.workers)
    load0 = _load1()
    t_validate, c_validate = _timed_cpu(lambda: run_study(study, scn, trials=args.trials, seed=args.seed,
                                                          workers=args.workers))
    load1 = _load1()
    t_robust, c_robust = _timed_cpu(lambda: run_robustness(study, scn, trials=args.trials, seed=args.seed,
                                                           workers=args.workers))
    load2 = _load1()
    t_separate = c_separate = None
    if args.separate or args.study == "toy":
        t_separate, c_separate = _timed_cpu(lambda: [run_study(study, c.scenario, trials=args.trials, seed=args.seed,
                                                               workers=args.workers) for c in cases])
    ratio, cpu_ratio = t_robust / t_validate, c_robust / c_validate
    print_machine(workers=args.workers, **extra)
    print(f"load average (1 min) before validate {load0:.2f}, before robustness {load1:.2f}, after {load2:.2f} "
          f"(on {os.cpu_count()} cores: wall times are inflated by the other jobs, CPU times much less)")
    what = ("toy world study" if args.study == "toy" else f"study {study.name} ({study.title}), embedded default")
    print(f"{what}: {n_effects} effects, {len(cases)} cases ({', '.join(c.name for c in cases)}), "
          f"{args.trials} trials each, seed {args.seed}, {args.workers} workers; truths computed in {own} of "
          f"{len(cases)} cases (the others share the ideal case's)"
          + (f"; ~{args.trial_ms:g} ms of busy work per trial, 10x that for the truths" if args.study == "toy" else ""))
    rows = [(f"validate, {args.trials} trials", f"{t_validate:.2f} s", "1.00", f"{c_validate:.2f} s", "1.00"),
            (f"robustness, {len(cases)} cases x {args.trials} trials, one pool", f"{t_robust:.2f} s", f"{ratio:.2f}",
             f"{c_robust:.2f} s", f"{cpu_ratio:.2f}")]
    if t_separate is not None:
        rows.append((f"{len(cases)} separate validate runs (reference)", f"{t_separate:.2f} s",
                     f"{t_separate / t_validate:.2f}", f"{c_separate:.2f} s", f"{c_separate / c_validate:.2f}"))
    print(format_table(["what", "wall", "x validate", "cpu (all processes)", "x validate"], rows))
    print(f"per case: {cpu_ratio / len(cases):.2f} of a validate's CPU time (1.00 = no sharing at all)")
    label = "toy world" if args.study == "toy" else study.name
    emit_result("robustness", [
        figure("robustness_over_validate_cpu",
               f"robustness / validate CPU time of all processes, {label}, {n_effects} effects "
               f"({len(cases)} cases), {args.trials} trials, {args.workers} workers", cpu_ratio, "x",
               target=8.0, target_source="project target"),
        figure("robustness_over_validate", f"robustness / validate wall time, same runs (load {load1:.1f} "
               f"on {os.cpu_count()} cores)", ratio, "x", target=8.0, target_source="project target"),
        figure("robustness_s", f"robustness wall time, {len(cases)} cases x {args.trials} trials (s)", t_robust, "s",
               peer=f"{len(cases)} separate validate runs" if t_separate is not None else None,
               peer_value=t_separate),
        figure("validate_s", f"validate wall time, {args.trials} trials (s)", t_validate, "s"),
    ], quick=args.quick, study=label, effects=n_effects, trials=args.trials, workers=args.workers, cases=len(cases),
        cpu_validate_s=c_validate, cpu_robustness_s=c_robust, load_1min=[load0, load1, load2],
        **({"trial_ms": args.trial_ms} if args.study == "toy" else {}))


if __name__ == "__main__":
    main()
