"""A robustness cell's verdict (budget.runner.robustness_verdicts) is validate's per-class verdict
on the same numbers, and it does not flip between holds and fails with the trial count beyond
the rule's error rate. On the toy world (tests/toys/toy_world_study.py); fixed seeds."""

from itertools import combinations

import pytest
from scipy.stats import binom
from toy_world_study import ToyWorldStudy

from budget.runner.capabilities import Claims
from budget.runner.claims import Claim, ToleranceRule
from budget.runner.findings import findings
from budget.runner.robustness import ALL, IDEAL, run_robustness
from budget.runner.run import run_study

LEDGER_RULE = ToleranceRule(reason="the paper's 0.3 units^2", source="paper", absolute=0.3)


class _LedgerToy(ToyWorldStudy, Claims):
    """The toy with a claims ledger: a method claim on the variance (source "paper"); the
    hook's claimed accuracy (``claims=``) is the tolerance where it states one."""

    def __init__(self, **kw):
        super().__init__(**kw)
        self.accuracy = self.__dict__.pop("claims")  # the toy's attribute would hide the ledger hook

    def claim(self, scenario, class_name, variant):
        return self.accuracy.get((class_name, variant))

    def claims(self, scenario):
        return (Claim(id="variance.method", words="the sample variance measures the noise's", figures=(),
                      unit="units^2", axis="a", condition="toy", section="none", kind="method",
                      scenario="embedded:default", class_name="variance", variant="improved",
                      tolerance=LEDGER_RULE),)


@pytest.mark.parametrize("study", [ToyWorldStudy(), _LedgerToy()], ids=["default tolerance", "ledger claim"])
def test_a_cell_has_validates_verdict(study):
    """The scenario's own case ("all") of a robustness run and a plain validate of the same
    scenario, seed and trials draw the same trials (trial k from SeedSequence(seed, (k,))):
    every class verdict of validate's findings is the robustness cell's bias verdict, with the
    same tolerance, and the cell's verdict where no sigma is stated (where one is, the
    coverage part joins: the cell can only be as good as the bias part)."""
    scn = study.load_scenario()
    rob = run_robustness(study, scn, trials=120, seed=9, workers=1)
    val = run_study(study, scn, trials=120, seed=9, workers=1, prewarm=False)
    cells = rob.cells()[ALL]
    found = {(f["class"], f["variant"], f["axis"]): f for f in findings(val)}
    assert set(found) == set(cells)
    for key, f in found.items():
        c = cells[key]
        assert c["bias"] == f["bias"] and c["se_bias"] == f["se_bias"]
        assert c["bias_verdict"].outcome == f["verdict"], key
        t = c["bias_verdict"].tolerance
        assert (t.low, t.high, t.reason, t.source) == (f["tolerance"]["low"], f["tolerance"]["high"],
                                                       f["tolerance"]["reason"], f["tolerance"]["source"])
        if c["coverage_1sigma"] is None:
            assert c["verdict"] == f["verdict"]
        elif f["verdict"] == "fails":
            assert c["verdict"] == "fails"
        if isinstance(study, _LedgerToy) and key[0] == "variance":
            assert t.source == "paper" and t.high == 0.3  # the ledger's


def test_the_claimed_accuracy_is_the_tolerance():
    """Where the study states a claimed accuracy (WorldEffects.claim) it is the tolerance: with
    the ledger's reason and source where the ledger's rule on the class is that same absolute
    value, else a declared one (source "default") naming it."""
    from budget.runner.robustness_verdicts import cell_rules

    scn = _LedgerToy().load_scenario()
    for accuracy, source, reason in ((0.3, "paper", LEDGER_RULE.reason),
                                     (9.0, "default", "the method's claimed accuracy 9")):
        study = _LedgerToy(claims={("variance", "improved"): accuracy})
        res = run_robustness(study, scn, trials=20, seed=2, workers=1)
        t = res.cells()[IDEAL][("variance", "improved", "a")]["bias_verdict"].tolerance
        assert (t.high, t.source, t.reason) == (accuracy, source, reason)
        # the other variant (no claimed accuracy) keeps the ledger's rule
        assert cell_rules(res.results[IDEAL], "variance", "published")[("variance", "a")] is LEDGER_RULE


# The rule's error rate: a decision is wrong only when the 95 % interval misses the true
# value on the far side, at most 2.5 % per part; a cell of two parts (bias and coverage)
# decides wrongly at most 5 %. A holds<->fails flip between two trial counts needs at least
# one wrong decision of the two: at most 10 % per cell and pair. Over C cells the count of
# flips is then at most Binomial(C, 0.1) if the cells were independent (they share trials,
# an approximation); the test allows its 99.9 % quantile per pair. With the significance rule
# (|b| <= 3 se) every resolvable bias turns from "holds" to "fails" as the trials grow: the
# toy's offset of 0.1 units on a mean with per-trial error sd 0.707 is 1.4 se at 50 trials
# and 5.7 se at 1600.
ERROR_PER_CELL_PAIR = 0.10
TRIAL_COUNTS = (50, 200, 800, 1600)


def test_more_trials_do_not_flip_holds_and_fails():
    study = ToyWorldStudy()
    scn = study.load_scenario()
    outcomes = {}
    for n in TRIAL_COUNTS:
        cells = run_robustness(study, scn, trials=n, seed=21, workers=1).cells()
        outcomes[n] = {(cn, k): c["verdict"] for cn, row in cells.items() for k, c in row.items()
                       if c["verdict"] is not None}
    judged = len(outcomes[TRIAL_COUNTS[0]])
    allowed = int(binom.ppf(0.999, judged, ERROR_PER_CELL_PAIR))
    for a, b in combinations(TRIAL_COUNTS, 2):
        flips = [k for k in outcomes[a] if {outcomes[a][k], outcomes[b][k]} == {"holds", "fails"}]
        assert len(flips) <= allowed, (a, b, flips)
    # the offset case's mean: 2 % of its truth, inside the 10 % tolerance at every count
    # (never "fails"), where the significance rule would call it biased from 800 trials on
    key = ("offset_units", ("mean", "published", "a"))
    assert all(outcomes[n][key] != "fails" for n in TRIAL_COUNTS)
    # more trials settle: the undetermined cells at 1600 are no more than at 50
    count = {n: sum(v == "undetermined" for v in outcomes[n].values()) for n in TRIAL_COUNTS}
    assert count[1600] <= count[50], count
    assert IDEAL in {cn for cn, _ in outcomes[50]}


def test_a_real_study_cell_has_validates_verdict():
    """The same on the whiskbroom study (4 trials: the equality is exact whatever the count),
    whose claimed accuracy (WorldEffects.claim) and ledger agree: every cell's verdict and
    tolerance, reason and source included, are validate's."""
    from budget.runner.registry import get_study, study_names

    if "whiskbroom" not in study_names():
        pytest.skip("whiskbroom is not installed")
    study = get_study("whiskbroom")
    scn = study.load_scenario()
    cells = run_robustness(study, scn, trials=4, seed=1, workers=1).cells()[ALL]
    val = run_study(study, scn, trials=4, seed=1, workers=1, prewarm=False)
    judged = 0
    for f in findings(val):
        c = cells[(f["class"], f["variant"], f["axis"])]
        assert c["bias"] == f["bias"]
        if f["verdict"] is None:
            continue
        judged += 1
        t = c["bias_verdict"].tolerance
        assert c["verdict"] == f["verdict"] and c["coverage_1sigma"] is None
        assert (t.low, t.high, t.reason, t.source) == tuple(f["tolerance"][k] for k in ("low", "high", "reason", "source"))
    assert judged >= 5
