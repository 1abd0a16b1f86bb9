"""Seed 000's eq 32 in the claims ledger, judged by the attitude study: the claim maps to the
study's class and evaluates from a run (a small fixed-seed run: the structure and the verdict's
agreement with its own numbers; the 1,000-pointing figures are in docs/attitude.md)."""

from budget.attitude.study import STUDY
from budget.runner.claims import evaluate_claims, ledger_markdown, ledger_runs, study_claims, world_scenario
from budget.runner.run import run_study


def test_eq32_is_judged_from_a_run_in_the_simulators_world():
    claims = study_claims(STUDY, STUDY.load_scenario(None))
    assert [c.id for c in claims] == ["attitude.x.eq32", "attitude.y.eq32"]
    assert all(c.figures[0] == (fig / 3.0) ** 2 for c, fig in zip(claims, (0.56, 0.62)))
    runs = {key: run_study(STUDY, world_scenario(STUDY, STUDY.load_scenario(key[0]), key[1]), trials=12, seed=5,
                           workers=1)
            for key in ledger_runs(claims)}
    results = evaluate_claims(claims, runs)
    assert len(results) == 4 and all(r.verdict is not None for r in results)
    for r in results:  # the verdict follows from its own interval and tolerance
        v = r.verdict
        inside = v.tolerance.low <= v.low and v.high <= v.tolerance.high
        outside = v.high < v.tolerance.low or v.low > v.tolerance.high
        assert v.outcome == ("holds" if inside else "fails" if outside else "undetermined")
    table = ledger_markdown(results)
    assert "attitude.x.eq32" in table or "sqrt(10)" in table
