"""The registry of studies: name -> where its :class:`~budget.runner.study.Study` lives.

Nothing else in the machinery knows a study's name: the CLI, the sweep engine and the
reports look studies up here. Entries are imported only when used, so a command pays only
for the study it runs.
"""

from __future__ import annotations

import importlib

from budget.runner.study import Study

__all__ = ["STUDIES", "get_study", "study_names"]

#: name -> "module:attribute" of the study instance
STUDIES: dict[str, str] = {
    "starcam": "budget.starcam.study:STUDY",
    "inductosyn": "budget.inductosyn.study:STUDY",
    "whiskbroom": "budget.whiskbroom.study:STUDY",
    "scanmirror": "budget.scanmirror.study:STUDY",
    "linecam": "budget.linecam.study:STUDY",
}
#: one line of help per study (shown without importing it)
SUMMARIES: dict[str, str] = {
    "starcam": "Seed 000: star-camera TE, HSFE and LSFE lab methods.",
    "inductosyn": "Seed 001: polygon calibration of an inductosyn's harmonic errors.",
    "whiskbroom": "Seed 002: whiskbroom TDI camera image motion, synthesis and MTF.",
    "scanmirror": "Seed 003: GEO two-axis scan mirror pointing and its normal deviation from stars.",
    "linecam": "Seed 004: star-based on-orbit calibration of a TDI line camera.",
}


def study_names(*, available_only: bool = True) -> list[str]:
    """Registered study names (those whose module is installed, by default)."""
    if not available_only:
        return list(STUDIES)
    out = []
    for name, target in STUDIES.items():
        mod = target.split(":")[0]
        if importlib.util.find_spec(mod.rsplit(".", 1)[0]) is not None:
            out.append(name)
    return out


def get_study(name: str) -> Study:
    """The study registered as ``name``; an unknown name is an error listing the known ones."""
    from simcam.cli_common import UserInputError

    if name not in STUDIES:
        raise UserInputError(f"unknown study {name!r}; known: {', '.join(study_names())}")
    mod, attr = STUDIES[name].split(":")
    study = getattr(importlib.import_module(mod), attr)
    if not isinstance(study, Study):
        raise TypeError(f"{STUDIES[name]} is not a Study")
    return study
