"""``budget claims`` (budget.runner.claims_run, claims_page, claims_cmd), ``--tolerance
CLASS=VALUE`` (budget.runner.requirements) and the ledger every report opens with
(budget.runner.ledger_view), on the claims toy (tests/toys/claims_toy.py), whose answers are
analytic: noise variance 4 in the seed's own world, 4.25 in the realistic one; ``published``
(ddof 0) biased by -12.5 %, ``improved`` unbiased."""

from __future__ import annotations

import json
import re
from html.parser import HTMLParser

import pytest
from claims_toy import STUDY
from click.testing import CliRunner

from budget.runner.claims_run import LEDGER_JSON, run_claims
from budget.runner.ledger_view import instrument_line, ledger_lines, ledger_section
from budget.runner.requirements import (
    parse_requirements,
    split_tolerance_options,
    with_requirements,
)
from budget.runner.run import run_study
from simcam.infra.errors import UserInputError

#: 800 trials, seed 5: the sample variance has a per-trial sd of v sqrt(2 / 7) (m = 8), so the
#: standard error of its mean is about 0.08 units^2: every outcome asserted below is at least 3
#: standard errors beyond what the 95 % interval needs (the published bias -0.53 (-0.5 in the
#: seed's world) against -+0.085 (2 %): 5 se; the improved bias 0 against -+0.425 (10 %): 3 se;
#: the truth 4 or 4.25, exact (no sampling), against 4 -+ 0.08)
TRIALS, SEED = 800, 5


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    out = tmp_path_factory.mktemp("claims") / "out"
    return run_claims(out, studies=[STUDY], trials=TRIALS, seed=SEED, workers=1)


class _Links(HTMLParser):
    def __init__(self):
        super().__init__()
        self.hrefs, self.text = [], []

    def handle_starttag(self, tag, attrs):
        if tag == "a":
            self.hrefs.append(dict(attrs)["href"])

    def handle_data(self, data):
        self.text.append(data)


def _outcomes(res) -> dict:
    return {(r.claim.id, r.world): (r.verdict.outcome if r.verdict else None)
            for led in res.ledgers for r in led.results}


def test_claims_runs_both_worlds_and_judges_every_claim(page):
    got = _outcomes(page)
    assert got == {("variance.figure", "seed"): "holds", ("variance.figure", "realistic"): "fails",
                   ("variance.published", "seed"): "fails", ("variance.published", "realistic"): "fails",
                   ("variance.improved", "seed"): "holds", ("variance.improved", "realistic"): "holds",
                   ("mean.bound", "seed"): None, ("mean.bound", "realistic"): None}
    (led,) = page.ledgers
    assert set(led.runs) == {("embedded:default", "seed"), ("embedded:default", "realistic")}
    assert all(run.trials == TRIALS for run in led.runs.values())


def test_the_page_links_each_row_to_an_existing_report_and_the_json(page):
    html = page.page.read_text()
    p = _Links()
    p.feed(html)
    text = " ".join(p.text)
    assert "What holds of the five papers" in text
    assert "the noise variance is 4 units^2" in text and "untestable: the toy has no such figure" in text
    assert "holds in the seed's own world, fails in the realistic world" in text
    reports = [h for h in p.hrefs if h.endswith("report.html")]
    assert len(reports) == 2 * 3  # three testable claims, one link per world
    for h in set(reports) | {LEDGER_JSON}:
        assert (page.out / h).is_file(), h
    assert "../shared" not in html and "http://" not in html and "https://" not in html  # nothing fetched
    data = json.loads(page.json_path.read_text())
    (st,) = data["studies"]
    assert st["study"] == "claimstoy" and len(st["claims"]) == 8
    fig = next(c for c in st["claims"] if c["id"] == "variance.figure" and c["world"] == "realistic")
    assert fig["outcome"] == "fails" and fig["truth"] == pytest.approx(4.25)
    assert fig["tolerance"] == {"low": pytest.approx(3.92), "high": pytest.approx(4.08),
                                "reason": "2 % of the figure", "source": "default"}


def test_each_run_report_opens_with_its_ledger(page):
    md = (page.out / "claimstoy" / "embedded-default-realistic" / "report.md").read_text()
    assert md.index("## What holds of the paper's claims") < md.index("## Findings") < md.index("## Table")
    # the realistic run judges its world only; the other reads "not run here"
    assert "not run here: `budget claims` runs both" in md
    assert "holds in the realistic world" in md or "fails in the realistic world" in md
    html = (page.out / "claimstoy" / "embedded-default-realistic" / "report.html").read_text()
    assert "<details>" in html and "<table>" in html and "```" not in html


def test_user_tolerance_replaces_the_declared_one(tmp_path):
    # 1.0 units^2 admits the published bias (-0.53 +- 0.08): its 95 % interval ends 3.9 se inside
    res = run_claims(tmp_path / "out", studies=[STUDY], trials=TRIALS, seed=SEED, workers=1,
                     tolerances=("variance=1",))
    by = {(r.claim.id, r.world): r for led in res.ledgers for r in led.results}
    r = by[("variance.published", "realistic")]
    assert r.verdict.outcome == "holds"
    assert r.verdict.tolerance.source == "user"
    assert r.verdict.tolerance.reason == "your requirement: variance <= 1 units^2"
    assert (r.verdict.tolerance.low, r.verdict.tolerance.high) == (-1.0, 1.0)
    assert res.requirements == {"variance": 1.0}
    assert "your requirement: variance &lt;= 1 units^2" in res.page.read_text()


@pytest.mark.parametrize("text, msg", [
    ("variance", "give CLASS=VALUE"), ("=1", "give CLASS=VALUE"), ("nope=1", "unknown class 'nope'; known: variance"),
    ("variance=-1", "a number > 0"), ("variance=abc", "a number > 0"), ("variance=nan", "a number > 0"),
])
def test_bad_requirements_are_one_line_naming_the_option_and_the_classes(text, msg):
    with pytest.raises(UserInputError, match=re.escape(msg)) as e:
        parse_requirements([text], ("variance",))
    assert str(e.value).startswith(f"--tolerance {text}") and "\n" not in str(e.value)


def test_validate_tolerance_keeps_a_bare_number_as_the_stopping_target():
    assert split_tolerance_options(["0.01"], ("te",)) == (0.01, {})
    assert split_tolerance_options(["te=0.2", "0.5"], ("te",)) == (0.5, {"te": 0.2})
    assert split_tolerance_options([], ("te",)) == (None, {})
    with pytest.raises(UserInputError, match="one standard-error target at most"):
        split_tolerance_options(["0.1", "0.2"], ("te",))
    with pytest.raises(UserInputError, match=r"--tolerance abc: a standard-error target .* CLASS one of te"):
        split_tolerance_options(["abc"], ("te",))
    with pytest.raises(UserInputError, match="given twice"):
        parse_requirements(["te=1", "te=2"], ("te",))
    c = with_requirements(STUDY.claims(None), {"variance": 0.3})
    assert [x.tolerance.source for x in c if x.testable] == ["user"] * 3


def test_out_follows_the_overwrite_rule(tmp_path, page):
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "thesis.tex").write_text("mine")
    with pytest.raises(UserInputError, match="--out .*--overwrite"):
        run_claims(foreign, studies=[STUDY], trials=2, seed=0, workers=1)
    assert (foreign / "thesis.tex").read_text() == "mine"  # refused before any work
    with pytest.raises(UserInputError, match="--tolerance nope=1: unknown class"):
        run_claims(tmp_path / "x", studies=[STUDY], trials=2, tolerances=("nope=1",))
    assert not (tmp_path / "x").exists()


def test_a_single_run_ledger_and_the_pinned_instrument_line(page):
    run = run_study(STUDY, STUDY.load_scenario(None), trials=20, seed=1, workers=1, prewarm=False)
    lines = ledger_section(run)
    text = "\n".join(lines)
    assert lines[0] == "## What holds of the paper's claims"
    assert text.count("| not run here") == 3  # the seed's own world, for each testable claim
    assert "Untestable here: the mean is known to 1 unit (the toy has no such figure)." in text
    term = ledger_lines(run)
    assert term[0].startswith("claims of the paper") and len(term) == 1 + 3

    class _V:
        instrument_seed = 7

    class _S:
        validation = _V()

    assert "instrument seed 7" in instrument_line(_S()) and "that instrument only" in instrument_line(_S())


def test_cli_help_and_bad_study():
    from budget.cli import cli

    r = CliRunner().invoke(cli, ["claims", "--help"])
    assert r.exit_code == 0 and "CLASS=VALUE" in r.output and "--study" in r.output and "--out" in r.output
    r = CliRunner().invoke(cli, ["claims", "--study", "nope", "--out", "unused"])
    assert r.exit_code != 0 and "--study nope: unknown study" in str(r.exception or r.output)
    r = CliRunner().invoke(cli, ["starcam", "validate", "--help"])
    assert "CLASS=VALUE" in r.output and "standard error" in r.output


def test_a_pinned_instrument_is_said_also_without_claims():
    from types import SimpleNamespace

    from toy_world_study import STUDY as NO_CLAIMS

    run = SimpleNamespace(study=NO_CLAIMS, scenario=SimpleNamespace(validation=SimpleNamespace(instrument_seed=3)))
    (line, blank) = ledger_section(run)
    assert line.startswith("**One instrument (instrument seed 3)") and "that instrument only" in line and blank == ""
    assert ledger_lines(run) == [line.strip("*")]
    run.scenario.validation.instrument_seed = None
    assert ledger_section(run) == [] and ledger_lines(run) == []


def test_the_api_checks_its_arguments_and_returns_the_typed_result(tmp_path):
    import budget
    from budget.runner.claims_run import ClaimsResult

    with pytest.raises(TypeError, match="out=5: the output folder must be a path"):
        budget.claims(5)
    with pytest.raises(UserInputError, match="seed"):
        budget.claims(tmp_path / "o", seed=-1)
    res = budget.claims(tmp_path / "o", studies=[STUDY], trials=4, seed=0, workers=1, tolerances="variance=1")
    assert isinstance(res, ClaimsResult) and res.page.is_file() and res.requirements == {"variance": 1.0}
    assert "claims" in budget.__all__
