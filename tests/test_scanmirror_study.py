"""Seed 003 study on the shared runner: equivalence (same seed, same numbers; any
worker count), classes, CLI. The equivalence tests check the code against itself, not
physics; the documented figures are pinned in tests/test_scanmirror_headline.py."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from budget.scanmirror.study import STUDY


@pytest.fixture(scope="module")
def scenario():
    return STUDY.load_scenario()


def test_trial_keys_truths_and_sigmas(scenario):
    r = STUDY.trial(scenario, 0, 3)
    names = {c.name for c in STUDY.classes(scenario)}
    assert {k[0] for k in r.estimates} == names
    assert {k[1] for k in r.estimates} == set(STUDY.variants)
    # per-trial truths: the injected deviation, and the world's error of the improved chain
    assert set(r.truths) == {k for k in r.estimates if k[0] in ("dtau", "compensated_max")}
    assert {k for k in r.estimates if k[0] == "compensated_max"} == {("compensated_max", "improved", ax)
                                                                     for ax in ("lat", "lon")}
    assert set(r.sigmas) == {("dtau", "improved", "x"), ("dtau", "improved", "y")}
    # the same trial twice: bit-identical (trial k draws only from its own seed sequence;
    # exact equality is the point here, not a computed-float comparison)
    r2 = STUDY.trial(scenario, 0, 3)
    assert r.estimates == r2.estimates
    truths = STUDY.truths(scenario, 0)
    assert all(t.value == 0.0 for t in truths.values())  # a stated constant, not a computation


def test_run_study_workers_equivalence(scenario):
    """Equivalence: two workers give one worker's numbers (not a physics check)."""
    from budget.runner.run import run_study

    # bit-identity across worker counts is the requirement (exact comparison on purpose)
    a = run_study(STUDY, scenario, trials=6, seed=11, workers=1)
    b = run_study(STUDY, scenario, trials=6, seed=11, workers=2)
    assert a.samples.keys() == b.samples.keys()
    for k in a.samples:
        assert np.array_equal(a.samples[k], b.samples[k])
    for k in a.trial_truths:
        assert np.array_equal(a.trial_truths[k], b.trial_truths[k])


def test_simulate_command_and_bad_input(tmp_path, capsys):
    from budget.cli import cli
    from simcam.infra.cli import run_cli

    out = tmp_path / "sim.json"
    coarse = tmp_path / "coarse.toml"
    coarse.write_text(STUDY.default_text().replace("ground_step_s = 0.1 ", "ground_step_s = 1.0 "))
    res = CliRunner().invoke(cli, ["scanmirror", "simulate", str(coarse), "--json", str(out)])
    assert res.exit_code == 0, res.output
    data = json.loads(out.read_text())
    assert set(data["scans"]) == {"1", "2"}
    # scan 2 after estimation and exact compensation is far better than without the estimate
    s2 = data["scans"]["2"]
    assert s2["improved"]["lon_max_deg"] < 0.1 * s2["without_estimate"]["lon_max_deg"]
    bad = tmp_path / "bad.toml"
    text = STUDY.default_text().replace("eccentricity = 0.001", "eccentricity = 1.5")
    bad.write_text(text)
    with pytest.raises(SystemExit) as exc:
        run_cli(cli, ["scanmirror", "simulate", str(bad)])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {bad}: orbit.eccentricity")


def test_validate_names_the_file_of_a_starless_dwell(tmp_path, capsys):
    from budget.cli import cli
    from simcam.infra.cli import run_cli

    bad = tmp_path / "dim.toml"
    bad.write_text(STUDY.default_text().replace("mag_limit = 7.5 ", "mag_limit = 2.0 "))
    with pytest.raises(SystemExit) as exc:
        run_cli(cli, ["scanmirror", "validate", str(bad), "--trials", "2", "--workers", "1"])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {bad}: star_sensing.mag_limit: no catalogue star")


def test_star_dwell_count_is_a_sweepable_field():
    """``star_sensing.dwells = N`` flies N star-sensing dwells, each extra one after a move of
    ``extra_dwell_beta_step_deg`` in scan angle at the same step angle; more dwells see the
    deviation from more directions, so the improved fit states a smaller uncertainty."""
    import tomllib

    import numpy as np

    from budget.runner.registry import get_study
    from budget.runner.run import run_study
    from simcam.scanmirror.scanplan import evaluate_plan, plan_duration_s

    study = get_study("scanmirror")
    data = tomllib.loads(study.default_text())
    sigma = {}
    for n in (1, 2):
        data.setdefault("star_sensing", {})["dwells"] = n
        scn = study.from_dict(data, source="test")
        plan = scn.effective_plan
        stars = [s for s in plan.segments if s.kind == "dwell" and s.star_sensing]
        assert len(stars) == n
        t = np.arange(0.0, plan_duration_s(plan), 0.5)
        p = evaluate_plan(plan, t)
        beta = [np.rad2deg(p.beta_rad[p.star_dwell == j]).mean() for j in range(1, n + 1)]
        # the extra dwell sits one step further in scan angle (exact: a held angle)
        assert np.allclose(np.diff(beta), scn.star_sensing.extra_dwell_beta_step_deg, atol=1e-9)
        res = run_study(study, scn, trials=6, seed=0, workers=1)
        sigma[n] = np.nanmean(res.sigmas[("dtau", "improved", "x")])
    assert sigma[2] < sigma[1]
