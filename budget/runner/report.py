"""The report every study gets: the findings in words (:mod:`budget.runner.findings`), the
table, the estimates plot, then the study's own sections (:meth:`~budget.runner.capabilities.Presented.report_sections`);
``report.md`` and its self-contained twin ``report.html`` (:mod:`budget.runner.html`).

Written into a temporary folder beside the target and renamed into place when complete, so
an interrupted run never leaves a half-written report that looks finished.
"""

from __future__ import annotations

import contextlib
import math
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from budget.figures import save
from budget.runner.capabilities import Presented, capability
from budget.runner.findings import (
    finding_sentence,
    findings_json,
    findings_markdown,
    unit_prose,
    with_unit,
)
from budget.runner.html import write_html
from budget.runner.ledger_view import ledger_section
from budget.runner.numbers import fmt
from simcam.effects import scenario_effects
from simcam.infra.cli import write_json_atomic
from simcam.infra.errors import UserInputError
from simcam.infra.lifecycle import partial_prefix, remove_stale_partials
from simcam.infra.outputs import StagedOutputs

__all__ = [
    "TABLE_LEGEND",
    "estimates_caption",
    "estimates_panels",
    "finding",
    "format_table",
    "plot_estimates",
    "publish_report",
    "staged_report",
    "table_legend",
    "table_markdown",
    "write_outputs",
    "write_report",
]


def _verdicts(result, fdata: dict | None) -> dict:
    """``{(class, variant, axis): the table's verdict cell}`` from the findings' verdicts."""
    fdata = fdata or findings_json(result)
    short = {"input": "input", "reference": "ref", "gauge": "n/d", "none": "-"}
    return {(f["class"], f["variant"], f["axis"]): short.get(f["rule"], f["rule"]) for f in fdata["findings"]}


def format_table(result, fdata: dict | None = None) -> str:
    """A fixed-width text table of every key: truth (+- se), mean, bias (%), the verdict,
    spread, coverage (the terminal's; the report's is :func:`table_markdown`)."""
    verdicts = _verdicts(result, fdata)
    rows = [("class", "axis", "variant", "truth", "+-se", "mean", "bias", "bias %", "verdict", "spread", "cov 1s")]
    for key in result.keys():
        st = result.statistics(key)
        cls, var, ax = key
        cov = st.get("coverage")
        rows.append((cls, ax, var, fmt(st["truth"]), fmt(st["truth_se"]), fmt(st["mean"]), fmt(st["bias"]),
                     "n/a" if not math.isfinite(st["bias_percent"]) else f"{st['bias_percent']:+.1f}",
                     verdicts[key], fmt(st["std"]), f"{cov['within_1sigma']:.2f}" if cov else "-"))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows)


#: the report table's columns and what each means (its legend)
TABLE_LEGEND = (
    ("class", "the error class (its label; the unit column gives its unit)"),
    ("axis", "the axis or component"),
    ("variant", "`published`: the source document's method; the others: improved estimators using only what a "
                "lab knows; `(ref)`: a reference that estimates nothing"),
    ("unit", "the unit of every number in the row but the percentage and the coverage"),
    ("truth", "what the method claims to measure, from the injected physics (per-trial truths: their mean), "
              "with its own Monte Carlo standard error where it is sampled"),
    ("mean estimate", "the variant's estimate averaged over the trials"),
    ("bias", "mean estimate less truth, with its standard error over the trials"),
    ("bias % of truth", "the bias as a percentage of the truth, only where the truth is far from zero "
                        "against its spread"),
    ("verdict", "holds / fails / undetermined: the bias's 95 % interval wholly inside, wholly outside or across "
                "the tolerance (the Findings give each tolerance and its reason); `input`, `ref` and `n/d` (a "
                "gauge freedom the data cannot determine) have none"),
    ("spread", "the standard deviation of the estimate (less the trial's truth, for per-trial truths) over "
               "the trials"),
    ("within 1 sigma", "the fraction of trials whose stated 1-sigma holds the truth (68.3 % expected); "
                       "blank where no sigma is stated"),
)


def table_markdown(result, fdata: dict | None = None) -> str:
    """The report's results table in Markdown (an HTML table in ``report.html``), one row
    per key, units in their own column; :data:`TABLE_LEGEND` explains the columns."""
    verdicts = _verdicts(result, fdata)
    lines = ["| " + " | ".join(c for c, _ in TABLE_LEGEND) + " |", "|" + "---|" * len(TABLE_LEGEND)]
    for key in result.keys():
        st = result.statistics(key)
        cls, var, ax = key
        spec = result.class_spec(cls)
        unit = "-" if spec.unit.strip() in ("", "1") else unit_prose(spec.unit)
        cov = st.get("coverage")
        truth = fmt(st["truth"]) + (f" +- {fmt(st['truth_se'])}" if st["truth_se"] else "")
        pct = f"{st['bias_percent']:+.1f} %" if math.isfinite(st["bias_percent"]) else ""
        ref = " (ref)" if st.get("reference") else ""
        cells = (spec.label, ax, f"`{var}`{ref}", unit, truth, fmt(st["mean"]),
                 f"{fmt(st['bias'], sign=True)} +- {fmt(st['se_bias'])}", pct, verdicts[key], fmt(st["std"]),
                 f"{100 * cov['within_1sigma']:.1f} %" if cov else "")
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return "\n".join(lines)


def table_legend() -> str:
    """The table's legend: one line per column."""
    return "Columns: " + "; ".join(f"**{c}**, {what}" for c, what in TABLE_LEGEND) + "."


def finding(result, key) -> str:
    """One sentence about ``key``, chosen by the shared rules (:mod:`budget.runner.findings`)."""

    st = result.statistics(key)
    cls, var, ax = key
    return f"{result.class_spec(cls).label}, {ax}, {var}: {finding_sentence(result, key, st)}."


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


#: histogram bins of one panel of ``estimates.png`` (shared by every variant of the panel)
ESTIMATE_BINS = 30


def _constant(x: np.ndarray, scale: float) -> bool:
    """A sample every trial of which gives the same value (to 1e-9 of the compared values'
    magnitude ``scale``: the rounding of an exact estimator)."""
    return bool(x.size) and not float(np.ptp(x)) > 1e-9 * max(scale, 1e-300)


def estimates_panels(result) -> list[dict]:
    """What ``estimates.png`` draws, one entry per panel (class and axis): ``cls``, ``axis``,
    ``errors`` (per-trial truths: estimate minus truth), ``truth`` (the line: 0 for errors),
    ``edges`` (the bin edges every variant of the panel shares, None when no variant has a
    spread), ``constants`` (variant -> the value every trial gives, drawn as a vertical line)
    and ``samples`` (variant -> values, the histograms)."""
    groups: dict = {}
    for k in result.keys():
        groups.setdefault((k[0], k[2]), []).append(k)
    panels = []
    for (cls, ax), ks in groups.items():
        errors = all(k in result.trial_truths for k in ks)
        samples, constants = {}, {}
        for k in ks:
            x = np.asarray(result.samples[k], dtype=float)
            scale = float(np.max(np.abs(x))) if x.size else 0.0
            if k in result.trial_truths:
                t = np.asarray(result.trial_truths[k], dtype=float)
                scale = max(scale, float(np.max(np.abs(t))) if t.size else 0.0)
                x = x - t
            x = x[np.isfinite(x)]
            if _constant(x, scale):
                constants[k[1]] = float(np.mean(x))
            else:
                samples[k[1]] = x
        edges = None
        if samples:
            allv = np.concatenate(list(samples.values()))
            edges = np.linspace(float(allv.min()), float(allv.max()), ESTIMATE_BINS + 1)
        panels.append({"cls": cls, "axis": ax, "errors": errors,
                       "truth": 0.0 if errors else result.truths[(cls, ax)].value,
                       "edges": edges, "samples": samples, "constants": constants})
    return panels


def plot_estimates(result, path: Path, fdata: dict | None = None):
    """Histograms of the estimates (errors, for per-trial truths) of every key, truth marked;
    returns the path with its caption (:func:`estimates_caption`, from what is drawn).

    Every variant of a panel is binned on the same edges (:data:`ESTIMATE_BINS` between the
    panel's smallest and largest value), so their histograms compare; a variant whose every
    trial gives the same value (an exact or a reference estimator, an input) has no histogram
    and is drawn as a vertical line of its colour, its value in the legend. Variants are
    outlines with their own line style and width (the widest first), so that identical
    histograms stay visible; a reference variant is marked in the legend; titles are wrapped,
    never clipped; a dimensionless class has no unit on its axis."""
    import textwrap


    plt = _plt()
    panels = estimates_panels(result)
    n = len(panels)
    ncol = min(3, n)
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.8 * ncol, 3.7 * nrow), squeeze=False)
    styles = [("-", 2.6), ("--", 1.8), (":", 1.4), ("-.", 1.2)]
    refs = set(getattr(result.study, "reference_variants", ()))
    variants = list(result.study.variants)
    for ax_, p in zip(axes.flat, panels):
        spec = result.class_spec(p["cls"])
        unit = unit_prose(spec.unit)
        unit_s = "" if unit in ("", "1") else f" ({unit})"
        ax_.axvline(p["truth"], color="k", lw=1, label="truth (error 0)" if p["errors"] else "truth")
        for var in [v for v in variants if v in p["samples"] or v in p["constants"]]:
            i = variants.index(var)
            ls, lw = styles[i % len(styles)]
            label = var + (" (reference)" if var in refs else "")
            if var in p["samples"]:
                ax_.hist(p["samples"][var], bins=p["edges"], histtype="step", linestyle=ls, linewidth=lw,
                         color=f"C{i}", label=label)
            else:
                # every trial the same value: a line, not a one-bin spike of arbitrary width
                ax_.axvline(p["constants"][var], color=f"C{i}", linestyle=ls if ls != "-" else (0, (6, 3)),
                            linewidth=lw, label=f"{label}: every trial {fmt(p['constants'][var])}")
        ax_.set_xlabel(f"estimate - truth{unit_s}" if p["errors"] else f"estimate{unit_s}")
        if p["samples"]:
            ax_.set_ylabel("trials")
        else:
            ax_.set_yticks([])  # lines only: no counts to read
            v = [p["truth"], *p["constants"].values()]
            pad = 0.5 * (max(v) - min(v)) or 0.5 * max(abs(max(v)), abs(min(v))) or 1.0
            ax_.set_xlim(min(v) - pad, max(v) + pad)
        ax_.set_title("\n".join(textwrap.wrap(f"{spec.label} ({p['axis']})", 48)), fontsize=9)
        ax_.legend(fontsize=7)
    for ax_ in list(axes.flat)[n:]:
        ax_.set_visible(False)
    caption = estimates_caption(result, fdata, panels) if fdata is not None else ""
    return save(fig, path, caption, dpi=110)


def estimates_caption(result, fdata: dict, panels: list[dict] | None = None) -> str:
    """The estimates figure's caption: what it shows (from ``panels``, what
    :func:`plot_estimates` draws: the shared bins, the constant samples drawn as lines) and
    its finding (from the findings)."""

    panels = estimates_panels(result) if panels is None else panels
    biased = sorted({f"{f['class']} ({f['axis']}) {f['variant']}" for f in fdata["findings"]
                     if f["rule"] == "fails"})
    binned = [p for p in panels if p["edges"] is not None]
    s = ("Each panel: the estimates of one class and axis over the trials (for per-trial truths, estimate "
         "minus the trial's truth), one outline per variant")
    if binned:
        widths = [float(p["edges"][1] - p["edges"][0]) for p in binned]
        s += (f", every variant of a panel on the same {ESTIMATE_BINS} bins between the panel's smallest and "
              f"largest value")
        if len(binned) == 1:
            spec = result.class_spec(binned[0]["cls"])
            s += f" (bin width {with_unit(widths[0], spec.unit)})"
    s += "; the black line is the truth."
    const = [(p, v, c) for p in panels for v, c in p["constants"].items()]
    if const:
        by_value: dict = {}
        for p, v, c in const:
            spec = result.class_spec(p["cls"])
            by_value.setdefault((p["cls"], p["axis"], c, spec.unit), []).append(v)
        items = [f"{cls} ({ax}) {' and '.join(vs)} {with_unit(c, unit)}"
                 for (cls, ax, c, unit), vs in by_value.items()]
        s += (" Every trial gives the same value, drawn as a vertical line of the variant's colour "
              "(no histogram): " + "; ".join(items) + ".")
    if biased:
        s += " Off the line by more than its tolerance (the verdict fails): " + ", ".join(biased) + "."
    else:
        s += " No variant's estimate fails its tolerance about the truth."
    return s


def world_line(scenario) -> str:
    """One line naming the world a run simulated: which ``[world.effects]`` were on
    (printed under the validate header and at the top of the report)."""

    effects = scenario_effects(scenario)
    if effects is None:
        return "world: the simulator's model (this study has no [world.effects])"
    on = effects.active()
    if not on:
        return "world: ideal (every [world.effects] magnitude is 0: the world the lab's model assumes)"
    return f"world: {len(on)} of {len(effects.names())} unmodelled effects on ({', '.join(on)})"


def write_report(result, out_dir: str | os.PathLike, *, claims=None) -> Path:
    """Write ``report.md``, ``estimates.png``, the study's sections and figures,
    ``scenario.toml`` and ``summary.json`` (the JSON result) into ``out_dir``. The report
    opens with the ledger of the study's claims judged in this run's world
    (:func:`budget.runner.ledger_view.ledger_section`; ``claims``: in place of the declared
    ones, e.g. with a user's tolerances)."""

    with staged_report(out_dir) as tmp:
        study = result.study

        fdata = findings_json(result, claims)
        lines = [f"# {study.title}: Monte Carlo validation", "",
                 f"Study `{study.name}` (seed document {study.seed_document}); scenario "
                 + (f"`{getattr(result.scenario, 'name', '')}` " if getattr(result.scenario, "name", "") else "")
                 + f"(hash `{study.scenario_hash(result.scenario)}`), "
                 f"seed {result.seed}, {result.trials} trials (stopped by {result.stopped_by}).", "",
                 world_line(result.scenario).replace("world: ", "World: ", 1) + ".", "",
                 *ledger_section(result, claims),
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
        lines += ["", "## Table", "", table_markdown(result, fdata), "", table_legend(), "",
                  "![estimates](estimates.png)", "",
                  plot_estimates(result, tmp / "estimates.png", fdata).caption, ""]
        for sec in capability(study, Presented).report_sections(result, tmp):
            lines += [f"## {sec.title}", "", sec.markdown, ""]
            for fig in sec.figures:
                lines += [f"![{Path(fig).stem}]({Path(fig).name})", ""]
        scenario_toml = study.scenario_text(result.scenario)
        lines += ["## Scenario", "", "```toml", scenario_toml.rstrip(), "```", ""]
        (tmp / "scenario.toml").write_text(scenario_toml)
        write_json_atomic(tmp / "summary.json", result.to_json())
        (tmp / "report.md").write_text("\n".join(lines))

        write_html(tmp / "report.md", tmp / "report.html", title=f"{study.title}: Monte Carlo validation")
    return Path(out_dir) / "report.md"


@contextlib.contextmanager
def staged_report(out_dir: str | os.PathLike):
    """The one way every report folder is written (validate, robustness, plan): a stale partial
    report a killed run left is removed (and said so), the report is written into a temporary
    sibling (yielded), and only when complete moved to ``out_dir`` by :func:`publish_report`;
    on any error the temporary folder is removed, so no half-written report is left."""
    import sys


    out = Path(out_dir)
    out.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_partials(out, echo=lambda msg: print(msg, file=sys.stderr))
    tmp = Path(tempfile.mkdtemp(prefix=partial_prefix(out), dir=out.parent))
    try:
        yield tmp
        publish_report(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def publish_report(tmp: Path, out: Path) -> None:
    """Move a report written in full into ``tmp`` to ``out``, replacing an earlier report (or an
    empty folder) whole; any other existing ``out`` is a user error naming ``--report``."""
    if out.exists():
        if out.is_dir() and (not any(out.iterdir()) or (out / "report.md").exists()):
            shutil.rmtree(out)
        else:

            raise UserInputError(f"--report {out}: exists and is not an earlier report; give a new folder")
    os.replace(tmp, out)


def write_outputs(res, *, json_out, report_dir, write_report=None) -> None:
    """A command's ``--json`` and ``--report`` together or not at all (staged, then moved into
    place: :class:`simcam.infra.outputs.StagedOutputs`), then the report's path on the terminal; the
    one way validate, robustness and plan write. ``write_report(res, folder)`` defaults to
    ``res.write_report(folder)``."""
    import click


    with StagedOutputs() as staged:
        if json_out:
            write_json_atomic(staged.file(json_out), res.to_json())
        if report_dir:
            folder = staged.folder(report_dir)
            (res.write_report(folder) if write_report is None else write_report(res, folder))
    if report_dir:
        click.echo(f"report: {Path(report_dir) / 'report.md'}")
