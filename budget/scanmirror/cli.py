"""``budget scanmirror simulate``: the default (or a user's) timeline, pointing and ground errors
before and after compensation, as JSON and a report with plots (the work is
:mod:`budget.scanmirror.timeline`'s; this module reads the options and writes the outputs)."""

from __future__ import annotations

from pathlib import Path

import click

from budget.scanmirror.study import STUDY
from simcam.infra.cli import overwrite_option, write_json_atomic
from simcam.infra.outputs import StagedOutputs, check_run_outputs

__all__ = ["commands", "simulate_command"]


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
        from budget.scanmirror.timeline import simulate, write_simulate_report

        # before the work
        check_run_outputs(json_out=json_out, report_dir=report_dir, inputs=(scenario,), overwrite=overwrite)
        scn = STUDY.load_scenario(scenario)
        timeline = simulate(scn, seed=seed, source=scenario or "embedded scanmirror default")
        summary = timeline.to_json()
        for s, row in summary["scans"].items():
            for name, r in row.items():
                click.echo(f"scan {s} {name:17s} max |lat err| {r['lat_max_deg']:.5f} deg  "
                           f"max |lon err| {r['lon_max_deg']:.5f} deg")
        with StagedOutputs() as staged:  # the JSON and the report appear together or not at all
            if json_out:
                write_json_atomic(staged.file(json_out), summary)
            if report_dir:
                write_simulate_report(timeline, summary, staged.folder(report_dir))
        if report_dir:
            click.echo(f"report: {Path(report_dir) / 'report.md'}")

    return cmd


def commands() -> list[click.Command]:
    """The scanmirror study's own commands: ``simulate``."""
    return [simulate_command()]
