"""Findings in words, built from one verdict per class, variant and axis.

A report (Markdown, HTML, the terminal and the JSON's ``findings``) opens with what the run
found, per variant: for which classes its estimate holds, fails or is undetermined, the most
likely cause where the study knows it (:meth:`~budget.runner.capabilities.Presented.likely_cause`),
and which variant to use. Every sentence and every headline is built from the same
three-valued verdict per ``(class, variant, axis)`` (:func:`budget.runner.class_verdicts.class_verdict`:
the bias against a practical tolerance, the claim's where the study declares one, else 10 %
of the truth), so a headline cannot contradict its lines and more trials can only settle an
undetermined verdict. Significance is reported as a number (standard errors from 0), never
as the verdict.

Each finding names its ``rule``:

``input``
    the class is an input of the method (:attr:`ClassSpec.role` ``"input"``): no verdict.
``reference``
    the variant does not estimate (:attr:`Study.reference_variants`, e.g. the scan mirror's
    ``without_estimate``, which returns 0 by design): a reference, no verdict.
``gauge``
    the axis is a gauge freedom (:attr:`ClassSpec.undetermined`): "not determined", no sigma,
    no verdict.
``holds``, ``fails``, ``undetermined``
    the verdict (:mod:`budget.runner.verdicts`). Its sentence says what was judged: an
    estimate's bias, a residual's difference from what the compensation actually leaves
    (role ``"residual"``), or a stated figure's difference from the actual one (role
    ``"stated"``; for a one-sided claim, :attr:`ClassSpec.at_most`, the stated bound holds
    at or above the actual), and, where the estimator states a 1-sigma, how often it holds
    the truth (a number, not the verdict).
``none``
    no verdict for another reason (a zero truth without a declared tolerance), said in the
    sentence.
"""

from __future__ import annotations

import math

from budget.runner.capabilities import Presented, capability
from budget.runner.class_verdicts import class_verdict, method_rules
from budget.runner.numbers import fmt

__all__ = ["NO_VERDICT", "RULES", "annotate", "finding_sentence", "findings", "findings_json", "findings_lines",
           "findings_markdown", "headline", "unit_prose", "with_unit"]

RULES = ("input", "reference", "gauge", "holds", "fails", "undetermined", "none")
#: the rules without a verdict
NO_VERDICT = ("input", "reference", "gauge", "none")


def with_unit(value: float, unit: str) -> str:
    """``value`` with its unit spelled for a reader: no unit for a dimensionless ``"1"``,
    ``x 1e-4`` for a scale unit, ``"`` never invented."""
    u = (unit or "").strip()
    if u in ("", "1", "-", "dimensionless"):
        return fmt(value)
    if u.replace("e", "", 1).replace("-", "", 1).replace(".", "", 1).isdigit():  # "1e-4"
        return f"{fmt(value)} x {u}"
    return f"{fmt(value)} {unit_prose(u)}"


def unit_prose(unit: str) -> str:
    """A unit for prose: ``"arcsec, 3 sigma"`` reads ``arcsec (3 sigma)``."""
    u = (unit or "").strip()
    if ", " in u:
        head, tail = u.split(", ", 1)
        return f"{head} ({tail})"
    return u


def with_pm(value: float, se: float, unit: str) -> str:
    """``value +- se unit`` (the unit once, after both numbers; none for a dimensionless class)."""
    return f"{fmt(value)} +- {with_unit(se, unit)}"


def _spec(result, cls):
    try:
        return result.class_spec(cls)
    except KeyError:
        return None


def annotate(result, key, st: dict) -> dict:
    """Apply the class's and study's declarations to the statistics of ``key`` (called by
    :meth:`StudyResult.statistics`): the numerical floor in the significance test, a
    reference variant, an undetermined axis (no sigma, no coverage, no percentage)."""
    cls, var, ax = key
    spec = _spec(result, cls)
    floor = float(getattr(spec, "numerical_floor", 0.0) or 0.0)
    if floor > 0 and math.isfinite(st["bias"]) and abs(st["bias"]) <= floor:
        st["bias_significant"] = False
        if 3.0 * st["se_bias"] <= floor:
            st["exact_to_numerical_precision"] = True
            st["bias_percent"] = float("nan")
    if floor > 0:
        st["numerical_floor"] = floor
    if var in getattr(result.study, "reference_variants", ()):
        st["reference"] = True
    if spec is not None and ax in getattr(spec, "undetermined", ()):
        st["determined"] = False
        st["bias_significant"] = False
        st["bias_percent"] = float("nan")
        st.pop("coverage", None)
    return st


def _at_most(result, cls) -> bool:
    """Whether the class's claim is one-sided (:attr:`ClassSpec.at_most`)."""
    return bool(getattr(_spec(result, cls), "at_most", False))


def _rule(st: dict, cv) -> str:
    if st.get("role") == "input":
        return "input"
    if st.get("reference"):
        return "reference"
    if st.get("determined") is False:
        return "gauge"
    return cv.outcome or "none"


def _truth_words(st: dict, unit: str) -> str:
    if st["per_trial_truth"]:
        return f"the trials' truths (mean {with_unit(st['truth'], unit)})"
    if st["truth_se"] > 0:
        return f"the truth {with_pm(st['truth'], st['truth_se'], unit)}"
    return f"the truth {with_unit(st['truth'], unit)}"


def _coverage_words(st: dict) -> str:
    cov = st.get("coverage")
    if not cov:
        return ""
    s = f"; its stated 1-sigma holds the truth in {100 * cov['within_1sigma']:.1f} % of trials (68.3 % expected)"
    r = cov.get("sd_normalised_error", float("nan"))
    if math.isfinite(r) and r > 0 and abs(cov["within_1sigma"] - cov["expected_1sigma"]) > 3.0 * cov["se_1sigma"]:
        s += (f", the actual scatter {fmt(r)} times the stated sigma" if r >= 1
              else f", the stated sigma {fmt(1 / r)} times the actual scatter")
    return s


def _what(result, key, st: dict, unit: str) -> str:
    """What was judged, with its numbers (no verdict in it)."""
    b, se = st["bias"], st["se_bias"]
    pct = st.get("bias_percent", float("nan"))
    pct_s = f" ({pct:+.1f} % of the truth)" if math.isfinite(pct) and pct != 0 else ""
    role = st.get("role", "result")
    if role == "stated":
        ratio = st["mean"] / st["truth"] if st["truth"] else float("nan")
        bound = " (a stated bound: at or above the actual holds)" if _at_most(result, key[0]) else ""
        return (f"it states {with_unit(st['mean'], unit)} against an actual {with_unit(st['truth'], unit)} "
                f"(ratio {fmt(ratio)}, difference {with_pm(b, se, unit)}){bound}")
    if role == "residual":
        return (f"the residual, what the compensation leaves, is estimated at {with_unit(st['mean'], unit)} against "
                f"{_truth_words(st, unit)} (difference {with_pm(b, se, unit)}{pct_s})")
    exact = "exact to numerical precision: " if st.get("exact_to_numerical_precision") else ""
    return f"{exact}bias {with_pm(b, se, unit)}{pct_s} against {_truth_words(st, unit)}"


def _sentence(result, key, st: dict, cv) -> str:
    """One sentence: the verdict, what was judged, its tolerance (and what would settle an
    undetermined one), spread and coverage as numbers."""
    spec = _spec(result, key[0])
    unit = spec.unit if spec else ""
    rule = _rule(st, cv)
    spread = f", spread {with_unit(st['std'], unit)}"
    if rule == "input":
        return f"an input of the method ({with_unit(st['mean'], unit)}), taken as given: no verdict"
    if rule == "reference":
        return (f"a reference, not an estimate (no verdict): its error against {_truth_words(st, unit)} is "
                f"{with_pm(st['bias'], st['se_bias'], unit)}{spread}")
    if rule == "gauge":
        return ("not determined: the data cannot separate it from another parameter (a gauge freedom); its "
                f"estimate is a convention{spread} over {st['n']} trials, no sigma stated, no verdict")
    if rule == "none":
        return f"no verdict ({cv.no_verdict}): {_what(result, key, st, unit)}{spread}"
    v = cv.verdict
    u = "" if unit.strip() in ("", "1", "-", "dimensionless") else unit_prose(unit)
    tol = f"tolerance {v.tolerance.describe(u)} ({v.tolerance.reason})"
    s = f"{v.outcome}: {_what(result, key, st, unit)}, {tol}"
    if v.outcome == "undetermined":
        s += ("; no number of trials settles it (on the edge)" if v.on_edge
              else f"; about {v.n_to_settle} trials would settle it" if v.n_to_settle
              else f"; about {fmt(v.growth_to_settle, 2)} times the samples would settle it")
    z = v.significance_se
    sig = (f"; {fmt(z, 2, sign=True)} standard errors from 0" if math.isfinite(z) and abs(z) < 1e4
           else "; far beyond its standard error" if math.isfinite(z) else "")
    return s + sig + spread + _coverage_words(st)


def finding_sentence(result, key, st: dict, claims=None) -> str:
    """The finding's sentence of ``key`` (``(class, variant, axis)``) with its statistics ``st``."""
    spec = _spec(result, key[0])
    cv = class_verdict(result, key, st, method_rules(result, claims), unit=unit_prose(spec.unit if spec else ""))
    return _sentence(result, key, st, cv)


def findings(result, claims=None) -> list[dict]:
    """One finding per ``(class, variant, axis)``: its rule (the verdict, or why none), the
    sentence and the numbers it quotes. ``claims``: in place of the study's declared claims
    (their method tolerances judge their classes)."""
    rules = method_rules(result, claims)
    out = []
    for key in result.keys():
        st = result.statistics(key)
        cls, var, ax = key
        spec = _spec(result, cls)
        cv = class_verdict(result, key, st, rules, unit=unit_prose(spec.unit if spec else ""))
        rule = _rule(st, cv)
        cause = None
        if rule in ("fails", "undetermined"):
            try:
                cause = capability(result.study, Presented).likely_cause(result, key, st)
            except Exception:  # a study's hook must never break a report
                cause = None
        rms = st.get("rms_error", math.hypot(st["bias"], st["std"]))
        f = {"class": cls, "variant": var, "axis": ax, "rule": rule, "verdict": cv.outcome,
             "no_verdict": cv.no_verdict,
             "recovered": rule == "holds", "rms_error": rms, "text": _sentence(result, key, st, cv),
             "bias": st["bias"], "se_bias": st["se_bias"],
             "bias_percent": st.get("bias_percent") if math.isfinite(st.get("bias_percent", float("nan"))) else None}
        if cv.verdict is not None:
            t = cv.verdict.tolerance
            f.update(significance_se=(cv.verdict.significance_se if math.isfinite(cv.verdict.significance_se)
                                      else None), n_to_settle=cv.verdict.n_to_settle,
                     tolerance={"low": t.low if math.isfinite(t.low) else None,
                                "high": t.high if math.isfinite(t.high) else None,
                                "reason": t.reason, "source": t.source})
        if cause:
            f["likely_cause"] = cause
        out.append(f)
    return out


def _class_outcome(fs: list[dict]) -> str | None:
    """A class's outcome over its axes: fails if any axis fails, holds if every judged axis
    holds, undetermined otherwise; None when no axis has a verdict."""
    outs = [f["verdict"] for f in fs if f["verdict"] is not None]
    if not outs:
        return None
    if "fails" in outs:
        return "fails"
    return "holds" if all(o == "holds" for o in outs) else "undetermined"


def _variant_summary(result, items: list[dict]) -> dict:
    """Per variant: the classes whose estimate holds, fails, is undetermined (from the
    per-axis verdicts, :func:`_class_outcome`), and those without a verdict."""
    by_var: dict = {}
    for f in items:
        by_var.setdefault(f["variant"], {}).setdefault(f["class"], []).append(f)
    out = {}
    for var, classes in by_var.items():
        groups: dict = {"holds": [], "fails": [], "undetermined": [], "other": []}
        for cls, fs in classes.items():
            o = _class_outcome(fs)
            gauge = [f["axis"] for f in fs if f["rule"] == "gauge"]
            judged = ", ".join(f["axis"] for f in fs if f["rule"] != "gauge")
            name = cls if not gauge or o is None else f"{cls} ({judged} only)"
            groups[o or "other"].append(name)
        out[var] = {**groups, "recovered": groups["holds"], "not_recovered": groups["fails"],
                    "reference": all(f["rule"] == "reference" for fs in classes.values() for f in fs)}
    return out


def _recommendation(result, items: list[dict], summary: dict) -> str | None:
    """Which variant to use, class by class: among the variants whose estimate of the class
    holds on every judged axis, the one with the smallest rms error (averaged over the axes);
    where none holds, said so."""
    per_class: dict = {}
    for f in items:
        if f["rule"] in NO_VERDICT:
            continue
        per_class.setdefault(f["class"], {}).setdefault(f["variant"], []).append(f)
    if not per_class:
        return None
    use: dict = {}
    none: list = []
    for cls, by_var in per_class.items():
        ok = {v: sum(f["rms_error"] for f in fs) / len(fs) for v, fs in by_var.items()
              if all(f["verdict"] == "holds" for f in fs)}
        if not ok:
            none.append(_label(result, cls))
            continue
        best = min(ok, key=ok.get)
        use.setdefault(best, []).append(_label(result, cls))
    parts = [f"`{v}` for {', '.join(c)}" for v, c in sorted(use.items(), key=lambda kv: -len(kv[1]))]
    s = ("Use " + "; ".join(parts) + " (of the variants whose estimate holds, the one with the smallest rms "
         "error)." if parts else "")
    if none:
        s += (" " if s else "") + f"No variant's estimate holds for {', '.join(none)}."
    gauge = sorted({(f["class"], f["axis"]) for f in items if f["rule"] == "gauge"})
    if gauge:
        s += (" Not determined by the data (a gauge freedom, no sigma): "
              + ", ".join(f"{ax} ({_label(result, c)})" for c, ax in gauge) + ".")
    return s


def findings_json(result, claims=None) -> dict:
    """What the JSON result carries: ``findings`` (a list, each with its ``rule`` and
    ``verdict``), the per-variant summary and the recommendation."""
    items = findings(result, claims)
    summary = _variant_summary(result, items)
    return {"findings": items, "variants": summary, "recommendation": _recommendation(result, items, summary)}


def _label(result, cls) -> str:
    name, _, rest = cls.partition(" (")
    spec = _spec(result, name)
    return (spec.label if spec else name) + (f" ({rest}" if rest else "")


def headline(result, var: str, s: dict) -> str:
    """A variant's headline from its classes' verdicts (:func:`_variant_summary`)."""
    if s["reference"]:
        return f"`{var}` is a reference (it does not estimate): no verdict."
    parts = [f"{word} for {', '.join(_label(result, c) for c in s[key])}"
             for key, word in (("holds", "holds"), ("fails", "fails"), ("undetermined", "is undetermined"))
             if s[key]]
    s_ = f"`{var}`'s estimate " + ("; ".join(parts) if parts else "has no verdict on any class") + "."
    if s["other"]:
        s_ += f" No verdict: {', '.join(_label(result, c) for c in s['other'])}."
    return s_


def findings_markdown(result, data: dict | None = None) -> list[str]:
    """Markdown lines of the Findings section: per variant, its headline, then one line per
    class and axis (a verdict that is not "holds" first)."""
    data = data or findings_json(result)
    lines: list[str] = []
    if data["recommendation"]:
        lines += [f"**{data['recommendation']}**", ""]
    by_var: dict = {}
    for f in data["findings"]:
        by_var.setdefault(f["variant"], []).append(f)
    order = {"fails": 0, "undetermined": 1, "none": 2, "holds": 3, "gauge": 4, "reference": 5, "input": 6}
    for var, fs in by_var.items():
        lines += [f"### {var}", "", headline(result, var, data["variants"][var]), ""]
        for f in sorted(fs, key=lambda f: order[f["rule"]]):
            cause = f" Likely cause: {f['likely_cause'].rstrip('.')}." if f.get("likely_cause") else ""
            lines.append(f"* {_label(result, f['class'])} ({f['axis']}): {f['text']}.{cause}")
        lines.append("")
    return lines


def findings_lines(result, data: dict | None = None) -> list[str]:
    """Terminal lines: per variant its headline and each axis whose verdict is not "holds"."""
    data = data or findings_json(result)
    out = ["findings:"]
    by_var: dict = {}
    for f in data["findings"]:
        by_var.setdefault(f["variant"], []).append(f)
    for var, fs in by_var.items():
        s = data["variants"][var]
        out.append("  " + headline(result, var, s).replace("`", ""))
        if s["reference"]:
            continue
        shown: dict = {}
        for f in fs:
            if f["rule"] in ("fails", "undetermined", "none", "gauge"):
                shown[f["class"]] = shown.get(f["class"], 0) + 1
                if shown[f["class"]] <= 3:  # a class of many axes: three, then a count
                    out.append(f"    {f['class']} {f['axis']}: {f['text']}")
        for cls, k in shown.items():
            if k > 3:
                out.append(f"    {cls}: {k - 3} more axes without a holding verdict (see the report or the JSON)")
    if data["recommendation"]:
        out.append(f"  {data['recommendation']}")
    return out
