"""The planner's entry, :func:`plan_protocol`: the settings checked, one pool of workers for
every candidate, then the whole-test plan (:func:`plan_joint`) or, where the study declares
field classes, the separable one (:func:`budget.runner.plan.separable.plan_separable`)."""

from __future__ import annotations

import math
import time
from typing import Any

from budget.arguments import check_seed, check_trials
from budget.runner.capabilities import Plannable, ProtocolShapes, SeparablePlans, Warmup, capability, has_capability
from budget.runner.executors import make_executor
from budget.runner.plan.quantiles import DEFAULT_SURE
from budget.runner.plan.requirements import (DEFAULT_CONFIDENCE, Requirement, default_variant, parse_fixes,
                                             parse_requirements)
from budget.runner.plan.result import PlanResult
from budget.runner.plan.search import PlanRun
from budget.runner.plan.separable import plan_separable
from budget.runner.plan.trials import MIN_TRIALS, validation_seed
from budget.runner.scheduler import init_worker
from budget.runner.study import Study
from simcam.allocation import check_allocations
from simcam.infra.errors import UserInputError
from simcam.units import SECONDS_PER_HOUR

__all__ = ["check_estimated", "plan_joint", "plan_protocol"]


def plan_protocol(study: Study, scenario: Any, requirements, *, variant: str | None = None,
                  confidence: float = DEFAULT_CONFIDENCE, budget_hours: float | None = None, seed: int = 0,
                  trials: int | None = None, workers: int | None = 1, progress: bool = False,
                  sure: float = DEFAULT_SURE, fix=None) -> PlanResult:
    """Plan ``study``'s protocol on ``scenario`` (docs/planning.md). ``requirements``: texts
    ``CLASS.AXIS<=VALUE`` or :class:`Requirement`; ``trials``: a validation's trials (default
    the scenario's ``validation.trials``); ``sure``: a candidate meets when the verdict on its
    quantile holds at this one-sided level, trials added near the bound until it is decided
    (:func:`budget.runner.plan.quantiles.requirement_verdict`; 0.5: the measured quantile itself,
    the boundary protocol); ``fix``: knobs pinned, ``{field: value}`` or texts ``FIELD=VALUE``
    (:func:`parse_fixes`)."""
    t0, c0 = time.perf_counter(), time.process_time()
    check_seed(seed)  # the API's checks, here too: a bad seed or trial count before any truth
    check_trials(trials)
    check_allocations(scenario, source=getattr(scenario, "source", "scenario"))  # before any truth (simcam.allocation)
    if not has_capability(study, Plannable):
        raise UserInputError(f"plan: the {study.name} study has no plannable protocol")
    knobs = tuple(study.protocol_knobs(scenario))
    if not knobs:
        raise UserInputError(f"plan: the {study.name} study declares no protocol knobs on this scenario")
    if not study.lab_time_s(scenario):
        raise TypeError(f"{type(study).__name__} declares protocol knobs but no lab time (Plannable.lab_time_s): "
                        "a plan has no cost to minimise")
    fixed = parse_fixes(knobs, fix)
    if not (0.5 <= confidence < 1.0):
        raise UserInputError(f"--confidence {confidence}: must be in [0.5, 1)")
    if not (0.5 <= sure < 1.0):
        raise UserInputError(f"--sure {sure}: must be in [0.5, 1)")
    if budget_hours is not None and not (math.isfinite(budget_hours) and budget_hours > 0):
        raise UserInputError(f"--budget-hours {budget_hours}: must be a positive number")
    if requirements and all(isinstance(r, Requirement) for r in requirements):
        reqs, variant = list(requirements), variant or default_variant(study)
    else:
        reqs, variant = parse_requirements(study, scenario, requirements, variant)
    n = int(trials) if trials is not None else int(scenario.validation.trials)
    if n < MIN_TRIALS:
        raise UserInputError(f"--trials {n}: a plan needs at least {MIN_TRIALS} trials per validation")
    budget_s = None if budget_hours is None else SECONDS_PER_HOUR * budget_hours
    # one pool for every candidate (the study's kernels compiled first, so its workers load them
    # from the cache): starting workers per candidate would cost more than the toy's trials
    capability(study, Warmup).prewarm(scenario)
    check_estimated(study, scenario, reqs, variant, seed)  # before any truth or search
    with make_executor(workers=workers, initializer=init_worker, initargs=(study,)) as pool:
        run = PlanRun(study, scenario, reqs, variant, confidence, budget_hours, budget_s, seed, n, workers, progress,
                      pool, knobs, sure, fixed, t0, c0)
        # the whole-test search where the study declares no field classes (every field may change
        # every class), else the separable plan
        return plan_separable(run) if capability(study, SeparablePlans).field_classes(scenario) else plan_joint(run)


def check_estimated(study: Study, scenario: Any, reqs: list[Requirement], variant: str, seed: int) -> None:
    """Refuse, as one :class:`UserInputError` naming the requirement, a required class the
    judged variant does not estimate (the line camera's ``lookangle`` has no camera parameters:
    ``focal.df``), before any truth is computed or any protocol run. The study declares no such
    map, so one trial (trial 0 of the plan's seed, on the scenario restricted to the required
    classes where the study can) says which ``(class, variant, axis)`` it estimates. A trial the
    study refuses (a ``ValueError`` or an arithmetic error) checks nothing here: the search
    skips and lists such protocols."""
    scn = capability(study, SeparablePlans).restrict_classes(scenario, tuple(dict.fromkeys(r.cls for r in reqs)))
    try:
        keys = set(study.trial(scenario if scn is None else scn, seed, 0).estimates)
    except (ValueError, ArithmeticError):
        return
    for r in reqs:
        if (r.cls, variant, r.axis) not in keys:
            others = sorted({v for c, v, a in keys if c == r.cls and a == r.axis} - set(study.reference_variants))
            alt = f" (--variant {' or '.join(others)} does)" if others else ""
            raise UserInputError(f"--require {r.text!r}: the {variant} variant does not estimate {r.name}{alt}")


def plan_joint(run: PlanRun) -> PlanResult:
    """The whole-test plan: every shape searched over every free knob with every requirement;
    the cheapest shape's answer re-validated on fresh seeds, else the most accurate protocol."""
    oracle = run.oracle()
    shapes = capability(run.study, ProtocolShapes).protocol_shapes(run.scenario) or {"scenario": {}}
    free = tuple(k for k in run.knobs if k.field not in run.fixed)
    results = run.search_shapes(oracle, shapes, free, run.budget_s)
    bests = [s.best for s in results.values() if s.best is not None]
    rec = min(bests, key=lambda e: e.cost_s) if bests else None
    search_trials = oracle.trials_run
    validation = best_ach = None
    if rec is not None:
        vseed = validation_seed(run.seed)
        validation = oracle.evaluate(rec.shape, rec.knobs, rec.scenario, stage="validation", seed=vseed, full=True)
        oracle.evaluations.remove(validation)
    else:
        cands = [s.best_achievable for s in results.values() if s.best_achievable is not None]
        best_ach = min(cands, key=lambda e: e.ratio) if cands else None
    return run.result(shapes=results, recommended=rec, validation=validation, best_achievable=best_ach,
                      evaluations=list(oracle.evaluations), search_trials=search_trials, truth_runs=oracle.truth_runs)
