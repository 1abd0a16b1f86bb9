"""`budget` command line: the lab side (estimators, combination, validation).

One grammar for every study: ``budget <study> <verb>`` (``budget starcam measure``,
``budget inductosyn fit``, ``budget linecam validate``, ...), one group per registered
study (:mod:`budget.runner.registry`). Besides them: ``budget sweep`` and ``budget plot``
(the sweep engine), and ``budget validate``, the documented alias of the main job
(``budget starcam validate``).
"""

from __future__ import annotations

import importlib

import click

from budget import __version__
from budget.runner.cli import study_group
from budget.runner.registry import aliases, study_names
from simcam.infra.cli import run_cli
from simcam.infra.errors import UserInputError
from simcam.infra.lifecycle import quick_teardown

#: command name -> "module:attribute"; each module is imported only when its command runs
#: (or when ``--help`` lists them), so a command pays only for its own imports
COMMANDS = {
    "sweep": "budget.sweeps.run:sweep_command",
    "plot": "budget.sweeps.plot:plot_command",
    "claims": "budget.runner.claims_cmd:claims_command",
}
#: the main job's alias: ``budget validate`` is ``budget starcam validate``
MAIN_STUDY = "starcam"
#: former top-level commands -> where they live now (invoking one is a one-line error)
MOVED = {"measure": "starcam measure", "simulate": "starcam simulate", "combine": "starcam combine"}


class _LazyGroup(click.Group):
    """The ``budget`` group: sub-commands from :data:`COMMANDS` and one group per registered
    study (:mod:`budget.runner.registry`; an alias gives the same group), imported on first use."""

    def list_commands(self, ctx):
        return sorted(set(COMMANDS) | set(study_names()) | {"validate"} | set(self.commands))

    def get_command(self, ctx, cmd_name):
        name = aliases().get(cmd_name, cmd_name)
        if name in self.commands:
            return self.commands[name]
        if name in COMMANDS:
            module_name, attr = COMMANDS[name].split(":")
            cmd = getattr(importlib.import_module(module_name), attr)
        elif name == "validate":
            # `budget validate`: the main job, the seed-000 study's validate
            group = self.get_command(ctx, MAIN_STUDY)
            cmd = group.get_command(ctx, "validate")
        elif name in MOVED:
            raise UserInputError(f"`budget {name}` is now `budget {MOVED[name]}`")
        elif name in study_names():
            cmd = study_group(name)
        else:
            return None
        self.add_command(cmd, name)
        return cmd


@click.group(cls=_LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="budget")
def cli() -> None:
    """Error-budget tools: `budget <study> <verb>` runs a study's lab methods on frames or
    tables (e.g. `budget starcam measure`) or validates them against injected truth
    (`budget <study> validate`; `budget validate` is the star camera's, the main job);
    `budget sweep` / `budget plot` sweep design parameters; `budget claims` judges every
    paper's claims and writes one page. `budget harmonics` is an alias
    of `budget inductosyn`."""


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point (the process then skips the final garbage collections
    at its exit: :func:`simcam.infra.lifecycle.quick_teardown`)."""
    quick_teardown()
    run_cli(cli, argv)


if __name__ == "__main__":  # python -m budget.cli (benchmarks run it so)
    main()
