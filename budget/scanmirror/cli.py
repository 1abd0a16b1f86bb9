"""``budget scanmirror simulate``: the default (or a user's) timeline, pointing and ground errors
before and after compensation, as JSON and a report with plots."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from budget.figures import figure_markdown
from budget.runner.html import write_html
from budget.scanmirror.plots import plot_deviation_timeline, plot_ground_error_maps, plot_scan_pattern
from budget.scanmirror.study import STUDY
from simcam.infra.cli import overwrite_option, write_json_atomic
from simcam.infra.outputs import StagedOutputs, check_run_outputs
from simcam.units import RAD_PER_ARCSEC

__all__ = ["commands", "simulate_command", "simulate", "write_simulate_report"]


def simulate(scenario, *, seed: int = 0, source: str | None = None) -> tuple[dict, object, dict]:
    """Run the timeline once (the draws of trial ``seed``'s stream, ground points every
    ``compensation.ground_step_s``); returns (JSON summary, setup, raw output)."""
    from budget.scanmirror.pipeline import Setup, run

    setup = Setup(scenario, scenario.compensation.ground_step_s, source=source or scenario.source)
    out = run(setup, np.random.default_rng(np.random.SeedSequence(seed)), keep_series=True)
    lat0, lon0 = setup.world.latlon(setup.g0)
    summary = {
        "scenario_hash": scenario.hash, "seed": seed, "duration_s": setup.world.duration_s,
        "ground_step_s": scenario.compensation.ground_step_s,
        "dtau_true_arcsec": (out["dtau_true"] / RAD_PER_ARCSEC).tolist(),
        "dtau_estimate_arcsec": {k: (v / RAD_PER_ARCSEC).tolist() for k, v in out["dtau"].items()},
        "dtau_sigma_arcsec": (out["dtau_sigma"] / RAD_PER_ARCSEC).tolist(),
        "dwells": [{"t_s": [float(d.frame_t_s[0]), float(d.frame_t_s[-1])], "hip": d.hip.tolist(),
                    "v_mag": np.round(d.v_mag, 2).tolist()} for d in setup.dwells],
        "scans": {},
        "timeline": {"t_s": setup.t_s.tolist(), "scan": setup.scan.tolist(),
                     "alpha_deg": np.rad2deg(setup.alpha0).tolist(), "beta_deg": np.rad2deg(setup.beta0).tolist(),
                     "lat0_deg": np.rad2deg(lat0).tolist(), "lon0_deg": np.rad2deg(lon0).tolist()},
    }
    for s, errs in out["errors"].items():
        row = {}
        for name in ("uncompensated", "without_estimate", "published", "improved"):
            lat, lon = errs[name]
            row[name] = {"lat_max_deg": float(np.abs(lat).max()), "lon_max_deg": float(np.abs(lon).max()),
                         "lat_rms_deg": float(np.sqrt(np.mean(lat**2))), "lon_rms_deg": float(np.sqrt(np.mean(lon**2)))}
            summary["timeline"][f"scan{s}_{name}_lat_err_deg"] = lat.tolist()
            summary["timeline"][f"scan{s}_{name}_lon_err_deg"] = lon.tolist()
        summary["scans"][str(s)] = row
    return summary, setup, out


def write_simulate_report(summary, setup, out, report_dir) -> Path:
    d = Path(report_dir)
    d.mkdir(parents=True, exist_ok=True)
    w = setup.world
    t = np.arange(0.0, w.duration_s, 0.1)
    plan = w.plan(t)
    sc = setup.scenario
    figs = [plot_ground_error_maps(w, setup, out, d / "ground_error_maps.png")]
    ser = out["series"]
    dx, dy = ser["dtau_x_all"], ser["dtau_y_all"]
    dwell_end = float(setup.dwells[-1].frame_t_s[-1]) if setup.dwells else float(t[0])
    figs.append(plot_deviation_timeline(ser["t_all_s"], dx, dy, {k: out["dtau"][k] for k in ("published", "improved")},
                                        dwell_end, d / "deviation_timeline.png"))
    figs.append(plot_scan_pattern(w, t, plan.alpha_rad, plan.beta_rad, plan.scan, plan.star_dwell,
                                  d / "scan_pattern.png"))
    lines = ["# Scan-mirror timeline (seed 003)", "", f"Scenario hash `{sc.hash}`, seed {summary['seed']}, "
             f"ground points every {summary['ground_step_s']} s.", "",
             f"Injected deviation at the dwell: dtau = ({summary['dtau_true_arcsec'][0]:.2f}, "
             f"{summary['dtau_true_arcsec'][1]:.2f}) arcsec; published estimate "
             f"({summary['dtau_estimate_arcsec']['published'][0]:.2f}, {summary['dtau_estimate_arcsec']['published'][1]:.2f}), "
             f"improved ({summary['dtau_estimate_arcsec']['improved'][0]:.2f}, "
             f"{summary['dtau_estimate_arcsec']['improved'][1]:.2f}) +- ({summary['dtau_sigma_arcsec'][0]:.2f}, "
             f"{summary['dtau_sigma_arcsec'][1]:.2f}) arcsec.", "",
             "| scan | compensation | max lat err (deg) | max lon err (deg) | rms lat | rms lon |",
             "|---|---|---|---|---|---|"]
    for s, row in summary["scans"].items():
        for name, r in row.items():
            lines.append(f"| {s} | {name} | {r['lat_max_deg']:.5f} | {r['lon_max_deg']:.5f} | "
                         f"{r['lat_rms_deg']:.5f} | {r['lon_rms_deg']:.5f} |")
    lines += ["", "Scan 1 has no deviation estimate yet: its `published`/`improved` rows compensate with "
              "dtau = 0, as the paper does.", ""]
    lines += [figure_markdown(figs)]  # each figure with its caption under it
    (d / "report.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    write_html(d / "report.md")  # its self-contained twin, report.html
    return d / "report.md"


def simulate_command() -> click.Command:
    @click.command("simulate", help="Simulate the scan-mirror timeline of SCENARIO (default: the embedded "
                                    "one): pointing, star dwell, deviation estimates, ground errors before and "
                                    "after compensation.")
    @click.argument("scenario", required=False, type=click.Path(dir_okay=False))
    @click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True)
    @click.option("--json", "json_out", type=click.Path(dir_okay=False), help="Write the timeline as JSON.")
    @click.option("--report", "report_dir", type=click.Path(file_okay=False), help="Write a report with plots.")
    @overwrite_option
    def cmd(scenario, seed, json_out, report_dir, overwrite):
        check_run_outputs(json_out=json_out, report_dir=report_dir, inputs=(scenario,), overwrite=overwrite)  # before the work
        scn = STUDY.load_scenario(scenario)
        source = scenario or "embedded scanmirror default"
        summary, setup, out = simulate(scn, seed=seed, source=source)
        for s, row in summary["scans"].items():
            for name, r in row.items():
                click.echo(f"scan {s} {name:17s} max |lat err| {r['lat_max_deg']:.5f} deg  "
                           f"max |lon err| {r['lon_max_deg']:.5f} deg")
        with StagedOutputs() as staged:  # the JSON and the report appear together or not at all
            if json_out:
                write_json_atomic(staged.file(json_out), summary)
            if report_dir:
                write_simulate_report(summary, setup, out, staged.folder(report_dir))
        if report_dir:
            click.echo(f"report: {Path(report_dir) / 'report.md'}")

    return cmd


def commands() -> list[click.Command]:
    """The scanmirror study's own commands: ``simulate``."""
    return [simulate_command()]
