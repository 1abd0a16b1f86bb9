"""``budget scanmirror simulate`` without the command line: one run of the scan-mirror
timeline (:func:`simulate`), the JSON summary the command writes (:func:`simulate_payload`)
and its report with plots (:func:`write_simulate_report`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from budget.figures import figure_markdown
from budget.runner.html import write_html
from budget.scanmirror.pipeline import ScanOutcome, Setup, run
from budget.scanmirror.plots import plot_deviation_timeline, plot_ground_error_maps, plot_scan_pattern
from simcam.units import RAD_PER_ARCSEC

__all__ = ["SimulatedTimeline", "simulate", "simulate_payload", "write_simulate_report", "COMPENSATIONS"]

#: the compensations the summary lists for every area scan, in its order
COMPENSATIONS = ("uncompensated", "without_estimate", "published", "improved")


@dataclass(frozen=True)
class SimulatedTimeline:
    """One run of the timeline (:func:`simulate`).

    Attributes
    ----------
    scenario : simcam.scanmirror.scenario.ScanMirrorScenario
        The scenario run.
    seed : int
        The seed of the run's stream (``SeedSequence(seed)``).
    setup : budget.scanmirror.pipeline.Setup
        Ground points every ``compensation.ground_step_s`` over every area scan.
    outcome : budget.scanmirror.pipeline.ScanOutcome
        The run, with its timeline series.
    """

    scenario: object
    seed: int
    setup: Setup
    outcome: ScanOutcome

    def to_json(self) -> dict:
        """The JSON summary ``budget scanmirror simulate --json`` writes (:func:`simulate_payload`)."""
        return simulate_payload(self)


def simulate(scenario, *, seed: int = 0, source: str | None = None) -> SimulatedTimeline:
    """Run the timeline once (the draws of ``SeedSequence(seed)``, ground points every
    ``compensation.ground_step_s``); ``source`` names the scenario in errors (default: its
    own source)."""
    setup = Setup(scenario, scenario.compensation.ground_step_s, source=source or scenario.source)
    outcome = run(setup, np.random.default_rng(np.random.SeedSequence(seed)), keep_series=True)
    return SimulatedTimeline(scenario=scenario, seed=seed, setup=setup, outcome=outcome)


def simulate_payload(timeline: SimulatedTimeline) -> dict:
    """The JSON summary of a run: the deviation (injected, estimated, stated sigma; arcsec),
    the dwells, per area scan the largest and rms ground errors of each compensation, and
    the timeline (the nominal pointing and ground points, each compensation's errors)."""
    scenario, setup, out = timeline.scenario, timeline.setup, timeline.outcome
    lat0, lon0 = setup.world.latlon(setup.g0)
    summary = {
        "scenario_hash": scenario.hash, "seed": timeline.seed, "duration_s": setup.world.duration_s,
        "ground_step_s": scenario.compensation.ground_step_s,
        "dtau_true_arcsec": (out.dtau_true_rad / RAD_PER_ARCSEC).tolist(),
        "dtau_estimate_arcsec": {k: (v / RAD_PER_ARCSEC).tolist() for k, v in out.dtau_rad.items()},
        "dtau_sigma_arcsec": (out.dtau_sigma_rad / RAD_PER_ARCSEC).tolist(),
        "dwells": [{"t_s": [float(d.frame_t_s[0]), float(d.frame_t_s[-1])], "hip": d.hip.tolist(),
                    "v_mag": np.round(d.v_mag, 2).tolist()} for d in setup.dwells],
        "scans": {},
        "timeline": {"t_s": setup.t_s.tolist(), "scan": setup.scan.tolist(),
                     "alpha_deg": np.rad2deg(setup.alpha0).tolist(), "beta_deg": np.rad2deg(setup.beta0).tolist(),
                     "lat0_deg": np.rad2deg(lat0).tolist(), "lon0_deg": np.rad2deg(lon0).tolist()},
    }
    for s, errs in out.errors.items():
        row = {}
        for name in COMPENSATIONS:
            lat, lon = errs[name].lat_deg, errs[name].lon_deg
            row[name] = {"lat_max_deg": float(np.abs(lat).max()), "lon_max_deg": float(np.abs(lon).max()),
                         "lat_rms_deg": float(np.sqrt(np.mean(lat**2))), "lon_rms_deg": float(np.sqrt(np.mean(lon**2)))}
            summary["timeline"][f"scan{s}_{name}_lat_err_deg"] = lat.tolist()
            summary["timeline"][f"scan{s}_{name}_lon_err_deg"] = lon.tolist()
        summary["scans"][str(s)] = row
    return summary


def write_simulate_report(timeline: SimulatedTimeline, summary: dict, report_dir) -> Path:
    """``report.md`` (and its twin ``report.html``) in ``report_dir``: the deviation and its
    estimates, the table of ground errors (``summary``, :func:`simulate_payload`) and the
    figures (ground error maps, deviation timeline, scan pattern)."""
    d = Path(report_dir)
    d.mkdir(parents=True, exist_ok=True)
    setup, out = timeline.setup, timeline.outcome
    w = setup.world
    t = np.arange(0.0, w.duration_s, 0.1)
    plan = w.plan(t)
    sc = setup.scenario
    figs = [plot_ground_error_maps(w, setup, out.errors, d / "ground_error_maps.png")]
    ser = out.series
    dwell_end = float(setup.dwells[-1].frame_t_s[-1]) if setup.dwells else float(t[0])
    figs.append(plot_deviation_timeline(ser.t_all_s, ser.dtau_x_all_rad, ser.dtau_y_all_rad,
                                        {k: out.dtau_rad[k] for k in ("published", "improved")},
                                        dwell_end, d / "deviation_timeline.png"))
    figs.append(plot_scan_pattern(w, t, plan.alpha_rad, plan.beta_rad, plan.scan, plan.star_dwell,
                                  d / "scan_pattern.png"))
    est = summary["dtau_estimate_arcsec"]
    lines = ["# Scan-mirror timeline (seed 003)", "", f"Scenario hash `{sc.hash}`, seed {summary['seed']}, "
             f"ground points every {summary['ground_step_s']} s.", "",
             f"Injected deviation at the dwell: dtau = ({summary['dtau_true_arcsec'][0]:.2f}, "
             f"{summary['dtau_true_arcsec'][1]:.2f}) arcsec; published estimate "
             f"({est['published'][0]:.2f}, {est['published'][1]:.2f}), "
             f"improved ({est['improved'][0]:.2f}, "
             f"{est['improved'][1]:.2f}) +- ({summary['dtau_sigma_arcsec'][0]:.2f}, "
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
