"""``validate --ideal-world``: the same run as the scenario with every ``[world.effects]``
magnitude 0, one option away; the header names the world a run simulated."""

from __future__ import annotations

import json
from pathlib import Path

from budget.runner.report import world_line
from simcam.infra.cli import run_cli

ROOT = Path(__file__).resolve().parents[1]


def _budget(argv) -> int:
    from budget.cli import cli

    try:
        run_cli(cli, argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    return 0


def test_ideal_world_flag_equals_the_ideal_scenario_file(tmp_path, capsys):
    a, b = tmp_path / "flag.json", tmp_path / "file.json"
    common = ["--trials", "4", "--workers", "1", "--no-progress"]
    assert _budget(["inductosyn", "validate", *common, "--ideal-world", "--json", str(a)]) == 0
    out = capsys.readouterr().out
    assert "world: ideal" in out
    assert _budget(["inductosyn", "validate", str(ROOT / "docs" / "examples" / "inductosyn_ideal.toml"),
                    *common, "--json", str(b)]) == 0
    ja, jb = json.loads(a.read_text()), json.loads(b.read_text())
    assert ja["classes"] == jb["classes"] and ja["truths"] == jb["truths"]   # the same run, bit for bit
    assert ja["world_effects_on"] == [] and jb["world_effects_on"] == []


def test_world_line_names_the_effects_on():
    from budget.runner.registry import get_study
    from budget.runner.robustness import scenario_with_effects

    study = get_study("scanmirror")
    scn = study.load_scenario()
    names = scn.world.effects.names()
    assert world_line(scn).startswith(f"world: {len(names)} of {len(names)} unmodelled effects on (")
    one = scenario_with_effects(study, scn, {n: 0.0 for n in names[1:]}, source="test")
    assert world_line(one) == f"world: 1 of {len(names)} unmodelled effects on ({names[0]})"


def test_ideal_world_on_a_study_without_effects_is_a_user_error():
    import pytest

    from budget.runner.validate_cmd import ideal_world_scenario
    from simcam.infra.errors import UserInputError
    from toy_study import STUDY as TOY   # a study whose scenario has no world

    with pytest.raises(UserInputError, match="--ideal-world: the .* study has no \\[world.effects\\]"):
        ideal_world_scenario(TOY, TOY.load_scenario(), source="toy")
