"""The star camera study's own commands, ``budget starcam simulate|measure|combine``: the lab's
data (frames, centroid tables, the combined budget) beside the runner's ``validate``,
``robustness``, ``plan`` and ``scenario`` (:mod:`budget.runner.cli`)."""

from __future__ import annotations

import click

from budget.starcam.combine import combine_command
from budget.starcam.measure import measure_command
from budget.starcam.simulate import simulate_command

__all__ = ["commands"]


def commands() -> list[click.Command]:
    """``simulate``, ``measure`` and ``combine``."""
    return [simulate_command, measure_command, combine_command]
