"""``[validation] protocols``: a validation of some of seed 000's protocols computes only their
classes, with the same numbers as a validation of all four on the same seed; and the two
planning hooks of the star camera (``field_classes``, ``restrict_classes``)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from budget.starcam import validate as V
from budget.starcam.study import STUDY
from simcam.infra.errors import ScenarioError
from simcam.config_base import read_toml
from simcam.starcam.scenario import default, with_updates

sys.path.insert(0, str(Path(__file__).parent))
from tiny_camera import TINY  # noqa: E402


def _tiny(**validation):
    d = read_toml(text=TINY, source="tiny")
    d["validation"].update(validation)
    return STUDY.from_dict(d, source="tiny")


def test_classes_follow_the_protocols():
    names = {tuple(p): [c.name for c in STUDY.classes(with_updates(default(), {"validation.protocols": p}))]
             for p in (["te"], ["hsfe"], ["chromatic"], ["distortion"], ["distortion", "chromatic"])}
    assert names[("te",)] == ["te", "lsfe_c2"]
    assert names[("hsfe",)] == ["hsfe", "lsfe_c2"]
    assert names[("chromatic",)] == ["lsfe_s", "lsfe_c2"]
    assert names[("distortion",)] == ["lsfe_c1", "lsfe_c2"]
    assert names[("distortion", "chromatic")] == ["lsfe_s", "lsfe_c1", "lsfe_c2", "lsfe"]
    assert [c.name for c in STUDY.classes(default())] == list(V.CLASSES)


@pytest.mark.parametrize("value, message", [
    ([], r"validation\.protocols: .*at least one protocol"),
    (["hsfe", "hsfe"], r"validation\.protocols: .*listed twice"),
    (["hsfe", "lsfe"], r"validation\.protocols\.1: Input should be 'te', 'hsfe', 'chromatic' or 'distortion'"),
])
def test_a_wrong_protocol_list_is_one_error_naming_the_field(value, message):
    with pytest.raises(ScenarioError, match=message):
        with_updates(default(), {"validation.protocols": value})


@pytest.mark.parametrize("protocols", [["hsfe"], ["chromatic"], ["te", "distortion"]])
def test_a_restricted_trial_gives_the_full_trials_numbers(protocols):
    """The default (realistic) world, run seed 5, trial 1: every value of the restricted trial
    is the full trial's, bit for bit (each protocol's frames draw from their own streams; the
    world's drift and hexapod follow the whole run's timeline whatever is computed)."""
    full = V.run_trial(default(), 5, 1)["values"]
    sub = V.run_trial(with_updates(default(), {"validation.protocols": protocols}), 5, 1)["values"]
    computed = V.computed_classes(with_updates(default(), {"validation.protocols": protocols}))
    assert {k[0] for k in sub} == set(computed)
    for k, v in sub.items():
        assert v == full[k], k


def test_restricted_truths_are_the_full_truths_of_their_classes():
    """Small test camera, truth seed of run seed 3: the truths of a restricted scenario are the
    full scenario's for its classes (same streams, bit for bit), and only those are computed
    (no HSFE pieces without the HSFE protocol, nor TE or HSFE pieces where their truths are
    each trial's camera's own: pixel maps drawn per trial, the default)."""
    for maps in (True, False):
        full = with_updates(_tiny(), {"validation.new_maps_per_trial": maps})
        ft = STUDY.truths(full, 3)
        for protocols in (["hsfe"], ["chromatic"], ["te", "distortion"]):
            s = with_updates(full, {"validation.protocols": protocols})
            t = STUDY.truths(s, 3)
            # LSFE-C1, LSFE and the total (and HSFE with its own maps) are each trial's
            # camera's own: not among the run's truths
            own = set(V.instrument_classes(s))
            assert ("hsfe" in own) == ("te" in own) == maps
            assert {c for c, _ in t} == set(V.computed_classes(s)) - own
            for key, v in t.items():
                assert (v.value, v.se) == (ft[key].value, ft[key].se), (protocols, key)
            phases = s.validation.hsfe_phase_grid**2
            assert len(STUDY.truth_parts(s, 3)) == (1 + ("te" in protocols and not maps)
                                                     + phases * ("hsfe" in protocols and not maps))


def test_restrict_classes_picks_the_protocols_the_classes_need():
    d = default()
    assert STUDY.restrict_classes(d, frozenset({"hsfe"})).validation.protocols == ("hsfe",)
    assert STUDY.restrict_classes(d, frozenset({"lsfe"})).validation.protocols == ("chromatic", "distortion")
    assert STUDY.restrict_classes(d, frozenset({"te", "lsfe_s"})).validation.protocols == ("te", "chromatic")
    assert STUDY.restrict_classes(d, frozenset({"lsfe_c2"})).validation.protocols == ("te",)
    assert STUDY.restrict_classes(d, frozenset({"total"})) is d
    r = STUDY.restrict_classes(d, frozenset({"lsfe_s"}))
    # lab time is the unrestricted scenario's business, but a restriction changes none of it
    assert STUDY.lab_time_s(r) == STUDY.lab_time_s(d)
    with pytest.raises(ValueError, match="unknown class"):
        STUDY.restrict_classes(d, frozenset({"lsfe_z"}))


def test_field_classes_name_every_plannable_field():
    """Every knob's field and every shape's field is listed, with classes of the study."""
    d = default()
    fc = STUDY.field_classes(d)
    fields = {k.field for k in STUDY.protocol_knobs(d)}
    for overrides in STUDY.protocol_shapes(d).values():
        fields |= set(overrides)
    assert fields <= set(fc)
    names = {c.name for c in STUDY.classes(d)}
    for f, cls in fc.items():
        assert set(cls) <= names, f
        # each class a field changes, the combinations built from it change too
        if "lsfe_s" in cls or "lsfe_c1" in cls:
            assert "lsfe" in cls and "total" in cls, f
        if cls:
            assert "total" in cls, f


def test_a_restricted_validation_reports_only_its_classes(tmp_path):
    """A whole run through the runner on the small test camera (3 trials, seed 0): the report
    and its likely causes are written without the missing classes."""
    from budget.runner.run import run_study

    s = with_updates(_tiny(), {"validation.protocols": ["hsfe"]})
    res = run_study(STUDY, s, trials=3, seed=0, workers=1)
    assert {k[0] for k in res.samples} == {"hsfe", "lsfe_c2"}
    assert {k[0] for k in res.truths} == {"hsfe", "lsfe_c2"}
    from budget.runner.report import write_report

    out = write_report(res, tmp_path / "rep")
    assert Path(out).exists()
    for key in res.samples:
        STUDY.likely_cause(res, key, res.statistics(key))
