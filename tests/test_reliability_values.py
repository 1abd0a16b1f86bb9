"""Bad input, round three (issue #35): one shape for a bad value in every study's scenario.

* a boolean is never a number (``true`` was read as 1 in ``[world.effects]`` of every study
  and in the inductosyn, whiskbroom and scan-mirror fields): every numeric field of every
  study's scenario is tried with ``true``;
* every float is finite and every magnitude and sigma has a physical range declared beside
  its field; a value outside it is refused with the range, naming the field (not a later
  symptom such as ``u_px: must be finite``).
"""

from __future__ import annotations

import re
import types

import pytest
from pydantic import BaseModel

from budget.runner.registry import get_study, study_names
from simcam.config_base import _bounds, _leaf_types, bool_where_number
from simcam.effects import EffectsBase
from simcam.infra.errors import ScenarioError

STUDIES = study_names()
#: a field whose name says it is an uncertainty or an error's size
SIGMA = re.compile(r"(sigma|noise|_std|rms|_error)(_|$)")


def _numeric_fields(model: BaseModel, prefix: tuple = ()):
    """(path, field info, is an effect) of every field taking an int or a float, through
    nested models (the first element of a list of models)."""
    for name, info in type(model).model_fields.items():
        value = getattr(model, name)
        path = (*prefix, name)
        if isinstance(value, BaseModel):
            yield from _numeric_fields(value, path)
        elif isinstance(value, (list, tuple)) and value and isinstance(value[0], BaseModel):
            yield from _numeric_fields(value[0], (*path, 0))
        elif any(t in (int, float) for t in _leaf_types(info.annotation)) and bool not in _leaf_types(info.annotation):
            yield path, info, isinstance(model, EffectsBase)


def _with(data: dict, path: tuple, value, depth: int = 1):
    """A copy of ``data`` with ``path`` set (in a list or tuple value, its first number)."""
    import copy

    out = copy.deepcopy(data)
    node, key = out, path[-1]
    for part in path[:-1]:
        node = node[part]
    while isinstance(node.get(key) if isinstance(node, dict) else node[key], (list, tuple)) and node[key]:
        node[key] = list(node[key])
        node, key = node[key], 0
    if isinstance(node.get(key) if isinstance(node, dict) else node[key], (list, tuple)):
        for _ in range(depth):  # an empty list gets one element (a list of lists, one list of one)
            value = [value]
    node[key] = value
    return out


def _depth(ann) -> int:
    """How many lists or tuples deep the numbers of an annotation are (0 for a number)."""
    import typing

    while typing.get_origin(ann) is typing.Annotated or typing.get_origin(ann) in (typing.Union, types.UnionType):
        ann = next(a for a in typing.get_args(ann) if a is not type(None))
    if typing.get_origin(ann) in (list, tuple):
        return 1 + _depth(typing.get_args(ann)[0])
    return 0


def _dump(study):
    scn = study.load_scenario()
    return scn, scn.model_dump(mode="json", exclude_none=True)


@pytest.mark.parametrize("name", STUDIES)
def test_a_boolean_is_never_a_number_in_any_field_of_any_study(name):
    study = get_study(name)
    scn, data = _dump(study)
    study.from_dict(data, source="s.toml")  # the dump is accepted back
    tried = 0
    for path, info, _effect in _numeric_fields(scn):
        dotted = ".".join(map(str, path))
        with pytest.raises(ScenarioError) as ei:
            study.from_dict(_with(data, path, True, _depth(info.annotation)), source="s.toml")
        msg = str(ei.value)
        assert "a boolean (true/false) is not a number" in msg and path[-1] in msg and "s.toml" in msg, (dotted, msg)
        tried += 1
    assert tried >= 15, tried


@pytest.mark.parametrize("name", STUDIES)
def test_every_magnitude_and_sigma_declares_a_physical_range(name):
    scn = get_study(name).load_scenario()
    missing = []
    for path, info, effect in _numeric_fields(scn):
        if not (effect or SIGMA.search(path[-1])) or float not in _leaf_types(info.annotation):
            continue
        b = _bounds(info.annotation, info.metadata)
        if not (("ge" in b or "gt" in b) and ("le" in b or "lt" in b)):
            missing.append(".".join(map(str, path)))
    assert not missing, f"{name}: declare Field(ge=..., le=...) beside {missing}"


@pytest.mark.parametrize("name,path,value,expected", [
    # a table of nan, 300-digit numbers, a residual of 1.8e5 arcsec: now refused with the range
    ("inductosyn", ("calibration", "autocollimator", "noise_arcsec"), float("inf"),
     "calibration.autocollimator.noise_arcsec: must be a finite number; its range is [0, 3600] (got inf)"),
    ("inductosyn", ("calibration", "autocollimator", "noise_arcsec"), 1e300,
     "calibration.autocollimator.noise_arcsec: Input should be less than or equal to 3600; its range is [0, 3600]"),
    ("inductosyn", ("world", "effects", "polygon_tilt_arcsec"), 1e308,
     "world.effects.polygon_tilt_arcsec: Input should be less than or equal to 3600; its range is [0, 3600]"),
    # accepted; and "u_px: must be finite" named a later symptom
    ("starcam", ("world", "effects", "hexapod_repeatability_arcsec"), -1.0,
     "world.effects.hexapod_repeatability_arcsec: Input should be greater than or equal to 0; its range is [0, 60]"),
    ("starcam", ("world", "effects", "hexapod_repeatability_arcsec"), 1e308,
     "world.effects.hexapod_repeatability_arcsec: Input should be less than or equal to 60; its range is [0, 60]"),
    # "check orbit, mirror.rest_angle_deg" named the wrong field
    ("whiskbroom", ("camera", "focal_length_mm"), 1e-300,
     "camera.focal_length_mm: Input should be greater than or equal to 1; its range is [1, 100000]"),
    ("whiskbroom", ("world", "effects", "attitude_jitter_arcsec"), 1e4,
     "world.effects.attitude_jitter_arcsec: Input should be less than or equal to 100; its range is [0, 100]"),
    ("scanmirror", ("orbit", "knowledge_sigma_km"), 1e300, "orbit.knowledge_sigma_km: Input should be less than"),
    ("linecam", ("world", "effects", "jitter_band_arcsec"), float("nan"),
     "world.effects.jitter_band_arcsec: must be a finite number; its range is [0, 3600] (got nan)"),
])
def test_extreme_values_are_refused_with_the_range_naming_their_field(name, path, value, expected):
    study = get_study(name)
    _, data = _dump(study)
    with pytest.raises(ScenarioError) as ei:
        study.from_dict(_with(data, path, value), source="s.toml")
    lines = str(ei.value).splitlines()
    assert len(lines) == 1 and lines[0].startswith("s.toml: ") and expected in lines[0], lines


def test_bool_where_number_looks_inside_containers():
    from typing import Annotated, Any, Literal

    from pydantic import Field

    assert bool_where_number(True, float) and bool_where_number(True, int | None)
    assert not bool_where_number(True, bool) and not bool_where_number(True, float | bool)
    assert not bool_where_number(True, Any) and not bool_where_number(1.0, float)
    assert bool_where_number([1.0, True], list[float])
    assert bool_where_number((1.0, True), tuple[float, Annotated[float, Field(ge=0)]])
    assert not bool_where_number((1.0, True), tuple[float, bool])
    assert bool_where_number({"a": True}, dict[str, float])
    assert not bool_where_number("x", Literal["x"])


def test_sweep_files_refuse_a_boolean_for_a_number(tmp_path):
    from budget.sweeps.models import SweepSpec

    from simcam.config_base import validate_model

    with pytest.raises(ScenarioError, match=r"sw.toml: seed: a boolean \(true/false\) is not a number"):
        validate_model(SweepSpec, {"name": "x", "base": "b.toml", "kind": "starcam", "seed": True,
                                   "parameters": {"a.b": [1.0, 2.0]}}, source="sw.toml")
