"""`budget` command line: the lab side (estimators, combination, validation)."""

from __future__ import annotations

import click

from budget import __version__
from simcam.cli_common import run_cli


#: command name -> "module:attribute"; each module is imported only when its command runs
#: (or when ``--help`` lists them), so a command pays only for its own imports
COMMANDS = {
    "combine": "budget.starcam.combine:combine_command",
    "measure": "budget.starcam.measure:measure_command",
    "simulate": "budget.starcam.simulate:simulate_command",
    "harmonics": "budget.inductosyn.cli:harmonics_group",
    "sweep": "budget.sweeps.run:sweep_command",
    "plot": "budget.sweeps.plot:plot_command",
}


class _LazyGroup(click.Group):
    """The ``budget`` group: sub-commands from :data:`COMMANDS` and one group per registered
    study (:mod:`budget.runner.registry`), imported on first use."""

    def list_commands(self, ctx):
        from budget.runner.registry import study_names

        return sorted(set(COMMANDS) | set(study_names()) | {"validate"} | set(self.commands))

    def get_command(self, ctx, cmd_name):
        import importlib

        if cmd_name in self.commands:
            return self.commands[cmd_name]
        if cmd_name in COMMANDS:
            module_name, attr = COMMANDS[cmd_name].split(":")
            cmd = getattr(importlib.import_module(module_name), attr)
        elif cmd_name == "validate":
            # `budget validate`: the seed-000 study, as it always was
            from budget.runner.cli import validate_command_for

            cmd = validate_command_for("starcam", help_text="Monte Carlo validation of the seed-000 lab methods "
                                                            "on SCENARIO (default: the embedded seed-000 scenario).")
        else:
            from budget.runner.cli import study_group
            from budget.runner.registry import study_names

            if cmd_name not in study_names():
                return None
            cmd = study_group(cmd_name)
        self.add_command(cmd, cmd_name)
        return cmd


@click.group(cls=_LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="budget")
def cli() -> None:
    """Error-budget tools: run the lab's estimators on frames or tables, validate lab methods
    against injected truth (one study per source method), sweep design parameters."""


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point."""
    run_cli(cli, argv)


if __name__ == "__main__":  # python -m budget.cli (benchmarks run it so)
    main()
