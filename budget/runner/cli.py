"""The command-line face of every study: the click group ``budget <study>``, with the runner's
``validate``, ``robustness``, ``plan`` and ``scenario`` and the study's own commands.

A study's own commands live in its command module (the registry's
:attr:`~budget.runner.registry.StudyEntry.cli_module`), whose ``commands()`` returns them; a
command of the study named ``validate`` replaces the runner's. The command module imports
its study and the runner's commands, never the reverse, so only this builder imports it.
"""

from __future__ import annotations

import importlib

import click

from budget.arguments import checked_command
from budget.runner.plan import has_knobs, plan_command_for
from budget.runner.registry import entry, get_study, summary
from budget.runner.robustness import robustness_command_for
from budget.runner.scenario_cmd import scenario_command_for
from budget.runner.validate_cmd import validate_command_for

__all__ = ["own_commands", "study_group"]


def own_commands(study_name: str) -> list[click.Command]:
    """The click commands of study ``study_name``'s command module (none without one)."""
    e = entry(study_name)
    if e is None or e.cli_module is None:
        return []
    return list(importlib.import_module(e.cli_module).commands())


def study_group(study_name: str) -> click.Group:
    """The click group of a registered study: ``validate``, ``robustness``, ``plan`` (where its
    default scenario declares protocol knobs) plus the study's own commands
    (:func:`own_commands`; one named ``validate`` replaces the runner's).

    The study module is imported only when the group is invoked (or asked for help), and a
    command runs without building the others: ``validate`` loads no scenario to learn
    whether the study has ``plan`` (the listing, ``--help``, builds them all).
    """

    def _plan():
        # a protocol with knobs: `plan` (budget.runner.plan)
        return plan_command_for(study_name) if has_knobs(get_study(study_name)) else None

    #: the runner's commands of every study, built on first use; the study's own replace them
    generic = {"validate": lambda: validate_command_for(study_name),
               "robustness": lambda: checked_command(robustness_command_for(study_name)),
               "plan": lambda: checked_command(_plan())}

    class _Lazy(click.Group):
        def _load_own(self) -> None:
            """The study's own commands, then every study's ``scenario`` (with comments)."""
            if getattr(self, "_own", None) is not None:
                return
            own = own_commands(study_name)
            self._own = {cmd.name for cmd in own}
            for cmd in own:
                self.add_command(cmd)
            self.add_command(scenario_command_for(study_name))
            self._built: set = set()

        def _generic(self, name: str) -> None:
            """Build the runner's command ``name`` once, unless the study has its own."""
            if name in generic and name not in self._own and name not in self._built:
                self._built.add(name)
                cmd = generic[name]()
                if cmd is not None:
                    self.add_command(cmd)

        def list_commands(self, ctx):
            self._load_own()
            for name in generic:
                self._generic(name)
            return super().list_commands(ctx)

        def get_command(self, ctx, cmd_name):
            self._load_own()
            self._generic(cmd_name)
            return super().get_command(ctx, cmd_name)

    return _Lazy(name=study_name, help=f"{summary(study_name)} Validation and its own commands.")
