"""Reading scenario files: strict TOML, every failure a one-line error naming the file."""

from __future__ import annotations

import tomllib
from pathlib import Path

from simcam.config_base import ScenarioError


def read_toml(*, path: str | Path | None = None, text: str | None = None, source: str | None = None) -> dict:
    """Parse TOML from ``path`` or ``text``; a missing, unreadable, non-UTF-8 or invalid
    file raises :class:`ScenarioError` naming it."""
    if (path is None) == (text is None):
        raise TypeError("read_toml: give path or text")
    if path is not None:
        source = source or str(path)
        p = Path(path)
        if p.is_dir():
            raise ScenarioError(f"{source}: is a folder, not a scenario file")
        from simcam.outputs import input_file_problem  # issue 24: a FIFO blocked forever, /dev/null read as empty

        if (why := input_file_problem(p)) is not None:
            raise ScenarioError(f"{source}: {why}")
        try:
            raw = p.read_bytes()
        except FileNotFoundError:
            raise ScenarioError(f"{source}: file not found") from None
        except OSError as exc:
            raise ScenarioError(f"{source}: cannot read ({exc.strerror})") from None
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ScenarioError(f"{source}: not UTF-8 text (byte {exc.start}): is this a scenario file?") from None
        if not text.strip():
            raise ScenarioError(f"{source}: the file is empty (omit the argument to use the embedded default)")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{source}: not valid TOML: {exc}") from None
