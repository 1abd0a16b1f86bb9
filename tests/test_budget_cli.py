"""One command grammar: `budget <study> <verb>` for every study.

The star camera's lab commands live in its group (`budget starcam simulate|measure|combine`
beside `validate`); `budget validate` is the documented alias of the main job (the same
command object as `budget starcam validate`); `budget harmonics` is the inductosyn group
under a second name; the former top-level commands are one `error:` line naming the new
command, exit 2. Every study's `validate` takes --seed with the one default, 0.
"""

from __future__ import annotations

import click
import pytest

from budget.cli import cli
from budget.runner.registry import REGISTRY, study_names
from simcam.infra.cli import run_cli


def _ctx():
    return click.Context(cli)


def test_top_level_lists_the_studies_and_the_machinery_only():
    names = cli.list_commands(_ctx())
    assert names == sorted({*study_names(), "validate", "sweep", "plot", "claims"})
    for gone in ("measure", "simulate", "combine", "harmonics"):
        assert gone not in names


def test_starcam_group_holds_the_lab_commands():
    group = cli.get_command(_ctx(), "starcam")
    assert set(group.list_commands(_ctx())) == {"validate", "simulate", "measure", "combine", "robustness", "scenario", "plan"}


def test_budget_validate_is_the_starcam_validate_command():
    group = cli.get_command(_ctx(), "starcam")
    assert cli.get_command(_ctx(), "validate") is group.get_command(_ctx(), "validate")


def test_aliases_are_the_same_group():
    for e in REGISTRY:
        for alias in e.aliases:
            assert cli.get_command(_ctx(), alias) is cli.get_command(_ctx(), e.name)


@pytest.mark.parametrize("old", ["measure", "simulate", "combine"])
def test_former_top_level_command_is_one_line_naming_the_new_one(old, capsys):
    with pytest.raises(SystemExit) as ei:
        run_cli(cli, [old, "te", "somewhere"])
    assert ei.value.code == 2
    cap = capsys.readouterr()
    assert cap.err == f"error: `budget {old}` is now `budget starcam {old}`\n"
    assert cap.out == ""


@pytest.mark.parametrize("name", study_names())
def test_every_validate_defaults_the_seed_to_zero(name):
    validate = cli.get_command(_ctx(), name).get_command(_ctx(), "validate")
    seed = next(p for p in validate.params if p.name == "seed")
    assert seed.default == 0
    assert "dense_step_deg" not in {p.name for p in validate.params}


def test_registry_table_entries_resolve_to_their_study():
    """One table (name, module:attribute, help): each entry's instance carries its name,
    names are unique, and an alias or former name is no study's name."""
    from budget.runner.registry import get_study

    names = [e.name for e in REGISTRY]
    assert len(set(names)) == len(names)
    for e in REGISTRY:
        assert get_study(e.name).name == e.name and e.summary
        assert not set(e.aliases + e.former_names) & set(names)
