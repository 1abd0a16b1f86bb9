"""The layout of a sweep's points for any study: the coordinate labels of its class, axis and
variant dimensions, the unit of each class, and the variables each point yields
(:func:`schema`). The sweep file's check (:mod:`budget.sweeps.models`), the store
(:mod:`budget.sweeps.store`), the plots and the evaluation of a point
(:mod:`budget.sweeps.evaluate`) read them here; the sweep's ``kind`` names a registered study
(:mod:`budget.runner.registry`).
"""

from __future__ import annotations

from budget.runner.registry import get_study

__all__ = ["STOPPED_BY", "class_layout", "class_units", "fixed_truth_classes", "labels", "schema", "study_for_kind",
           "truth_has_variant"]

#: codes of ``stopped_by`` (CF flag values)
STOPPED_BY = ("trials", "tolerance", "max_trials")


def study_for_kind(kind: str):
    """The registered study a sweep ``kind`` names."""
    return get_study(kind)


def class_layout(kind: str):
    """The study ``kind`` names, its classes (on its default scenario) and every axis of them, in order."""
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
    study, classes, axes = class_layout(kind)
    return {"class": tuple(c.name for c in classes), "axis": axes, "variant": tuple(study.variants)}


def class_units(kind: str) -> dict[str, str]:
    """The unit of each class of ``kind`` (the store's ``class_units`` attribute)."""
    return {c.name: c.unit for c in class_layout(kind)[1]}


def truth_has_variant(kind: str) -> bool:
    """Whether the truth of ``kind`` has a variant dimension (some class's truth is per trial)."""
    return any(c.per_trial_truth for c in class_layout(kind)[1])


def fixed_truth_classes(kind: str) -> tuple[str, ...]:
    """The classes of ``kind`` whose truth is the run's, not drawn per trial: what a sweep in
    truth mode computes (a per-trial truth needs trials: NaN there)."""
    return tuple(c.name for c in class_layout(kind)[1] if not c.per_trial_truth)


def schema(kind: str, evaluate: str) -> dict[str, tuple[tuple[str, ...], str, dict]]:
    """Variables of a point: name -> (dimensions besides the point's, dtype, attributes)."""
    ca, cav = ("class", "axis"), ("class", "axis", "variant")
    u = "the class's unit (class_units attribute)"
    tdims = cav if truth_has_variant(kind) else ca
    out: dict[str, tuple[tuple[str, ...], str, dict]] = {
        "truth": (tdims, "f8", {"units": u, "long_name": "truth of the error class (mean over trials where "
                                "it is drawn per trial; NaN there in truth mode, which runs no trial)"}),
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
