"""The ``budget <study> plan`` command (:func:`plan_command_for`) and whether a study has it
(:func:`has_knobs`)."""

from __future__ import annotations

import sys

import click

from budget.runner.capabilities import Plannable, has_capability
from budget.runner.executors import default_workers
from budget.runner.plan.planner import plan_protocol
from budget.runner.plan.quantiles import DEFAULT_SURE
from budget.runner.plan.requirements import DEFAULT_CONFIDENCE, parse_fixes, parse_requirements
from budget.runner.plan.trials import BUDGET_VALIDATIONS, MIN_TRIALS
from budget.runner.registry import get_study as registry_study
from budget.runner.report import write_outputs
from budget.runner.study import Study
from simcam.infra.cli import overwrite_option
from simcam.infra.outputs import check_run_outputs

__all__ = ["has_knobs", "plan_command_for"]


def has_knobs(study: Study) -> bool:
    """Whether the study is :class:`~budget.runner.capabilities.Plannable` and its default scenario
    declares protocol knobs (then it has ``plan``; no scenario is loaded for a study without
    the capability)."""
    if not has_capability(study, Plannable):
        return False
    try:
        return bool(study.protocol_knobs(study.load_scenario()))
    except Exception:  # noqa: BLE001 - a study without a loadable default has no plan command
        return False


def plan_command_for(study_name: str, *, get_study=None) -> click.Command:
    """``plan [SCENARIO] --require ... --variant --confidence --sure --fix --budget-hours --trials
    --seed --workers --json --report``; ``get_study``: how to find the study (default the registry)."""

    @click.command("plan", help=f"Plan the {study_name} test before booking the lab: the cheapest protocol "
                                "(knobs and shapes the study declares) whose estimates meet every --require "
                                "CLASS.AXIS<=VALUE (the --confidence quantile of |estimate - truth|, in the "
                                "class's unit), re-validated on fresh trials (SCENARIO: default the embedded one).")
    @click.argument("scenario", required=False, type=click.Path(dir_okay=False))
    @click.option("--require", "require", multiple=True, metavar="CLASS.AXIS<=VALUE",
                  help="A requirement (repeat for several): the error's quantile at most VALUE.")
    @click.option("--variant", default=None, help="The estimator judged (default: the study's last that estimates).")
    @click.option("--confidence", type=float, default=DEFAULT_CONFIDENCE, show_default=True,
                  help="The share of tests that must land within VALUE (the quantile).")
    @click.option("--sure", "sure", type=float, default=DEFAULT_SURE, show_default=True,
                  help="How sure the plan must be that the recommended protocol meets each requirement: a "
                       "protocol meets when the verdict on its quantile holds at this one-sided level (interval "
                       "confidence 2 SURE - 1; near the bound trials are added until it is decided); K "
                       "requirements together with probability at least 1 - K (1 - SURE) (for a joint P give "
                       "1 - (1 - P) / K); 0.5: the boundary protocol.")
    @click.option("--fix", "fix", multiple=True, metavar="FIELD=VALUE",
                  help="Pin a protocol knob (repeat for several; FIELD one of the study's knobs, VALUE within "
                       "its bounds): the search leaves it at VALUE.")
    @click.option("--budget-hours", "budget_hours", type=float, default=None,
                  help="Lab time allowed: protocols above it are not considered.")
    @click.option("--trials", type=click.IntRange(min=MIN_TRIALS), default=None,
                  help="Trials of one validation (default: the scenario's validation.trials); the search "
                       f"uses at most {BUDGET_VALIDATIONS - 1} times as many per shape.")
    @click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True)
    @click.option("--workers", type=click.IntRange(min=1), default=None,
                  help="Local worker processes (default: all cores). Results do not depend on it.")
    @click.option("--json", "json_out", type=click.Path(dir_okay=False), help="Write the plan as JSON.")
    @click.option("--report", "report_dir", type=click.Path(file_okay=False),
                  help="Write a report (report.md, report.html, trade_curve.png, recommended.toml).")
    @overwrite_option
    @click.option("--progress/--no-progress", default=None,
                  help="Each protocol run on stderr (default: on a terminal).")
    def plan(scenario, require, variant, confidence, sure, fix, budget_hours, trials, seed, workers, json_out,
             report_dir, overwrite, progress):
        study = (get_study or registry_study)(study_name)
        scn = study.load_scenario(scenario)
        parse_requirements(study, scn, require, variant)  # a bad requirement before any work
        parse_fixes(tuple(study.protocol_knobs(scn)), list(fix))  # a bad --fix too
        check_run_outputs(json_out=json_out, report_dir=report_dir, inputs=(scenario,), overwrite=overwrite)
        if progress is None:
            progress = sys.stderr.isatty()
        if workers is None:
            workers = default_workers()
        res = plan_protocol(study, scn, list(require), variant=variant, confidence=confidence,
                            budget_hours=budget_hours, seed=seed, trials=trials, workers=workers, progress=progress,
                            sure=sure, fix=list(fix))
        click.echo(res.answer())
        for s in res.sentences():
            click.echo(f"* {s}")
        write_outputs(res, json_out=json_out, report_dir=report_dir)

    return plan
