"""The verdict of each ``(class, variant, axis)`` of a run, the one every headline and finding
is built from (:mod:`budget.runner.findings`).

The quantity judged is the bias (mean estimate less truth, its standard error and trials:
:func:`budget.runner.stats.key_statistics`), by :func:`budget.runner.verdicts.judge`, against

* the tolerance of a ``method`` claim the study declares on that class and axis (or on that
  class; :class:`budget.runner.claims.Claim`, a user's ``--tolerance CLASS=VALUE`` included,
  :mod:`budget.runner.requirements`), resolved on the run's truth; otherwise
* the declared default :data:`DEFAULT_RELATIVE` (10 %) of the truth's size: ``|truth|``, or for
  per-trial truths their root mean square ``sqrt(mean^2 + sd^2)`` (a truth that varies about
  zero is still a quantity of that size), at least the class's numerical floor.

A one-sided class (:attr:`~budget.runner.study.ClassSpec.at_most`: the estimate a stated
bound) holds when the bias is at least minus that half-width (the bound at or above the truth,
less the tolerance). Three outcomes, holds / fails / undetermined; significance is a number
(:attr:`~budget.runner.verdicts.Verdict.significance_se`), never the verdict. No verdict for
an input class, a reference variant (it estimates nothing), a gauge-free axis (not
determined by the data), or a zero-size truth without a declared tolerance; each says why.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from budget.runner.capabilities import Claims, capability
from budget.runner.verdicts import Tolerance, Verdict, judge

__all__ = ["DEFAULT_RELATIVE", "ClassVerdict", "class_verdict", "method_rules"]

#: the declared default tolerance: this fraction of the truth's size
DEFAULT_RELATIVE = 0.10


@dataclass(frozen=True)
class ClassVerdict:
    """The verdict of one key, or why there is none (``no_verdict``)."""

    verdict: Verdict | None
    no_verdict: str = ""

    @property
    def outcome(self) -> str | None:
        return self.verdict.outcome if self.verdict is not None else None


def method_rules(result, claims=None) -> dict:
    """``{(class, axis): rule}`` and ``{(class, None): rule}`` of the study's testable method
    claims (``claims``, or those it declares for the run's scenario); the first claim wins."""
    if claims is None:
        try:
            claims = capability(result.study, Claims).claims(result.scenario)
        except Exception:  # a study's hook must never break a report
            claims = ()
    out: dict = {}
    for c in claims:
        if getattr(c, "untestable", None) is None and c.kind == "method" and c.tolerance is not None:
            out.setdefault((c.class_name, c.axis), c.tolerance)
            out.setdefault((c.class_name, None), c.tolerance)
    return out


def _size(st: dict) -> tuple[float, str]:
    t = float(st["truth"])
    if st.get("per_trial_truth"):
        return math.hypot(t, float(st.get("truth_sd", 0.0))), "of the truths' rms"
    return abs(t), "of the truth"


def class_verdict(result, key, st: dict, rules: dict, *, unit: str = "") -> ClassVerdict:
    """The verdict of ``key`` with its statistics ``st`` (module docstring); ``rules`` from
    :func:`method_rules`."""
    cls, _var, ax = key
    spec = result.class_spec(cls) if cls in {c.name for c in result.classes} else None
    if st.get("role") == "input":
        return ClassVerdict(None, "an input of the method, taken as given")
    if st.get("reference"):
        return ClassVerdict(None, "a reference variant: it estimates nothing")
    if st.get("determined") is False:
        return ClassVerdict(None, "not determined by the data (a gauge freedom)")
    b, se, n = st["bias"], st["se_bias"], st["n"]
    if not (math.isfinite(b) and math.isfinite(se)):
        return ClassVerdict(None, "no finite bias")
    floor = float(getattr(spec, "numerical_floor", 0.0) or 0.0)
    rule = rules.get((cls, ax)) or rules.get((cls, None))
    if rule is not None:
        w = rule.half_width(st["truth"])
        reason, source = rule.reason, rule.source
    else:
        size, of = _size(st)
        w = max(DEFAULT_RELATIVE * size, floor)
        reason, source = f"{100 * DEFAULT_RELATIVE:g} % {of}", "default"
        if floor > DEFAULT_RELATIVE * size:
            reason += ", at least the numerical floor"
    if not (math.isfinite(w) and w > 0):
        return ClassVerdict(None, "a zero truth and no declared tolerance (give --tolerance CLASS=VALUE)")
    if getattr(spec, "at_most", False):
        tol = Tolerance(-w, math.inf, reason, source, 0.0)
    else:
        tol = Tolerance.around(0.0, w, reason=reason, source=source)
    quantity = "the difference" if st.get("role") in ("residual", "stated") else "the bias"
    return ClassVerdict(judge(b, se, int(n) if n else None, tol, unit=unit, quantity=quantity))
