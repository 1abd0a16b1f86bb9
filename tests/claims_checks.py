"""What every study's claims-ledger test shares: the ledger's runs in both worlds, and the
verdict rule recomputed from a verdict's own numbers (docs/claims.md, "The verdict rule")."""

from __future__ import annotations

from budget.runner.claims import WORLDS, evaluate_claims, ledger_markdown, ledger_runs, study_claims, world_scenario
from budget.runner.run import run_study
from simcam.effects import scenario_effects

#: the normal quantile of 0.975: the rule's default two-sided 95 % interval
Z95 = 1.959963984540054


def ledger_of(study, scenario_name, trials: int | None, seed: int, *, workers: int = 1):
    """``(claims, runs, results)``: the study's claims on ``scenario_name``, a run of each
    scenario-world they name, and the claims judged from those runs."""
    claims = study_claims(study, study.load_scenario(scenario_name))
    runs = {key: run_study(study, world_scenario(study, study.load_scenario(key[0]), key[1]), trials=trials,
                           seed=seed, workers=workers)
            for key in ledger_runs(claims)}
    return claims, runs, evaluate_claims(claims, runs)


def assert_worlds(runs) -> None:
    """The seed's own world has no effect on, the realistic world some."""
    for (name, world), res in runs.items():
        on = scenario_effects(res.scenario).active()
        assert (on == ()) == (world == "seed"), (name, world, on)


def expected_outcome(v, low: float | None = None, high: float | None = None) -> str:
    """The rule on the verdict's own numbers: its 95 % interval against the tolerance
    ``[low, high]`` (the verdict's own when not given)."""
    low = v.tolerance.low if low is None else low
    high = v.tolerance.high if high is None else high
    lo, hi = v.estimate - Z95 * v.se, v.estimate + Z95 * v.se
    return "holds" if low <= lo and hi <= high else "fails" if lo > high or hi < low else "undetermined"


def assert_outcome_follows_numbers(r, low: float | None = None, high: float | None = None) -> str:
    """The claim result's outcome and the start of its sentence are the rule's; returns it."""
    want = expected_outcome(r.verdict, low, high)
    assert r.verdict.outcome == want, r.sentence
    assert r.sentence.startswith(want + ": "), r.sentence
    return want


def outcomes(results) -> dict:
    """``(claim id, world) -> outcome`` of the results with a verdict."""
    return {(r.claim.id, r.world): r.verdict.outcome for r in results if r.verdict is not None}


def judged(claims, results):
    """The testable claims' results, after checking that ``results`` holds one per claim and
    world in order and that an untestable claim has no verdict, only its reason."""
    assert [(r.claim.id, r.world) for r in results] == [(c.id, w) for c in claims for w in WORLDS]
    for r in results:
        if r.claim.testable:
            yield r
        else:
            assert r.verdict is None and r.no_verdict == f"untestable: {r.claim.untestable}"


def assert_ledger_table(claims, results) -> list[str]:
    """The ledger's Markdown table: a header, a rule and one row per claim, in the claims'
    order, each opening with the claim's words; returns the rows (a study checks more)."""
    table = ledger_markdown(results).splitlines()
    assert len(table) == 2 + len(claims)
    for c, line in zip(claims, table[2:]):
        assert line.startswith(f"| {c.words} ")
    return table[2:]
