"""simcam.effects: the one shape of every study's world effects."""

import pytest
from pydantic import Field

from simcam.infra.errors import ScenarioError
from simcam.config_base import validate_model
from simcam.effects import EffectsBase, WorldBase, scenario_effects


class _Effects(EffectsBase):
    tilt_arcsec: float = Field(0.5, description="a data sheet's repeatability")
    gain_ratio: float = Field(0.0, description="off by default")
    drift_um: float = Field(-2.0, description="a signed magnitude")


class _World(WorldBase):
    effects: _Effects = _Effects()
    drift_time_constant_s: float = 600.0


def test_names_active_ideal_only():
    e = _Effects()
    assert e.names() == ("tilt_arcsec", "gain_ratio", "drift_um")
    assert e.active() == ("tilt_arcsec", "drift_um")
    assert e.ideal().magnitudes() == {"tilt_arcsec": 0.0, "gain_ratio": 0.0, "drift_um": 0.0}
    assert e.ideal().active() == ()
    assert e.only("drift_um").magnitudes() == {"tilt_arcsec": 0.0, "gain_ratio": 0.0, "drift_um": -2.0}
    assert type(e.only("tilt_arcsec")) is _Effects
    with pytest.raises(KeyError, match="no effect 'nope'"):
        e.only("nope")
    assert _Effects.sources()["tilt_arcsec"] == "a data sheet's repeatability"


def test_world_from_a_mapping_and_bad_magnitudes_name_the_field():
    w = validate_model(_World, {"effects": {"gain_ratio": 1e-3}, "drift_time_constant_s": 60})
    assert w.effects.active() == ("tilt_arcsec", "gain_ratio", "drift_um")
    assert scenario_effects(type("S", (), {"world": w})()) is w.effects
    assert scenario_effects(object()) is None
    with pytest.raises(ScenarioError, match=r"w.toml: effects.tilt_arcsec: .*finite"):
        validate_model(_World, {"effects": {"tilt_arcsec": float("inf")}}, source="w.toml")
    with pytest.raises(ScenarioError, match=r"effects.bogus: unknown key"):
        validate_model(_World, {"effects": {"bogus": 1.0}})


def test_subclasses_that_break_the_shape_are_refused():
    with pytest.raises(TypeError, match="float magnitude"):
        class _IntEffect(EffectsBase):
            n: int = Field(1, description="x")
    with pytest.raises(TypeError, match="physical source"):
        class _Unsourced(EffectsBase):
            x_um: float = 1.0
    with pytest.raises(TypeError, match="never switches"):
        class _Switch(WorldBase):
            effects: _Effects = _Effects()
            jitter_on: bool = True
