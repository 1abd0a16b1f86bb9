"""Report plots of the line-camera calibration (seed 004): the stars' tracks on the array,
the residual field before and after calibration, the LOS error field, coverage of the line;
the study's report section and the report pages of ``budget linecam simulate`` and
``calibrate`` (:func:`write_simulation_report`, :func:`write_calibration_report`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from budget import figures  # figures.save: looked up when called (a test spies on it)
from budget.figures import figure_markdown
from budget.runner.html import write_html
from budget.runner.numbers import fmt
from budget.runner.study import ReportSection

__all__ = ["plot_tracks", "plot_residuals", "plot_los_error", "plot_coverage", "report_sections", "plot_los_field",
           "write_simulation_report", "write_calibration_report"]


def _plt():
    return figures.plt()


def _rms(x) -> float:
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(x ** 2))) if x.size else float("nan")


def plot_tracks(ex: dict, path: Path) -> Path:
    """Where the identified stars crossed the line: sample vs time tag, one colour per pass."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 4.5))
    passes = np.unique(ex["pass"])
    for k in passes:
        m = ex["pass"] == k
        ax.plot(ex["sample"][m], ex["t_s"][m], ".", ms=4, label=f"pass {k}")
    ax.set_xlabel("sample along the line (px)")
    ax.set_ylabel("time tag (s after the orbit epoch)")
    ax.set_xlim(0, ex["n_pixels"])
    ax.set_title("identified stars on the TDI line (trial 0)")
    ax.legend(fontsize=7, ncol=4)
    s = np.asarray(ex["sample"])
    caption = (f"Trial 0: {s.size} identified star crossings in {passes.size} passes, from sample "
               f"{s.min():.0f} to {s.max():.0f} of the {ex['n_pixels']} px line.")
    return figures.save(fig, path, caption)


def plot_residuals(ex: dict, path: Path) -> Path:
    """Image residuals (px) of every star before calibration (nominal camera) and after; the
    variants' markers differ (open and filled) so that coinciding residuals stay visible."""
    plt = _plt()
    s = ex["sample"]
    n = s.size
    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    rms: dict = {}
    for i, (ax, name) in enumerate(zip(axes, ("along track (x)", "across track (y)"))):
        before = ex["residual_before_px"][i * n:(i + 1) * n]
        rms[("before", i)] = _rms(before)
        ax.plot(s, before, ".", ms=3, color="0.6", label="before (nominal camera)")
        for k, (v, r) in enumerate(ex["residual_after_px"].items()):
            after = r[i * n:(i + 1) * n]
            rms[(v, i)] = _rms(after)
            ax.plot(s, after, ("o", ".", "x", "+")[k % 4], ms=(5, 3, 4, 4)[k % 4], mfc="none" if k == 0 else None,
                    mew=0.8, color=f"C{k}", label=f"after: {v}")
        ax.set_ylabel(f"residual {name} (px)")
        ax.legend(fontsize=7)
    axes[-1].set_xlabel("sample along the line (px)")
    axes[0].set_title("star residuals before and after calibration (trial 0)")
    parts = [f"{v} {rms[(v, 0)]:.3f} / {rms[(v, 1)]:.3f} px" for v in ex["residual_after_px"]]
    caption = (f"Trial 0, rms residual along / across track: before calibration {rms[('before', 0)]:.2f} / "
               f"{rms[('before', 1)]:.2f} px; after: " + ", ".join(parts) + ".")
    return figures.save(fig, path, caption)


def plot_los_error(ex: dict, path: Path) -> Path:
    """Calibrated minus true look angles over the whole line with the stated 1-sigma band; the
    caption gives each variant's rms error and how much of the line its stated sigma covers."""
    plt = _plt()
    g = ex["grid"]
    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    parts = []
    for i, (ax, name) in enumerate(zip(axes, ("along track", "across track"))):
        for v, (ea, ec, sa, sc) in ex["los_error_arcsec"].items():
            e, s = (ea, sa) if i == 0 else (ec, sc)
            e, s = np.asarray(e), np.asarray(s)
            line, = ax.plot(g, e, label=f"{v}: error")
            ax.fill_between(g, -s, s, color=line.get_color(), alpha=0.15, label=f"{v}: stated 1 sigma")
            parts.append((v, name, _rms(e), float(np.mean(np.abs(e) <= s))))
        ax.set_ylabel(f"LOS error {name} (arcsec)")
        ax.axhline(0, color="k", lw=0.5)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    axes[-1].set_xlabel("detector along the line (px)")
    eb = ex["los_error_before_arcsec"]
    b_along, b_across = np.sqrt(np.mean(eb[0] ** 2)), np.sqrt(np.mean(eb[1] ** 2))
    axes[0].set_title("LOS field after calibration (trial 0); before: rms "
                      f"{b_along:.1f}\" along, {b_across:.1f}\" across")
    caption = (f"Trial 0, calibrated minus true look angle over the line (before calibration: rms "
               f"{b_along:.1f} / {b_across:.1f} arcsec along / across). After: "
               + "; ".join(f"{v} {name} rms {r:.3f} arcsec, within its stated 1 sigma over {100 * c:.0f} % "
                           "of the line" for v, name, r, c in parts)
               + " (nominal 68 % for a right 1 sigma).")
    return figures.save(fig, path, caption)


def plot_coverage(ex: dict, path: Path) -> Path:
    """Stars per bin of the line (step 7's coverage)."""
    plt = _plt()
    bins = np.linspace(0, ex["n_pixels"], ex["coverage_bins"] + 1)
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.hist([ex["sample"][ex["pass"] == k] for k in np.unique(ex["pass"])], bins=bins, stacked=True,
            label=[f"pass {k}" for k in np.unique(ex["pass"])])
    counts, _ = np.histogram(ex["sample"], bins=bins)
    ax.set_xlabel("sample along the line (px)")
    ax.set_ylabel("identified stars per bin")
    ax.set_title(f"coverage of the line: {np.mean(counts > 0):.0%} of {ex['coverage_bins']} bins hold a star")
    ax.legend(fontsize=7, ncol=4)
    caption = (f"{np.mean(counts > 0):.0%} of the {ex['coverage_bins']} bins of the line hold at least one "
               f"identified star (stacked by pass); the emptiest bin holds {counts.min()}, the fullest "
               f"{counts.max()}.")
    return figures.save(fig, path, caption)


def example_markdown(ex: dict) -> str:
    sep = ex["separability"]
    null = "; ".join(" ".join(f"{c:+.2f} {p}" for p, c in d.items()) for d in sep["null_space"]) or "none"
    lines = [
        f"Trial 0: {ex['windows']} star windows imaged, {ex['centroids']} centroids, {ex['identified']} "
        f"identified ({ex['unmatched']} unmatched: stars fainter than the lab's limit; {ex['ambiguous']} "
        "ambiguous or duplicated, dropped).",
        "",
        "| variant | rms residual (px) | iterations | condition number (normal matrix) |",
        "|---|---|---|---|",
    ]
    for v in ex["sigma0_px"]:
        lines.append(f"| {v} | {ex['sigma0_px'][v]:.3f} | {ex['iterations'][v]} | {fmt(ex['condition'][v], 3)} |")
    lines += ["", f"Plan separability (all ten parameters, column-normalised Jacobian): condition "
              f"{fmt(sep['condition'], 3)}; unobservable combinations: {null}. Parameters in them "
              f"({', '.join(sep['inseparable']) or 'none'}) are a gauge: not determined, reported without "
              "a sigma; what the stars determine of them is the class `gauge_combination` "
              "(pitch + dx0/F, roll - dy0/F). Compare LOS fields, not these parameters."]
    return "\n".join(lines)


def report_sections(result, out_dir: Path) -> list[ReportSection]:
    ex = result.example.extra if result.example is not None else {}
    if not ex:
        return []
    out_dir.mkdir(parents=True, exist_ok=True)
    figs = [plot_tracks(ex, out_dir / "linecam_tracks.png"), plot_residuals(ex, out_dir / "linecam_residuals.png"),
            plot_los_error(ex, out_dir / "linecam_los_error.png"), plot_coverage(ex, out_dir / "linecam_coverage.png")]
    # the figures are placed in the text, each with its caption under it (not repeated in
    # ``figures``: the runner would draw them a second time)
    md = example_markdown(ex) + "\n\n" + figure_markdown(figs)
    return [ReportSection(title="Line camera: the example trial", markdown=md, figures=[])]


def plot_los_field(payload: dict, path: Path) -> Path:
    """Calibrated look angles minus nominal over the line, with the stated 1-sigma band
    (real data: no truth to compare with)."""
    plt = _plt()
    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for m, r in payload["methods"].items():
        L = r["los_field"]
        g = np.asarray(L["sample_px"])
        for ax, key, sk in ((axes[0], "along_minus_nominal_arcsec", "sigma_along_arcsec"),
                            (axes[1], "across_minus_nominal_arcsec", "sigma_across_arcsec")):
            v, s = np.asarray(L[key]), np.asarray(L[sk])
            line, = ax.plot(g, v, label=m)
            ax.fill_between(g, v - s, v + s, color=line.get_color(), alpha=0.2)
    axes[0].set_ylabel("along-track look angle\nminus nominal (arcsec)")
    axes[1].set_ylabel("across-track look angle\nminus nominal (arcsec)")
    axes[1].set_xlabel("detector along the line (px)")
    axes[0].set_title("calibrated LOS field (band: stated 1 sigma)")
    axes[0].legend(fontsize=7)
    parts = []
    for m, r in payload["methods"].items():
        L = r["los_field"]
        parts.append(f"{m}: up to {np.max(np.abs(L['along_minus_nominal_arcsec'])):.2f} / "
                     f"{np.max(np.abs(L['across_minus_nominal_arcsec'])):.2f} arcsec from nominal, stated 1 sigma "
                     f"up to {np.max(L['sigma_along_arcsec']):.3f} / {np.max(L['sigma_across_arcsec']):.3f}")
    return figures.save(fig, path, "Calibrated look angles minus nominal, along / across track (no truth to compare "
                "with): " + "; ".join(parts) + ".")


def write_simulation_report(example: dict, folder: Path) -> Path:
    """``simulate.md`` (and its twin ``simulate.html``) in ``folder``: the figures of one
    simulated calibration (``example``: :func:`budget.linecam.study.trial_extra`)."""
    d = Path(folder)
    d.mkdir(parents=True, exist_ok=True)
    figs = [plot_tracks(example, d / "tracks.png"), plot_residuals(example, d / "residuals.png"),
            plot_los_error(example, d / "los_error.png"), plot_coverage(example, d / "coverage.png")]
    (d / "simulate.md").write_text("# Line camera: one simulated calibration\n\n" + figure_markdown(figs) + "\n")
    write_html(d / "simulate.md")  # its self-contained twin, simulate.html
    return d / "simulate.md"


def write_calibration_report(result, payload: dict, folder: Path) -> Path:
    """``calibrate.md`` (and its twin ``calibrate.html``) in ``folder``: the table of each
    method's parameters (from ``payload``, :func:`budget.linecam.calibrate.calibration_payload`)
    and the figures of the table's calibration ``result``
    (:class:`budget.linecam.calibrate.TableCalibration`)."""
    d = Path(folder)
    d.mkdir(parents=True, exist_ok=True)
    obs, scn = result.table.observations, result.scenario
    ex = {"sample": obs.sample, "t_s": result.table.t_s, "pass": obs.pass_index, "n_pixels": scn.camera.n_pixels,
          "coverage_bins": scn.lab.coverage_bins, "residual_before_px": result.residuals_before_px(),
          "residual_after_px": {m: c.residuals_px for m, c in result.calibrations.items() if m != "lookangle"}}
    figs = [plot_tracks(ex, d / "tracks.png"), plot_residuals(ex, d / "residuals.png"),
            plot_los_field(payload, d / "los_field.png"), plot_coverage(ex, d / "coverage.png")]
    rows = ["| method | parameter | value | 1-sigma | unit |", "|---|---|---|---|---|"]
    for m, pm in payload["methods"].items():
        for p in pm.get("solved", []):
            rows.append(f"| {m} | {p} | not determined | - | {pm['units'][p]} |" if p in pm["not_determined"]
                        else f"| {m} | {p} | {fmt(pm['theta'][p], 5)} | {fmt(pm['sigma'][p], 3)} | {pm['units'][p]} |")
        for name, cmb in pm.get("determined_combinations", {}).items():
            rows.append(f"| {m} | {name} | {fmt(cmb['value'], 5)} | {fmt(cmb['sigma'], 3)} | arcsec |")
    note = ("Parameters this plan cannot separate are not determined (no sigma); the combinations the "
            "stars do determine are listed in their place." if any(
                pm.get("not_determined") for pm in payload["methods"].values()) else "")
    (d / "calibrate.md").write_text(f"# Line camera calibration from {result.table.source}\n\n" + "\n".join(rows)
                                    + "\n\n" + (note + "\n\n" if note else "") + figure_markdown(figs) + "\n")
    write_html(d / "calibrate.md")  # its self-contained twin, calibrate.html
    return d / "calibrate.md"
