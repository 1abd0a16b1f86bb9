"""One shape per concept across the five instruments: every scenario module has the same
four functions, every scenario the same base (name, validation, hash, source), every
[validation] table the same fields and limits, and every study reaches its scenario
through ``scenario_module``."""

from __future__ import annotations

import importlib

import pytest

from budget.runner.registry import get_study, study_names
from budget.runner.study import ClassSpec
from simcam.infra.errors import ScenarioError
from simcam.config_base import ScenarioBase, ValidationSettings, read_toml

STUDIES = study_names()


def test_every_study_is_here():
    assert set(STUDIES) == {"starcam", "inductosyn", "whiskbroom", "scanmirror", "linecam", "attitude"}


@pytest.mark.parametrize("name", STUDIES)
def test_scenario_module_has_the_four_functions(name):
    study = get_study(name)
    module = importlib.import_module(study.scenario_module)
    scenario = module.default()
    assert isinstance(scenario, ScenarioBase) and isinstance(scenario.validation, ValidationSettings)
    assert scenario.name.strip(), "every embedded default has a name"
    assert module.load(None) == scenario
    assert module.from_dict(read_toml(text=module.default_text(), source="t"), source="t") == scenario
    assert study.load_scenario(None) == scenario and study.default_text() == module.default_text()
    assert len(scenario.hash) == 16 and study.scenario_hash(scenario) == scenario.hash
    assert module.from_dict(read_toml(text=module.default_text(), source="here.toml"),
                            source="here.toml").source == "here.toml"


@pytest.mark.parametrize("name", STUDIES)
def test_validation_fields_and_limits_are_shared(name):
    study = get_study(name)
    module = importlib.import_module(study.scenario_module)
    data = read_toml(text=module.default_text(), source="t")
    for field, bad in (("trials", 1), ("max_trials", 1), ("batch_trials", 0), ("tolerance", 0.0)):
        broken = dict(data, validation=dict(data.get("validation", {}), **{field: bad}))
        with pytest.raises(ScenarioError, match=rf"f\.toml: validation\.{field}"):
            module.from_dict(broken, source="f.toml")
    ok = dict(data, validation=dict(data.get("validation", {}), tolerance=0.5))
    assert module.from_dict(ok, source="f.toml").validation.tolerance == 0.5
    assert module.default().validation.tolerance is None  # a fixed count by default, every study


@pytest.mark.parametrize("name", STUDIES)
def test_the_source_is_not_part_of_the_content(name):
    module = importlib.import_module(get_study(name).scenario_module)
    data = read_toml(text=module.default_text(), source="t")
    a, b = module.from_dict(data, source="a.toml"), module.from_dict(data, source="b.toml")
    assert a == b and a.hash == b.hash and a.source != b.source


def test_class_role_is_checked():
    ClassSpec("x", "x", "1", role="residual")
    with pytest.raises(ValueError, match="role"):
        ClassSpec("x", "x", "1", role="biased")
