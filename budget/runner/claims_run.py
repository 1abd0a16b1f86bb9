"""``budget claims``' work, shared by the command and :func:`budget.claims`: every registered
study's claims ledger run in both worlds, judged, and written as one folder.

:func:`run_claims` takes the studies (registered names, or :class:`~budget.runner.study.Study`
objects for a test's toy), runs each ledger's ``(scenario, world)`` runs
(:func:`budget.runner.claims.ledger_runs`, :func:`~budget.runner.claims.world_scenario`),
writes each run's full report (:func:`budget.runner.report.write_report`) into
``OUT/<study>/<scenario>-<world>/``, judges the claims (:func:`~budget.runner.claims.evaluate_claims`,
the user's ``--tolerance CLASS=VALUE`` in place of the declared tolerances:
:mod:`budget.runner.requirements`) and writes the front page ``OUT/index.html``
(:mod:`budget.runner.claims_page`) and the ledger as JSON, ``OUT/claims.json``. The folder is
staged and put in place whole (:class:`simcam.infra.outputs.StagedOutputs`).
"""

from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass, field
from pathlib import Path

from budget.runner.claims import (
    WORLDS,
    ClaimResult,
    evaluate_claims,
    ledger_runs,
    study_claims,
    world_scenario,
)
from budget.runner.claims_page import write_page
from budget.runner.ledger_view import pinned_instrument
from budget.runner.registry import entry, get_study, study_names
from budget.runner.report import write_report
from budget.runner.requirements import parse_requirements, with_requirements
from budget.runner.study import Study
from simcam.infra.cli import write_json_atomic
from simcam.infra.errors import UserInputError
from simcam.infra.outputs import StagedOutputs, check_output_dir

__all__ = ["LEDGER_JSON", "PAGE", "ClaimsResult", "LedgerRun", "StudyLedger", "is_earlier_claims", "run_claims"]

#: the front page and the ledger's JSON in the output folder
PAGE, LEDGER_JSON = "index.html", "claims.json"
#: a study's default trials per run where the registry gives none
DEFAULT_TRIALS = 20


def is_earlier_claims(path: Path) -> bool:
    """A folder ``budget claims --out`` may replace: empty, or an earlier output (its page and JSON)."""
    return not any(path.iterdir()) or ((path / PAGE).is_file() and (path / LEDGER_JSON).is_file())


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "-", text).strip("-").lower() or "scenario"


@dataclass(frozen=True)
class LedgerRun:
    """One scenario-world run behind a ledger: its trials, wall time (s), report page
    (relative to the output folder) and what fixed one instrument for every trial
    (:func:`budget.runner.ledger_view.pinned_instrument`), or None."""

    trials: int
    elapsed_s: float
    report: str
    pinned_instrument: str | None = None

    def to_json(self) -> dict:
        return {"trials": self.trials, "elapsed_s": self.elapsed_s, "report": self.report,
                "pinned_instrument": self.pinned_instrument}


@dataclass(frozen=True)
class StudyLedger:
    """One study's ledger: its claims judged in both worlds, and the runs behind them.

    Attributes
    ----------
    study : str
    title : str
    seed_document : str
    results : tuple of ClaimResult
        One per claim and world (:func:`~budget.runner.claims.evaluate_claims`).
    runs : dict
        ``(scenario, world) -> LedgerRun``.
    elapsed_s : float
        The study's wall time (its runs and reports).
    """

    study: str
    title: str
    seed_document: str
    results: tuple[ClaimResult, ...]
    runs: dict = field(default_factory=dict)
    elapsed_s: float = 0.0

    def report_of(self, result: ClaimResult) -> str | None:
        """The page of the run that judged ``result`` (relative to the folder), if any."""
        run = self.runs.get((result.claim.scenario, result.world))
        return run.report if run else None


@dataclass(frozen=True)
class ClaimsResult:
    """What ``budget claims`` wrote: the ledgers, the folder, its page and JSON."""

    ledgers: tuple[StudyLedger, ...]
    out: Path
    seed: int
    trials: int | None
    elapsed_s: float
    requirements: dict = field(default_factory=dict)

    @property
    def page(self) -> Path:
        return self.out / PAGE

    @property
    def json_path(self) -> Path:
        return self.out / LEDGER_JSON

    def counts(self) -> dict[str, dict[str, int]]:
        """``{world: {outcome or "no verdict": count}}`` over every claim."""
        out: dict[str, dict[str, int]] = {w: {} for w in WORLDS}
        for led in self.ledgers:
            for r in led.results:
                k = r.verdict.outcome if r.verdict is not None else "no verdict"
                out[r.world][k] = out[r.world].get(k, 0) + 1
        return out

    def to_json(self) -> dict:
        """The ledger as JSON (``claims.json``)."""
        return {"seed": self.seed, "trials": self.trials, "elapsed_s": self.elapsed_s,
                "requirements": dict(self.requirements),
                "studies": [_ledger_json(led) for led in self.ledgers]}

    def __repr__(self) -> str:
        c = self.counts()
        words = "; ".join(f"{w}: " + ", ".join(f"{n} {k}" for k, n in sorted(c[w].items())) for w in WORLDS)
        return f"<ClaimsResult {len(self.ledgers)} studies, {self.page} ({words})>"


def _num(x) -> float | None:
    return None if x is None or not math.isfinite(float(x)) else float(x)


def _result_json(r: ClaimResult, report: str | None) -> dict:
    c, v = r.claim, r.verdict
    d = {"id": c.id, "words": c.words, "kind": c.kind, "figures": list(c.figures), "unit": c.unit, "axis": c.axis,
         "section": c.section, "condition": c.condition, "scenario": c.scenario, "class": c.class_name,
         "variant": c.variant, "world": r.world, "outcome": v.outcome if v else None, "no_verdict": r.no_verdict,
         "sentence": r.sentence, "ours": r.ours, "truth": _num(r.truth), "truth_se": _num(r.truth_se),
         "mean": _num(r.mean), "trials": r.trials, "report": report}
    if v is not None:
        d.update(estimate=v.estimate, se=v.se, low=v.low, high=v.high, confidence=v.confidence,
                 n_to_settle=v.n_to_settle,
                 tolerance={"low": _num(v.tolerance.low), "high": _num(v.tolerance.high),
                            "reason": v.tolerance.reason, "source": v.tolerance.source})
    return d


def _ledger_json(led: StudyLedger) -> dict:
    return {"study": led.study, "title": led.title, "seed_document": led.seed_document, "elapsed_s": led.elapsed_s,
            "runs": [{"scenario": s, "world": w, **run.to_json()} for (s, w), run in led.runs.items()],
            "claims": [_result_json(r, led.report_of(r)) for r in led.results]}


def _studies(studies) -> list[Study]:
    if not studies:
        return [get_study(n) for n in study_names()]
    out = []
    for s in studies:
        if isinstance(s, Study):
            out.append(s)
        elif isinstance(s, str):
            out.append(get_study(s))
        else:
            raise UserInputError(f"--study {s!r}: a registered study name ({', '.join(study_names())})")
    names = [s.name for s in out]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise UserInputError(f"--study {dup[0]}: given twice")
    return out


def _trials(study: Study, trials: int | None) -> int:
    if trials is not None:
        return trials
    e = entry(study.name)
    return getattr(e, "ledger_trials", None) or DEFAULT_TRIALS


def _known_classes(ledgers_claims) -> tuple[str, ...]:
    out: dict[str, None] = {}
    for _study, claims in ledgers_claims:
        for c in claims:
            if c.testable:
                out[c.class_name] = None
    return tuple(out)


def run_claims(out, *, studies=(), trials: int | None = None, seed: int = 0, workers: int = 1,
               tolerances=(), overwrite: bool = False, progress: bool = False, echo=None) -> ClaimsResult:
    """Run every study's ledger in both worlds and write the folder ``out`` (module docstring).

    ``studies``: names or Study objects (default: every registered study); ``trials``: per
    run (default: each study's registered ``ledger_trials``); ``tolerances``: texts
    ``CLASS=VALUE`` (:mod:`budget.runner.requirements`); ``echo(line)``: progress lines.
    """
    from budget.runner.run import run_study

    echo = echo or (lambda line: None)
    sts = _studies(studies)
    declared = [(st, study_claims(st, st.load_scenario(None))) for st in sts]
    reqs = parse_requirements(tolerances, _known_classes(declared))
    check_output_dir(out, option="--out", replaceable=is_earlier_claims, overwrite=overwrite)
    t0 = time.perf_counter()
    ledgers = []
    with StagedOutputs() as staged:
        folder = staged.folder(out)
        folder.mkdir(parents=True)
        for st, claims in declared:
            claims = with_requirements(claims, reqs)
            ts = time.perf_counter()
            runs, info, done = {}, {}, {}
            n = _trials(st, trials)
            for scn_name, world in ledger_runs(claims):
                tr = time.perf_counter()
                scn = world_scenario(st, st.load_scenario(scn_name), world)
                key = st.scenario_hash(scn)
                if key in done:  # a study without world effects: one run is both worlds
                    runs[(scn_name, world)], info[(scn_name, world)] = runs[done[key]], info[done[key]]
                    continue
                res = run_study(st, scn, trials=n, seed=seed, workers=workers, progress=progress)
                rel = Path(st.name) / f"{_slug(scn_name)}-{world}"
                write_report(res, folder / rel, claims=claims)
                runs[(scn_name, world)], done[key] = res, (scn_name, world)
                info[(scn_name, world)] = LedgerRun(res.trials, round(time.perf_counter() - tr, 2),
                                                    (rel / "report.html").as_posix(), pinned_instrument(scn))
                echo(f"{st.name}: {scn_name}, {world} world: {res.trials} trials in "
                     f"{time.perf_counter() - tr:.1f} s")
            results = evaluate_claims(claims, runs)
            ledgers.append(StudyLedger(st.name, st.title, st.seed_document, results, info,
                                       round(time.perf_counter() - ts, 2)))
        result = ClaimsResult(tuple(ledgers), Path(out), seed, trials, round(time.perf_counter() - t0, 2), reqs)
        write_json_atomic(folder / LEDGER_JSON, result.to_json())
        write_page(result, folder / PAGE)
    return result
