"""``budget <study> validate``: the runner's Monte Carlo validation of a study from the command
line, and the steps it is made of (:func:`run_and_write`, :func:`ideal_world_scenario`) for a
study's own ``validate`` (built with :func:`validate_command_for`) and for scripts.
"""

from __future__ import annotations

import sys

import click

from budget.arguments import checked_command
from budget.runner import (  # their functions looked up when called (tests replace them)
    report,
    run,
)
from budget.runner.claims import study_claims
from budget.runner.executors import default_workers
from budget.runner.findings import findings_json, findings_lines
from budget.runner.ledger_view import ledger_lines
from budget.runner.registry import get_study, summary
from budget.runner.report import format_table, world_line, write_outputs
from budget.runner.requirements import split_tolerance_options, with_requirements
from budget.runner.robustness import scenario_with_effects
from simcam.dotted import scenario_with
from simcam.effects import scenario_effects
from simcam.infra.cli import overwrite_option
from simcam.infra.errors import UserInputError
from simcam.infra.outputs import check_run_outputs

__all__ = ["ideal_world_scenario", "run_and_write", "validate_command_for"]


def run_and_write(study, scenario, *, trials=None, tolerance=None, seed=0, workers=None, scheduler=None,
                  dask_local=None, json_out=None, report_dir=None, progress=None, more_lines=None,
                  overwrite=False, truth_size="adaptive", inputs=(), requirements=None):
    """What ``validate`` does once its options are read: run the study through the runner,
    print the header, the ledger of the paper's claims judged in this run's world, the table
    (then ``more_lines(result)``, if given: a study's own summary lines), write the JSON and
    the report. Returns the :class:`StudyResult`.

    ``requirements``: ``{class: value}`` from ``--tolerance CLASS=VALUE``, the claims' tolerances
    in place of the declared ones (:mod:`budget.runner.requirements`).

    ``workers=None`` (and no Dask) means all cores; ``progress=None`` a bar only on a terminal;
    ``overwrite`` lets the report replace a folder that is not an earlier report;
    ``truth_size``: ``adaptive`` (truths sized to the run, :func:`budget.runner.run.run_study`)
    or ``fixed`` (the scenario's own truth sizes).
    """
    if progress is None:
        progress = sys.stderr.isatty()
    check_run_outputs(json_out=json_out, report_dir=report_dir, inputs=inputs, overwrite=overwrite)  # before the work
    if workers is None and scheduler is None and dask_local is None:
        workers = default_workers()
    res = run.run_study(study, scenario, trials=trials, tolerance=tolerance, seed=seed, workers=workers,
                    scheduler=scheduler, dask_local=dask_local, progress=progress, truth_size=truth_size)
    click.echo(f"{study.title}: scenario {getattr(scenario, 'name', '')} (hash {study.scenario_hash(scenario)}), "
               f"seed {seed}: {res.trials} trials (stopped by {res.stopped_by}) in {res.elapsed_s:.1f} s "
               f"on {res.executor}")
    click.echo(world_line(scenario))
    claims = with_requirements(study_claims(study, scenario), requirements or {})
    for line in ledger_lines(res, claims):  # the paper's claims first
        click.echo(line)
    fdata = findings_json(res, claims)
    click.echo(format_table(res, fdata))
    click.echo("\n".join(findings_lines(res, fdata)))  # the findings in words
    for line in (more_lines(res) if more_lines is not None else []):
        click.echo(line)
    write_outputs(res, json_out=json_out, report_dir=report_dir,
                  write_report=(lambda r, folder: report.write_report(r, folder, claims=claims)) if requirements
                  else report.write_report)
    return res


def claim_classes(study, scenario) -> tuple[str, ...]:
    """The classes ``--tolerance CLASS=VALUE`` may name: those the study's claims map to."""
    return tuple(dict.fromkeys(c.class_name for c in study_claims(study, scenario) if c.testable))


def ideal_world_scenario(study, scenario, *, source: str):
    """``scenario`` with every ``world.effects`` magnitude 0 (``--ideal-world``); a study
    without world effects is a one-line user error."""
    effects = scenario_effects(scenario)
    if effects is None:
        raise UserInputError(f"--ideal-world: the {study.name} study has no [world.effects]")
    return scenario_with_effects(study, scenario, {n: 0.0 for n in effects.names()},
                                 source=f"{source} (--ideal-world)")


def pinned_instrument_scenario(study, scenario, instrument_seed: int, *, source: str):
    """``scenario`` with ``validation.instrument_seed`` set: one instrument for every trial
    (``--instrument-seed``)."""
    return scenario_with(scenario, {"validation.instrument_seed": int(instrument_seed)},
                         from_dict=study.from_dict, where=f"{source} (--instrument-seed)")


def validate_command_for(study_name: str, *, name: str = "validate", help_text: str | None = None,
                         more_lines=None) -> click.Command:
    """``validate [SCENARIO] --trials --tolerance --seed --workers --scheduler --dask-local --json --report``.

    ``more_lines(result)``: a study's own summary lines printed after the table (a study
    whose command module returns its own ``validate`` built here replaces the plain one).
    """
    @click.command(name, help=help_text or f"Monte Carlo validation of the {study_name} study on SCENARIO "
                                           f"(default: its embedded scenario). {summary(study_name)}")
    @click.argument("scenario", required=False, type=click.Path(dir_okay=False))
    @click.option("--trials", type=click.IntRange(min=2), default=None,
                  help="Number of Monte Carlo trials (default: the scenario's validation.trials).")
    @click.option("--tolerance", "tolerances", multiple=True, metavar="SE | CLASS=VALUE",
                  help="A bare number: stop when every Monte Carlo standard error is below it (in the classes' "
                       "unit). CLASS=VALUE (repeatable): your requirement on CLASS, in its unit, replaces the "
                       "declared tolerance of the paper's claims on it (docs/claims.md).")
    @click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True)
    @click.option("--truth-size", "truth_size", type=click.Choice(["adaptive", "fixed"]), default="adaptive",
                  show_default=True,
                  help="adaptive: each sampled truth's standard error about a quarter of what the trials "
                       "resolve (the scenario's truth sizes the most); fixed: the scenario's truth sizes.")
    @click.option("--workers", type=click.IntRange(min=1), default=None,
                  help="Local worker processes (default: all cores). Results do not depend on it.")
    @click.option("--scheduler", default=None, help="Run the trials on a Dask cluster (tcp://HOST:PORT).")
    @click.option("--dask-local", type=int, default=None, help="Run on a Dask LocalCluster of N processes.")
    @click.option("--json", "json_out", type=click.Path(dir_okay=False), help="Write the results as JSON.")
    @click.option("--report", "report_dir", type=click.Path(file_okay=False), help="Write a Markdown report with plots.")
    @overwrite_option
    @click.option("--ideal-world", is_flag=True, default=False,
                  help="Turn every [world.effects] magnitude to 0: the world the lab's model assumes "
                       "(default: the scenario's world, realistic in the embedded defaults).")
    @click.option("--instrument-seed", "instrument_seed", type=click.IntRange(min=0), default=None,
                  help="Pin one instrument (its maps, encoder, lens, biases) for every trial; the results then "
                       "speak for that instrument only (default: the scenario's validation.instrument_seed, "
                       "unset in the embedded defaults: each trial draws its own instrument).")
    @click.option("--progress/--no-progress", default=None, help="Progress bar (default: on a terminal).")
    def validate(scenario, trials, tolerances, seed, truth_size, workers, scheduler, dask_local, json_out, report_dir,
                 overwrite, ideal_world, instrument_seed, progress):
        study = get_study(study_name)
        scn = study.load_scenario(scenario)
        tolerance, requirements = split_tolerance_options(tolerances, claim_classes(study, scn))
        if instrument_seed is not None:
            scn = pinned_instrument_scenario(study, scn, instrument_seed,
                                             source=str(scenario or f"embedded {study_name} default"))
        if ideal_world:
            scn = ideal_world_scenario(study, scn, source=str(scenario or f"embedded {study_name} default"))
        run_and_write(study, scn, trials=trials, tolerance=tolerance, seed=seed,
                      workers=workers, scheduler=scheduler, dask_local=dask_local, json_out=json_out,
                      report_dir=report_dir, progress=progress, more_lines=more_lines, overwrite=overwrite,
                      truth_size=truth_size, inputs=(scenario,), requirements=requirements)

    return checked_command(validate)  # the option values checked as the API's arguments
