"""What one sweep point computes, and the arrays it yields, for any study.

Every point runs in a worker (a local process, a Dask worker, or this process) through
:func:`evaluate_point`, a pure function of the point's scenario, seed and settings: the
same inputs give bit-identical outputs wherever it runs. The sweep's ``kind`` names a
registered study (:mod:`budget.runner.registry`), and nothing here knows one study from
another:

* ``validate``: :func:`budget.runner.run.run_study` with one worker (the parallelism is
  across points): for each class, axis and estimator variant the truth (and its standard
  error), the mean estimate, bias, spread (sample sd over trials; of the errors where the
  truth is drawn per trial), their Monte Carlo standard errors and the 95 % interval of
  the estimates, in the class's unit;
* ``truth`` (fast, budget only): the study's truths (:meth:`Study.truths`) with their
  standard errors, no trials and no estimator: the error budget the instrument really
  has, not what the lab would measure. Only for studies whose truths are all properties
  of the scenario (not drawn per trial).

Truths shared among points: a point's truths depend on the fields its study names
(:meth:`~budget.runner.capabilities.SharedTruths.truth_fields`) and on its *truth seed* (:func:`truth_seed_of`: the point
seed of its truth-relevant swept values only, so points that differ only in fields the
truths cannot see have one truth seed; the point seed itself when every swept field is
truth-relevant). The sweep engine (:mod:`budget.sweeps.run`) computes each distinct truth
once, in runs of pieces (:class:`TruthPartTask`, :func:`evaluate_truth_part`), and hands it to
every point that has it (``PointTask.truths``); a point given no truths computes its own
with its truth seed, the same numbers. A sweep's truths have the scenario's own sizes
(``truth_size = "fixed"``), or, when its points stop at a tolerance, sizes for a quarter of
it (:func:`budget.runner.scheduler.truth_targets`).

The truth has a ``variant`` dimension when a class of the study carries per-trial truths
(each variant's compensation leaves its own error); otherwise it is per class and axis.
"""

from __future__ import annotations

import math
import os
import platform
import time
import warnings
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

import simcam
from budget.runner.capabilities import SharedTruths, SplitTruths, capability
from budget.runner.run import run_study
from budget.runner.scheduler import sized_truths_scenario, truth_targets, with_targets
from budget.sweeps.layout import STOPPED_BY, class_layout, labels, schema, study_for_kind, truth_has_variant
from budget.sweeps.values import point_seed as seed_of  # truth_seed_of has a parameter point_seed

__all__ = [
    "PointResult",
    "PointTask",
    "TruthPartTask",
    "evaluate_point",
    "evaluate_truth_part",
    "truth_seed_of",
    "truths_scenario",
]

@dataclass(frozen=True)
class PointTask:
    """Everything a worker needs for one point (picklable, small)."""

    group: str  # "grid" or "sensitivity"
    index: int
    kind: str
    evaluate: str
    scenario: Any
    seed: int
    trials: int | None = None
    tolerance: float | None = None  # in the unit of the study's classes
    #: seed of the point's truths (None: the point's seed; :func:`truth_seed_of`)
    truth_seed: int | None = None
    #: the point's truths, computed before (shared with other points); None: computed here
    truths: dict | None = None


@dataclass(frozen=True)
class TruthPartTask:
    """A run of consecutive pieces (:meth:`~budget.runner.capabilities.SplitTruths.truth_parts`) of a truth shared by sweep
    points: pieces ``index .. index + len(parts) - 1`` of truth ``group``."""

    group: int
    index: int
    kind: str
    scenario: Any  # the truths' scenario (sized: :func:`truths_scenario`)
    truth_seed: int
    parts: tuple


def truth_relevant(fields: tuple[str, ...] | None, key: str) -> bool:
    """Whether the dotted ``key`` can change truths that depend on ``fields`` (None: all)."""
    if fields is None:
        return True
    return any(key == f or key.startswith(f + ".") or f.startswith(key + ".") for f in fields)


def truth_seed_of(study, scenario, sweep_seed: int, values: dict, point_seed: int, *, common: bool) -> int:
    """The truth seed of a point with swept ``values``: the common seed of the Sobol samples
    (``common``), else :func:`budget.sweeps.values.point_seed` of its truth-relevant values
    (``point_seed`` itself when they are all of them)."""
    if common:
        return point_seed
    fields = capability(study, SharedTruths).truth_fields(scenario)
    rel = {k: v for k, v in values.items() if truth_relevant(fields, k)}
    return point_seed if len(rel) == len(values) else seed_of(sweep_seed, rel)


def _truth_size(task) -> str:
    return "adaptive" if task.evaluate == "validate" and task.tolerance is not None else "fixed"


def truths_scenario(study, task) -> tuple[Any, dict]:
    """The scenario a point's truths are computed on and their targets (module docstring)."""
    if _truth_size(task) == "fixed":
        return task.scenario, {}
    targets = truth_targets(study.classes(task.scenario), tolerance=task.tolerance)
    ts = task.seed if task.truth_seed is None else task.truth_seed
    return sized_truths_scenario(study, task.scenario, ts, targets), targets


def evaluate_truth_part(task: TruthPartTask) -> TruthPartTask:
    """A run of pieces of a shared truth: the task with ``parts`` replaced by their results
    (each piece a pure function of the scenario, the truth seed and the piece, so how the
    pieces are batched changes no number)."""
    study = study_for_kind(task.kind)
    return replace(task, parts=tuple(capability(study, SplitTruths).truth_part(task.scenario, task.truth_seed, p) for p in task.parts))


@dataclass
class PointResult:
    """A point's arrays (see :func:`schema`) and where it ran."""

    group: str
    index: int
    values: dict
    version: str
    pid: int
    host: str
    cpu_s: float = float("nan")  # CPU time of the worker process on this point (not stored)


def _evaluate(task: PointTask) -> dict:
    study, classes, axes = class_layout(task.kind)
    lab = labels(task.kind)
    cls_i = {c: i for i, c in enumerate(lab["class"])}
    ax_i = {a: j for j, a in enumerate(axes)}
    var_i = {v: k for k, v in enumerate(lab["variant"])}
    shape = (len(cls_i), len(ax_i), len(var_i))
    tv = truth_has_variant(task.kind)
    tshape = shape if tv else shape[:2]
    truth = np.full(tshape, np.nan)
    truth_se = np.full(tshape, np.nan)

    def put_truth(c, a, v, value, se):
        idx = (cls_i[c], ax_i[a], var_i[v]) if tv else (cls_i[c], ax_i[a])
        truth[idx], truth_se[idx] = value, se

    given = task.truths
    if given is None and task.truth_seed not in (None, task.seed):
        tscn, targets = truths_scenario(study, task)
        given = with_targets(study.truths(tscn, task.truth_seed), targets)
    if task.evaluate == "truth":
        for (c, a), t in (given if given is not None else study.truths(task.scenario, task.seed)).items():
            for v in lab["variant"]:
                put_truth(c, a, v, t.value, t.se)
        return {"truth": truth, "truth_se": truth_se}
    res = run_study(study, task.scenario, trials=task.trials, tolerance=task.tolerance,
                    seed=task.seed, workers=1, progress=False, prewarm=False, truth_size=_truth_size(task),
                    truths=given)
    out = {k: np.full(shape, np.nan) for k in ("mean", "bias", "spread", "se_bias", "se_spread",
                                              "ci95_low", "ci95_high")}
    for (c, a), t in res.truths.items():
        for v in lab["variant"]:
            put_truth(c, a, v, t.value, t.se)
    for key in res.keys():
        c, v, a = key
        st = res.statistics(key)
        i = (cls_i[c], ax_i[a], var_i[v])
        out["mean"][i], out["bias"][i], out["spread"][i] = st["mean"], st["bias"], st["std"]
        out["se_bias"][i], out["se_spread"][i] = st["se_bias"], st["se_std"]
        out["ci95_low"][i], out["ci95_high"][i] = st["interval_95"]
        if st["per_trial_truth"]:
            # the mean over trials of each trial's truth, and its standard error
            tt = res.trial_truths[key]
            put_truth(c, a, v, float(tt.mean()), float(tt.std(ddof=1) / math.sqrt(tt.size)) if tt.size > 1 else 0.0)
    out.update(truth=truth, truth_se=truth_se, trials=np.int32(res.trials),
               stopped_by=np.int8(STOPPED_BY.index(res.stopped_by)))
    return out


def evaluate_point(task: PointTask) -> PointResult:
    """Compute one point (see the module docstring); pure in the task."""
    t0, c0 = time.perf_counter(), time.process_time()
    with warnings.catch_warnings():
        # clipped variances and flagged stars are expected at some points (as in validate)
        warnings.simplefilter("ignore", RuntimeWarning)
        values = _evaluate(task)
    values["seed"] = np.uint64(task.seed)
    values["compute_s"] = np.float64(time.perf_counter() - t0)
    sch = schema(task.kind, task.evaluate)
    missing = set(sch) - set(values)
    if missing:  # pragma: no cover - a programming error, not user input
        raise RuntimeError(f"point {task.index}: no value for {sorted(missing)}")
    return PointResult(task.group, task.index, {k: np.asarray(values[k], dtype=sch[k][1]) for k in sch},
                       simcam.__version__, os.getpid(), platform.node(), time.process_time() - c0)
