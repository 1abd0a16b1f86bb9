"""A fuzz test per command-line entry point (issue #35: "a fuzz test per entry point keeps them").

Every command of ``budget`` and ``simcam`` (found by walking the click groups, so a command
added later is fuzzed too) gets malformed arguments from a numpy generator with a fixed seed:
a value of the wrong type for one of its typed options, an unknown option, a missing or
unreadable positional file, random bytes as its file, and for the five studies' scenario
arguments a scenario with one numeric field set to a value no numeric field accepts (a
string, a boolean, a table, NaN, infinity) or an unknown key. Each case asserts: exit status
2 (a user mistake; 1 is never expected), every stderr line an ``error:`` line or click's
usage block, no traceback (an exception escaping ``main`` fails the test), no output left
(the folder holds what it held before).

The default suite runs :data:`FAST_CASES` cases per command; ``slow`` runs :data:`SLOW_CASES`.
The cases are drawn from ``numpy.random.default_rng(seed)`` with the seed fixed per command
(a crc32 of its name), so a failure names a case that replays exactly.
"""

from __future__ import annotations

import contextlib
import math
import tomllib
import zlib
from pathlib import Path

import click
import numpy as np
import pytest
import tomli_w

from cli_capture import run_cli

FAST_CASES = 2
SLOW_CASES = 24

#: the five studies' scenario kinds (and the attitude study's) whose fields are edited
STUDIES = ("starcam", "inductosyn", "whiskbroom", "scanmirror", "linecam", "attitude")
#: values that no numeric field accepts (booleans are not numbers; every float is finite)
BAD_NUMBERS = ("abc", True, {"x": 1}, float("nan"), float("inf"), [1, 2])
#: outputs a command may be given, and the option names it has them under
OUTPUT_OPTIONS = {"--json": "out.json", "--report": "rep", "--out": "out", "--csv": "out.csv",
                  "--centroids": "c.csv", "--plot": "p.png"}


def _commands() -> list[tuple[str, list[str], click.Command]]:
    """(program, path, command) of every leaf command of both programs."""
    from budget.cli import cli as budget_cli
    from simcam.cli import cli as simcam_cli

    out = []

    def walk(prog, group, ctx, path):
        for name in group.list_commands(ctx):
            cmd = group.get_command(ctx, name)
            if isinstance(cmd, click.Group):
                walk(prog, cmd, click.Context(cmd, parent=ctx), path + [name])
            elif cmd is not None:
                out.append((prog, path + [name], cmd))

    walk("budget", budget_cli, click.Context(budget_cli), [])
    walk("simcam", simcam_cli, click.Context(simcam_cli), [])
    return out


COMMANDS = _commands()


def _run(prog: str, argv: list[str]) -> tuple[int, str]:
    """``main(argv)`` of the program in this process: (exit status, stderr)."""
    code, _out, err = run_cli(prog, argv)
    return code, err


def _numeric_leaves(d: dict, prefix: str = "") -> list[str]:
    out = []
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out += _numeric_leaves(v, key + ".")
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            out.append(key)
    return out


def _set(d: dict, dotted: str, value) -> None:
    *head, last = dotted.split(".")
    for k in head:
        d = d[k]
    d[last] = value


def _bad_scenario(rng: np.random.Generator, kind: str) -> tuple[bytes, str]:
    """The study's default scenario with one numeric field spoiled (or an unknown key)."""
    from budget.sweeps.spec import _default_raw

    raw, _ = _default_raw(kind)
    leaves = _numeric_leaves(raw)
    if not leaves or rng.random() < 0.2:
        section = str(rng.choice(sorted(k for k, v in raw.items() if isinstance(v, dict)) or ["x"]))
        raw.setdefault(section, {})["zz_no_such_field"] = 1.0
        return tomli_w.dumps(raw).encode(), f"{section}.zz_no_such_field"
    field = str(rng.choice(leaves))
    bad = BAD_NUMBERS[int(rng.integers(len(BAD_NUMBERS)))]
    if isinstance(bad, float):  # TOML writes nan and inf as such
        _set(raw, field, 0.123456789)
        text = tomli_w.dumps(raw).replace("0.123456789", "nan" if math.isnan(bad) else "inf", 1).encode()
        return text, field
    _set(raw, field, bad)
    return tomli_w.dumps(raw).encode(), field


def _typed_options(cmd: click.Command) -> list[click.Option]:
    """Options whose type refuses a word (numbers, choices, ranges)."""
    kinds = (click.types.IntParamType, click.types.FloatParamType, click.Choice)
    return [p for p in cmd.params if isinstance(p, click.Option) and not p.is_flag and isinstance(p.type, kinds)]


def _study_of(prog: str, path: list[str]) -> str | None:
    if prog == "budget" and path and path[0] in STUDIES:
        return path[0]
    if prog == "budget" and path == ["validate"]:
        return "starcam"
    if prog == "simcam" and path and path[0] in ("render", "scenario"):
        return "starcam"
    return None


def _case(rng: np.random.Generator, prog: str, path: list[str], cmd: click.Command, tmp: Path) -> list[str]:
    """One malformed argument vector for the command (files it needs written into ``tmp``)."""
    args = [p for p in cmd.params if isinstance(p, click.Argument)]
    outputs = [o for o in cmd.params if isinstance(o, click.Option) and o.opts[0] in OUTPUT_OPTIONS]
    typed = _typed_options(cmd)
    study = _study_of(prog, path)
    kinds = ["unknown option"] + (["bytes"] if args else [])
    if typed:
        kinds += ["word for a number"] * 2
    if args:
        kinds.append("missing file")
    if study and any(a.name in ("scenario",) for a in args):
        kinds += ["scenario edit"] * 3
    kind = str(rng.choice(kinds))
    argv = list(path)
    positional = []
    for a in args:
        name = f"in_{a.name}"
        payload = bytes(rng.integers(0, 256, int(rng.integers(1, 200)), dtype=np.uint8))
        if kind == "missing file" and not positional:
            positional.append("no_such_file.toml")
            continue
        if kind == "scenario edit" and a.name == "scenario":
            text, _field = _bad_scenario(rng, study)
            (tmp / "s.toml").write_bytes(text)
            positional.append("s.toml")
            continue
        if a.name in ("protocol",):
            positional.append("te")
            continue
        if kind == "bytes":
            (tmp / name).write_bytes(payload)
            positional.append(name)
        else:  # a valid-looking file beside the mistake under test: an empty table
            (tmp / name).write_text("")
            positional.append(name)
        if a.nargs == -1:
            break
    argv += positional
    for o in outputs:
        argv += [o.opts[0], OUTPUT_OPTIONS[o.opts[0]]]
    if kind == "unknown option":
        argv.append("--no-such-option")
    elif kind == "word for a number":
        o = typed[int(rng.integers(len(typed)))]
        argv += [o.opts[0], str(rng.choice(["abc", "1x", "0x1g", "one"]))]
    if any(o.opts[0] == "--workers" for o in cmd.params if isinstance(o, click.Option)):
        argv += ["--workers", "1"]
    return argv


def _check(prog: str, path: list[str], cmd: click.Command, tmp: Path, seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    for i in range(n):
        case = tmp / f"case{i}"
        case.mkdir()
        with contextlib.chdir(case):
            argv = _case(rng, prog, path, cmd, case)
            before = {p.name for p in case.iterdir()}
            code, err = _run(prog, argv)
            after = {p.name for p in case.iterdir()}
        shown = f"{prog} {' '.join(argv)} (seed {seed}, case {i}):\n{err}"
        assert code == 2, shown
        assert "Traceback" not in err, shown
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert lines, shown
        usage = lines[0].startswith("Usage:")
        # our one-line errors, or click's usage block (its "Error:" may list the choices below it)
        ours = all(ln.startswith("error: ") for ln in lines)
        assert ours or (usage and any(ln.startswith("Error: ") for ln in lines)), shown
        assert after == before, f"left behind {sorted(after - before)}: {shown}"


def _seed(prog: str, path: list[str]) -> int:
    return zlib.crc32(" ".join([prog, *path]).encode())


IDS = [" ".join([prog, *path]) for prog, path, _ in COMMANDS]


@pytest.mark.parametrize("prog, path, cmd", COMMANDS, ids=IDS)
def test_fuzz_entry_point(tmp_path, prog, path, cmd):
    _check(prog, path, cmd, tmp_path, _seed(prog, path), FAST_CASES)


@pytest.mark.slow
@pytest.mark.parametrize("prog, path, cmd", COMMANDS, ids=IDS)
def test_fuzz_entry_point_many(tmp_path, prog, path, cmd):
    _check(prog, path, cmd, tmp_path, _seed(prog, path) + 1, SLOW_CASES)


def test_every_command_is_fuzzed():
    """The walk finds both programs' commands (a broken walk would fuzz nothing)."""
    assert {"budget sweep", "budget starcam validate", "budget starcam measure", "simcam render"} <= set(IDS)
    assert len(IDS) >= 30
    assert tomllib.loads("a = 1") == {"a": 1}
