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
        ("budget.validate", "validate_command"),
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


_register()


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point."""
    run_cli(cli, argv)
