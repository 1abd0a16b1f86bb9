"""Commands of the linecam study: ``budget linecam simulate`` and ``budget linecam calibrate``.

``calibrate`` runs the lab's estimators on a table of observed stars
(:mod:`budget.linecam.table`), so a real camera can be calibrated; ``simulate`` writes exactly
that table for a simulated calibration (``--csv``), so the two commands round-trip. The
camera's nominal model (focal length, pitch, number of detectors, line position) and the
lab's settings come from the scenario (default: the embedded one).

The commands read their options, call the Python entries
(:func:`budget.linecam.simulated.simulate_trial`, :func:`budget.linecam.calibrate.calibrate_file`),
print the lines of the result and write its outputs.
"""

from __future__ import annotations

from pathlib import Path

import click

from simcam.infra.cli import overwrite_option, write_json_atomic
from simcam.infra.outputs import StagedOutputs, apply_umask, check_run_outputs

from .report import write_calibration_report, write_simulation_report
from .study import STUDY
from .table import parse_epoch, write_observation_csv

__all__ = ["commands"]


def _scenario(path):
    return STUDY.load_scenario(path)


# --------------------------------------------------------------------------- simulate
@click.command("simulate", help="Simulate one star-observation calibration (one trial of SCENARIO, default: "
                                "the embedded one) and compare the calibrated LOS field with the truth.")
@click.argument("scenario", required=False, type=click.Path(dir_okay=False))
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True)
@click.option("--trial", "k", type=click.IntRange(min=0), default=0, show_default=True,
              help="Trial number (draws from SeedSequence(seed, spawn_key=(trial,))).")
@click.option("--csv", "csv_out", type=click.Path(dir_okay=False),
              help="Write the identified observations as a table for 'budget linecam calibrate'.")
@click.option("--json", "json_out", type=click.Path(dir_okay=False), help="Write the results as JSON.")
@click.option("--report", "report_dir", type=click.Path(file_okay=False), help="Write plots and a Markdown page.")
@overwrite_option
def simulate_cmd(scenario, seed, k, csv_out, json_out, report_dir, overwrite):
    from .simulated import simulate_trial

    check_run_outputs(json_out=json_out, report_dir=report_dir, files={"--csv": csv_out}, inputs=(scenario,),
                      overwrite=overwrite)
    scn = _scenario(scenario)
    result = simulate_trial(scn, seed=seed, trial=k)
    for line in result.summary_lines():
        click.echo(line)
    with StagedOutputs() as staged:  # the table, the JSON and the report appear together or not at all
        if csv_out:
            tmp = staged.file(csv_out)
            write_observation_csv(scn, result.simulation, tmp)
            apply_umask(tmp, is_dir=False)
        if json_out:
            write_json_atomic(staged.file(json_out), result.to_json())
        if report_dir:
            write_simulation_report(result.example, staged.folder(report_dir))
    if csv_out:
        click.echo(f"observations: {csv_out}")
    if report_dir:
        click.echo(f"report: {Path(report_dir) / 'simulate.md'}")


# --------------------------------------------------------------------------- calibrate
@click.command("calibrate", help="Calibrate a line camera from OBSERVATIONS (CSV: time_s, sample_px, hip, "
                                 "q_w..q_z, pos_*_km, vel_*_km_s; see docs/linecam.md) with the nominal "
                                 "camera of --scenario.")
@click.argument("observations", type=click.Path(dir_okay=False))
@click.option("--scenario", "scenario", type=click.Path(dir_okay=False), default=None,
              help="Scenario with the camera's nominal model and the lab settings (default: embedded).")
@click.option("--epoch", default=None, help="UTC epoch of time_s (ISO; default: the scenario's orbit.epoch_utc).")
@click.option("--method", type=click.Choice(["all", "published", "improved", "lookangle"]), default="all",
              show_default=True, help="Estimator(s): the patent's steps, the joint fit, the look-angle polynomials.")
@click.option("--solve", default=None,
              help="Comma-separated parameters for the improved fit (others held at nominal), e.g. "
                   "'yaw,df,k1,k2,p1,p2'; an inseparable set is an error. Default: all ten, gauge removed.")
@click.option("--json", "json_out", type=click.Path(dir_okay=False), help="Write the results as JSON.")
@click.option("--report", "report_dir", type=click.Path(file_okay=False), help="Write plots and a Markdown page.")
@overwrite_option
def calibrate_cmd(observations, scenario, epoch, method, solve, json_out, report_dir, overwrite):
    from .calibrate import calibrate_file, parse_solve

    # before any work: --json/--report are new files/folders or earlier outputs, not a
    # device and not the observation table or the scenario
    check_run_outputs(json_out=json_out, report_dir=report_dir, inputs=(observations, scenario), overwrite=overwrite)
    scn = _scenario(scenario)
    names = parse_solve(solve, field="--solve")
    epoch_time = None if epoch is None else parse_epoch(epoch, field="--epoch")
    result = calibrate_file(observations, scn, epoch=epoch_time, method=method, solve=names)
    for line in result.summary_lines():
        click.echo(line)
    payload = result.to_json()
    with StagedOutputs() as staged:  # the JSON and the report appear together or not at all
        if json_out:
            write_json_atomic(staged.file(json_out), payload)
        if report_dir:
            write_calibration_report(result, payload, staged.folder(report_dir))
    if report_dir:
        click.echo(f"report: {Path(report_dir) / 'calibrate.md'}")


def commands() -> list[click.Command]:
    """The linecam study's own commands: ``simulate`` and ``calibrate``."""
    return [simulate_cmd, calibrate_cmd]


@click.group("linecam")
def _local_group():
    """Local group for manual testing: python -m budget.linecam.cli ..."""


for _c in commands():
    _local_group.add_command(_c)

if __name__ == "__main__":  # pragma: no cover
    from simcam.infra.cli import run_cli

    run_cli(_local_group)
