"""The report every study gets: the findings in words (:mod:`budget.runner.findings`), the
table, the estimates plot, then the study's own sections (:meth:`Study.report_sections`);
``report.md`` and its self-contained twin ``report.html`` (:mod:`budget.runner.html`).

Written into a temporary folder beside the target and renamed into place when complete, so
an interrupted run never leaves a half-written report that looks finished.
"""

from __future__ import annotations

import math
import os

import numpy as np
import shutil
import tempfile
from pathlib import Path


__all__ = ["finding", "format_table", "plot_estimates", "write_report"]


def _fmt(v: float) -> str:
    if v is None or not math.isfinite(v):
        return "n/a"
    a = abs(v)
    if a != 0 and (a < 1e-3 or a >= 1e5):
        return f"{v:.3e}"
    return f"{v:.4g}"


def _sig(st: dict) -> str:
    """The table's verdict column: input, ref(erence), n/d (not determined), exact, yes/no."""
    if st.get("role") in ("input", "residual"):
        return st["role"]
    if st.get("reference"):
        return "ref"
    if st.get("determined") is False:
        return "n/d"
    if st.get("exact_to_numerical_precision"):
        return "exact"
    return "yes" if st["bias_significant"] else "no"


def format_table(result) -> str:
    """A fixed-width text table of every key: truth (+- se), mean, bias (%), spread, coverage."""
    rows = [("class", "axis", "variant", "truth", "+-se", "mean", "bias", "bias %", "sig", "spread", "cov 1s")]
    for key in result.keys():
        st = result.statistics(key)
        cls, var, ax = key
        cov = st.get("coverage")
        rows.append((cls, ax, var, _fmt(st["truth"]), _fmt(st["truth_se"]), _fmt(st["mean"]), _fmt(st["bias"]),
                     "n/a" if not math.isfinite(st["bias_percent"]) else f"{st['bias_percent']:+.1f}",
                     _sig(st),
                     _fmt(st["std"]),
                     f"{cov['within_1sigma']:.2f}" if cov else "-"))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows)


def finding(result, key) -> str:
    """One sentence about ``key``, chosen by the shared rules (:mod:`budget.runner.findings`)."""
    from budget.runner.findings import _sentence, _verdict

    st = result.statistics(key)
    cls, var, ax = key
    return f"{result.class_spec(cls).label}, {ax}, {var}: {_sentence(result, key, st, _verdict(result, key, st))}."


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_estimates(result, path: Path) -> Path:
    """Histograms of the estimates (errors, for per-trial truths) of every key, truth marked.

    Variants are drawn as outlines with their own line style and width (the widest first), so
    that identical histograms stay visible; a reference variant is marked in the legend;
    titles are wrapped, never clipped; a dimensionless class has no unit on its axis."""
    import textwrap

    from budget.runner.findings import _unit

    plt = _plt()
    keys = result.keys()
    groups: dict = {}
    for k in keys:
        groups.setdefault((k[0], k[2]), []).append(k)
    n = len(groups)
    ncol = min(3, n)
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.8 * ncol, 3.7 * nrow), squeeze=False)
    styles = [("-", 2.6), ("--", 1.8), (":", 1.4), ("-.", 1.2)]
    refs = set(getattr(result.study, "reference_variants", ()))
    for ax_, ((cls, ax), ks) in zip(axes.flat, groups.items()):
        spec = result.class_spec(cls)
        unit = _unit(spec.unit)
        unit_s = "" if unit in ("", "1") else f" ({unit})"
        for i, k in enumerate(ks):
            x = result.samples[k]
            if k in result.trial_truths:
                x = x - result.trial_truths[k]
            # a constant (or numerically constant) sample has no 30 finite bins
            flat = not np.ptp(x) > 1e-9 * max(float(np.max(np.abs(x))), 1e-300)
            ls, lw = styles[i % len(styles)]
            ax_.hist(x, bins=1 if flat else 30, histtype="step", linestyle=ls, linewidth=lw,
                     label=k[1] + (" (reference)" if k[1] in refs else ""))
        if all(k in result.trial_truths for k in ks):
            ax_.axvline(0.0, color="k", lw=1, label="truth (error 0)")
            ax_.set_xlabel(f"estimate - truth{unit_s}")
        else:
            t = result.truths[(cls, ax)].value
            ax_.axvline(t, color="k", lw=1, label="truth")
            ax_.set_xlabel(f"estimate{unit_s}")
        ax_.set_ylabel("trials")
        ax_.set_title("\n".join(textwrap.wrap(f"{spec.label} ({ax})", 48)), fontsize=9)
        ax_.legend(fontsize=7)
    for ax_ in list(axes.flat)[n:]:
        ax_.set_visible(False)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def estimates_caption(result, fdata: dict) -> str:
    """The estimates figure's caption: what it shows, and its finding (from the findings)."""
    biased = sorted({f"{f['class']} ({f['axis']}) {f['variant']}" for f in fdata["findings"]
                     if f["rule"] == "biased"})
    s = ("Each panel: the estimates of one class and axis over the trials (for per-trial truths, estimate "
         "minus the trial's truth), one outline per variant; the black line is the truth.")
    if biased:
        s += " Off the line (significantly biased): " + ", ".join(biased) + "."
    else:
        s += " Every variant's histogram is centred on the truth within its standard error."
    return s


def write_report(result, out_dir: str | os.PathLike) -> Path:
    """Write ``report.md``, ``estimates.png``, the study's sections and figures,
    ``scenario.toml`` and ``summary.json`` (the JSON result) into ``out_dir``."""
    from simcam.cli_common import write_json_atomic

    import sys

    from simcam.lifecycle import partial_prefix, remove_stale_partials

    out = Path(out_dir)
    out.parent.mkdir(parents=True, exist_ok=True)
    # a report a killed run left half-written is removed (and said so), never taken as complete
    remove_stale_partials(out, echo=lambda msg: print(msg, file=sys.stderr))
    tmp = Path(tempfile.mkdtemp(prefix=partial_prefix(out), dir=out.parent))
    try:
        study = result.study
        from budget.runner.findings import findings_json, findings_markdown

        fdata = findings_json(result)
        lines = [f"# {study.title}: Monte Carlo validation", "",
                 f"Study `{study.name}` (seed document {study.seed_document}); scenario "
                 + (f"`{getattr(result.scenario, 'name', '')}` " if getattr(result.scenario, "name", "") else "")
                 + f"(hash `{study.scenario_hash(result.scenario)}`), "
                 f"seed {result.seed}, {result.trials} trials (stopped by {result.stopped_by}).", "",
                 "## Findings", "", *findings_markdown(result, fdata),
                 "## Method", "",
                 "Each trial simulates one measurement with known injected errors and runs the lab's "
                 "estimators on it: `published` is the method as its source document writes it, the other "
                 "variants are improved estimators that use only what a lab would know. The truth of each "
                 "class is the quantity the method claims to measure, computed from the injected physics "
                 "without the estimator.", "", "## Classes", ""]
        for c in result.classes:
            unit = "dimensionless" if c.unit.strip() in ("1", "") else c.unit
            lines.append(f"* **{c.label}** (`{c.name}`, {unit}): {c.description}")
        lines += ["", "## Table", "", "```", format_table(result), "```", "",
                  "`+-se` is the truth's own Monte Carlo standard error; a bias is significant (`sig`) when it "
                  "exceeds 3 standard errors of the trials' mean combined with the truth's and the class's "
                  "numerical floor (`exact` below it); `ref` marks a reference variant that does not estimate, "
                  "`n/d` a quantity the data cannot determine; `bias %` only where the truth is far from zero "
                  "against its spread.", "",
                  "![estimates](estimates.png)", "", estimates_caption(result, fdata), ""]
        plot_estimates(result, tmp / "estimates.png")
        for sec in study.report_sections(result, tmp):
            lines += [f"## {sec.title}", "", sec.markdown, ""]
            for fig in sec.figures:
                lines += [f"![{Path(fig).stem}]({Path(fig).name})", ""]
        scenario_toml = study.scenario_text(result.scenario)
        lines += ["## Scenario", "", "```toml", scenario_toml.rstrip(), "```", ""]
        (tmp / "scenario.toml").write_text(scenario_toml)
        write_json_atomic(tmp / "summary.json", result.to_json())
        (tmp / "report.md").write_text("\n".join(lines))
        from budget.runner.html import write_html

        write_html(tmp / "report.md", tmp / "report.html", title=f"{study.title}: Monte Carlo validation")
        if out.exists():
            if out.is_dir() and (not any(out.iterdir()) or (out / "report.md").exists()):
                shutil.rmtree(out)  # an earlier report (or an empty folder): replaced whole
            else:
                from simcam.cli_common import UserInputError

                raise UserInputError(f"--report {out}: exists and is not an earlier report; "
                                     "give a new folder")
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out / "report.md"
