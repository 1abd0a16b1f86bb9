"""``budget <study> scenario`` and ``simcam scenario``: the scenario with its comments, text
that the study reads back to the same scenario (same hash); --resolved every field."""

import pytest
from click.testing import CliRunner

from budget.cli import cli as budget_cli
from budget.runner.registry import get_study, study_names
from simcam.cli import cli as simcam_cli


@pytest.mark.parametrize("name", study_names())
def test_every_study_prints_its_default_scenario_with_comments(name, tmp_path):
    study = get_study(name)
    r = CliRunner().invoke(budget_cli, [name, "scenario"])
    assert r.exit_code == 0, r.output
    body = r.output.split("\n", 1)[1]
    assert body == study.default_text() if study.default_text().endswith("\n") else body == study.default_text() + "\n"
    assert sum(line.lstrip().startswith("#") for line in body.splitlines()) >= 3  # the comments kept
    p = tmp_path / "s.toml"
    p.write_text(r.output)  # the header is a comment: the output is itself a scenario file
    h = study.scenario_hash(study.load_scenario())
    assert study.scenario_hash(study.load_scenario(p)) == h and h in r.output.splitlines()[0]
    r2 = CliRunner().invoke(budget_cli, [name, "scenario", "--resolved"])
    assert r2.exit_code == 0, r2.output
    p.write_text(r2.output)
    assert study.scenario_hash(study.load_scenario(p)) == h


def test_a_bad_scenario_file_is_one_error_line(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("nonsense_key = 1\n")
    r = CliRunner().invoke(budget_cli, ["linecam", "scenario", str(p)])
    # a ScenarioError naming file and field: the console script prints it as one error line, exit 2
    from simcam.infra.errors import ScenarioError

    assert isinstance(r.exception, ScenarioError) and r.output == ""
    assert str(p) in str(r.exception) and "nonsense_key" in str(r.exception)


def test_simcam_scenario_keeps_its_comments():
    r = CliRunner().invoke(simcam_cli, ["scenario"])
    assert r.exit_code == 0, r.output
    assert sum(line.startswith("#") for line in r.output.splitlines()) >= 3
    assert "# Embedded default scenario" in r.output
    r2 = CliRunner().invoke(simcam_cli, ["scenario", "--resolved"])
    assert r2.exit_code == 0 and sum(line.startswith("#") for line in r2.output.splitlines()) == 1
