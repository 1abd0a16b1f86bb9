"""What one sweep point computes, and the arrays it yields.

Every point runs in a worker (a local process, a Dask worker, or this process) through
:func:`evaluate_point`, a pure function of the point's scenario, seed and settings: the
same inputs give bit-identical outputs wherever it runs.

Modes (``evaluate`` in the sweep file):

* camera, ``validate``: :func:`budget.validate.validate` with ``workers=1`` (the
  parallelism is across points): for each class, axis and estimator variant the truth,
  the mean estimate, bias, spread (sample sd over trials), their Monte Carlo standard
  errors and the 95 % interval of the estimates, all in arcsec, 3 sigma;
* camera, ``truth`` (fast, budget only): the truth of every class as
  :func:`budget.validate.validate` computes it (:mod:`budget.truth`, same seed rule), no
  trials and no estimator: the error budget the camera really has, not what the lab
  would measure. Its only Monte Carlo element is the TE truth (``te_truth_frames``
  noise-only frames), whose standard error is reported (``truth_se``);
* inductosyn, ``validate``: :func:`budget.harmonics_validate.validate` (``trials``
  simulated calibrations). Classes: ``before`` (error over the whole circle before
  compensation; the lab's figure is the 3 sigma of the 23-face table once the
  long-period fit is removed, as seed 001 reports it), ``residual`` (3 sigma
  over the whole circle after compensation, mean over calibrations; the lab's figure is
  the 23-face verification after compensation) and ``residual_max`` (max |residual -
  mean| over the circle; no lab figure). Variants: ``published`` (the in-sequence
  procedure, eqs 7-9) and ``improved`` (the joint fit). One axis, ``angle``.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "INDUCTOSYN_CLASSES",
    "STOPPED_BY",
    "PointResult",
    "PointTask",
    "camera_truths",
    "evaluate_point",
    "labels",
    "schema",
]

INDUCTOSYN_CLASSES = ("before", "residual", "residual_max")
INDUCTOSYN_AXES = ("angle",)
#: codes of ``stopped_by`` (CF flag values)
STOPPED_BY = ("trials", "tolerance", "max_trials")
#: spawn key of the truth seed inside budget.validate.validate (kept equal, tested)


def labels(kind: str) -> dict[str, tuple[str, ...]]:
    """Coordinate labels of the class, axis and variant dimensions of ``kind``."""
    from budget.validate import AXES, CLASSES, VARIANTS

    if kind == "camera":
        return {"class": tuple(CLASSES), "axis": tuple(AXES), "variant": tuple(VARIANTS)}
    return {"class": INDUCTOSYN_CLASSES, "axis": INDUCTOSYN_AXES, "variant": tuple(VARIANTS)}


def schema(kind: str, evaluate: str) -> dict[str, tuple[tuple[str, ...], str, dict]]:
    """Variables of a point: name -> (dimensions besides the point's, dtype, attributes)."""
    ca, cav = ("class", "axis"), ("class", "axis", "variant")
    u = "arcsec, 3 sigma"
    out: dict[str, tuple[tuple[str, ...], str, dict]] = {}
    if kind == "camera":
        out["truth"] = (ca, "f8", {"units": u, "long_name": "truth of the error class (budget.truth)"})
        out["truth_se"] = (ca, "f8", {"units": u, "long_name": "Monte Carlo standard error of the truth "
                                      "(TE's sample of frames, propagated to LSFE and total; 0 = exact)"})
    else:
        out["truth"] = (cav, "f8", {"units": u, "long_name": "true error over the whole circle, "
                                    "mean over calibrations"})
        out["truth_spread"] = (cav, "f8", {"units": u, "long_name": "sd over calibrations of the true error"})
        out["truth_se"] = (cav, "f8", {"units": u, "long_name": "standard error of the truth's mean"})
    if evaluate == "validate":
        out["mean"] = (cav, "f8", {"units": u, "long_name": "mean estimate over trials"})
        out["bias"] = (cav, "f8", {"units": u, "long_name": "mean estimate minus truth"})
        out["spread"] = (cav, "f8", {"units": u, "long_name": "sample sd of the estimate over trials"})
        out["se_bias"] = (cav, "f8", {"units": u, "long_name": "Monte Carlo standard error of the bias"})
        out["se_spread"] = (cav, "f8", {"units": u, "long_name": "Monte Carlo standard error of the spread"})
        if kind == "camera":
            out["ci95_low"] = (cav, "f8", {"units": u, "long_name": "2.5 % quantile of the estimates"})
            out["ci95_high"] = (cav, "f8", {"units": u, "long_name": "97.5 % quantile of the estimates"})
        out["trials"] = ((), "i4", {"long_name": "Monte Carlo trials run"})
        if kind == "camera":
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
    tolerance_3sigma_arcsec: float | None = None
    dense_step_deg: float | None = None


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


def camera_truths(scenario, seed: int) -> dict:
    """Every class's truth (:class:`budget.truth.ClassTruth`) as ``validate(scenario, seed=seed)``
    has it: :func:`budget.validate.truths`."""
    from budget.validate import truths

    return truths(scenario, seed=seed)


def _truth_arrays(scenario, truths) -> tuple[np.ndarray, np.ndarray]:
    from budget.validate import AXES, CLASSES

    f = 3.0 * scenario.camera.scale_arcsec_per_px
    truth = np.array([[getattr(truths[c], f"{a}_px") * f for a in AXES] for c in CLASSES])
    # each truth carries its own Monte Carlo standard error (budget.truth.ClassTruth; the
    # combined classes propagate their parts')
    se = np.array([[getattr(truths[c], f"se_{a}_px") * f for a in AXES] for c in CLASSES])
    return truth, se


def _camera(task: PointTask) -> dict:
    from budget.validate import AXES, CLASSES, VARIANTS, validate

    scn = task.scenario
    if task.evaluate == "truth":
        truth, se = _truth_arrays(scn, camera_truths(scn, task.seed))
        return {"truth": truth, "truth_se": se}
    res = validate(scn, trials=task.trials, tolerance_3sigma_arcsec=task.tolerance_3sigma_arcsec,
                   seed=task.seed, workers=1, progress=False, keep_example=False)
    truth, se = _truth_arrays(scn, res.truths)
    s = res.summary()
    shape = (len(CLASSES), len(AXES), len(VARIANTS))
    out = {k: np.empty(shape) for k in ("mean", "bias", "spread", "se_bias", "se_spread", "ci95_low", "ci95_high")}
    for i, c in enumerate(CLASSES):
        for j, a in enumerate(AXES):
            for k, v in enumerate(VARIANTS):
                d = s[c][a][v]
                out["mean"][i, j, k] = d["mean"]
                out["bias"][i, j, k] = d["bias"]
                out["spread"][i, j, k] = d["std"]
                out["se_bias"][i, j, k] = d["se_bias"]
                out["se_spread"][i, j, k] = d["se_std"]
                out["ci95_low"][i, j, k], out["ci95_high"][i, j, k] = d["interval_95"]
    out.update(truth=truth, truth_se=se, trials=np.int32(res.trials),
               stopped_by=np.int8(STOPPED_BY.index(res.stopped_by)))
    return out


def _inductosyn(task: PointTask) -> dict:
    from budget.harmonics_validate import validate
    from budget.validate import VARIANTS

    trials = task.trials if task.trials is not None else task.scenario.validation.trials
    out = validate(scenario=task.scenario, trials=trials, seed=task.seed, dense_step_deg=task.dense_step_deg)
    s = out["summary"]
    shape = (len(INDUCTOSYN_CLASSES), 1, len(VARIANTS))
    r = {k: np.full(shape, np.nan) for k in ("truth", "truth_spread", "truth_se", "mean", "bias", "spread",
                                            "se_bias", "se_spread")}
    n = trials
    # (truth key, lab estimate key) per class and variant (published = in sequence, improved = joint)
    keys = {
        "before": {"published": (None, "short_sigma3_before_arcsec"),
                   "improved": (None, "short_sigma3_before_arcsec")},
        "residual": {"published": ("dense_sigma3_after_arcsec", "short_sigma3_after_arcsec"),
                     "improved": ("joint_dense_sigma3_after_arcsec", "joint_short_sigma3_after_arcsec")},
        "residual_max": {"published": ("dense_maxabs_after_arcsec", None),
                         "improved": ("joint_dense_maxabs_after_arcsec", None)},
    }
    for i, c in enumerate(INDUCTOSYN_CLASSES):
        for k, v in enumerate(VARIANTS):
            tk, ek = keys[c][v]
            if tk is None:  # deterministic: the dense truth before compensation
                t, ts = s["dense_sigma3_before_arcsec"], 0.0
            else:
                t, ts = s[tk]["mean"], s[tk]["std"]
            r["truth"][i, 0, k], r["truth_spread"][i, 0, k] = t, ts
            r["truth_se"][i, 0, k] = ts / math.sqrt(n)
            if ek is not None:
                m, sd = s[ek]["mean"], s[ek]["std"]
                r["mean"][i, 0, k], r["spread"][i, 0, k], r["bias"][i, 0, k] = m, sd, m - t
                # estimate and truth come from the same calibrations and are positively
                # correlated: treating them as independent bounds the error from above
                r["se_bias"][i, 0, k] = math.sqrt(sd**2 + ts**2) / math.sqrt(n)
                r["se_spread"][i, 0, k] = sd / math.sqrt(2 * (n - 1))
    r["trials"] = np.int32(n)
    return r


def evaluate_point(task: PointTask) -> PointResult:
    """Compute one point (see the module docstring); pure in the task."""
    import platform
    import warnings

    import simcam

    t0, c0 = time.perf_counter(), time.process_time()
    with warnings.catch_warnings():
        # clipped variances and flagged stars are expected at some points (as in validate)
        warnings.simplefilter("ignore", RuntimeWarning)
        values = _camera(task) if task.kind == "camera" else _inductosyn(task)
    values["seed"] = np.uint64(task.seed)
    values["compute_s"] = np.float64(time.perf_counter() - t0)
    sch = schema(task.kind, task.evaluate)
    missing = set(sch) - set(values)
    if missing:  # pragma: no cover - a programming error, not user input
        raise RuntimeError(f"point {task.index}: no value for {sorted(missing)}")
    return PointResult(task.group, task.index, {k: np.asarray(values[k], dtype=sch[k][1]) for k in sch},
                       simcam.__version__, os.getpid(), platform.node(), time.process_time() - c0)


def evaluate_in_worker(task: PointTask) -> PointResult:
    """:func:`evaluate_point` in a Dask worker: one numba thread per task, as the local pool."""
    from budget.validate import worker_init

    worker_init()
    return evaluate_point(task)
