"""The report every study gets: the table, one sentence per finding, the estimates plot,
then the study's own sections (:meth:`Study.report_sections`).

Written into a temporary folder beside the target and renamed into place when complete, so
an interrupted run never leaves a half-written report that looks finished.
"""

from __future__ import annotations

import math
import os
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


def format_table(result) -> str:
    """A fixed-width text table of every key: truth (+- se), mean, bias (%), spread, coverage."""
    rows = [("class", "axis", "variant", "truth", "+-se", "mean", "bias", "bias %", "sig", "spread", "cov 1s")]
    for key in result.keys():
        st = result.statistics(key)
        cls, var, ax = key
        cov = st.get("coverage")
        rows.append((cls, ax, var, _fmt(st["truth"]), _fmt(st["truth_se"]), _fmt(st["mean"]), _fmt(st["bias"]),
                     "n/a" if not math.isfinite(st["bias_percent"]) else f"{st['bias_percent']:+.1f}",
                     "input" if st.get("role") == "input" else ("yes" if st["bias_significant"] else "no"),
                     _fmt(st["std"]),
                     f"{cov['within_1sigma']:.2f}" if cov else "-"))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows)


def finding(result, key) -> str:
    """One sentence: what the estimator recovers of its truth, with the uncertainty."""
    cls, var, ax = key
    spec = result.class_spec(cls)
    st = result.statistics(key)
    unit = spec.unit
    if st.get("role") == "input":
        return (f"{spec.label}, {ax}, {var}: an input of the method ({_fmt(st['mean'])} {unit}), "
                f"taken as given, not measured: nothing to validate.")
    truth = (f"the truth {_fmt(st['truth'])} {unit}" + (f" (+- {_fmt(st['truth_se'])})" if st["truth_se"] > 0 else "")
             if not st["per_trial_truth"] else "the truth of each trial")
    if st.get("role") in ("residual", "stated"):
        # not an estimate of its truth: the difference is no estimator's bias
        diff = (f"{_fmt(st['bias'])} +- {_fmt(st['se_bias'])} {unit}"
                + (", significant" if st["bias_significant"] else ", not significant"))
        what = ("a residual (what the calibration leaves), not an estimate" if st["role"] == "residual"
                else "a stated uncertainty compared with the actual error")
        return (f"{spec.label}, {ax}, {var}: {what}: mean {_fmt(st['mean'])} {unit} against {truth} "
                f"(difference {diff}); its spread over {st['n']} trials is {_fmt(st['std'])} {unit}.")
    if st["bias_significant"]:
        pct = f" ({st['bias_percent']:+.1f} %)" if math.isfinite(st["bias_percent"]) and not st["per_trial_truth"] else ""
        verdict = f"is biased by {_fmt(st['bias'])} {unit}{pct} +- {_fmt(st['se_bias'])}"
    else:
        verdict = f"recovers it without a significant bias ({_fmt(st['bias'])} +- {_fmt(st['se_bias'])} {unit})"
    s = (f"{spec.label}, {ax}, {var}: against {truth}, the estimator {verdict}; "
         f"its spread over {st['n']} trials is {_fmt(st['std'])} {unit}.")
    cov = st.get("coverage")
    if cov:
        s += (f" Its stated 1-sigma interval holds the truth in {100 * cov['within_1sigma']:.1f} % of trials "
              f"(+- {100 * cov['se_1sigma']:.1f}; 68.3 % expected).")
    return s


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_estimates(result, path: Path) -> Path:
    """Histograms of the estimates (errors, for per-trial truths) of every key, truth marked."""
    plt = _plt()
    keys = result.keys()
    groups: dict = {}
    for k in keys:
        groups.setdefault((k[0], k[2]), []).append(k)
    n = len(groups)
    ncol = min(3, n)
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.6 * ncol, 3.4 * nrow), squeeze=False)
    for ax_, ((cls, ax), ks) in zip(axes.flat, groups.items()):
        spec = result.class_spec(cls)
        for k in ks:
            x = result.samples[k]
            if k in result.trial_truths:
                x = x - result.trial_truths[k]
            ax_.hist(x, bins=30, histtype="step", label=k[1])
        if all(k in result.trial_truths for k in ks):
            ax_.axvline(0.0, color="k", lw=1, label="truth (error 0)")
            ax_.set_xlabel(f"estimate - truth ({spec.unit})")
        else:
            t = result.truths[(cls, ax)].value
            ax_.axvline(t, color="k", lw=1, label="truth")
            ax_.set_xlabel(f"estimate ({spec.unit})")
        ax_.set_ylabel("trials")
        ax_.set_title(f"{spec.label} ({ax})", fontsize=9)
        ax_.legend(fontsize=7)
    for ax_ in list(axes.flat)[n:]:
        ax_.set_visible(False)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


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
        lines = [f"# {study.title}: Monte Carlo validation", "",
                 f"Study `{study.name}` (seed document {study.seed_document}); scenario "
                 f"`{getattr(result.scenario, 'name', '')}` (hash `{study.scenario_hash(result.scenario)}`), "
                 f"seed {result.seed}, {result.trials} trials (stopped by {result.stopped_by}).", "",
                 "Each trial simulates one measurement with known injected errors and runs the lab's "
                 "estimators on it: `published` is the method as its source document writes it, the other "
                 "variants are improved estimators that use only what a lab would know. The truth of each "
                 "class is the quantity the method claims to measure, computed from the injected physics "
                 "without the estimator.", "", "## Classes", ""]
        for c in result.classes:
            lines.append(f"* **{c.label}** (`{c.name}`, {c.unit}): {c.description}")
        lines += ["", "## Findings", ""]
        lines += [f"* {finding(result, k)}" for k in result.keys()]
        lines += ["", "## Table", "", "```", format_table(result), "```", "",
                  "`+-se` is the truth's own Monte Carlo standard error; a bias is significant when it exceeds "
                  "3 standard errors of the trials' mean combined with the truth's.", "",
                  "![estimates](estimates.png)", ""]
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
