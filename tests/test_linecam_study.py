"""The linecam study on the shared runner: reproducibility, keys, report."""

from __future__ import annotations

import numpy as np

from budget.linecam.study import STUDY
from budget.runner.run import run_study

SC = STUDY.load_scenario()
#: a quicker plan for the runner test: a given strip (no sky search), two passes
SMALL = STUDY.from_dict({"stars": {"region": "manual", "ra_deg": 280.0, "dec_deg": -5.0},
                         "observation": {"passes": 2, "shift_px": 2000.0}}, source="small")


def test_trial_is_reproducible_and_complete():
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


def test_two_workers_equal_one_worker_bit_for_bit(tmp_path):
    r1 = run_study(STUDY, SMALL, trials=4, seed=7, workers=1)
    r2 = run_study(STUDY, SMALL, trials=4, seed=7, workers=2)
    for key in r1.samples:
        assert np.array_equal(r1.samples[key], r2.samples[key]), key
        assert np.array_equal(r1.trial_truths[key], r2.trial_truths[key]), key
    for key in r1.sigmas:
        assert np.array_equal(r1.sigmas[key], r2.sigmas[key], equal_nan=True), key
    sections = STUDY.report_sections(r1, tmp_path)
    assert len(sections) == 1 and len(sections[0].figures) == 4
    assert all(f.exists() and f.stat().st_size > 1000 for f in sections[0].figures)
    assert "unobservable combinations" in sections[0].markdown
