"""The registry of studies: one table, name -> where its :class:`~budget.runner.study.Study`
lives, where its own commands live and one line of help.

Nothing else in the machinery knows a study's name: the CLI, the sweep engine and the
reports look studies up here (a test scans budget/runner and budget/sweeps for study names
outside this table). Entries are imported only when used, so a command pays only for the
study it runs. The registry imports a study's module (:func:`get_study`), never its command
module: that one imports the runner's commands, which look studies up here; the CLI's group
builder (:func:`budget.runner.cli.study_group`) imports it.
"""

from __future__ import annotations

import importlib
import importlib.util
from dataclasses import dataclass

from budget.runner.study import Study
from simcam.infra.errors import UserInputError

__all__ = ["REGISTRY", "StudyEntry", "aliases", "entry", "get_study", "renamed", "study_names", "summary"]


@dataclass(frozen=True)
class StudyEntry:
    """One registered study: its name (CLI group, sweep ``kind``), where its instance lives
    (``"module:attribute"``), one line of help (shown without importing it) and the module
    of its own commands."""

    name: str
    target: str
    summary: str
    #: the module whose ``commands()`` returns the study's own click commands besides the
    #: runner's (its own ``validate`` replaces the runner's); None: the runner's only
    cli_module: str | None = None
    #: other names of its CLI group (the same command objects)
    aliases: tuple[str, ...] = ()
    #: names it had before (e.g. as a sweep file's ``kind``): refused, naming this one
    former_names: tuple[str, ...] = ()
    #: trials per run of ``budget claims`` by default (every study together within 10 minutes
    #: on 2 cores; docs/claims.md gives the measured times)
    ledger_trials: int = 20

    @property
    def module(self) -> str:
        return self.target.split(":")[0]


#: every registered study, in the order the CLI lists them
REGISTRY: tuple[StudyEntry, ...] = (
    StudyEntry("starcam", "budget.starcam.study:STUDY",
               "Seed 000: star-camera TE, HSFE and LSFE lab methods.", cli_module="budget.starcam.cli",
               former_names=("camera",), ledger_trials=600),
    StudyEntry("inductosyn", "budget.inductosyn.study:STUDY",
               "Seed 001: polygon calibration of an inductosyn's harmonic errors.", cli_module="budget.inductosyn.cli",
               aliases=("harmonics",), ledger_trials=2000),
    StudyEntry("whiskbroom", "budget.whiskbroom.study:STUDY",
               "Seed 002: whiskbroom TDI camera image motion, synthesis and MTF.", cli_module="budget.whiskbroom.cli",
               ledger_trials=600),
    StudyEntry("scanmirror", "budget.scanmirror.study:STUDY",
               "Seed 003: GEO two-axis scan mirror pointing and its normal deviation from stars.",
               cli_module="budget.scanmirror.cli", ledger_trials=600),
    StudyEntry("linecam", "budget.linecam.study:STUDY",
               "Seed 004: star-based on-orbit calibration of a TDI line camera.", cli_module="budget.linecam.cli",
               ledger_trials=160),
    StudyEntry("attitude", "budget.attitude.study:STUDY",
               "Seed 000's star camera on the real sky: attitude error against eq 32.", cli_module="budget.attitude.cli",
               ledger_trials=600),
)
_BY_NAME = {e.name: e for e in REGISTRY}
_ALIASES = {a: e.name for e in REGISTRY for a in e.aliases}


def entry(name: str) -> StudyEntry | None:
    """The entry registered as ``name`` or as one of its aliases (None if neither)."""
    return _BY_NAME.get(_ALIASES.get(name, name))


def renamed(name: str) -> str | None:
    """The study that ``name`` was a former name of (None if it was none)."""
    return next((e.name for e in REGISTRY if name in e.former_names), None)


def aliases() -> dict[str, str]:
    """alias -> study name, for the CLI's group aliases."""
    return dict(_ALIASES)


def study_names(*, available_only: bool = True) -> list[str]:
    """Registered study names (those whose package is installed, by default)."""
    return [e.name for e in REGISTRY
            if not available_only or importlib.util.find_spec(e.module.rsplit(".", 1)[0]) is not None]


def summary(name: str) -> str:
    """The one-line help of study ``name`` (without importing it)."""
    e = entry(name)
    return e.summary if e is not None else name


def get_study(name: str) -> Study:
    """The study registered as ``name``; an unknown name is an error listing the known ones."""
    e = _BY_NAME.get(name)
    if e is None:
        raise UserInputError(f"unknown study {name!r}; known: {', '.join(study_names())}")
    mod, attr = e.target.split(":")
    study = getattr(importlib.import_module(mod), attr)
    if not isinstance(study, Study):
        raise TypeError(f"{e.target} is not a Study")
    return study
