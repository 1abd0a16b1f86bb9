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


def test_the_star_camera_draws_its_pixel_maps_per_trial_and_says_so_when_told_not_to():
    """The star camera draws each trial's pixel maps and onboard calibration by default
    (docs/validation.md): nothing is pinned. With ``new_maps_per_trial = false`` the maps are
    the scenario seed's for every trial, and its reports must say the maps are one draw; so
    must the attitude study's when its flown camera keeps one draw of maps."""
    assert _scenario("starcam").pinned_instrument() is None
    assert _scenario("attitude").pinned_instrument() is None
    scn = _scenario("starcam", {"validation.new_maps_per_trial": False})
    assert "scenario seed's pixel maps" in scn.pinned_instrument()
    line = instrument_line(scn)
    assert "Part of the instrument is one draw" in line and "new_maps_per_trial = false" in line
