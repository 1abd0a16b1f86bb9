"""Seed 004's protocol for the planner: its knobs (passes, magnitude limit) and lab time."""

from __future__ import annotations

import math

import pytest

from budget.linecam.study import STUDY
from simcam.dotted import set_dotted
from simcam.infra.errors import ScenarioError
from simcam.linecam.scenario import default, from_dict


def _with(sc, **keys):
    raw = sc.model_dump(mode="json", exclude_none=True)
    resolved = sc.model_dump(mode="json", exclude_none=True)
    for k, v in keys.items():
        set_dotted(raw, resolved, k, v, where="test")
    return from_dict(raw, source="test")


def test_lab_time_of_the_default_protocol_by_hand():
    # 10 deg strip at 10 um / (1000 mm x 0.5 ms) = 0.02 rad/s: 0.174533 rad / 0.02 = 8.7266 s a scan;
    # four passes started 30 s apart: 3 x 30 s + the last scan
    scan = 10 * math.pi / 180 / 0.02
    t = STUDY.lab_time_s(default())
    assert t["scans"] == pytest.approx(4 * scan, rel=1e-12)
    assert t["returns between passes"] == pytest.approx(3 * (30.0 - scan), rel=1e-12)
    assert sum(t.values()) == pytest.approx(90.0 + 8.72665, abs=1e-5)
    # the magnitude limit costs no time
    assert STUDY.lab_time_s(_with(default(), **{"stars.mag_limit": 7.0})) == t


def test_knob_bounds_are_settable_and_checked():
    sc = default()
    knobs = STUDY.protocol_knobs(sc)
    assert [k.field for k in knobs] == ["observation.passes", "stars.mag_limit"]
    assert knobs[1].high == sc.stars.world_mag_limit
    for knob in knobs:
        for v in (knob.low, knob.high):
            STUDY.check(_with(sc, **{knob.field: int(v) if knob.kind == "int" else float(v)}), where="test")
    with pytest.raises(ScenarioError, match="world_mag_limit"):  # the world images no fainter star
        _with(sc, **{"stars.mag_limit": knobs[1].high + 0.5})


def test_the_bright_end_of_the_magnitude_knob_still_calibrates_in_one_pass():
    sc = _with(default(), **{"observation.passes": 1, "stars.mag_limit": STUDY.protocol_knobs(default())[1].low})
    r = STUDY.trial(sc, 0, 0)
    assert all(math.isfinite(v) for v in r.estimates.values())


def test_plan_end_to_end_on_a_loose_requirement():
    """`plan` on the study's own hooks (passes 1 to 2, the default magnitude limit fixed, to
    keep it short: ~8 s of CPU): a bound of 10 arcsec on the improved
    look angle at the line's end (one pass: ~0.5 arcsec) is met by one pass, 8.73 s of scan,
    and the re-validation on fresh seeds confirms it. Fixed seed 0."""
    from budget.linecam.study import LineCamStudy
    from budget.runner.plan import plan_protocol
    from budget.runner.study import Knob

    class FewPasses(LineCamStudy):
        def protocol_knobs(self, scenario):
            return (Knob("observation.passes", "int", 1, 2, "passes", "passes over the strip"),)

    res = plan_protocol(FewPasses(), default(), ["los.across_100<=10"], variant="improved", trials=20, seed=0)
    assert res.feasible and res.confirmed
    assert res.recommended.knobs == {"observation.passes": 1}
    assert res.recommended.cost_s == pytest.approx(10 * math.pi / 180 / 0.02, rel=1e-12)
