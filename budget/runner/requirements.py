"""``--tolerance CLASS=VALUE``: a user's requirement on a class becomes its claims' tolerance.

A requirement ``CLASS=VALUE`` (``te=0.2``) says: on class ``CLASS`` an error up to ``VALUE``
(in the class's unit) is good enough. Every claim on that class then takes it as its
:class:`~budget.runner.claims.ToleranceRule` (source ``"user"``, absolute half-width
``VALUE``, the reason ``"your requirement: CLASS <= VALUE UNIT"``), replacing the declared
default: a method claim's bias within ``-+ VALUE``, a performance claim's truth within the
paper's figure ``-+ VALUE``, a bound's truth at most the figure plus ``VALUE``
(docs/claims.md, "Your requirement").

On ``validate`` the option keeps its older meaning for a bare number (``--tolerance 0.01``:
stop when every Monte Carlo standard error is below it); :func:`split_tolerance_options`
separates the two forms.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping

from budget.runner.claims import Claim, ToleranceRule
from budget.runner.findings import unit_prose
from budget.runner.numbers import fmt
from simcam.infra.errors import UserInputError

__all__ = ["parse_requirements", "split_tolerance_options", "user_rule", "with_requirements"]

#: the option's name in errors
OPTION = "--tolerance"


def _number(text: str) -> float | None:
    try:
        v = float(text)
    except ValueError:
        return None
    return v


def split_tolerance_options(texts: Iterable[str], known: Iterable[str], *,
                            option: str = OPTION) -> tuple[float | None, dict[str, float]]:
    """``validate``'s ``--tolerance`` values: at most one bare number (the adaptive stopping's
    standard-error target, > 0) and any ``CLASS=VALUE`` requirements (:func:`parse_requirements`)."""
    bare: list[float] = []
    pairs: list[str] = []
    for t in texts:
        if "=" in t:
            pairs.append(t)
            continue
        v = _number(t.strip())
        if v is None or not (math.isfinite(v) and v > 0):
            raise UserInputError(f"{option} {t}: a standard-error target (a number > 0) or CLASS=VALUE with "
                                 f"CLASS one of {', '.join(known)}")
        bare.append(v)
    if len(bare) > 1:
        raise UserInputError(f"{option}: one standard-error target at most, got {', '.join(fmt(b) for b in bare)}")
    return (bare[0] if bare else None), parse_requirements(pairs, known, option=option)


def parse_requirements(texts: Iterable[str], known: Iterable[str], *, option: str = OPTION) -> dict[str, float]:
    """``{class: value}`` from texts ``CLASS=VALUE``; a bad form, an unknown class, a value
    that is not a finite number > 0 or a class given twice is one line naming the option and
    the known classes."""
    known = tuple(known)
    names = ", ".join(known) or "none (no claims)"
    out: dict[str, float] = {}
    for t in texts:
        cls, sep, val = t.partition("=")
        cls, val = cls.strip(), val.strip()
        if not sep or not cls:
            raise UserInputError(f"{option} {t}: give CLASS=VALUE (a requirement in the class's unit), "
                                 f"CLASS one of {names}")
        if cls not in known:
            raise UserInputError(f"{option} {t}: unknown class {cls!r}; known: {names}")
        v = _number(val)
        if v is None or not (math.isfinite(v) and v > 0):
            raise UserInputError(f"{option} {t}: VALUE must be a number > 0 in {cls}'s unit, got {val!r}")
        if cls in out:
            raise UserInputError(f"{option} {t}: class {cls!r} given twice")
        out[cls] = v
    return out


def user_rule(class_name: str, value: float, unit: str) -> ToleranceRule:
    """The tolerance rule of a user's requirement ``class_name <= value unit``."""
    u = unit_prose(unit)
    return ToleranceRule(reason=f"your requirement: {class_name} <= {fmt(value)}{' ' + u if u else ''}",
                         source="user", absolute=float(value))


def with_requirements(claims: Iterable[Claim], requirements: Mapping[str, float]) -> tuple[Claim, ...]:
    """``claims`` with every testable claim on a required class taking the user's rule
    (:func:`user_rule`) in place of its declared one; the others as they are."""
    out = []
    for c in claims:
        if c.testable and c.class_name in requirements:
            c = dataclasses.replace(c, tolerance=user_rule(c.class_name, requirements[c.class_name], c.unit))
        out.append(c)
    return tuple(out)
