"""The star camera's set-up through the runner's cache (budget.starcam.setup,
budget.runner.capabilities.prepared): one camera build for scenarios that differ only in the
truths' sampling sizes, and no module-level cache left in budget/starcam."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

import budget.starcam
from budget.runner.capabilities import SETUPS_KEPT, prepared
from budget.starcam.study import STUDY
from simcam.starcam.scenario import default, with_updates

STARCAM = Path(budget.starcam.__file__).parent


def test_truth_sizes_share_one_camera_build_through_the_runners_cache():
    a = with_updates(default(), {"validation.te_truth_frames": 300, "validation.hsfe_truth_frames": 40})
    b = with_updates(a, {"validation.te_truth_frames": 120, "validation.hsfe_truth_frames": 22})
    c = with_updates(a, {"detector.prnu_rms": a.detector.prnu_rms * 0.5})
    assert a.hash != b.hash
    sa, sb, sc = prepared(STUDY, a), prepared(STUDY, b), prepared(STUDY, c)
    assert sa is sb and sa.camera() is sb.camera()
    assert sc is not sa  # the camera reads the PRNU: its own set-up
    # a set-up keeps its cameras of other detector maps, the most recent few
    assert sa.camera(11) is sa.camera(11) and sa.camera(11) is not sa.camera()
    assert SETUPS_KEPT >= 2


def _module_level_caches(path: Path) -> list[str]:
    """Names bound at module level to an empty dict / OrderedDict / set, or functions decorated
    with functools' caches: what a module-level cache looks like."""
    tree = ast.parse(path.read_text())
    out = []
    for node in tree.body:
        value = getattr(node, "value", None)
        targets = getattr(node, "targets", None) or [getattr(node, "target", None)]
        empty = (isinstance(value, (ast.Dict, ast.Set)) and not getattr(value, "keys", getattr(value, "elts", None))) or (
            isinstance(value, ast.Call) and getattr(value.func, "id", getattr(value.func, "attr", "")) in
            {"dict", "OrderedDict", "set", "defaultdict"} and not value.args)
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and empty:
            out += [f"{path.name}: {ast.unparse(t)}" for t in targets if t is not None]
        if isinstance(node, ast.FunctionDef):
            for d in node.decorator_list:
                name = ast.unparse(d)
                if name.split("(")[0].split(".")[-1] in {"cache", "lru_cache", "cached_property"}:
                    out.append(f"{path.name}: @{name} {node.name}")
    return out


def test_no_module_level_cache_in_budget_starcam():
    found = [c for p in sorted(STARCAM.rglob("*.py")) for c in _module_level_caches(p)]
    assert found == []


def test_the_cache_finder_finds_one(tmp_path):
    # the check itself, on a module that has one of each
    p = tmp_path / "m.py"
    p.write_text("import functools\n_CACHE: dict = {}\nX = dict()\n@functools.lru_cache\ndef f():\n    pass\n")
    assert _module_level_caches(p) == ["m.py: _CACHE", "m.py: X", "m.py: @functools.lru_cache f"]


def test_a_pinned_instrument_seed_draws_the_camera_and_nothing_else():
    """validation.instrument_seed = N: the camera's drawn properties (its maps' key, its
    onboard calibration's errors) come from N whatever the scenario seed, and a trial is then the
    same for two scenario seeds (no other draw reads it); another N is another camera."""
    base = with_updates(default(), {"validation.protocols": ["distortion"]})
    a = with_updates(base, {"validation.instrument_seed": 5})
    b = with_updates(base, {"validation.instrument_seed": 5, "seed": base.seed + 1})
    c = with_updates(base, {"validation.instrument_seed": 6})
    ca, cb, cc = (prepared(STUDY, s).instrument(3, 1) for s in (a, b, c))
    c0 = prepared(STUDY, base).camera()
    assert ca.detector_key == cb.detector_key and len({ca.detector_key, cc.detector_key, c0.detector_key}) == 3
    assert (ca.onboard_correction.coef_x == cb.onboard_correction.coef_x).all()
    assert not (ca.onboard_correction.coef_x == cc.onboard_correction.coef_x).all()
    assert prepared(STUDY, a).instrument(4, 7) is ca  # every trial and run seed: the one camera
    assert STUDY.trial(a, 3, 1).estimates == STUDY.trial(b, 3, 1).estimates


def test_unset_every_trial_draws_its_camera_maps_and_calibration():
    """instrument_seed unset (the default): trial k's camera has the pixel maps and calibration
    errors of the first word of instrument_seed_sequence(None, seed, k); with
    new_maps_per_trial = false the maps are the scenario seed's. Its LSFE-C1 truth is its own,
    and the trial carries it (a per-trial truth; LSFE and the total combine it with the fixed
    truths); so are TE's and HSFE's with its own maps."""
    from budget.runner.study import instrument_seed_sequence
    from budget.starcam.truth import lsfe_c1_truth

    base = with_updates(default(), {"validation.protocols": ["distortion"]})
    assert base.validation.maps_per_trial
    setup = prepared(STUDY, base)
    cams = [setup.instrument(3, k) for k in (0, 1)]
    words = [int(instrument_seed_sequence(None, 3, k).generate_state(1, dtype=np.uint32)[0]) for k in (0, 1)]
    assert [c.calibration_seed for c in cams] == words and words[0] != words[1]
    assert [c.detector_seed for c in cams] == words
    assert not (cams[0].onboard_correction.coef_x == cams[1].onboard_correction.coef_x).all()
    shared = with_updates(base, {"validation.new_maps_per_trial": False})
    one = [prepared(STUDY, shared).instrument(3, k) for k in (0, 1)]
    assert {c.detector_key for c in one} == {prepared(STUDY, shared).camera().detector_key}
    assert [c.calibration_seed for c in one] == words
    r = STUDY.trial(base, 3, 1)
    f = STUDY._factor(base)
    assert r.truths[("lsfe_c1", "improved", "x")] == pytest.approx(lsfe_c1_truth(cams[1]).x_px * f, rel=1e-12)
    assert [c.per_trial_truth for c in STUDY.classes(base)] == [True, False]  # lsfe_c1, lsfe_c2
    both = with_updates(default(), {"validation.protocols": ["te", "hsfe"]})
    assert [(c.name, c.per_trial_truth) for c in STUDY.classes(both)] == [
        ("te", True), ("hsfe", True), ("lsfe_c2", False)]
    fixed = with_updates(both, {"validation.new_maps_per_trial": False})
    assert [c.per_trial_truth for c in STUDY.classes(fixed)] == [False, False, False]


def test_a_pinned_instrument_fixes_the_maps_whatever_new_maps_per_trial_says():
    """A pinned camera serves every trial, its maps included: new_maps_per_trial (true by
    default) no longer applies (``maps_per_trial`` False), and every truth is the run's."""
    pinned = with_updates(default(), {"validation.instrument_seed": 5, "validation.protocols": ["te", "hsfe"]})
    assert pinned.validation.new_maps_per_trial and not pinned.validation.maps_per_trial
    setup = prepared(STUDY, pinned)
    assert setup.instrument(3, 0) is setup.instrument(3, 1)
    assert not any(c.per_trial_truth for c in STUDY.classes(pinned))


def test_a_twin_is_the_camera_built_with_its_seeds_though_it_shares_the_optical_caches():
    """StarCamera.twin shares the scene cache of the camera it comes from: a scene the first
    camera rendered (and whose detector chain it keeps) must give the twin the chain, drift
    gradients and reported positions of a camera built anew with the twin's seeds, bit for bit."""
    from budget.starcam.protocols import _star_grid, make_plan
    from simcam.starcam.render import Placement, StarCamera

    scn = default()
    base = StarCamera(scn, parallel=False)
    c = make_plan("te", scn).conditions[0]
    placement = Placement(layout=_star_grid(base, c.field_center_px), condition=5)
    scene = base.scene(placement)
    base.window_chain(scene)
    base.drift_chain(scene)
    twin = base.twin(detector_seed=11, calibration_seed=12)
    fresh = StarCamera(scn, detector_seed=11, calibration_seed=12, parallel=False)
    assert twin.scene(placement) is scene  # the optical cache is shared
    np.testing.assert_array_equal(twin.window_chain(scene).mean_e, fresh.window_chain(fresh.scene(placement)).mean_e)
    (_, gu, gv), (_, fu, fv) = twin.drift_chain(scene), fresh.drift_chain(fresh.scene(placement))
    np.testing.assert_array_equal(gu, fu)
    np.testing.assert_array_equal(gv, fv)
    assert not np.array_equal(twin.window_chain(scene).mean_e, base.window_chain(scene).mean_e)
    x, y = np.array([100.0, 2500.0]), np.array([300.0, 1700.0])
    np.testing.assert_array_equal(np.stack(twin.report_positions(x, y)), np.stack(fresh.report_positions(x, y)))
    assert not np.array_equal(np.stack(twin.report_positions(x, y)), np.stack(base.report_positions(x, y)))
