"""Fuzz of the newer studies' readers, as tests/test_reliability.py does for the
star camera's: the whiskbroom, line camera and scan mirror scenarios and the line camera's
observation table, fed through their commands in this process.

Scenarios are fuzzed two ways: random structures (real section and field names mixed with
junk) and the embedded default with one to three fields replaced by hostile values (NaN,
+-inf, 1e308, huge integers, strings, negative numbers), which reaches the range and
size checks behind the structure. Every refused input must give exit status 2, only
``error:`` lines, the first naming the file, no traceback and nothing written. An input
the reader accepts is not bad input: the example is skipped (``assume``).
Derandomised (the same examples on every machine and run).
"""

from __future__ import annotations

import tempfile
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from cli_capture import run_cli

FUZZ = settings(max_examples=25, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])


def _budget(argv):
    code, _out, err = run_cli("budget", argv)
    return code, err


def _load_whisk(path):
    from simcam.whiskbroom import scenario as wsc

    return wsc.load(path)


def _load_linecam(path):
    from budget.linecam.study import STUDY

    return STUDY.load_scenario(str(path))


def _load_scanmirror(path):
    from budget.scanmirror.study import STUDY

    return STUDY.load_scenario(str(path))


def _default_text(study):
    if study == "whiskbroom":
        from simcam.whiskbroom.scenario import default_text
    elif study == "linecam":
        from simcam.linecam.scenario import default_text
    else:
        from simcam.scanmirror.scenario import default_text
    return default_text()


#: study -> (loader, command with FILE and OUT.json)
STUDIES = {
    "whiskbroom": (_load_whisk, ["whiskbroom", "synthesize", "FILE", "--json", "OUT.json"]),
    "linecam": (_load_linecam, ["linecam", "validate", "FILE", "--trials", "2", "--workers", "1",
                                "--no-progress", "--json", "OUT.json"]),
    "scanmirror": (_load_scanmirror, ["scanmirror", "validate", "FILE", "--trials", "2", "--workers", "1",
                                      "--no-progress", "--json", "OUT.json"]),
}


def _refused(study_or_loader, payload: bytes, argv, name="input.toml"):
    loader = STUDIES[study_or_loader][0] if isinstance(study_or_loader, str) else study_or_loader
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        f = d / name
        f.write_bytes(payload)
        try:
            loader(f)
            accepted = True
        except Exception:  # noqa: BLE001 - refused (or crashed: the command must say so in one line)
            accepted = False
        assume(not accepted)
        before = {p.name for p in d.iterdir()}
        args = [str(f) if a == "FILE" else str(d / "out.json") if a == "OUT.json" else a for a in argv]
        code, err = _budget(args)
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert code == 2, err
        assert lines and all(ln.startswith("error: ") for ln in lines), err
        assert str(f) in lines[0], err
        assert "Traceback" not in err
        assert {p.name for p in d.iterdir()} == before, "something was written"


_SCALARS = (st.integers(min_value=-(2**63), max_value=2**63 - 1) | st.floats(allow_nan=True, allow_infinity=True)
            | st.sampled_from([1e308, -1e308, 0.0, -1.0, 1e-320, 10**9, 10**12, "2025-13-45T00:00:00", ""])
            | st.text(max_size=8) | st.booleans())
_KEYS = st.sampled_from(["camera", "mirror", "orbit", "synthesis", "tdi", "errors", "lab", "stars",
                         "observation", "scan_plan", "segments", "epoch_utc", "rate_deg_s", "n_chips",
                         "chip_cols", "focal_length_mm", "zz"]) | st.text(min_size=1, max_size=6)
_VALUES = st.recursive(_SCALARS, lambda inner: st.lists(inner, max_size=3) | st.dictionaries(_KEYS, inner, max_size=3),
                       max_leaves=8)
STRUCTURES = st.dictionaries(_KEYS, _VALUES, min_size=1, max_size=4)


def _leaves(d, path=()):
    out = []
    for k, v in d.items():
        if isinstance(v, dict):
            out += _leaves(v, path + (k,))
        else:
            out.append(path + (k,))
    return out


def _set(d, path, value):
    for k in path[:-1]:
        d = d[k]
    d[path[-1]] = value


@pytest.mark.parametrize("study", list(STUDIES))
@FUZZ
@given(data=STRUCTURES)
def test_fuzz_structures_to_study_scenarios(study, data):
    try:
        text = tomli_w.dumps(data)
    except (TypeError, ValueError):
        assume(False)
    _refused(study, text.encode(), STUDIES[study][1])


@pytest.mark.parametrize("study", list(STUDIES))
@FUZZ
@given(picks=st.lists(st.tuples(st.integers(0, 10**6), _SCALARS), min_size=1, max_size=3))
def test_fuzz_hostile_values_in_the_default_scenarios(study, picks):
    base = tomllib.loads(_default_text(study))
    leaves = _leaves(base)
    for i, v in picks:
        _set(base, leaves[i % len(leaves)], v)
    try:
        text = tomli_w.dumps(base)
    except (TypeError, ValueError):
        assume(False)
    _refused(study, text.encode(), STUDIES[study][1])


@pytest.mark.parametrize("study", list(STUDIES))
@FUZZ
@given(payload=st.binary(max_size=200))
def test_fuzz_bytes_to_study_scenarios(study, payload):
    _refused(study, payload, STUDIES[study][1])


# ----------------------------------------------------------------------------- observation table
def _load_obs(path):
    from budget.linecam.table import read_observations
    from budget.linecam.study import STUDY

    return read_observations(path, STUDY.load_scenario(None))


_COLUMNS = ["time_s", "sample_px", "hip", "q_w", "q_x", "q_y", "q_z", "pos_x_km", "pos_y_km", "pos_z_km",
            "vel_x_km_s", "vel_y_km_s", "vel_z_km_s", "pass"]
_CELLS = (st.integers(-5, 120000) | st.floats(allow_nan=True, allow_infinity=True)
          | st.sampled_from(["", "x", "1e308", "7000", "0.5", "\ufeff"]))


@FUZZ
@given(rows=st.lists(st.lists(_CELLS, min_size=len(_COLUMNS), max_size=len(_COLUMNS)), max_size=6),
       drop=st.integers(-1, len(_COLUMNS) - 1), dup=st.booleans())
def test_fuzz_rows_to_the_observation_table(rows, drop, dup):
    cols = [c for i, c in enumerate(_COLUMNS) if i != drop]
    rows = [[r[i] for i in range(len(_COLUMNS)) if i != drop] for r in rows]
    if dup and rows:
        rows = rows + rows[:1]
    text = "\n".join(",".join(str(c) for c in r) for r in [cols, *rows]) + "\n"
    _refused(_load_obs, text.encode(), ["linecam", "calibrate", "FILE", "--json", "OUT.json"], name="obs.csv")


@FUZZ
@given(payload=st.binary(max_size=300))
def test_fuzz_bytes_to_the_observation_table(payload):
    _refused(_load_obs, payload, ["linecam", "calibrate", "FILE", "--json", "OUT.json"], name="obs.csv")


def test_a_good_observation_table_loads():
    """The fuzz above skips what the reader accepts; make sure it accepts a plausible table
    (else every example would be skipped and the test mean nothing)."""
    from budget.linecam.table import CSV_COLUMNS, check_observation_values

    n = 12
    a = {c: np.zeros(n) for c in CSV_COLUMNS}
    a.update(time_s=np.arange(n, dtype=float), sample_px=np.linspace(10, 6000, n), hip=np.arange(1.0, n + 1),
             q_w=np.ones(n), pos_x_km=np.full(n, 6978.0), vel_y_km_s=np.full(n, 7.5))
    check_observation_values("obs.csv", a, n_pixels=6144)
