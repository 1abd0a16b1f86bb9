"""`budget` command line: the lab side (estimators, combination, validation)."""

from __future__ import annotations

import click

from budget import __version__
from simcam.cli_common import run_cli


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="budget")
def cli() -> None:
    """Error-budget tools: run the lab's estimators on frames or tables, combine budgets."""


def _register() -> None:
    # Sub-commands live next to the code they drive; registered here only.
    import importlib

    for module_name, attr in (
        ("budget.combine", "combine_command"),
        ("budget.measure", "measure_command"),
        ("budget.simulate", "simulate_command"),
        ("budget.harmonics_cli", "harmonics_group"),
        ("budget.sweep", "sweep_command"),
        ("budget.sweep_plot", "plot_command"),
    ):
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name == module_name:
                continue
            raise
        cli.add_command(getattr(module, attr))
    # every registered study is a group (`budget <study> validate ...`); the study's module
    # is imported only when its group runs
    from budget.runner.cli import study_group, validate_command_for
    from budget.runner.registry import study_names

    for name in study_names():
        if name not in cli.commands:
            cli.add_command(study_group(name))
    # `budget validate`: the seed-000 study, as it always was
    cli.add_command(validate_command_for(
        "starcam", help_text="Monte Carlo validation of the seed-000 lab methods on SCENARIO "
                             "(default: the embedded seed-000 scenario)."))


_register()


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point."""
    run_cli(cli, argv)
