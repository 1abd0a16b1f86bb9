"""The star camera's set-up through the runner's cache (budget.starcam.setup,
budget.runner.capabilities.prepared): one camera build for scenarios that differ only in the
truths' sampling sizes, and no module-level cache left in budget/starcam."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import budget.starcam
from budget.runner.capabilities import SETUPS_KEPT, prepared
from budget.starcam.study import STUDY
from simcam.infra.errors import ScenarioError
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
    ca, cb, cc, c0 = (prepared(STUDY, s).camera() for s in (a, b, c, base))
    assert ca.detector_key == cb.detector_key and len({ca.detector_key, cc.detector_key, c0.detector_key}) == 3
    assert (ca.onboard_correction.coef_x == cb.onboard_correction.coef_x).all()
    assert not (ca.onboard_correction.coef_x == cc.onboard_correction.coef_x).all()
    assert STUDY.trial(a, 3, 1).estimates == STUDY.trial(b, 3, 1).estimates
    assert c0.scenario.seed == base.seed  # unset: the scenario seed's camera, as before


def test_a_pinned_instrument_refuses_new_maps_per_trial():
    with pytest.raises(ScenarioError, match=r"validation: .*new_maps_per_trial: a pinned instrument_seed"):
        with_updates(default(), {"validation.instrument_seed": 5, "validation.new_maps_per_trial": True})
