"""The chromatic test's filter set (``protocols.chromatic.filters_nm``,
``protocols.chromatic.plan_filter_sets``): the plan, the lab time, the world's timeline and
the LSFE-S estimators follow it; the truth does not (it is the stars' chromatic error)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from budget.starcam.study import STUDY
from simcam.infra.errors import ScenarioError
from simcam.starcam.scenario import default, with_updates


def _ideal(scn):
    eff = scn.world.effects
    return with_updates(scn, {f"world.effects.{n}": 0.0 for n in type(eff).model_fields})


# ------------------------------------------------------------------ the field
def test_default_takes_every_lab_filter():
    d = default()
    assert d.protocols.chromatic.filters_nm == ()
    assert d.chromatic_filters_nm() == (500.0, 600.0, 800.0)
    from budget.starcam.protocols import make_plan

    explicit = with_updates(d, {"protocols.chromatic.filters_nm": [800.0, 500.0, 600.0]})
    assert make_plan("chromatic", explicit).conditions == make_plan("chromatic", d).conditions


@pytest.mark.parametrize("value, message", [
    ([600.0], r"protocols\.chromatic\.filters_nm: .*at least 2 filters"),
    ([600.0, 600.0], r"protocols\.chromatic\.filters_nm: .*listed twice"),
    ([500.0, 800.0], r"protocols\.chromatic\.filters_nm: .*lacks the reference filter"),
    ([600.0, 700.0], r"protocols\.chromatic\.filters_nm: \[700\.0\] not among lab\.filters"),
])
def test_a_wrong_filter_set_is_one_error_naming_the_field(value, message):
    with pytest.raises(ScenarioError, match=message):
        with_updates(default(), {"protocols.chromatic.filters_nm": value})


def test_plan_filter_sets_are_checked():
    d = default()
    with pytest.raises(ScenarioError, match=r"protocols\.chromatic\.plan_filter_sets.*lacks the reference"):
        with_updates(d, {"protocols.chromatic.plan_filter_sets": [[500.0, 600.0], [500.0, 800.0]]})
    with pytest.raises(ScenarioError, match=r"protocols\.chromatic\.plan_filter_sets: .*listed twice"):
        with_updates(d, {"protocols.chromatic.plan_filter_sets": [[500.0, 600.0], [600.0, 500.0]]})
    nine = [[600.0, 500.0 + k] for k in range(9)]
    with pytest.raises(ScenarioError, match=r"protocols\.chromatic\.plan_filter_sets: .*at most 8"):
        with_updates(d, {"protocols.chromatic.plan_filter_sets": nine})


# ------------------------------------------------------------------ plan, world, lab time
def test_a_subset_plan_keeps_the_lab_condition_indices_and_the_world_agrees():
    """{600, 800}: 4 fields x 2 filters; each condition keeps its index in the full plan
    (field x 3 lab filters + lab filter), which is also the world's timeline key."""
    from budget.starcam.protocols import make_plan
    from simcam.starcam.world import commanded_pointing_px, timeline

    d = default()
    s = with_updates(d, {"protocols.chromatic.filters_nm": [600.0, 800.0]})
    full = {c.index: c for c in make_plan("chromatic", d).conditions}
    sub = make_plan("chromatic", s).conditions
    assert [c.filter_nm for c in sub] == [600.0, 800.0] * 4
    assert [c.index for c in sub] == [1, 2, 4, 5, 7, 8, 10, 11]
    for c in sub:
        assert c == full[c.index]
    assert sorted(k[1] for k in commanded_pointing_px(s) if k[0] == "chromatic") == [c.index for c in sub]
    # the distortion test starts 4 conditions of 30 frames (and their settling) earlier
    period = d.camera.exposure_s + d.world.frame_overhead_s
    shift = 4 * (30 * period + d.world.settle_s)
    assert timeline(d)[("distortion", 0)][0] - timeline(s)[("distortion", 0)][0] == pytest.approx(shift, rel=1e-12)


def test_lab_time_of_a_two_filter_test_by_hand():
    """{600, 800}, 0.1 s exposure + 0.05 s readout, filter change 2 s, move 2 s, settle 8 s: 4
    fields x 2 filters x 30 frames; one filter change per field (600 -> 800) and 3 field moves,
    each with the filter back to 600 nm (one settling for both)."""
    s = with_updates(default(), {"protocols.chromatic.filters_nm": [600.0, 800.0]})
    lt = STUDY.lab_time_s(s)
    assert lt["chromatic.frames"] == pytest.approx(4 * 2 * 30 * 0.15, rel=1e-12)
    assert lt["chromatic.changes"] == pytest.approx(4 * (2.0 + 8.0) + 3 * (2.0 + 2.0 + 8.0), rel=1e-12)
    full = STUDY.lab_time_s(default())
    assert {k: v for k, v in lt.items() if not k.startswith("chromatic")} == \
        {k: v for k, v in full.items() if not k.startswith("chromatic")}


# ------------------------------------------------------------------ shapes
def test_filter_sets_are_shapes_crossed_with_the_hsfe_patterns():
    d = default()
    shapes = STUDY.protocol_shapes(d)
    assert list(shapes) == [f"{p}, filters {f}" for p in ("diagonal", "grid")
                            for f in ("500/600", "600/800", "500/600/800")]
    assert shapes["grid, filters 600/800"] == {"protocols.hsfe.pattern": "grid",
                                                "protocols.chromatic.filters_nm": [600.0, 800.0]}
    # a plan that does not open the chromatic test keeps its filters: today's two HSFE names
    hs = with_updates(d, {"protocols.plan_knobs": ["hsfe.frames", "hsfe.poses"]})
    assert STUDY.protocol_shapes(hs) == {"diagonal": {"protocols.hsfe.pattern": "diagonal"},
                                         "grid": {"protocols.hsfe.pattern": "grid"}}
    ch = with_updates(d, {"protocols.plan_knobs": ["chromatic.frames"]})
    assert list(STUDY.protocol_shapes(ch)) == ["filters 500/600", "filters 600/800", "filters 500/600/800"]
    # nor does a validation that does not run it
    assert list(STUDY.protocol_shapes(with_updates(d, {"validation.protocols": ["hsfe"]}))) == ["diagonal", "grid"]
    assert STUDY.protocol_shapes(with_updates(d, {"protocols.plan_knobs": ["te.frames"]})) == {}
    given = with_updates(ch, {"protocols.chromatic.plan_filter_sets": [[800.0, 600.0]]})
    assert STUDY.protocol_shapes(given) == {"filters 600/800": {"protocols.chromatic.filters_nm": [600.0, 800.0]}}


def test_too_many_lab_filters_for_the_shapes_is_one_error_naming_the_field():
    filters = [{"center_nm": 450.0 + 50.0 * k, "width_nm": 50.0} for k in range(6)]   # 450 ... 700
    s = with_updates(default(), {"lab.filters": filters})
    with pytest.raises(ScenarioError, match=r"protocols\.chromatic\.plan_filter_sets: the lab's 6 filters give 31 sets.*more than the 8"):
        STUDY.protocol_shapes(s)
    listed = with_updates(s, {"protocols.chromatic.plan_filter_sets": [[450.0, 600.0], [600.0, 700.0]]})
    assert len(STUDY.protocol_shapes(listed)) == 2 * 2


# ------------------------------------------------------------------ the truth does not follow it
def test_lsfe_s_truth_does_not_depend_on_the_labs_filters():
    """The truth is the stars' chromatic displacement (no lab filter enters it): the same for
    every filter set, bit for bit, and the study says so (one truth identity)."""
    from budget.runner.study import truth_identity
    from budget.starcam.truth import lsfe_s_truth

    d = _ideal(default())
    ref = lsfe_s_truth(STUDY.prepared(d).camera())
    for fs in ([500.0, 600.0], [600.0, 800.0]):
        s = with_updates(d, {"protocols.chromatic.filters_nm": fs})
        t = lsfe_s_truth(STUDY.prepared(s).camera())
        assert (t.x_px, t.y_px) == (ref.x_px, ref.y_px)
        assert truth_identity(STUDY, s) == truth_identity(STUDY, d)
        assert "protocols.chromatic.filters_nm" not in STUDY.truth_fields(s)


def test_a_filters_frames_are_the_same_whichever_other_filters_are_taken():
    """Ideal world (no drift timeline): the 600 and 800 nm centroids of the {600, 800} test are
    those of the full test, frame for frame (common random numbers between filter sets)."""
    from budget.starcam.protocols import make_plan, simulate

    d = with_updates(_ideal(default()), {"protocols.chromatic.frames": 3})
    s = with_updates(d, {"protocols.chromatic.filters_nm": [600.0, 800.0]})
    full = simulate(make_plan("chromatic", d), STUDY.prepared(d).camera(), seed=11).centroids
    sub = simulate(make_plan("chromatic", s), STUDY.prepared(s).camera(), seed=11).centroids
    keep = full[full["filter_nm"].isin([600.0, 800.0])].reset_index(drop=True)
    pd.testing.assert_frame_equal(keep[["star", "frame", "condition", "x", "y"]],
                                  sub[["star", "frame", "condition", "x", "y"]].reset_index(drop=True))


# ------------------------------------------------------------------ estimators on two filters
def _table(shift_px: dict, fields=("a", "b", "c", "d"), stars=5, frames=2) -> pd.DataFrame:
    """Noise-free centroids: every star of every field displaced by ``shift_px[filter]`` (x,
    y) from its place, the same in every frame."""
    rows = []
    for fi, f in enumerate(fields):
        for j in range(stars):
            x0, y0 = 100.0 * fi + 10.0 * j, 50.0 * fi - 7.0 * j
            for fnm, (dx, dy) in shift_px.items():
                for fr in range(frames):
                    rows.append({"field": f, "star": j, "filter_nm": fnm, "frame": fr, "x": x0 + dx, "y": y0 + dy})
    return pd.DataFrame(rows)


@pytest.mark.parametrize("filters", [(500, 600), (600, 800), (500, 600, 800)])
def test_published_lsfe_s_takes_one_difference_per_non_reference_filter(filters):
    """Eqs 15-16: each filter's difference to the reference, longer minus shorter, summed over
    the W K (field, star) pairs and divided by 2 W K; table 1 gives one delta_bar per pair, so
    the "2" is not a count of differences and n filters give n - 1 of them. With shifts s_f:
    delta_bar(hi-lo) = (s_hi - s_lo) / 2, sigma = max |delta_bar| / 3 (section 1.4.1)."""
    from budget.starcam.estimators import chromatic_error

    s = {500: (-0.06, 0.01), 600: (0.0, 0.0), 800: (0.12, 0.007)}
    est = chromatic_error(_table({f: s[f] for f in filters}), plate_scale_arcsec=5.5, reference_filter_nm=600)
    assert len(est.pairs) == len(filters) - 1
    want = {ax: max(abs(s[f][i] - s[600][i]) / 2.0 for f in filters if f != 600) / 3.0
            for i, ax in enumerate(("x", "y"))}
    # noise-free sums of a few hundred terms: a few ulps of the 0.1 px shifts
    assert est.sigma_x_px == pytest.approx(want["x"], rel=1e-12, abs=1e-15)
    assert est.sigma_y_px == pytest.approx(want["y"], rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("filters", [(500, 600), (600, 800), (500, 600, 800)])
def test_improved_lsfe_s_on_two_filters_is_the_slope_through_them(filters):
    """The population estimator (docs/estimators.md 7.2) fits X = a + b lambda_f over the
    filters; two filters determine the line exactly. Shifts linear in the effective wavelength,
    s_f = b (lambda_f - 600): every filter set gives b, and sigma = |b| rms_p(lambda_p - lambda_cal)."""
    from budget.starcam.estimators import chromatic_error_population

    lam = {500: 512.0, 600: 603.0, 800: 790.0}
    bx, by = 2e-4, -5e-5
    tab = _table({f: (bx * (lam[f] - 600.0), by * (lam[f] - 600.0)) for f in filters})
    stars = [450.0, 600.0, 700.0]
    est = chromatic_error_population(tab, plate_scale_arcsec=5.5, filter_wavelength_nm=lam,
                                     star_wavelengths_nm=stars, calibration_wavelength_nm=600.0,
                                     reference_filter_nm=600)
    rms = math.sqrt(np.mean((np.array(stars) - 600.0) ** 2))
    assert est.sigma_x_px == pytest.approx(abs(bx) * rms, rel=1e-9)
    assert est.sigma_y_px == pytest.approx(abs(by) * rms, rel=1e-9)


def test_a_trial_runs_every_estimator_on_two_filters():
    """A whole chromatic protocol on the small test camera with {600, 800}: the published
    estimator has one pair, the improved one two effective wavelengths (the lab's model)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from tiny_camera import TINY

    from budget.starcam import validate as V
    from simcam.config_base import read_toml

    d = read_toml(text=TINY, source="tiny")
    d["protocols"]["chromatic"]["filters_nm"] = [600.0, 800.0]
    d["validation"]["protocols"] = ["chromatic"]
    scn = STUDY.from_dict(d, source="tiny")
    r = V.run_trial(scn, 3, 0, keep=True)
    est = r["kept"]["chromatic"]["estimates"]
    assert list(est["published"].pairs["pair"]) == ["800-600"]
    assert len(est["improved"].details["filter_effective_wavelengths_nm"]) == 2
    assert all(np.isfinite(v) for v in r["values"].values())
    # the lab's spectral model shifts the test's filters with the lab's (lab.knowledge)
    from budget.starcam.protocols import lab_spectral_scenario

    lab = lab_spectral_scenario(scn)
    k = scn.lab.knowledge.filter_center_nm_error
    assert lab.chromatic_filters_nm() == (600.0 + k, 800.0 + k)
