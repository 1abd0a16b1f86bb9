"""The verdict of one robustness cell: validate's per-class verdict, and the stated sigma's coverage.

A robustness cell is one ``(class, variant, axis)`` in one case of a robustness run
(:mod:`budget.runner.robustness`). Its decision is built from the one three-valued rule
(:func:`budget.runner.verdicts.judge`: holds / fails / undetermined, a 95 % interval against
a practical tolerance), in two parts:

* **the bias**: :func:`budget.runner.class_verdicts.class_verdict` on the case's own
  :class:`~budget.runner.run.StudyResult`, the verdict ``validate`` gives the same numbers.
  Its tolerance: where the study states a claimed accuracy ``A``
  (:meth:`~budget.runner.capabilities.WorldEffects.claim`) ``|bias| <= A``, with the reason
  and source of the study's ledger rule on the class where that rule is the same absolute
  ``A`` (so "paper" where the ledger says so), else source "default" (the hook gives a
  number, not where it comes from); without one, the ledger's claim on the class
  (:func:`~budget.runner.class_verdicts.method_rules`, exactly validate's); else the declared
  default, 10 % of the truth's size. Only where a study's hook and ledger disagree does a
  cell's tolerance differ from validate's, and its reason says which it is;
* **the coverage**, where the variant states a 1-sigma uncertainty: the fraction ``c`` of the
  ``m`` trials whose error is within it, judged against :data:`COVERAGE_TOLERANCE`
  (68.27 % +- 5 points: a stated sigma off by less than about 10 % moves the coverage by less
  than that, 2 Phi(1/1.1) - 1 = 63.7 %, 2 Phi(1/0.9) - 1 = 73.3 %, which is fine for a budget),
  its standard error the binomial ``sqrt(0.6827 * 0.3173 / m)`` (the coverage's spread when
  the sigma is right; never 0, also when every trial is within).

The cell **fails** when either part fails, **holds** when every part holds, and is otherwise
**undetermined**, with the trials that would settle it (the largest of its undetermined
parts'; none where a part's estimate sits on its tolerance's edge). No verdict (``None``, with
its reason) for a residual (what a compensation leaves: no claim to test), an input, a
reference variant (it estimates nothing), a gauge axis (not determined by the data).
"""

from __future__ import annotations

import math

from budget.runner.capabilities import WorldEffects, capability
from budget.runner.claims import ToleranceRule
from budget.runner.class_verdicts import ClassVerdict, class_verdict, method_rules
from budget.runner.findings import unit_prose
from budget.runner.numbers import fmt
from budget.runner.verdicts import Tolerance, Verdict, judge

__all__ = ["COVERAGE_TOLERANCE", "EXPECTED_1SIGMA", "VERDICT_TEXT", "cell_rules", "cell_verdict", "combine",
           "coverage_verdict", "excess", "summary_cell"]

#: probability of |N(0, 1)| <= 1
EXPECTED_1SIGMA = 0.6827
#: the practical tolerance on a stated sigma's 1-sigma coverage (module docstring)
COVERAGE_TOLERANCE = Tolerance.around(
    EXPECTED_1SIGMA, 0.05, source="default",
    reason="68.3 % +- 5 points: a stated sigma off by less than about 10 % is fine for a budget")
#: the cell's short word in a table
SHORT = {"holds": "holds", "fails": "FAILS", "undetermined": "undet."}


def coverage_verdict(coverage_1sigma: float, n: int) -> Verdict:
    """The verdict on a 1-sigma coverage ``coverage_1sigma`` over ``n`` trials against
    :data:`COVERAGE_TOLERANCE` (standard error the binomial one at 68.27 %)."""
    se = math.sqrt(EXPECTED_1SIGMA * (1.0 - EXPECTED_1SIGMA) / n)
    return judge(coverage_1sigma, se, int(n), COVERAGE_TOLERANCE, quantity="the 1-sigma coverage")


def cell_rules(result, class_name: str, variant: str, ledger: dict | None = None) -> dict:
    """The tolerance rules of one class and variant of ``result`` (a case's
    :class:`~budget.runner.run.StudyResult`): the claimed accuracy ``A`` of
    :meth:`~budget.runner.capabilities.WorldEffects.claim` where the study states one (with the
    ledger's reason and source where a ledger rule on the class is the same absolute ``A``,
    else source "default"), otherwise the study's ledger claims
    (:func:`~budget.runner.class_verdicts.method_rules`, validate's). ``ledger``:
    ``method_rules(result)`` computed once by the caller."""
    rules = method_rules(result) if ledger is None else ledger
    a = capability(result.study, WorldEffects).claim(result.scenario, class_name, variant)
    if a is None or not (math.isfinite(a) and a > 0):
        return rules
    same = [r for k, r in rules.items() if k[0] == class_name and r.relative == 0 and math.isclose(r.absolute, a)]
    rule = same[0] if same else ToleranceRule(reason=f"the method's claimed accuracy {fmt(a, 3)}",
                                              source="default", absolute=float(a))
    return {k: r for k, r in rules.items() if k[0] != class_name} | {(class_name, None): rule}


def combine(parts: list[Verdict]) -> tuple[str, int | None, bool]:
    """``(outcome, n_to_settle, on_edge)`` of a cell from its parts' verdicts (module docstring)."""
    outcomes = [v.outcome for v in parts]
    if "fails" in outcomes:
        return "fails", None, False
    if all(o == "holds" for o in outcomes):
        return "holds", None, False
    open_ = [v for v in parts if v.outcome == "undetermined"]
    if any(v.on_edge for v in open_):
        return "undetermined", None, True
    ns = [v.n_to_settle for v in open_]
    return "undetermined", (max(ns) if all(n is not None for n in ns) else None), False


def excess(v: Verdict | None) -> float:
    """How far a verdict's estimate lies from the value its tolerance states, as a fraction of
    the distance to the tolerance's edge on that side (> 1: outside; 0 without a verdict)."""
    if v is None:
        return 0.0
    t = v.tolerance
    target = t.target if t.target is not None else (t.low if math.isinf(t.high) else t.high)
    d = v.estimate - target
    edge = t.high if d > 0 else t.low
    span = abs(edge - target)
    if math.isinf(span):
        return 0.0
    return abs(d) / span if span > 0 else (math.inf if d else 0.0)


def cell_verdict(result, key, st: dict, ledger: dict | None = None) -> dict:
    """The verdict of one cell (module docstring) with the statistics ``st`` of ``key`` in
    ``result``: ``verdict`` (an outcome or None), ``no_verdict`` (why none), ``n_to_settle``,
    ``on_edge``, ``bias_verdict`` and ``coverage_verdict`` (:class:`Verdict` or None);
    ``ledger`` as for :func:`cell_rules`."""
    cls, var, _ax = key
    spec = result.class_spec(cls)
    none = {"verdict": None, "n_to_settle": None, "on_edge": False, "bias_verdict": None, "coverage_verdict": None}
    if spec.role == "residual":
        return none | {"no_verdict": "a residual: what a compensation leaves, no claim to test"}
    cv: ClassVerdict = class_verdict(result, key, st, cell_rules(result, cls, var, ledger), unit=unit_prose(spec.unit))
    if cv.verdict is None:
        return none | {"no_verdict": cv.no_verdict}
    parts = [cv.verdict]
    cov = st.get("coverage")
    cov_v = coverage_verdict(cov["within_1sigma"], cov["n"]) if cov and cov["n"] > 0 else None
    if cov_v is not None:
        parts.append(cov_v)
    outcome, n_settle, on_edge = combine(parts)
    return {"verdict": outcome, "no_verdict": "", "n_to_settle": n_settle, "on_edge": on_edge,
            "bias_verdict": cv.verdict, "coverage_verdict": cov_v}


def severity(cell: dict) -> float:
    """How far a cell is past its tolerances: the larger of its parts' :func:`excess`."""
    if not math.isfinite(cell["bias"]):
        return math.inf
    return max(excess(cell.get("bias_verdict")), excess(cell.get("coverage_verdict")))


def summary_cell(axes: list[tuple[str, dict]], *, markdown: bool = False) -> str:
    """One table cell for a class and variant over its axes ``[(axis, cell), ...]``: ``FAILS``
    when an axis fails (``FAILS k/n``: k of the n judged axes), else ``undet.`` when one is
    undetermined (``undet. k/n``), else ``holds``; ``--`` when no axis has a verdict. Then the
    bias of the axis farthest past its tolerances (:func:`severity`; the largest |bias|
    without a verdict), named when there are several."""
    judged = [(a, c) for a, c in axes if c["verdict"] is not None]
    if judged:
        failing = [ac for ac in judged if ac[1]["verdict"] == "fails"]
        open_ = [ac for ac in judged if ac[1]["verdict"] == "undetermined"]
        shown = failing or open_
        word = SHORT["fails" if failing else "undetermined" if open_ else "holds"]
        if shown and len(judged) > 1:
            word += f" {len(shown)}/{len(judged)}"
        if failing and markdown:
            word = f"**{word}**"
        a, c = max(shown or judged, key=lambda ac: severity(ac[1]))
        n = len(judged)
    else:
        a, c = max(axes, key=lambda ac: abs(ac[1]["bias"]) if math.isfinite(ac[1]["bias"]) else math.inf)
        word, n = "--", len(axes)
    return f"{word} {fmt(c['bias'], 3, sign=True)}" + (f" ({a})" if n > 1 else "")


#: the rule in words (the JSON and the report carry it)
VERDICT_TEXT = (
    "Each cell's verdict is validate's for the same numbers: the bias's 95 % interval against a practical "
    "tolerance (the method's claimed accuracy, else the study's ledger claim on the class, else 10 % of the "
    "truth's size; a one-sided claim only below the truth) and, where the variant states a 1-sigma "
    "uncertainty, the 1-sigma coverage's against 68.3 % +- 5 points (a stated sigma off by less than about "
    "10 %). A cell holds when every part's interval lies inside its tolerance, fails when one lies wholly "
    "outside, and is otherwise undetermined, with the trials that would settle it; more trials can only "
    "settle an undetermined cell (a decision flips only at the interval's error rate). Significance is "
    "never the verdict. No verdict for a residual, an input, a reference variant or a gauge axis.")
