"""The attitude study's own commands (``budget attitude ...``) besides the runner's
``validate``, ``robustness`` and ``scenario``: none yet."""

from __future__ import annotations

import click

__all__ = ["commands"]


def commands() -> list[click.Command]:
    """The attitude study's own commands."""
    return []
