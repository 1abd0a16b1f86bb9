"""The whiskbroom study on the shared runner, and its commands' error handling."""

import json

import numpy as np
import pytest

from budget.whiskbroom.study import STUDY


@pytest.fixture(scope="module")
def small():
    sc = STUDY.load_scenario()
    return sc.model_copy(update={
        "tdi": sc.tdi.model_copy(update={"columns": 20, "edge_columns": 114, "edge_time_samples_per_phase": 2}),
        "synthesis": sc.synthesis.model_copy(update={"trials": 20, "sobol_base_samples": 16}),
        # the paper's (ideal) world: these tests check the identities of the model itself
        # (tests/whiskbroom/test_world.py covers the realistic world's effects)
        "world": sc.world.model_copy(update={"effects": sc.world.effects.ideal()})})


def test_trial_keys_and_truths(small):
    r = STUDY.trial(small, 0, 0)
    assert set(r.truths) == set(r.estimates)
    # the improved prediction is the pixel-level simulation's own decomposition
    # (drift x clocking, test_tdi): agreement to the discrete-sampling terms (< 1e-4)
    for ax in ("along", "cross"):
        key = ("mtf_nyquist", "improved", ax)
        assert r.estimates[key] == pytest.approx(r.truths[key], abs=1e-4)
    # the published sinc has no clocking factor: it is above the truth by about 1 - 0.9745
    key = ("mtf_nyquist", "published", "along")
    assert r.estimates[key] - r.truths[key] == pytest.approx(1 - np.sinc(0.125), abs=0.01)


def test_trial_equivalence_same_seed_same_numbers(small):
    """Equivalence of the code with itself (not physics; the physics: test_geometry's first-
    principles image velocity, test_headline's documented figures, test_tdi)."""
    a = STUDY.trial(small, 4, 3)
    b = STUDY.trial(small, 4, 3)
    assert a.estimates == b.estimates and a.truths == b.truths


def test_run_study_workers_equivalence(small):
    """Equivalence: two workers give one worker's numbers (not a physics check)."""
    from budget.runner.run import run_study

    r1 = run_study(STUDY, small, trials=4, seed=2, workers=1)
    r2 = run_study(STUDY, small, trials=4, seed=2, workers=2)
    assert r1.samples.keys() == r2.samples.keys()
    for k in r1.samples:
        np.testing.assert_array_equal(r1.samples[k], r2.samples[k])
        np.testing.assert_array_equal(r1.trial_truths[k], r2.trial_truths[k])
    s = r1.summary()
    assert "mtf_nyquist" in s and "stage_limit" in s


def test_synthesize_command_writes_json(tmp_path, small):
    from budget.whiskbroom.cli import main

    toml = tmp_path / "s.toml"
    toml.write_text(STUDY.default_text().replace("trials = 1000                   # paper",
                                                 "trials = 20                   # paper")
                    .replace("sobol_base_samples = 512", "sobol_base_samples = 16"))
    out = tmp_path / "o.json"
    main(["synthesize", str(toml), "--json", str(out), "--report", str(tmp_path / "rep"), "--seeds", "2",
          "--criterion-trials", "3"])
    data = json.loads(out.read_text())
    assert data["trials"] == 20 and len(data["per_mirror_rate_error"]) == 4
    assert (tmp_path / "rep" / "mtf_vs_stages.png").exists()
    assert data["seed_distribution"]["seeds"] == [0, 1] and data["published_criterion"]["trials"] == 3
    assert "over 2 seeds" in (tmp_path / "rep" / "report.md").read_text()


def test_bad_scenario_is_one_error_line(tmp_path, capsys):
    from budget.whiskbroom.cli import main

    bad = tmp_path / "bad.toml"
    bad.write_text(STUDY.default_text().replace("altitude_km = 1200.0", "altitude_km = -1.0"))
    out = tmp_path / "o.json"
    with pytest.raises(SystemExit) as exc:
        main(["synthesize", str(bad), "--json", str(out)])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {bad}: orbit.altitude_km:")
    assert not out.exists()
