"""The linecam study on the shared runner: equivalence (same seed, same numbers; any worker
count), keys, report. These are equivalence tests of the code with itself, not physics: the
physics of the calibration is checked against its stated uncertainties in
tests/test_linecam_calibrate.py and by test_trial_errors_agree_with_the_stated_sigmas below."""

from __future__ import annotations

import numpy as np

from budget.linecam.study import STUDY
from budget.runner.run import run_study

SC = STUDY.load_scenario()
#: a quicker plan for the runner test: a given strip (no sky search), two passes
#: in the ideal world (every [world.effects] magnitude 0): these tests check the lab's
#: calibration against its own model; what the world's effects do to it is
#: tests/test_linecam_effects.py's and docs/linecam.md's
SMALL = STUDY.from_dict({"stars": {"region": "manual", "ra_deg": 280.0, "dec_deg": -5.0},
                         "observation": {"passes": 2, "shift_px": 2000.0},
                         "world": {"effects": {n: 0.0 for n in SC.world.effects.names()}}}, source="small")


def test_trial_equivalence_same_seed_same_numbers_and_complete():
    """Equivalence: the same trial twice gives the same numbers (not a physics check)."""
    a = STUDY.trial(SC, 3, 1)
    b = STUDY.trial(SC, 3, 1)
    assert a.estimates == b.estimates and a.truths == b.truths and a.sigmas == b.sigmas
    # LOS classes for every variant; camera parameters for those that have them
    keys = {(c.name, v, ax) for c in STUDY.classes(SC) for v in STUDY.variants for ax in c.axes
            if c.name.startswith("los") or v != "lookangle"}
    assert set(a.estimates) == keys
    assert set(a.truths) == keys  # every class has per-trial truths
    assert all(np.isfinite(list(a.estimates.values())))
    assert STUDY.truths(SC, 3) == {}


def test_workers_equivalence_two_equal_one_bit_for_bit(tmp_path):
    """Equivalence: two workers give one worker's numbers (not a physics check)."""
    r1 = run_study(STUDY, SMALL, trials=4, seed=7, workers=1)
    r2 = run_study(STUDY, SMALL, trials=4, seed=7, workers=2)
    for key in r1.samples:
        assert np.array_equal(r1.samples[key], r2.samples[key]), key
        assert np.array_equal(r1.trial_truths[key], r2.trial_truths[key]), key
    for key in r1.sigmas:
        assert np.array_equal(r1.sigmas[key], r2.sigmas[key], equal_nan=True), key
    sections = STUDY.report_sections(r1, tmp_path)
    # the four figures are placed in the text, each with its caption (not repeated in
    # ``figures``, which the runner would draw a second time)
    import re

    names = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", sections[0].markdown)
    assert len(sections) == 1 and len(names) == 4 and not sections[0].figures
    assert all((tmp_path / n).exists() and (tmp_path / n).stat().st_size > 1000 for n in names)
    assert "unobservable combinations" in sections[0].markdown


def test_trial_errors_agree_with_the_stated_sigmas():
    """The physics the equivalence tests stand in for: the calibration recovers the injected
    camera (the per-trial truths) within the uncertainty it states. For the parameters the
    stars determine (yaw, focal length, k1, k2, p1, p2; pitch, roll and the principal point
    are determined only in combinations, which the report lists), the normalised errors
    z = (estimate - truth) / sigma of K = 20 trials (fixed seed) are N(0, 1) when the
    stated sigma is right: |mean z| < 4 / sqrt(K) and (K - 1) sd(z)^2 within the 99.9 %
    limits of chi2(K - 1) (sd between 0.56 and 1.52). At this size that catches a stated
    sigma wrong by a factor 1.8 or more (or 0.66 or less), not finer."""
    from scipy import stats

    res = run_study(STUDY, SMALL, trials=20, seed=7, workers=1)
    k = res.trials
    lo, hi = (np.sqrt(stats.chi2.ppf(q, k - 1) / (k - 1)) for q in (0.0005, 0.9995))
    checked = 0
    for (cls, var, ax), x in res.samples.items():
        if ax not in ("yaw", "df", "k1", "k2", "p1", "p2"):
            continue
        z = (x - res.trial_truths[(cls, var, ax)]) / res.sigmas[(cls, var, ax)]
        assert abs(z.mean()) < 4 / np.sqrt(k), (cls, var, ax, z.mean())
        assert lo < z.std(ddof=1) < hi, (cls, var, ax, z.std(ddof=1))
        checked += 1
    assert checked == 12  # six parameters, published and improved


def test_a_folding_distortion_drawn_by_a_trial_names_the_file_and_fields():
    """A scenario at the edge of its ranges (distortion sigmas so large that a trial's camera
    folds its focal plane) is one ScenarioError naming the file and the fields, not an
    optics error without a file."""
    import pytest

    from simcam.infra.errors import ScenarioError

    sc = STUDY.from_dict({"errors": {"k1": {"sigma": 5.0}, "k2": {"sigma": 5.0}}}, source="edge.toml")
    with pytest.raises(ScenarioError, match=r"^edge\.toml: errors\.k1 / k2 / p1 / p2 .*folds"):
        STUDY.trial(sc, 0, 0)
