"""Seeds 000 and 001 run through the one runner give what their own machinery gives, bit for bit."""

import numpy as np
import pytest
from tiny_camera import TINY

from budget.runner.registry import get_study, study_names
from budget.runner.run import run_study


def test_registry_lists_the_built_studies():
    names = study_names()
    assert {"starcam", "inductosyn"} <= set(names)
    for n in names:
        assert get_study(n).name == n


def test_starcam_study_equals_its_trials_and_truths():
    """The runner adds nothing to seed 000's numbers: its samples are the seed-000 trials
    (budget.starcam.validate.run_trial, the same protocols and estimators) in arcsec 3 sigma, its
    truths budget.starcam.validate.truths, bit for bit."""
    import tomllib

    from budget.starcam.validate import run_trial, truths
    from simcam.starcam.scenario import from_dict

    scn = from_dict(tomllib.loads(TINY), source="tiny")
    study = get_study("starcam")
    # the scenario's own truth sizes (the adaptive sizing has its tests in tests/test_truth_sizing.py)
    res = run_study(study, scn, trials=3, seed=5, workers=1, truth_size="fixed")
    f = 3.0 * scn.camera.scale_arcsec_per_px
    direct = [run_trial(scn, 5, k)["values"] for k in range(3)]
    assert set(res.samples) == set(direct[0])
    for key in direct[0]:
        assert np.array_equal(res.samples[key], np.array([d[key] * f for d in direct])), key
    old = truths(scn, seed=5)
    for (cls, ax), t in res.truths.items():
        assert t.value == getattr(old[cls], f"{ax}_px") * f


def test_inductosyn_study_equals_harmonics_validate():
    from budget.inductosyn.validate import prepare, run_trials
    from simcam.encoder.inductosyn import default

    scn = default()
    study = get_study("inductosyn")
    res = run_study(study, scn, trials=30, seed=2, workers=1)
    ref = run_trials(prepared=prepare(scenario=scn, dense_step_deg=scn.validation.dense_step_deg),
                     trials=30, seed=2)
    assert np.array_equal(res.samples[("residual", "published", "angle")], ref["short_sigma3_after_arcsec"])
    assert np.array_equal(res.trial_truths[("residual", "improved", "angle")], ref["joint_dense_sigma3_after_arcsec"])
    # the coefficients and the report's per-trial figures are run_trials' numbers too
    assert np.array_equal(res.samples[("coefficient", "published", "A_S1s")], ref["c_short"][:, 1])
    assert np.array_equal(res.samples[("coefficient", "improved", "A_S4s")], ref["c_joint"][:, -1])
    assert np.array_equal(res.aux["e0_in_sequence_arcsec"], ref["c_long"][:, 0])
    assert np.array_equal(res.aux["joint_dense_maxabs_after_arcsec"], ref["joint_dense_maxabs_after_arcsec"])
    assert np.array_equal(res.example.extra["y_short"], ref["y_short"][0])
    # a trial's numbers do not depend on the batch it is computed in (row-wise products)
    one = study.trial(scn, 2, 7)
    assert one.estimates == study.trial_batch(scn, 2, [5, 6, 7])[2].estimates
    assert one.truths == study.trial_batch(scn, 2, list(range(40)))[7].truths


@pytest.mark.parametrize("new_maps", [False, True])
def test_starcam_truths_spread_over_workers_are_the_same(new_maps):
    """The truths computed piece by piece on two workers (the HSFE phases as separate
    tasks) equal the truths computed in one piece, bit for bit."""
    import tomllib

    from budget.starcam.validate import truths
    from simcam.starcam.scenario import from_dict

    data = tomllib.loads(TINY)
    data["validation"]["new_maps_per_trial"] = new_maps
    scn = from_dict(data, source="tiny")
    study = get_study("starcam")
    # the scenario's own truth sizes (the sized truths spread the same way: the runner sizes
    # the scenario first, tests/test_truth_sizing.py)
    res = run_study(study, scn, trials=2, seed=4, workers=2, truth_size="fixed")
    whole = study._contract_truths(scn, truths(scn, seed=4))
    assert res.truths.keys() == whole.keys()
    for key, t in whole.items():
        assert (res.truths[key].value, res.truths[key].se) == (t.value, t.se), key
