"""Running the ``budget`` and ``simcam`` command lines inside the test process, and what a user mistake must
print: shared by the reliability tests."""

from __future__ import annotations

import contextlib
import io


def run_cli(prog: str, argv: list[str]) -> tuple[int, str, str]:
    """``simcam ARGV`` or ``budget ARGV`` in this process: (exit status, stdout, stderr)."""
    if prog == "simcam":
        from simcam.cli import main
    else:
        from budget.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            main(argv)
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    return code, out.getvalue(), err.getvalue()


def run_budget(argv: list[str]) -> tuple[int, str, str]:
    """``budget ARGV`` in this process: (exit status, stdout, stderr)."""
    return run_cli("budget", argv)


def one_error(code: int, err: str, *named: str) -> str:
    """The one ``error:`` line of a refused command (status 2, no traceback) naming ``named``."""
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err
    for n in named:
        assert n in lines[0], err
    return lines[0]
