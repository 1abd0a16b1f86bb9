"""Dotted keys (simcam.dotted): reading and setting a scenario's fields by path with one error
rule, and the fields a scenario derives dropped before setting so they are derived again."""

from __future__ import annotations

import copy
import os
from typing import Any

import pytest
from pydantic import model_validator
from test_lens_products import SMALL_ANALYSIS, small_star_camera

from budget.runner.plan import scenario_with as plan_scenario_with
from budget.runner.registry import get_study
from budget.runner.robustness import scenario_with_effects
from simcam.config_base import ScenarioBase, StrictModel, validate_model
from simcam.dotted import (
    covers,
    derived_paths,
    drop_derived,
    get_dotted,
    scenario_with,
    set_dotted,
    set_values,
)
from simcam.infra.errors import ScenarioError
from simcam.starcam.scenario import from_dict as starcam_from_dict
from simcam.starcam.scenario import with_updates

# a hand-built scenario dump: tables, a list of tables, a list of values, an unset field
RESOLVED = {
    "camera": {"exposure_s": 0.1, "lens": None},
    "detector": {"chips": [{"read_noise_e": 3.0}, {"read_noise_e": 4.0}], "gain_e_per_adu": 2.0},
    "lab": {"target_center_px": [0.0, 0.0]},
}


def _err(fn, *args, **kwargs) -> str:
    with pytest.raises(ScenarioError) as exc:
        fn(*args, **kwargs)
    return str(exc.value)


# ------------------------------------------------------------------ get_dotted
def test_get_reads_mappings_lists_and_models():
    assert get_dotted(RESOLVED, "camera.exposure_s") == 0.1
    assert get_dotted(RESOLVED, "detector.chips.1.read_noise_e") == 4.0
    assert get_dotted(RESOLVED, "lab.target_center_px") == [0.0, 0.0]
    assert get_dotted(RESOLVED, "camera.lens") is None

    class Section(StrictModel):
        exposure_s: float = 0.2

        @property
        def rate_hz(self) -> float:
            return 1.0 / self.exposure_s

    class Model(StrictModel):
        camera: Section = Section()

    assert get_dotted(Model(), "camera.exposure_s") == 0.2
    assert get_dotted(Model(), "camera.rate_hz") == 5.0


def test_get_names_the_source_the_key_and_the_known_keys():
    msg = _err(get_dotted, RESOLVED, "camera.exposure", where="run.toml")
    assert msg == "run.toml: 'camera.exposure': unknown key 'exposure' at camera (known keys: exposure_s, lens)"
    assert "'camera.exposure_s.x': camera.exposure_s is a value, not a table" in _err(
        get_dotted, RESOLVED, "camera.exposure_s.x")
    assert "index 2 out of range at detector.chips (a list of 2: use an index 0..1 or *)" in _err(
        get_dotted, RESOLVED, "detector.chips.2.read_noise_e")
    assert "detector.chips is a list: 'first' is not an index" in _err(get_dotted, RESOLVED, "detector.chips.first")
    assert "empty component" in _err(get_dotted, RESOLVED, "camera..exposure_s")


def test_get_with_a_default_returns_it_where_the_key_leads_nowhere():
    for key in ("camera.exposure", "camera.exposure_s.x", "detector.chips.5", "detector.chips.x", "nothing"):
        assert get_dotted(RESOLVED, key, default=None) is None
    assert get_dotted(RESOLVED, "camera.exposure_s", default=None) == 0.1


# ------------------------------------------------------------------ set_dotted
def test_set_creates_missing_tables_and_copies_lists_from_the_resolved_scenario():
    raw: dict[str, Any] = {"camera": {"exposure_s": 0.1}}
    set_dotted(raw, RESOLVED, "camera.exposure_s", 0.5, where="t")
    set_dotted(raw, RESOLVED, "detector.gain_e_per_adu", 1.5, where="t")
    set_dotted(raw, RESOLVED, "detector.chips.1.read_noise_e", 6.0, where="t")
    assert raw == {"camera": {"exposure_s": 0.5},
                   "detector": {"gain_e_per_adu": 1.5, "chips": [{"read_noise_e": 3.0}, {"read_noise_e": 6.0}]}}
    set_dotted(raw, RESOLVED, "detector.chips.*.read_noise_e", 2.0, where="t")
    assert raw["detector"]["chips"] == [{"read_noise_e": 2.0}, {"read_noise_e": 2.0}]
    # a tuple in the dump (model_dump(mode="python")) is copied as a list
    raw2: dict[str, Any] = {}
    set_dotted(raw2, {"lab": {"target_center_px": (1.0, 2.0)}}, "lab.target_center_px.0", 5.0, where="t")
    assert raw2 == {"lab": {"target_center_px": [5.0, 2.0]}}
    # an unset field (None in the dump) takes a value or a table
    set_dotted(raw, RESOLVED, "camera.lens", "embedded:star_camera", where="t")
    assert raw["camera"]["lens"] == "embedded:star_camera"


def test_set_refuses_unknown_keys_naming_the_source_and_the_known_keys():
    raw: dict[str, Any] = {}
    assert _err(set_dotted, raw, RESOLVED, "detector.read_noise", 1.0, where="sweep.toml: fixed") == (
        "sweep.toml: fixed: 'detector.read_noise': unknown key 'read_noise' at detector "
        "(known keys: chips, gain_e_per_adu)")
    assert "unknown key 'camra' at top level (known keys: camera, detector, lab)" in _err(
        set_dotted, raw, RESOLVED, "camra.exposure_s", 1.0, where="t")
    assert "index 3 out of range at detector.chips" in _err(
        set_dotted, raw, RESOLVED, "detector.chips.3.read_noise_e", 1.0, where="t")
    assert "'detector.chips.x.read_noise_e': detector.chips is a list: 'x' is not an index" in _err(
        set_dotted, raw, RESOLVED, "detector.chips.x.read_noise_e", 1.0, where="t")
    assert "camera.exposure_s is a value, not a table" in _err(
        set_dotted, raw, RESOLVED, "camera.exposure_s.ms", 1.0, where="t")
    assert "empty component" in _err(set_dotted, raw, RESOLVED, "camera.", 1.0, where="t")
    assert raw == {}  # nothing set by a refused key


def test_set_refuses_a_table_for_a_value_and_a_value_for_a_table():
    raw: dict[str, Any] = {}
    assert "t: 'camera.exposure_s': camera.exposure_s is a value, not a table (got a table)" in _err(
        set_dotted, raw, RESOLVED, "camera.exposure_s", {"value": 0.2}, where="t")
    assert "lab.target_center_px is a list, not a table" in _err(
        set_dotted, raw, RESOLVED, "lab.target_center_px", {"x": 1.0}, where="t")
    assert "detector.chips.0 is a table (known keys: read_noise_e): give a table" in _err(
        set_dotted, raw, RESOLVED, "detector.chips.0", 3.0, where="t")
    assert "'camera': camera is a table" in _err(set_dotted, raw, RESOLVED, "camera", 0.1, where="t")
    # a table for a table, a list for a list, None to check a key: accepted
    set_dotted(raw, RESOLVED, "camera", {"exposure_s": 0.3}, where="t")
    set_dotted(raw, RESOLVED, "lab.target_center_px", [1.0, 2.0], where="t")
    set_dotted(raw, RESOLVED, "detector.gain_e_per_adu", None, where="t")
    assert raw == {"camera": {"exposure_s": 0.3}, "lab": {"target_center_px": [1.0, 2.0]},
                   "detector": {"gain_e_per_adu": None}}


# ------------------------------------------------------------------ derived fields
def test_covers_is_the_field_a_field_inside_it_or_a_table_around_it():
    assert covers("optics.psf", "optics.psf")
    assert covers("optics.psf.sigma0_px", "optics.psf")
    assert covers("optics", "optics.psf")
    assert not covers("optics.psf_x", "optics.psf")
    assert not covers("optics.distortion", "optics.psf")


def test_drop_derived_removes_what_no_key_sets():
    raw = {"optics": {"psf": {"sigma0_px": 1.0}, "distortion": {"k1": 0.1}, "r_norm_px": 2048.0},
           "camera": {"aperture_diameter_mm": 60.0, "exposure_s": 0.1}}
    derived = ("optics.psf", "optics.distortion", "camera.aperture_diameter_mm", "optics.missing.leaf")
    dropped = drop_derived(raw, derived, ["optics.distortion.k1", "camera.exposure_s"])
    assert dropped == ("optics.psf", "camera.aperture_diameter_mm")
    assert raw == {"optics": {"distortion": {"k1": 0.1}, "r_norm_px": 2048.0}, "camera": {"exposure_s": 0.1}}
    assert drop_derived(raw, (), ["camera.exposure_s"]) == ()


def test_set_values_copies_drops_the_derived_and_sets_in_order():
    raw = {"camera": {"exposure_s": 0.1, "lens": "x"}, "detector": {"gain_e_per_adu": 2.0}}
    before = copy.deepcopy(raw)
    out = set_values(raw, RESOLVED, {"camera.exposure_s": 0.4, "detector.chips.0.read_noise_e": 9.0},
                     where="t", derived=("detector.gain_e_per_adu", "camera.exposure_s"))
    assert raw == before  # the input is not changed
    assert out == {"camera": {"exposure_s": 0.4, "lens": "x"},
                   "detector": {"chips": [{"read_noise_e": 9.0}, {"read_noise_e": 4.0}]}}
    with pytest.raises(ScenarioError, match=r"^plan: 'camera\.exp': unknown key 'exp' at camera"):
        set_values(raw, RESOLVED, {"camera.exp": 1.0}, where="plan")


class _Square(StrictModel):
    side_m: float = 1.0
    area_m2: float = 1.0


class _Derives(ScenarioBase):
    """A scenario whose ``shape.area_m2`` is derived from ``shape.side_m`` (given, it must agree)."""

    shape: _Square = _Square()

    @model_validator(mode="before")
    @classmethod
    def _area(cls, data: Any) -> Any:
        shape = dict(data.get("shape", {}))
        side = shape.get("side_m", 1.0)
        if "area_m2" in shape and shape["area_m2"] != side * side:
            raise ValueError(f"shape.area_m2: {shape['area_m2']} is not side_m squared ({side * side})")
        return {**data, "shape": {**shape, "area_m2": side * side}}

    def derived_paths(self) -> tuple[str, ...]:
        return ("shape.area_m2",)


def _derives_from_dict(data: dict, *, source: str) -> _Derives:
    return validate_model(_Derives, data, source=source).with_source(source)


def test_scenario_with_derives_the_derived_fields_again():
    assert ScenarioBase().derived_paths() == ()  # a scenario derives nothing unless it says so
    assert derived_paths(ScenarioBase()) == () == derived_paths(_Square())  # nor does another model
    base = _derives_from_dict({"shape": {"side_m": 2.0}}, source="sq.toml")
    assert derived_paths(base) == ("shape.area_m2",)
    assert base.shape.area_m2 == 4.0
    moved = scenario_with(base, {"shape.side_m": 3.0}, from_dict=_derives_from_dict, where="sq.toml: plan")
    assert moved.shape == _Square(side_m=3.0, area_m2=9.0) and moved.source == "sq.toml: plan"
    # a derived field set explicitly is kept (and checked by the model)
    both = scenario_with(base, {"shape.side_m": 3.0, "shape.area_m2": 9.0}, from_dict=_derives_from_dict, where="t")
    assert both == moved
    with pytest.raises(ScenarioError, match=r"is not side_m squared"):
        scenario_with(base, {"shape.area_m2": 5.0}, from_dict=_derives_from_dict, where="t")
    assert "t: 'shape.side': unknown key 'side' at shape (known keys: area_m2, side_m)" in _err(
        scenario_with, base, {"shape.side": 3.0}, from_dict=_derives_from_dict, where="t")


# ------------------------------------------------------------------ the star camera's traced lens
@pytest.fixture(scope="module")
def lens_scenario(tmp_path_factory):
    """A star camera scenario through a traced lens (the embedded star camera on a small grid,
    with a private products cache)."""
    d = tmp_path_factory.mktemp("lens")
    old = os.environ.get("SIMCAM_CACHE_DIR")
    os.environ["SIMCAM_CACHE_DIR"] = str(d / "cache")
    path = small_star_camera(d, SMALL_ANALYSIS.replace("field_points = 4", "field_points = 6")
                             .replace("wavelength_points = 7", "wavelength_points = 13"))
    yield starcam_from_dict({"optics": {"lens": str(path)}}, source="lens.toml")
    if old is None:
        os.environ.pop("SIMCAM_CACHE_DIR", None)
    else:
        os.environ["SIMCAM_CACHE_DIR"] = old


def test_the_star_camera_derives_what_its_lens_sets(lens_scenario):
    assert "optics.psf" in lens_scenario.derived_paths()
    assert starcam_from_dict({}, source="t").derived_paths() == ()  # analytic optics: nothing derived


def test_a_planned_scenario_through_a_lens_derives_the_lens_fields_again(lens_scenario):
    # the planner used to resubmit the lens's old values, which the lens then refused
    study = get_study("starcam")
    change = {"optics.lateral_colour.ref_wavelength_nm": 700.0}
    moved = plan_scenario_with(study, lens_scenario, change, where="plan")
    assert moved == with_updates(lens_scenario, change)
    assert moved.optics.lateral_colour.radial_px_per_nm != lens_scenario.optics.lateral_colour.radial_px_per_nm
    # a change the lens does not see keeps what it sets
    frames = plan_scenario_with(study, lens_scenario, {"protocols.te.frames": 7}, where="plan")
    assert frames.optics == lens_scenario.optics and frames.camera == lens_scenario.camera


def test_a_robustness_case_through_a_lens_keeps_the_lens_fields(lens_scenario):
    study = get_study("starcam")
    ideal = scenario_with_effects(study, lens_scenario, {"hexapod_repeatability_arcsec": 0.0}, source="case ideal")
    assert ideal.world.effects.hexapod_repeatability_arcsec == 0.0
    assert ideal.optics == lens_scenario.optics and ideal.camera == lens_scenario.camera
    with pytest.raises(ScenarioError, match=r"^case x: 'world\.effects\.no_such': unknown key 'no_such'"):
        scenario_with_effects(study, lens_scenario, {"no_such": 1.0}, source="case x")
