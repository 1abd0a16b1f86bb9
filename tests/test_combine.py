"""Tests of `budget combine` (seed 000 eq 31, section 2.4, eq 32)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from click.testing import CliRunner

from budget.starcam.combine import combine_budget, combine_command, load_budget_toml
from simcam.infra.errors import ScenarioError

ROOT = Path(__file__).resolve().parents[1]
SEED_TOML = ROOT / "docs" / "examples" / "combine_seed000.toml"

COMPONENTS = """\
stars = 10
[te]
x = 1.14
y = 1.23
[hsfe]
x = 1.08
y = 1.01
[lsfe_s]
x = 0.03
y = 0.66
[lsfe_c1]
x = 0.29
y = 0.41
[lsfe_c2]
x = 0.5
y = 0.5
"""


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "budget.toml"
    p.write_text(text)
    return p


def test_seed_numbers_by_hand(tmp_path):
    components, n, given = load_budget_toml(_write(tmp_path, COMPONENTS))
    r = combine_budget(components=components, n_stars=n, given=given)
    # x: LSFE = sqrt(0.03^2 + (0.29 + 0.5)^2) = sqrt(0.0009 + 0.6241) = sqrt(0.625)
    assert r.lsfe["x"] == pytest.approx(math.sqrt(0.625), rel=1e-12)
    # y: sqrt(0.66^2 + (0.41 + 0.5)^2) = sqrt(0.4356 + 0.8281) = sqrt(1.2637)
    assert r.lsfe["y"] == pytest.approx(math.sqrt(1.2637), rel=1e-12)
    # single x: sqrt(1.14^2 + 1.08^2 + 0.625) = sqrt(1.2996 + 1.1664 + 0.625) = sqrt(3.091)
    assert r.single_star["x"] == pytest.approx(math.sqrt(3.091), rel=1e-12)
    # single y: sqrt(1.5129 + 1.0201 + 1.2637) = sqrt(3.7967)
    assert r.single_star["y"] == pytest.approx(math.sqrt(3.7967), rel=1e-12)
    # attitude: / sqrt(10)
    assert r.attitude["x"] == pytest.approx(math.sqrt(3.091 / 10), rel=1e-12)
    assert r.attitude["y"] == pytest.approx(math.sqrt(3.7967 / 10), rel=1e-12)
    assert r.warnings == ()


def test_cli_seed_example_flags_only_lsfe_x(tmp_path):
    out = tmp_path / "res.json"
    res = CliRunner().invoke(combine_command, [str(SEED_TOML), "--json", str(out)])
    assert res.exit_code == 0, res.output
    assert "single star" in res.output and "attitude, N = 10" in res.output
    data = json.loads(out.read_text())
    for key in ("lsfe", "single_star", "attitude"):
        assert set(data[key]) == {"x", "y"}
    # the seed prints two decimals: agree within half a unit of the last digit
    two = pytest.approx
    assert data["lsfe"]["x"] == two(0.79, abs=0.005) and data["lsfe"]["y"] == two(1.12, abs=0.005)
    assert data["single_star"]["x"] == two(1.76, abs=0.005) and data["single_star"]["y"] == two(1.95, abs=0.005)
    assert data["attitude"]["x"] == two(0.56, abs=0.005) and data["attitude"]["y"] == two(0.62, abs=0.005)
    # the printed LSFE_x = 0.91" is the only total that does not follow from its components
    assert len(data["warnings"]) == 1
    assert data["warnings"][0].startswith("lsfe.x: given 0.91")


def test_given_single_star_checked_with_and_without_given_lsfe(tmp_path):
    text = COMPONENTS + "[single_star]\nx = 1.90\ny = 1.95\n"
    r = CliRunner().invoke(combine_command, [str(_write(tmp_path, text))])
    assert r.exit_code == 0
    assert "single_star.x: given 1.9" in r.output
    assert "single_star.y" not in r.output


def test_tolerance_option(tmp_path):
    text = COMPONENTS + "[lsfe]\nx = 0.80\ny = 1.12\n"   # computed 0.7906: off by 0.0094
    p = _write(tmp_path, text)
    assert "warning" not in CliRunner().invoke(combine_command, [str(p)]).output
    assert "lsfe.x" in CliRunner().invoke(combine_command, [str(p), "--tolerance", "0.005"]).output


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        (COMPONENTS.replace("[te]\nx = 1.14\ny = 1.23\n", ""), "te: missing table"),
        (COMPONENTS.replace("[hsfe]\nx = 1.08\n", "[hsfe]\n"), "hsfe.x: missing"),
        (COMPONENTS.replace("x = 0.29", "x = -0.29"), "lsfe_c1.x: must be finite and >= 0"),
        (COMPONENTS.replace("x = 0.03", 'x = "0.03"'), "lsfe_s.x: expected a number"),
        (COMPONENTS.replace("stars = 10", "stars = 2.5"), "stars: expected an integer"),
        (COMPONENTS.replace("stars = 10\n", ""), "stars: missing"),
        (COMPONENTS + "[extra]\nx = 1\n", "extra: unknown key"),
        (COMPONENTS.replace("y = 0.66", "y = 0.66\nz = 1"), "lsfe_s.z: unknown key"),
    ],
)
def test_bad_input_names_file_and_key(tmp_path, text, needle):
    p = _write(tmp_path, text)
    with pytest.raises(ScenarioError) as err:
        load_budget_toml(p)
    assert needle in str(err.value) and str(p) in str(err.value)
    res = CliRunner().invoke(combine_command, [str(p)])
    assert res.exit_code != 0 and isinstance(res.exception, ScenarioError)


def test_cli_wrapper_prints_error_without_traceback(tmp_path, capsys):
    from budget.cli import main

    p = _write(tmp_path, COMPONENTS.replace("x = 0.29", "x = -1"))
    with pytest.raises(SystemExit) as exc:
        main(["starcam", "combine", str(p)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "lsfe_c1.x" in err and "Traceback" not in err
