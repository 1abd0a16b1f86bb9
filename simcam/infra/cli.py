"""Helpers shared by the `simcam` and `budget` command lines.

`run_cli(group)` runs a click group so that a user mistake (`ScenarioError`, `UsageError`
from our code, `FileNotFoundError` of a named input) is printed as ``error: ...`` lines
and exits with status 2, without a traceback.
"""

from __future__ import annotations

import io
import json
import math
import os
import stat
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import click

from simcam.infra.errors import WORKERS_LOST_STATUS, Interrupted, ScenarioError, UserInputError, WorkersLost
from simcam.infra.lifecycle import handle_termination
from simcam.infra.outputs import (JSON_TEMPORARY_NAME_BYTES, WRITE_ERRNOS, apply_umask, check_output_file,
                                  os_error_message)


def run_cli(group: click.Group, argv: list[str] | None = None) -> None:
    """Run ``group``; turn user errors into a one-line message and exit status 2.

    SIGINT, SIGTERM and SIGHUP stop the command through
    :class:`simcam.infra.errors.Interrupted` (so its clean-up runs: temporary folders
    removed, worker processes ended) and end in one line and exit status 128 + signal.
    A request that does not fit in memory is one ``error:`` line and status 2; lost
    workers (:class:`simcam.infra.errors.WorkersLost`) one line and status 3.
    """
    try:
        with handle_termination(), _stdout_reader_may_leave():
            group.main(args=argv, standalone_mode=False)
    except Interrupted as exc:
        click.echo(f"interrupted ({exc.name})", err=True)
        sys.exit(exc.exit_status)
    except (click.exceptions.Abort, KeyboardInterrupt):
        click.echo("interrupted (SIGINT)", err=True)
        sys.exit(130)
    except click.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except (ScenarioError, UserInputError) as exc:
        _error_lines(str(exc))
        sys.exit(2)
    except WorkersLost as exc:  # a killed worker, a cluster without workers: one line, status 3
        _error_lines(str(exc))
        sys.exit(WORKERS_LOST_STATUS)
    except ValueError as exc:
        # Our packages' own ValueError subclasses (OpticsError, SpectraError, ...) report
        # bad input by convention; anything else is a bug and keeps its traceback.
        if type(exc).__module__.split(".")[0] not in ("simcam", "budget"):
            raise
        _error_lines(str(exc))
        sys.exit(2)
    except FileNotFoundError as exc:
        click.echo(f"error: file not found: {exc.filename or exc}", err=True)
        sys.exit(2)
    except OSError as exc:
        # a write the location checks could not foresee (the disk filled up meanwhile, a
        # file system remounted read-only): one line naming the file, no traceback
        if exc.errno not in _USER_ERRNOS:
            raise
        where = exc.filename or ""
        click.echo(f"error: {where}{': ' if where else ''}{os_error_message(exc)}", err=True)
        sys.exit(2)
    except MemoryError as exc:
        # the size checks refuse what they can foresee; this is the last resort
        msg = str(exc).strip() or "an allocation failed"
        click.echo(f"error: not enough memory for this request ({msg}); reduce its size", err=True)
        sys.exit(2)


#: errors of a write that are the machine's state, not a bug: reported as one line
_USER_ERRNOS = WRITE_ERRNOS


class _PipeStdout(io.TextIOBase):
    """``sys.stdout`` on a pipe whose reader may leave (``| head -1``): once it has, the rest of
    the text goes to ``/dev/null`` (the command's outputs are still written, nothing is said)."""

    def __init__(self, stream, fd: int):
        super().__init__()
        self._stream, self._fd = stream, fd

    def _gone(self) -> None:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, self._fd)  # the buffered text, and what follows, go nowhere
        os.close(devnull)

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            self._gone()
            return len(text)

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError:
            self._gone()
            self._stream.flush()

    def fileno(self) -> int:
        return self._fd

    def writable(self) -> bool:
        return True

    def isatty(self) -> bool:
        return False

    @property
    def encoding(self) -> str:
        return self._stream.encoding

    @property
    def errors(self) -> str | None:
        return self._stream.errors


@contextmanager
def _stdout_reader_may_leave() -> Iterator[None]:
    """Where stdout is a pipe or a socket, a reader that leaves early (``budget ... validate --json
    v.json | head -1``) ends the printing, not the command: its files are written and it exits
    as it would have, without a word (was: exit 1, no JSON)."""
    out = sys.stdout
    try:
        fd = out.fileno()
        mode = os.fstat(fd).st_mode
    except (AttributeError, OSError, ValueError):  # a StringIO (tests), a closed stdout
        yield
        return
    if not (stat.S_ISFIFO(mode) or stat.S_ISSOCK(mode)):
        yield
        return
    sys.stdout = _PipeStdout(out, fd)
    try:
        yield
    finally:
        sys.stdout = out
        try:
            out.flush()
        except BrokenPipeError:
            _PipeStdout(out, fd)._gone()


def _error_lines(text: str) -> None:
    lines = [ln for ln in text.splitlines() if ln.strip()] or ["(no message)"]
    for line in lines:
        click.echo(f"error: {line}", err=True)


def write_json_atomic(path: str | os.PathLike, payload: Any, *, option: str = "--json") -> None:
    """Write JSON to ``path`` atomically (temp file + rename): never a half-written file.

    NaN and infinities are written as null (strict JSON). The file gets the user's umask
    (not ``mkstemp``'s 0600). ``path`` must be a regular file or new
    (:func:`simcam.infra.outputs.check_output_file`: a rename over ``/dev/null`` would replace
    the device); a link to a regular file is written through, so it stays a link. A
    failed write (disk full) is a :class:`UserInputError` naming the file.
    """
    path = check_output_file(path, option=option, temp_bytes=JSON_TEMPORARY_NAME_BYTES)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            json.dump(_finite_or_null(payload), fh, indent=2, sort_keys=False, default=_json_default,
                      allow_nan=False)
            fh.write("\n")
        apply_umask(tmp, is_dir=False)
        os.replace(tmp, path)
    except BaseException as exc:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(exc, OSError) and exc.errno in _USER_ERRNOS:
            raise UserInputError(f"{option} {path}: {os_error_message(exc)}") from None
        raise


def _finite_or_null(obj: Any) -> Any:
    """Replace NaN and infinities (not valid JSON) by null, recursively."""
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


def overwrite_option(f):
    """``--overwrite``, the same for every command that writes a folder: replace an existing
    folder that is neither empty nor an earlier output of the command (which are replaced
    without it); see :func:`simcam.infra.outputs.check_output_dir`."""
    return click.option("--overwrite", is_flag=True, default=False,
                        help="Replace an existing output folder that is not empty and not an earlier output "
                             "of this command (an empty folder or an earlier output is replaced without it).")(f)
