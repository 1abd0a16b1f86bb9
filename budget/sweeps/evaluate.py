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
(:meth:`Study.truth_fields`) and on its *truth seed* (:func:`truth_seed_of`: the point
seed of its truth-relevant swept values only, so points that differ only in fields the
truths cannot see have one truth seed; the point seed itself when every swept field is
truth-relevant). The sweep engine (:mod:`budget.sweeps.run`) computes each distinct truth
once, in runs of pieces (:class:`TruthPartTask`, :func:`evaluate_truth_part`), and hands it to
every point that has it (``PointTask.truths``); a point given no truths computes its own
with its truth seed, the same numbers. A sweep's truths have the scenario's own sizes
(``truth_size = "fixed"``), or, when its points stop at a tolerance, sizes for a quarter of
it (:func:`budget.runner.run.truth_targets`).

The truth has a ``variant`` dimension when a class of the study carries per-trial truths
(each variant's compensation leaves its own error); otherwise it is per class and axis.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "STOPPED_BY",
    "PointResult",
    "PointTask",
    "TruthPartTask",
    "evaluate_point",
    "evaluate_truth_part",
    "truth_seed_of",
    "truths_scenario",
    "labels",
    "schema",
    "class_units",
    "study_for_kind",
]

#: codes of ``stopped_by`` (CF flag values)
STOPPED_BY = ("trials", "tolerance", "max_trials")


def study_for_kind(kind: str):
    """The registered study a sweep ``kind`` names."""
    from budget.runner.registry import get_study

    return get_study(kind)


def _layout(kind: str):
    study = study_for_kind(kind)
    classes = study.classes(study.load_scenario())
    axes: list[str] = []
    for c in classes:
        for a in c.axes:
            if a not in axes:
                axes.append(a)
    return study, classes, tuple(axes)


def labels(kind: str) -> dict[str, tuple[str, ...]]:
    """Coordinate labels of the class, axis and variant dimensions of ``kind``."""
    study, classes, axes = _layout(kind)
    return {"class": tuple(c.name for c in classes), "axis": axes, "variant": tuple(study.variants)}


def class_units(kind: str) -> dict[str, str]:
    """The unit of each class of ``kind`` (the store's ``class_units`` attribute)."""
    return {c.name: c.unit for c in _layout(kind)[1]}


def truth_has_variant(kind: str) -> bool:
    """Whether the truth of ``kind`` has a variant dimension (some class's truth is per trial)."""
    return any(c.per_trial_truth for c in _layout(kind)[1])


def schema(kind: str, evaluate: str) -> dict[str, tuple[tuple[str, ...], str, dict]]:
    """Variables of a point: name -> (dimensions besides the point's, dtype, attributes)."""
    ca, cav = ("class", "axis"), ("class", "axis", "variant")
    u = "the class's unit (class_units attribute)"
    tdims = cav if truth_has_variant(kind) else ca
    out: dict[str, tuple[tuple[str, ...], str, dict]] = {
        "truth": (tdims, "f8", {"units": u, "long_name": "truth of the error class (mean over trials where "
                                "it is drawn per trial)"}),
        "truth_se": (tdims, "f8", {"units": u, "long_name": "Monte Carlo standard error of the truth (0 = exact)"}),
    }
    if evaluate == "validate":
        out["mean"] = (cav, "f8", {"units": u, "long_name": "mean estimate over trials"})
        out["bias"] = (cav, "f8", {"units": u, "long_name": "mean estimate minus truth"})
        out["spread"] = (cav, "f8", {"units": u, "long_name": "sample sd of the estimate over trials "
                                     "(of estimate - truth where the truth is drawn per trial)"})
        out["se_bias"] = (cav, "f8", {"units": u, "long_name": "Monte Carlo standard error of the bias "
                                      "(with the truth's own)"})
        out["se_spread"] = (cav, "f8", {"units": u, "long_name": "Monte Carlo standard error of the spread"})
        out["ci95_low"] = (cav, "f8", {"units": u, "long_name": "2.5 % quantile of the estimates"})
        out["ci95_high"] = (cav, "f8", {"units": u, "long_name": "97.5 % quantile of the estimates"})
        out["trials"] = ((), "i4", {"long_name": "Monte Carlo trials run"})
        out["stopped_by"] = ((), "i1", {"long_name": "why the trials stopped",
                                       "flag_values": list(range(len(STOPPED_BY))),
                                       "flag_meanings": " ".join(STOPPED_BY)})
    out["seed"] = ((), "u8", {"long_name": "seed of the point (docs/sweeps.md)"})
    out["compute_s"] = ((), "f8", {"units": "s", "long_name": "wall time of the point in its worker "
                                   "(not a result: varies from run to run)"})
    return out


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
    """A run of consecutive pieces (:meth:`Study.truth_parts`) of a truth shared by sweep
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
    from budget.sweeps.values import point_seed as seed_of

    fields = study.truth_fields(scenario)
    rel = {k: v for k, v in values.items() if truth_relevant(fields, k)}
    return point_seed if len(rel) == len(values) else seed_of(sweep_seed, rel)


def _truth_size(task) -> str:
    return "adaptive" if task.evaluate == "validate" and task.tolerance is not None else "fixed"


def truths_scenario(study, task) -> tuple[Any, dict]:
    """The scenario a point's truths are computed on and their targets (module docstring)."""
    from budget.runner.run import sized_truths_scenario, truth_targets

    if _truth_size(task) == "fixed":
        return task.scenario, {}
    targets = truth_targets(study.classes(task.scenario), tolerance=task.tolerance)
    ts = task.seed if task.truth_seed is None else task.truth_seed
    return sized_truths_scenario(study, task.scenario, ts, targets), targets


def evaluate_truth_part(task: TruthPartTask) -> TruthPartTask:
    """A run of pieces of a shared truth: the task with ``parts`` replaced by their results
    (each piece a pure function of the scenario, the truth seed and the piece, so how the
    pieces are batched changes no number)."""
    from dataclasses import replace

    study = study_for_kind(task.kind)
    return replace(task, parts=tuple(study.truth_part(task.scenario, task.truth_seed, p) for p in task.parts))


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
    from budget.runner.run import run_study

    study, classes, axes = _layout(task.kind)
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
        from budget.runner.run import with_targets

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
    import platform
    import warnings

    import simcam

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
