"""A protocol as a scenario: the scenario with knob values set (dotted keys, :mod:`simcam.dotted`,
validated by the study's model), a knob's values and levels, a scenario's lab time, and which
knobs are cost-flat (their lab time does not change with them; docs/planning.md, "Cost-flat
knobs")."""

from __future__ import annotations

from typing import Any

import numpy as np

from budget.runner.study import Knob, Study
from simcam.dotted import get_dotted
from simcam.dotted import scenario_with as _scenario_with

__all__ = ["COST_FLAT_TOLERANCE", "cost_flat_knobs", "dotted_value", "knob_levels", "knob_value", "lab_time",
           "scenario_with"]

#: a knob is cost-flat when the summed lab time over its low, middle and high value changes by no more
#: than this relative amount (floating-point noise of the study's arithmetic, not a lab time)
COST_FLAT_TOLERANCE = 1e-9


def scenario_with(study: Study, scenario: Any, values: dict[str, Any], *, where: str) -> Any:
    """``scenario`` with dotted ``values`` set, validated by the study
    (:func:`simcam.dotted.scenario_with`: the fields the scenario derives are derived again)."""
    return _scenario_with(scenario, values, from_dict=study.from_dict, where=where)


def dotted_value(scenario: Any, key: str):
    """The value of dotted ``key`` in ``scenario`` (:func:`simcam.dotted.get_dotted`)."""
    return get_dotted(scenario, key, where=getattr(scenario, "source", "scenario"))


def knob_value(k: Knob, x: float):
    """``x`` as knob ``k`` takes it: a whole number for an ``int`` knob, else a float."""
    return int(round(x)) if k.kind == "int" else float(x)


def knob_levels(k: Knob, count: int) -> np.ndarray:
    """``count`` values over ``[low, high]``, log-spaced where ``low > 0`` (whole for int knobs)."""
    if k.low == k.high:
        return np.array([k.low])
    v = np.geomspace(k.low, k.high, count) if k.low > 0 else np.linspace(k.low, k.high, count)
    if k.kind == "int":
        v = np.unique(np.round(v))
    return v


def lab_time(study: Study, scenario: Any) -> float:
    """The lab time of ``scenario`` (s): :meth:`~budget.runner.capabilities.Plannable.lab_time_s` summed over its items."""
    return float(sum(study.lab_time_s(scenario).values()))


def cost_flat_knobs(study: Study, scenario: Any, knobs: tuple[Knob, ...]) -> tuple[Knob, ...]:
    """The knobs whose lab time does not change with them (a magnitude limit, a threshold): by
    :meth:`~budget.runner.capabilities.Plannable.lab_time_s` itself, at the knob's low, middle and high value, with the other
    knobs at the scenario's values, all low and all high; unchanged (:data:`COST_FLAT_TOLERANCE`)
    at every setting the scenario model accepts (at least one with two values) makes it cost-flat."""
    out = []
    for k in knobs:
        others = [o for o in knobs if o is not k]
        settings = [{}] + ([{o.field: knob_value(o, o.low) for o in others},
                            {o.field: knob_value(o, o.high) for o in others}] if others else [])
        vals = sorted({knob_value(k, v) for v in (k.low, 0.5 * (k.low + k.high), k.high)})
        flat, seen = True, 0
        for st in settings:
            costs = []
            for v in vals:
                try:
                    scn = scenario_with(study, scenario, {**st, k.field: v}, where="plan: cost-flat check")
                    costs.append(lab_time(study, scn))
                except (ValueError, ArithmeticError):
                    continue
            if len(costs) >= 2:
                seen += 1
                if max(costs) - min(costs) > COST_FLAT_TOLERANCE * max(1.0, abs(max(costs))):
                    flat = False
                    break
        if flat and seen and len(vals) > 1:
            out.append(k)
    return tuple(out)
