"""Cost of a protocol plan (``budget <study> plan``) against one validation, and its answer against the analytic optimum.

The planner's speed target: a plan over two knobs costs at most the trials of 20
validations (common random numbers across candidates, screening trials with adaptive
stopping, a fitted model proposing candidates, bisection along lab time), the
re-validation on fresh trials included.

Measured on the planner's toy study (``tests/toys/plan_toy.py``: an offset averaged over frames
and stage positions, lab time linear in both, so that the cheapest protocol meeting a
bound on the 95 % quantile of the error is known in closed form, by Lagrange) with two
knobs, for ``--seeds`` seeds (default 8), each plan requiring ``offset.x <= --bound``
(default 0.01 px) with ``--trials`` per validation (default the scenario's 200):

* the trials the plan ran (counted by the study: every trial of every candidate and of the
  re-validation) over one validation's trials: worst and median over the seeds;
* the plan's lab time above setup over the analytic optimum's at the ``--sure`` margin
  (default 0.9: the optimum for the bound divided by ``sure_margin``, 1.12 at 200 trials;
  ``--sure 0.5``: the boundary optimum; the sampling of the 95 % quantile on 200 trials moves
  the answer by about 13 % either way);
* the CPU time of a plan (this process; ``--workers 1``, the toy's trials are microseconds,
  so this is the planner's own work: fitting, the frontier, the runner's bookkeeping) over
  the CPU time of one ``run_study`` validation of the recommended protocol, best of the seeds.

The last line is ``RESULT {json}`` (read by ``run_all.py``).

``--separable`` measures instead a separable plan against the whole-test plan on the separable
toy (``SplitToyStudy`` of ``tests/toys/plan_toy.py``: protocols a, b, c, each its own frames; ``a.x <= 0.01``
and ``b.x <= 0.01``, so two groups, c's frames not searched), per seed: the trials each plan ran
and the protocols they computed (a restricted trial computes its group's protocol only, a whole
one all three), the answer's lab time above setup, whether the re-validation confirms, and the
CPU time of the plan (best of 3 repeats). Its ``RESULT`` is bench ``plan-separable`` (not run
by ``run_all.py``).

Usage: ``python benchmarks/bench_plan.py [--seeds 8] [--bound 0.01] [--trials 200] [--sure 0.9] [--quick]
[--separable]``
"""

from __future__ import annotations

import os
import statistics
import sys
import time

if not __package__:  # run as a file (python benchmarks/bench_x.py): the repository root on the path
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks._common import REPO_ROOT, bench_parser, emit_result, figure, format_table, print_machine  # noqa: E402

sys.path.insert(0, str(REPO_ROOT / "tests" / "toys"))  # the planner's toy (tests/toys/plan_toy.py)

from budget.runner.plan import BUDGET_VALIDATIONS, DEFAULT_SURE, plan_protocol, sure_margin  # noqa: E402
from budget.runner.run import run_study  # noqa: E402
from plan_toy import ToyStudy, analytic_optimum  # noqa: E402


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--bound", type=float, default=0.01, help="offset.x bound (px)")
    ap.add_argument("--trials", type=int, default=None, help="trials of one validation (default the scenario's)")
    ap.add_argument("--sure", type=float, default=DEFAULT_SURE, help="the plan's --sure")
    ap.add_argument("--separable", action="store_true", help="a separable plan against the joint (docstring)")
    args = ap.parse_args()
    if args.quick:
        args.seeds = min(args.seeds, 2)
    if args.separable:
        return separable(args)
    study = ToyStudy(record=True)
    scn = study.load_scenario()
    n = args.trials or scn.validation.trials
    opt = analytic_optimum(scn, args.bound / sure_margin(args.sure, n, 0.95))
    setup = scn.lab.setup_time_s
    rows, ratios, costs, cpu_plan, cpu_val = [], [], [], [], []
    plan_protocol(study, scn, [f"offset.x<={args.bound}"], seed=0, trials=n, sure=args.sure)  # untimed warm-up (imports)
    for seed in range(args.seeds):
        study.calls.clear()
        c0, t0 = time.process_time(), time.perf_counter()
        res = plan_protocol(study, scn, [f"offset.x<={args.bound}"], seed=seed, trials=n, sure=args.sure)
        c_plan, t_plan = time.process_time() - c0, time.perf_counter() - t0
        trials = len(study.calls)
        rec = res.recommended
        c1 = time.process_time()
        run_study(study, rec.scenario, trials=n, seed=seed, workers=1, prewarm=False)
        c_val = time.process_time() - c1
        ratio = trials / n
        cost = (rec.cost_s - setup) / (opt["cost_s"] - setup)
        ratios.append(ratio)
        costs.append(cost)
        cpu_plan.append(c_plan)
        cpu_val.append(c_val)
        rows.append((str(seed), f"{rec.knobs['protocol.frames']} x {rec.knobs['protocol.positions']}",
                     f"{rec.cost_s / 3600:.3f} h", f"{cost:.3f}", str(len(res.evaluations)), str(trials),
                     f"{ratio:.2f}", f"{res.sure:.2f}", f"{c_plan:.2f} s", f"{t_plan:.2f} s"))
    print_machine(workers=1)
    print(f"toy study, two knobs (frames, positions), offset.x <= {args.bound:g} px at 95 %, {n} trials per "
          f"validation, sure {args.sure:g}; analytic optimum at its margin {opt['frames']:.1f} frames x {opt['positions']:.2f} positions, "
          f"{opt['cost_s'] / 3600:.3f} h")
    print(format_table(["seed", "frames x positions", "lab time", "above setup / optimum", "protocols run",
                        "trials", "validations", "sure", "cpu", "wall"], rows))
    cpu_ratio = min(cp / cv for cp, cv in zip(cpu_plan, cpu_val)) if min(cpu_val) > 0 else float("nan")
    emit_result("plan", [
        figure("plan_trials_over_validation_max",
               f"trials of a two-knob plan / trials of one validation ({n}), worst of {args.seeds} seeds "
               "(re-validation included)", max(ratios), "x", target=float(BUDGET_VALIDATIONS),
               target_source="project target"),
        figure("plan_trials_over_validation_median", f"the same, median of {args.seeds} seeds",
               statistics.median(ratios), "x"),
        figure("plan_cost_over_optimum_median",
               f"plan's lab time above setup / the analytic optimum's (at the --sure margin), median of {args.seeds} seeds",
               statistics.median(costs), "x"),
        figure("plan_cpu_over_validate", "CPU time of a plan / of one validation of its answer, best of the seeds "
               "(toy: microsecond trials, so the planner's own work)", cpu_ratio, "x"),
    ], quick=args.quick, seeds=args.seeds, bound_px=args.bound, trials=n)


def separable(args) -> None:
    """The separable toy's two-group plan against its whole-test plan (module docstring)."""
    from plan_toy import SplitToyStudy

    reqs = [f"a.x<={args.bound}", f"b.x<={args.bound}"]
    plan_protocol(SplitToyStudy(), SplitToyStudy().load_scenario(), reqs, seed=0, sure=args.sure)  # warm-up
    rows, out = [], {True: [], False: []}
    for seed in range(args.seeds):
        for sep in (True, False):
            cpus = []
            for _ in range(3):
                study = SplitToyStudy(record=True, separable=sep)
                scn = study.load_scenario()
                c0 = time.process_time()
                res = plan_protocol(study, scn, reqs, seed=seed, trials=args.trials, sure=args.sure)
                cpus.append(time.process_time() - c0)
            work = sum(study.computed.values())
            out[sep].append((len(study.calls), work, res.recommended.cost_s, min(cpus)))
            k = res.recommended.knobs
            rows.append((str(seed), "separable" if sep else "joint", str(len(res.to_json()["groups"])),
                         f"{k['a.frames']} / {k['b.frames']} / {k['c.frames']}",
                         f"{res.recommended.cost_s - scn.lab.setup_time_s:.0f} s", str(len(study.calls)), str(work),
                         "yes" if res.confirmed else "no", f"{min(cpus):.2f} s"))
    print_machine(workers=1)
    print(f"separable toy, a.x <= {args.bound:g} px and b.x <= {args.bound:g} px at 95 %, sure {args.sure:g}; "
          "CPU best of 3 repeats")
    print(format_table(["seed", "plan", "groups", "frames a / b / c", "lab time above setup", "trials",
                        "protocols computed", "confirmed", "cpu"], rows))

    def med(sep, i):
        return statistics.median(r[i] for r in out[sep])

    emit_result("plan-separable", [
        figure("plan_separable_trials_over_joint", f"trials of a two-group plan / of the joint plan, median of "
               f"{args.seeds} seeds", med(True, 0) / med(False, 0), "x"),
        figure("plan_separable_work_over_joint", "protocols computed by a two-group plan / by the joint plan, "
               "median", med(True, 1) / med(False, 1), "x"),
        figure("plan_separable_cost_over_joint", "the answer's lab time, separable / joint, median",
               med(True, 2) / med(False, 2), "x"),
        figure("plan_separable_cpu_over_joint", "CPU time of a plan, separable / joint (best of 3 each), median",
               med(True, 3) / med(False, 3), "x"),
    ], quick=args.quick, seeds=args.seeds, bound_px=args.bound)


if __name__ == "__main__":
    main()
