"""Helpers shared by the `simcam` and `budget` command lines.

`run_cli(group)` runs a click group so that a user mistake (`ScenarioError`, `UsageError`
from our code, `FileNotFoundError` of a named input) is printed as ``error: ...`` lines
and exits with status 2, without a traceback.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
from pathlib import Path
from typing import Any

import click

from simcam.config_base import ScenarioError


class UserInputError(ValueError):
    """Bad user input other than a scenario (a frame directory, a manifest, a table)."""


def run_cli(group: click.Group, argv: list[str] | None = None) -> None:
    """Run ``group``; turn user errors into a one-line message and exit status 2."""
    try:
        group.main(args=argv, standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        sys.exit(130)
    except click.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except (ScenarioError, UserInputError) as exc:
        for line in str(exc).splitlines():
            click.echo(f"error: {line}", err=True)
        sys.exit(2)
    except ValueError as exc:
        # Our packages' own ValueError subclasses (OpticsError, SpectraError, ...) report
        # bad input by convention; anything else is a bug and keeps its traceback.
        if type(exc).__module__.split(".")[0] not in ("simcam", "budget"):
            raise
        for line in str(exc).splitlines():
            click.echo(f"error: {line}", err=True)
        sys.exit(2)
    except FileNotFoundError as exc:
        click.echo(f"error: file not found: {exc.filename or exc}", err=True)
        sys.exit(2)


def write_json_atomic(path: str | os.PathLike, payload: Any) -> None:
    """Write JSON to ``path`` atomically (temp file + rename): never a half-written file.

    NaN and infinities are written as null (strict JSON).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            json.dump(_finite_or_null(payload), fh, indent=2, sort_keys=False, default=_json_default,
                      allow_nan=False)
            fh.write("\n")
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _finite_or_null(obj: Any) -> Any:
    """Replace NaN and infinities (not valid JSON) by null, recursively."""
    import math

    import numpy as np

    if isinstance(obj, dict):
        return {k: _finite_or_null(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite_or_null(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return [_finite_or_null(v) for v in obj.tolist()]
    if isinstance(obj, (float, np.floating)) and not math.isfinite(float(obj)):
        return None
    return obj


def _json_default(obj: Any) -> Any:
    import numpy as np

    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")
