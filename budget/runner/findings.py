"""Findings in words, derived from the numbers by rules shared by every study.

A report (Markdown, HTML, the terminal and the JSON's ``findings``) opens with what the run
found, per variant: which classes it recovers within its claim, which not and by how much,
the most likely cause where the study knows it (:meth:`~budget.runner.capabilities.Presented.likely_cause`), and which
variant to use. Nothing here is templated per row: each sentence is chosen by one of the
rules below from the statistics it quotes, so it cannot contradict them. Each finding names
the rule that produced it (``rule`` in the JSON).

Rules, in the order they are tried for one ``(class, variant, axis)``:

``input``
    the class is an input of the method (:attr:`ClassSpec.role` ``"input"``): reported,
    never validated.
``residual``
    the class is what a calibration or compensation leaves (role ``"residual"``): "leaves X
    against Y", never called an estimator's bias.
``stated``
    the class compares a stated uncertainty (estimate) with the actual error (truth), role
    ``"stated"``: "states X against an actual Y", consistent, optimistic or pessimistic.
``reference``
    the variant does not estimate (:attr:`Study.reference_variants`, e.g. the scan mirror's
    ``without_estimate``, which returns 0 by design): labelled a reference, never "recovers".
``undetermined``
    the axis is a gauge freedom (:attr:`ClassSpec.undetermined`): "not determined", no sigma
    (its stated sigma and coverage are dropped from the statistics).
``exact``
    ``|bias|`` and 3 standard errors of it are both below the class's
    :attr:`ClassSpec.numerical_floor`: "exact to numerical precision", never significant.
``recovers``
    no significant bias (``|bias| <= 3 se`` or below the floor; for a one-sided claim, no
    significant shortfall) and, where the estimator states a 1-sigma, its coverage is
    consistent with 68.3 % (within 3 binomial standard errors): recovered within its claim.
``biased``
    a significant bias: "biased by b (p % of the truth)", the percentage only where the
    truth is far from zero against its spread (:func:`budget.runner.stats.key_statistics`).
``unresolved``
    no significant bias, but 3 standard errors of it exceed ``RESOLUTION`` (10 %) of a truth
    far from zero: too few trials (or too large a spread) to call it recovered.
A ``residual`` or ``stated`` class counts as held within its claim when its difference is
not significant.

A one-sided claim (:attr:`ClassSpec.at_most`: the estimate is a stated bound, the truth at or
below it) is past its claim only when the estimate is significantly *below* the truth: a
significant difference the other way (the bound above the actual) holds, and is said so
("a bound that holds"), never "biased" or "pessimistic" as a failure.

``coverage``
    no significant bias, but the stated 1-sigma interval holds the truth in a fraction
    inconsistent with 68.3 %: not within its claim; the ratio of the actual to the stated
    scatter (sd of error / sigma) says by how much.
"""

from __future__ import annotations

import math

from budget.runner.capabilities import Presented, capability
from budget.runner.numbers import fmt

__all__ = ["RULES", "annotate", "finding_sentence", "findings", "findings_json", "findings_lines", "findings_markdown",
           "unit_prose", "with_unit"]

RULES = ("input", "residual", "stated", "reference", "undetermined", "exact", "recovers", "biased", "coverage",
         "unresolved")
#: a class is called recovered only when the run resolves its bias to this fraction of the
#: truth (3 standard errors), where the truth is far from zero against its spread
RESOLUTION = 0.10
#: verdicts that count as "recovered within its claim"
_OK = ("exact", "recovers")


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


def _coverage_ok(st: dict) -> bool | None:
    cov = st.get("coverage")
    if not cov:
        return None
    return abs(cov["within_1sigma"] - cov["expected_1sigma"]) <= 3.0 * cov["se_1sigma"]


def _at_most(result, cls) -> bool:
    """Whether the class's claim is one-sided (:attr:`ClassSpec.at_most`)."""
    return bool(getattr(_spec(result, cls), "at_most", False))


def _past_claim(result, key, st: dict) -> bool:
    """A significant difference on the side the claim forbids: either side for a two-sided
    claim, the estimate below the truth for a one-sided one (:attr:`ClassSpec.at_most`)."""
    return bool(st["bias_significant"]) and (not _at_most(result, key[0]) or st["bias"] < 0)


def _verdict(result, key, st: dict) -> str:
    role = st.get("role", "result")
    if role == "input":
        return "input"
    if role in ("residual", "stated"):
        return role
    if st.get("reference"):
        return "reference"
    if st.get("determined") is False:
        return "undetermined"
    if st.get("exact_to_numerical_precision"):
        return "exact"
    if _past_claim(result, key, st):
        return "biased"
    if _coverage_ok(st) is False:
        return "coverage"
    if st["bias_significant"]:  # a one-sided claim's bound, significantly above its truth: it holds
        return "recovers"
    pct = st.get("bias_percent", float("nan"))
    if math.isfinite(pct) and 3.0 * st["se_bias"] > RESOLUTION * abs(st["truth"]):
        return "unresolved"
    return "recovers"


def _truth_words(st: dict, unit: str) -> str:
    if st["per_trial_truth"]:
        return f"the trials' truths (mean {with_unit(st['truth'], unit)})"
    if st["truth_se"] > 0:
        return f"the truth {with_pm(st['truth'], st['truth_se'], unit)}"
    return f"the truth {with_unit(st['truth'], unit)}"


def finding_sentence(result, key, st: dict) -> str:
    """The finding's sentence of ``key`` (``(class, variant, axis)``) with its statistics ``st``,
    by the rule its numbers select (the module docstring's rules)."""
    return _sentence(result, key, st, _verdict(result, key, st))


def _sentence(result, key, st: dict, verdict: str) -> str:
    cls, var, ax = key
    spec = _spec(result, cls)
    unit = spec.unit if spec else ""
    b, se = st["bias"], st["se_bias"]
    pct = st.get("bias_percent", float("nan"))
    pct_s = f", {pct:+.1f} % of the truth," if math.isfinite(pct) and pct != 0 else ""
    if verdict == "input":
        return f"an input of the method ({with_unit(st['mean'], unit)}), taken as given: nothing to validate"
    if verdict == "stated":
        ratio = st["mean"] / st["truth"] if st["truth"] else float("nan")
        if _at_most(result, cls):  # a stated bound: the actual at or below it holds
            word = ("a bound that holds (the actual at or below it)" if not _past_claim(result, key, st)
                    else "optimistic: the actual exceeds the stated bound")
        else:
            word = ("consistent with it" if not st["bias_significant"]
                    else ("pessimistic (states more)" if b > 0 else "optimistic (states less)"))
        return (f"states {with_unit(st['mean'], unit)} against an actual {with_unit(st['truth'], unit)} "
                f"(ratio {fmt(ratio)}, difference {with_pm(b, se, unit)}): {word}")
    if verdict == "residual":
        return (f"a residual, what the compensation leaves: mean {with_unit(st['mean'], unit)} against "
                f"{_truth_words(st, unit)} (difference {with_pm(b, se, unit)}), spread {with_unit(st['std'], unit)}")
    if verdict == "reference":
        return (f"a reference, not an estimate: its error against {_truth_words(st, unit)} is "
                f"{with_pm(b, se, unit)}, spread {with_unit(st['std'], unit)}")
    if verdict == "undetermined":
        return ("not determined: the data cannot separate it from another parameter (a gauge freedom); "
                f"its estimate is a convention, spread {with_unit(st['std'], unit)} over {st['n']} trials, "
                "no sigma stated")
    if verdict == "exact":
        return (f"exact to numerical precision: bias {with_pm(b, se, unit)}, below the "
                f"numerical floor {with_unit(st['numerical_floor'], unit)}")
    if verdict == "unresolved":
        return (f"no significant bias ({with_pm(b, se, unit)} against {_truth_words(st, unit)}), but 3 "
                f"standard errors are {100 * 3 * se / abs(st['truth']):.0f} % of the truth: too few trials "
                f"(or too large a spread, {with_unit(st['std'], unit)}) to call it recovered")
    if verdict == "biased":
        s = f"biased by {with_pm(b, se, unit)}{pct_s} against {_truth_words(st, unit)}"
    elif _at_most(result, cls) and st["bias_significant"]:
        s = (f"a bound that holds: {with_pm(b, se, unit)} above {_truth_words(st, unit)} (the truth at or "
             f"below the estimate), spread {with_unit(st['std'], unit)}")
    else:
        s = (f"recovered: bias {with_pm(b, se, unit)} against {_truth_words(st, unit)}, "
             f"spread {with_unit(st['std'], unit)}")
    cov = st.get("coverage")
    if cov:
        ok = _coverage_ok(st)
        s += (f"; its stated 1-sigma holds the truth in {100 * cov['within_1sigma']:.1f} % of trials "
              f"(68.3 % expected)")
        r = cov.get("sd_normalised_error", float("nan"))
        if ok is False and math.isfinite(r) and r > 0:
            s += (f": the actual scatter is {fmt(r)} times the stated sigma" if r >= 1
                  else f": the stated sigma is {fmt(1 / r)} times the actual scatter")
    return s


def findings(result) -> list[dict]:
    """One finding per ``(class, variant, axis)``: the rule, the sentence and the numbers it quotes."""
    out = []
    for key in result.keys():
        st = result.statistics(key)
        verdict = _verdict(result, key, st)
        cls, var, ax = key
        cause = None
        held = verdict in _OK or (verdict in ("residual", "stated") and not _past_claim(result, key, st))
        if not held and verdict in ("biased", "coverage", "unresolved", "residual", "stated"):
            try:
                cause = capability(result.study, Presented).likely_cause(result, key, st)
            except Exception:  # a study's hook must never break a report
                cause = None
        rms = st.get("rms_error", math.hypot(st["bias"], st["std"]))
        f = {"class": cls, "variant": var, "axis": ax, "rule": verdict, "rms_error": rms,
             "recovered": held, "text": _sentence(result, key, st, verdict),
             "bias": st["bias"], "se_bias": st["se_bias"],
             "bias_percent": st.get("bias_percent") if math.isfinite(st.get("bias_percent", float("nan"))) else None}
        if cause:
            f["likely_cause"] = cause
        out.append(f)
    return out


def _variant_summary(result, items: list[dict]) -> dict:
    """Per variant: classes recovered (every axis), not recovered (with their axes' findings)."""
    by_var: dict = {}
    for f in items:
        by_var.setdefault(f["variant"], {}).setdefault(f["class"], []).append(f)
    out = {}
    for var, classes in by_var.items():
        rec, notrec, other, held = [], [], [], []
        for cls, fs in classes.items():
            rules = {f["rule"] for f in fs}
            if rules & {"input", "reference"} or rules == {"undetermined"}:
                other.append(cls)
            elif rules <= {"residual", "stated"} and all(f["recovered"] for f in fs):
                held.append(cls)   # a residual or a stated figure is not "recovered": it agrees with its truth
            elif all(f["recovered"] or f["rule"] == "undetermined" for f in fs):
                und = [f["axis"] for f in fs if f["rule"] == "undetermined"]
                rec.append(cls if not und else
                           f"{cls} ({', '.join(f['axis'] for f in fs if f['rule'] != 'undetermined')} only)")
            else:
                notrec.append(cls)
        out[var] = {"recovered": rec, "not_recovered": notrec, "other": other, "held": held,
                    "reference": all(f["rule"] == "reference" for fs in classes.values() for f in fs)}
    return out


def _recommendation(result, items: list[dict], summary: dict) -> str | None:
    """Which variant to use, class by class: among the variants that recover the class within
    their claim, the one with the smallest rms error (averaged over the axes); where none
    recovers it, said so."""
    per_class: dict = {}
    for f in items:
        if f["rule"] in ("input", "reference", "undetermined"):
            continue
        per_class.setdefault(f["class"], {}).setdefault(f["variant"], []).append(f)
    if not per_class:
        return None
    use: dict = {}
    none: list = []
    for cls, by_var in per_class.items():
        ok = {v: sum(f["rms_error"] for f in fs) / len(fs) for v, fs in by_var.items()
              if all(f["recovered"] or f["rule"] == "undetermined" for f in fs)
              and any(f["recovered"] for f in fs)}
        if not ok:
            none.append(_label(result, cls))
            continue
        best = min(ok, key=ok.get)
        use.setdefault(best, []).append(_label(result, cls))
    parts = [f"`{v}` for {', '.join(c)}" for v, c in sorted(use.items(), key=lambda kv: -len(kv[1]))]
    s = ("Use " + "; ".join(parts) + " (of the variants within their claim on a class, the one with the "
         "smallest rms error)." if parts else "")
    if none:
        s += (" " if s else "") + f"No variant recovers {', '.join(none)} within its claim."
    undet = sorted({(f["class"], f["axis"]) for f in items if f["rule"] == "undetermined"})
    if undet:
        s += (" Not determined by the data (a gauge freedom, no sigma): "
              + ", ".join(f"{ax} ({_label(result, c)})" for c, ax in undet) + ".")
    return s


def findings_json(result) -> dict:
    """What the JSON result carries: ``findings`` (a list, each with the ``rule`` that produced
    it), the per-variant summary and the recommendation."""
    items = findings(result)
    summary = _variant_summary(result, items)
    return {"findings": items, "variants": summary, "recommendation": _recommendation(result, items, summary)}


def _label(result, cls) -> str:
    name, _, rest = cls.partition(" (")
    spec = _spec(result, name)
    return (spec.label if spec else name) + (f" ({rest}" if rest else "")


def findings_markdown(result, data: dict | None = None) -> list[str]:
    """Markdown lines of the Findings section: one paragraph per variant, then its details."""
    data = data or findings_json(result)
    lines: list[str] = []
    if data["recommendation"]:
        lines += [f"**{data['recommendation']}**", ""]
    by_var: dict = {}
    for f in data["findings"]:
        by_var.setdefault(f["variant"], []).append(f)
    for var, fs in by_var.items():
        s = data["variants"][var]
        if s["reference"]:
            head = f"`{var}` is a reference (it does not estimate): it recovers nothing by design."
        else:
            rec = ", ".join(_label(result, c) for c in s["recovered"]) or "none"
            nrec = ", ".join(_label(result, c) for c in s["not_recovered"]) or "none"
            head = f"`{var}` recovers within its claim: {rec}. Not recovered: {nrec}."
            if s.get("held"):
                head += (" Agrees with its truth (a residual or a stated figure, not an estimate): "
                         + ", ".join(_label(result, c) for c in s["held"]) + ".")
        lines += [f"### {var}", "", head, ""]
        for f in fs:
            if f["recovered"] or f["rule"] == "input":
                continue
            lines.append(f"* {_label(result, f['class'])} ({f['axis']}): {f['text']}."
                         + (f" Likely cause: {f['likely_cause']}" if f.get("likely_cause") else ""))
        shown = [f for f in fs if f["recovered"] or f["rule"] == "input"]
        for f in shown:
            lines.append(f"* {_label(result, f['class'])} ({f['axis']}): {f['text']}.")
        lines.append("")
    return lines


def findings_lines(result, data: dict | None = None) -> list[str]:
    """Terminal lines: the recommendation and, per variant, what it recovers and what not
    (with each non-recovered axis's sentence)."""
    data = data or findings_json(result)
    out = ["findings:"]
    by_var: dict = {}
    for f in data["findings"]:
        by_var.setdefault(f["variant"], []).append(f)
    for var, fs in by_var.items():
        s = data["variants"][var]
        if s["reference"]:
            out.append(f"  {var}: a reference (does not estimate)")
            continue
        out.append(f"  {var}: recovers {', '.join(s['recovered']) or 'none'}; "
                   f"not: {', '.join(s['not_recovered']) or 'none'}"
                   + (f"; agrees with its truth (residual or stated): {', '.join(s['held'])}" if s.get("held") else ""))
        shown: dict = {}
        for f in fs:
            if not f["recovered"] and f["rule"] not in ("input", "reference"):
                shown[f["class"]] = shown.get(f["class"], 0) + 1
                if shown[f["class"]] <= 3:  # a class of many axes: three, then a count
                    out.append(f"    {f['class']} {f['axis']}: {f['text']}")
        for cls, k in shown.items():
            if k > 3:
                out.append(f"    {cls}: {k - 3} more axes not recovered (see the report or the JSON's findings)")
    if data["recommendation"]:
        out.append(f"  {data['recommendation']}")
    return out
