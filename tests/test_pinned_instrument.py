"""What a run speaks for: each trial its own instrument, or one instrument pinned by
``validation.instrument_seed`` or by a study that does not yet draw its instrument per trial
(:meth:`simcam.config_base.ScenarioBase.pinned_instrument`), which the report and the claims
page then say (:func:`budget.runner.ledger_view.instrument_line`)."""

from budget.runner.ledger_view import instrument_line
from budget.runner.registry import get_study
from simcam.dotted import scenario_with


def _scenario(name, updates=None):
    study = get_study(name)
    scn = study.load_scenario(None)
    return scenario_with(scn, updates, from_dict=study.from_dict, where="test") if updates else scn


def test_studies_drawing_their_instrument_per_trial_pin_nothing_by_default():
    for name in ("inductosyn", "scanmirror", "linecam"):
        scn = _scenario(name)
        assert scn.pinned_instrument() is None and instrument_line(scn) is None, name


def test_an_instrument_seed_pins_the_instrument_and_the_line_says_so():
    scn = _scenario("scanmirror", {"validation.instrument_seed": 3})
    assert scn.pinned_instrument() == "instrument seed 3"
    line = instrument_line(scn)
    assert "instrument seed 3" in line and "that instrument only" in line and "leave the instrument seed unset" in line


def test_the_star_camera_says_its_default_camera_is_one_instrument():
    """The star camera's maps and onboard calibration are one draw of the scenario seed unless
    ``new_maps_per_trial`` (docs/validation.md): its reports must not speak for a population."""
    scn = _scenario("starcam")
    assert "scenario seed's camera" in scn.pinned_instrument()
    assert "does not yet draw it per trial" in instrument_line(scn)
    maps = _scenario("starcam", {"validation.new_maps_per_trial": True})
    assert "pixel maps drawn per trial" in maps.pinned_instrument()
    assert "flown camera's pixel maps" in _scenario("attitude").pinned_instrument()
