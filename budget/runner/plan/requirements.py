"""What a plan is asked: the requirements ``CLASS.AXIS<=VALUE`` on the judged variant and the
knobs pinned by ``--fix FIELD=VALUE``, parsed and checked; a bad one is one
:class:`UserInputError` naming it (docs/planning.md, "What a requirement means")."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

from budget.runner.capabilities import SeparablePlans, capability
from budget.runner.study import Knob, Study
from simcam.infra.errors import UserInputError

__all__ = ["DEFAULT_CONFIDENCE", "Requirement", "default_variant", "parse_fixes", "parse_requirements"]

#: the share of tests that must land within a requirement's bound: the default ``--confidence``
DEFAULT_CONFIDENCE = 0.95
_REQ = re.compile(r"^\s*([A-Za-z_][\w-]*)\.([A-Za-z_][\w-]*)\s*<=\s*(\S+)\s*$")
#: why a class of each role that cannot be required is not
_NOT_REQUIRABLE = {"input": "an input the method takes as given, not a figure it measures",
                   "stated": "an uncertainty the method states, not an error it makes"}


@dataclass(frozen=True)
class Requirement:
    """``CLASS.AXIS<=VALUE``: the C-quantile of ``|estimate - truth|`` at most ``value`` (``unit``)."""

    cls: str
    axis: str
    value: float
    unit: str = ""
    label: str = ""

    @property
    def name(self) -> str:
        return f"{self.cls}.{self.axis}"

    @property
    def text(self) -> str:
        return f"{self.name}<={self.value:g}"


def default_variant(study: Study) -> str:
    """The variant a plan judges by default: the study's last variant that estimates (the
    variants are in report order, the improved method last)."""
    own = [v for v in study.variants if v not in study.reference_variants]
    return own[-1] if own else study.variants[-1]


def parse_requirements(study: Study, scenario: Any, texts, variant: str | None = None
                       ) -> tuple[list[Requirement], str]:
    """The requirements and the variant, checked: a known variant that estimates; per text a
    ``result`` or ``residual`` class the scenario computes, an axis the data determine, a
    positive bound, no class and axis twice. A bad one is a :class:`UserInputError` naming it."""
    if variant is None:
        variant = default_variant(study)
    if variant not in study.variants:
        raise UserInputError(f"--variant {variant}: unknown; the {study.name} variants are "
                             f"{', '.join(study.variants)}")
    if variant in study.reference_variants:
        raise UserInputError(f"--variant {variant}: a reference (it estimates nothing); choose one of "
                             f"{', '.join(v for v in study.variants if v not in study.reference_variants)}")
    texts = list(texts or [])
    if not texts:
        raise UserInputError("--require: give at least one requirement CLASS.AXIS<=VALUE (e.g. "
                             f"{_example(study, scenario)})")
    specs = {c.name: c for c in study.classes(scenario)}
    out: list[Requirement] = []
    for t in texts:
        out.append(_requirement(study, scenario, specs, t, out))
    return out, variant


def _requirement(study: Study, scenario: Any, specs: dict, t, earlier: list[Requirement]) -> Requirement:
    """One requirement text, checked against the classes ``specs`` and the ``earlier`` ones."""
    m = _REQ.match(str(t))
    if not m:
        raise UserInputError(f"--require {t!r}: expected CLASS.AXIS<=VALUE (e.g. {_example(study, scenario)})")
    cls, ax, raw = m.groups()
    spec = specs.get(cls)
    if spec is None:
        why = capability(study, SeparablePlans).uncomputed_class(scenario, cls)
        if why:
            raise UserInputError(f"--require {t!r}: {why}")
        raise UserInputError(f"--require {t!r}: unknown class {cls!r}; the {study.name} classes are "
                             f"{', '.join(specs)}")
    if ax not in spec.axes:
        raise UserInputError(f"--require {t!r}: class {cls} has no axis {ax!r} (axes: {', '.join(spec.axes)})")
    if spec.role not in ("result", "residual"):
        why = _NOT_REQUIRABLE.get(spec.role, spec.role)
        raise UserInputError(f"--require {t!r}: class {cls} is {why}; require a result or a residual")
    if ax in spec.undetermined:
        raise UserInputError(f"--require {t!r}: the data do not determine {cls}.{ax} (a convention, no error)")
    try:
        value = float(raw)
    except ValueError:
        raise UserInputError(f"--require {t!r}: {raw!r} is not a number") from None
    if not (math.isfinite(value) and value > 0):
        raise UserInputError(f"--require {t!r}: the bound must be a positive number in {spec.unit}")
    if any(r.cls == cls and r.axis == ax for r in earlier):
        raise UserInputError(f"--require {t!r}: {cls}.{ax} is required twice; give one bound")
    return Requirement(cls, ax, value, spec.unit, spec.label)


def _example(study: Study, scenario: Any) -> str:
    for c in study.classes(scenario):
        if c.role in ("result", "residual"):
            ax = next((a for a in c.axes if a not in c.undetermined), c.axes[0])
            return f"{c.name}.{ax}<=VALUE"
    return "CLASS.AXIS<=VALUE"


def parse_fixes(knobs: tuple[Knob, ...], fix) -> dict[str, Any]:
    """The knobs pinned by ``--fix FIELD=VALUE`` (texts) or ``{field: value}``, checked: the
    field one of the study's knobs, given once, the value of the knob's kind (a whole number for
    an ``int`` knob) within its bounds; a bad one is a :class:`UserInputError` naming it."""
    if not fix:
        return {}
    by_field = {k.field: k for k in knobs}
    items = []
    if isinstance(fix, dict):
        items = [(str(f), v, f"{f}={v}") for f, v in fix.items()]
    else:
        for t in ([fix] if isinstance(fix, str) else list(fix)):
            f, eq, v = str(t).partition("=")
            if not eq or not f.strip() or not v.strip():
                raise UserInputError(f"--fix {t!r}: expected FIELD=VALUE (e.g. {knobs[0].field}={knobs[0].low:g})")
            items.append((f.strip(), v.strip(), str(t)))
    out: dict[str, Any] = {}
    for f, v, t in items:
        k = by_field.get(f)
        if k is None:
            raise UserInputError(f"--fix {t!r}: {f!r} is not a protocol knob; the knobs are {', '.join(by_field)}")
        if f in out:
            raise UserInputError(f"--fix {t!r}: {f} is fixed twice; give one value")
        out[f] = _fixed_value(k, v, t)
    return out


def _fixed_value(k: Knob, v, t: str):
    """The value ``v`` of a ``--fix`` (text ``t``) for knob ``k``, checked."""
    f = k.field
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise UserInputError(f"--fix {t!r}: {v!r} is not a number") from None
    if isinstance(v, bool) or not math.isfinite(x):
        raise UserInputError(f"--fix {t!r}: {v!r} is not a number")
    if k.kind == "int":
        if x != round(x) or (isinstance(v, str) and not re.fullmatch(r"[+-]?\d+", v)):
            raise UserInputError(f"--fix {t!r}: {f} takes a whole number ({k.unit})")
        x = int(round(x))
    if not (k.low <= x <= k.high):
        raise UserInputError(f"--fix {t!r}: {f} must be within [{k.low:g}, {k.high:g}] {k.unit}")
    return x
