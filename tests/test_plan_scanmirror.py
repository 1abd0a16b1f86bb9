"""Seed 003's protocol for the planner: its knobs (star dwells, frames per dwell) and lab time."""

from __future__ import annotations

import pytest

from budget.scanmirror.study import STUDY
from simcam.dotted import set_dotted
from simcam.scanmirror.scanplan import segment_durations
from simcam.scanmirror.scenario import default, from_dict


def _with(sc, **keys):
    raw = sc.model_dump(mode="json", exclude_none=True)
    resolved = sc.model_dump(mode="json", exclude_none=True)
    for k, v in keys.items():
        set_dotted(raw, resolved, k, v, where="test")
    return from_dict(raw, source="test")


def test_lab_time_of_the_paper_protocol_by_hand():
    # seed 003: slew to the star-sensing position 2 + 6 + 2 s, one 20 s star dwell, slew back 2 + 6 + 2 s
    t = STUDY.lab_time_s(default())
    assert t == {"star dwells": 20.0, "moves between dwells": 0.0, "slews to and from the stars": 20.0}
    # three dwells of six 5 s frames, two 2 s moves between them, the same two slews
    t3 = STUDY.lab_time_s(_with(default(), **{"star_sensing.dwells": 3, "star_sensing.frames_per_dwell": 6,
                                              "star_sensing.frame_time_s": 5.0}))
    assert t3 == {"star dwells": 90.0, "moves between dwells": 4.0, "slews to and from the stars": 20.0}


def test_frames_cost_time_only_with_a_frame_time():
    assert [k.field for k in STUDY.protocol_knobs(default())] == ["star_sensing.dwells"]
    sc = _with(default(), **{"star_sensing.frame_time_s": 5.0})
    assert [k.field for k in STUDY.protocol_knobs(sc)] == ["star_sensing.dwells", "star_sensing.frames_per_dwell"]
    # the flown plan: 4 frames of 5 s are the written 20 s dwell; 6 frames make it 30 s
    assert sc.effective_plan == default().scan_plan
    sc6 = _with(sc, **{"star_sensing.frames_per_dwell": 6})
    star = [s for s in sc6.effective_plan.segments if s.kind == "dwell" and s.star_sensing]
    assert [s.duration_s for s in star] == [30.0]
    flown = sum(segment_durations(sc6.effective_plan.segments))
    written = sum(segment_durations(default().scan_plan.segments))
    assert flown == pytest.approx(written + 10.0, abs=1e-9)


def test_knob_bounds_are_settable_and_checked():
    sc = _with(default(), **{"star_sensing.frame_time_s": 5.0})
    for knob in STUDY.protocol_knobs(sc):
        for v in (knob.low, knob.high):
            STUDY.check(_with(sc, **{knob.field: int(v)}), where="test")


def test_default_protocol_unchanged_by_a_zero_frame_time():
    """frame_time_s = 0 (the default) flies the plan as written: trial 0 is today's."""
    sc = default()
    assert sc.effective_plan is sc.scan_plan
    a = STUDY.trial(sc, 3, 0)
    b = STUDY.trial(_with(sc, **{"star_sensing.frame_time_s": 0.0}), 3, 0)
    assert a.estimates == b.estimates and a.truths == b.truths


def test_plan_end_to_end_on_a_loose_requirement():
    """`plan` on the study's own hooks (dwells 1 to 3 to keep it fast): a bound on the
    improved estimate of dtau ten times the realistic world's spread (sd ~6 arcsec, its
    tracker bias included) is met by one dwell, the paper's 40 s of star sensing, and the
    re-validation on fresh seeds confirms it. Fixed seed 0."""
    from budget.runner.plan import plan_protocol
    from budget.runner.study import Knob
    from budget.scanmirror.study import ScanMirrorStudy

    class FewDwells(ScanMirrorStudy):
        def protocol_knobs(self, scenario):
            return (Knob("star_sensing.dwells", "int", 1, 3, "dwells", "star-sensing dwells"),)

    res = plan_protocol(FewDwells(), default(), ["dtau.x<=60"], variant="improved", trials=20, seed=0)
    assert res.feasible and res.confirmed
    assert res.recommended.knobs == {"star_sensing.dwells": 1}
    assert res.recommended.cost_s == 40.0


@pytest.mark.slow
def test_the_ideal_world_plan_recommends_at_most_100_s_re_validated():
    """Issue #33 item 6: on the ideal-world scan mirror, ``dtau.x<=0.5``, the planner answered
    "infeasible, best 10 dwells x 4 frames (238 s)", deciding 10 dwells of one frame (88 s) on
    200 trials only, where 600 fresh trials give it 0.471 +- 0.014" (meets). With the verdict
    rule and settling it recommends a protocol of at most 100 s, confirmed by the re-validation
    (a fixed seed: deterministic; the fast variant of the rule is tests/test_plan_decide.py's toy)."""
    from pathlib import Path

    import budget

    scn = Path(__file__).parents[1] / "docs" / "examples" / "scenarios" / "scanmirror_plan_ideal.toml"
    res = budget.plan("scanmirror", scn, require=["dtau.x<=0.5"], trials=200, seed=0, workers=1)
    assert res.feasible and res.recommended.cost_s <= 100.0, res.answer()
    assert res.recommended.verdict == "holds" and res.confirmed, res.answer()
