"""Robustness: what each method's claim survives of the world's unmodelled effects.

``budget <study> robustness [SCENARIO] --trials K --seed S --workers W --json OUT --report DIR``
runs a study on *cases* of its scenario that differ only in ``world.effects``
(:mod:`simcam.effects`):

* ``ideal``: every effect off;
* one case per effect that is on in the scenario, named after the effect: that effect
  alone at the scenario's magnitude;
* ``all``: every effect at the scenario's magnitude (the scenario itself; left out when
  fewer than two effects are on: it would repeat a case).

Each case is built generically: the scenario dumped to a mapping, ``world.effects.<name>``
set, :meth:`Study.from_dict`. Every case runs the same trials with the same seed, so trial
``k`` of every case draws from ``SeedSequence(seed, spawn_key=(k,))`` (common random
numbers): a difference between two cases is the effect's, not sampling noise, and its
standard error (``se_shift``) is that of the paired per-trial differences. All cases run in
one executor (one pool of workers, started once); the truths (:meth:`Study.truths`, the
scenario's own truth sizes) are computed for the ideal case and reused by every case whose
active effects are outside :meth:`~budget.runner.capabilities.WorldEffects.truth_depends_on_effects` or that equals the ideal
case on every field of :meth:`~budget.runner.capabilities.SharedTruths.truth_fields`, computed anew otherwise.

Statistics per case and key are the runner's (:func:`budget.runner.stats.key_statistics`).
Classes of role ``"input"`` are left out (taken as given, nothing to validate).

``claim_holds`` (:func:`claim_holds`, the one definition)
---------------------------------------------------------
For a key with bias ``b``, its standard error ``se`` (the trials' combined with the
truth's) and, where the variant states a 1-sigma uncertainty, the fraction ``c`` of ``m``
trials whose error is within it:

* the bias part: with a claimed accuracy ``A`` (:meth:`~budget.runner.capabilities.WorldEffects.claim`, in the class unit),
  ``|b| + 3 se <= A``; without one, the method claims to be unbiased: ``|b| <= 3 se``
  (a bias below ``1e-9`` of the compared values' magnitude counts as rounding, for a
  deterministic estimator whose ``se`` is 0). A one-sided claim (:attr:`ClassSpec.at_most`:
  the estimate is a stated bound, the truth at or below it) puts the shortfall ``-b`` in
  place of ``|b|``: ``-b <= 3 se`` (``-b + 3 se <= A``), an estimate above the truth holds;
* the coverage part, where a sigma is stated: ``|c - 0.6827| <= 3 sqrt(0.6827 * 0.3173 / m)``
  (the binomial 3-standard-error band for ``m`` trials);
* ``claim_holds`` = both parts; ``null`` for a class of role ``"residual"`` (what a
  compensation leaves: no claim to test) or ``"input"`` (taken as given), for a reference
  variant (:attr:`Study.reference_variants`: it estimates nothing, so it is never shown
  ``ok``) and for an axis the data cannot determine (:attr:`ClassSpec.undetermined`, a
  gauge freedom: its estimate is a convention).

The result, :class:`RobustnessResult`, gives the JSON (schema ``budget.robustness/1``:
``cases[name].classes[class][axis][variant]`` with ``bias``, ``se_bias``, ``std``,
``coverage_1sigma`` (null where no sigma is stated), ``claim``, ``claim_holds``, ``shift``
and ``se_shift`` (the change from the ideal case, paired), and per case its active
effects, trials, seed and scenario hash), the table (:meth:`RobustnessResult.format_table`)
and ``report.md`` (:meth:`RobustnessResult.write_report`) with one sentence per class and
variant saying which effect breaks its claim first and by how much.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import click
import numpy as np

import simcam
from budget.runner.capabilities import (BatchedTrials, CheckedScenario, SharedTruths, SplitTruths, Warmup, WorldEffects,
                                        capability)
from budget.runner.executors import default_workers, make_executor
from budget.runner.html import write_html
from budget.runner.numbers import fmt
from budget.runner.registry import get_study
from budget.runner.report import staged_report, write_outputs
from budget.runner.run import StudyResult
from budget.runner.scheduler import init_worker
from budget.runner.study import ClassSpec, Study, TrialResult, truth_identity
from simcam.allocation import check_allocations
from simcam.dotted import scenario_with
from simcam.effects import scenario_effects
from simcam.infra.cli import overwrite_option, write_json_atomic
from simcam.infra.errors import UserInputError
from simcam.infra.lifecycle import check_memory
from simcam.infra.outputs import check_run_outputs

__all__ = ["ALL", "IDEAL", "SCHEMA", "Case", "RobustnessResult", "build_cases", "claim_holds",
           "coverage_consistent", "robustness_command_for", "run_robustness", "scenario_with_effects",
           "summary_cell"]

SCHEMA = "budget.robustness/1"
#: names of the cases with every effect off and every effect on
IDEAL, ALL = "ideal", "all"
#: probability of |N(0, 1)| <= 1
EXPECTED_1SIGMA = 0.6827
#: a bias below this fraction of the compared values' magnitude is rounding (se 0 only)
ROUNDING = 1e-9


# ---------------------------------------------------------------------- the definition
def coverage_consistent(coverage_1sigma: float, n: int) -> bool:
    """Whether a 1-sigma coverage over ``n`` trials is consistent with 68.27 %: within the
    binomial band of 3 standard errors, ``3 sqrt(0.6827 * 0.3173 / n)``."""
    return abs(coverage_1sigma - EXPECTED_1SIGMA) <= 3.0 * math.sqrt(EXPECTED_1SIGMA * (1 - EXPECTED_1SIGMA) / n)


def _off(bias: float, at_most: bool) -> float:
    """How far an estimate is off its claim's side: ``|b|`` (two-sided) or the shortfall
    ``-b`` below the truth (one-sided, :attr:`ClassSpec.at_most`; negative when above)."""
    return -bias if at_most else abs(bias)


def claim_holds(*, bias: float, se_bias: float, claim: float | None = None, coverage_1sigma: float | None = None,
                coverage_n: int = 0, scale: float = 0.0, at_most: bool = False) -> bool:
    """Whether a method's claim holds on one key (the module docstring's definition).

    ``scale`` is the magnitude of the compared values (truth, mean): with ``se_bias`` 0 a bias
    within ``1e-9 scale`` is rounding. ``at_most``: a one-sided claim (the estimate a bound
    the truth stays at or below, :attr:`ClassSpec.at_most`).
    """
    if not math.isfinite(bias):
        return False
    off = _off(bias, at_most)
    if claim is None:
        ok = off <= 3.0 * se_bias + ROUNDING * abs(scale)
    else:
        ok = off + 3.0 * se_bias <= claim
    if coverage_1sigma is not None:
        ok = ok and coverage_n > 0 and coverage_consistent(coverage_1sigma, coverage_n)
    return bool(ok)


def _severity(cell: dict) -> float:
    """How far a cell is past its claim (> 1: beyond): the larger of the bias's ratio to its
    threshold and the coverage's distance from 68.27 % in 3-se bands."""
    b, se, claim = _off(cell["bias"], cell.get("at_most", False)), cell["se_bias"], cell["claim"]
    if not math.isfinite(b):
        return math.inf
    if claim is not None:
        r = (b + 3 * se) / claim if claim > 0 else math.inf
    else:
        thr = 3 * se + ROUNDING * cell["scale"]
        r = b / thr if thr > 0 else (0.0 if b <= 0 else math.inf)
    if cell["coverage_1sigma"] is not None and cell["coverage_n"]:
        band = 3 * math.sqrt(EXPECTED_1SIGMA * (1 - EXPECTED_1SIGMA) / cell["coverage_n"])
        r = max(r, abs(cell["coverage_1sigma"] - EXPECTED_1SIGMA) / band)
    return r


def summary_cell(axes: list[tuple[str, dict]], *, markdown: bool = False) -> str:
    """One table cell for a class and variant over its axes ``[(axis, cell), ...]``: the
    verdict (``ok`` when every determined axis holds; ``FAIL k/n`` when k of the n
    determined axes fail, ``FAIL`` for one axis; ``--`` without a claim) and the bias of the
    axis farthest past its claim (:func:`_severity`; the largest |bias| without a claim),
    named when there are several."""
    judged = [(a, c) for a, c in axes if c["claim_holds"] is not None]
    if judged:
        failing = [(a, c) for a, c in judged if c["claim_holds"] is False]
        a, c = max(judged, key=lambda ac: _severity(ac[1]))
        if failing:
            v = "FAIL" if len(judged) == 1 else f"FAIL {len(failing)}/{len(judged)}"
            v = f"**{v}**" if markdown else v
        else:
            v = "ok"
        n = len(judged)
    else:
        a, c = max(axes, key=lambda ac: abs(ac[1]["bias"]) if math.isfinite(ac[1]["bias"]) else math.inf)
        v, n = "--", len(axes)
    return f"{v} {fmt(c['bias'], 3, sign=True)}" + (f" ({a})" if n > 1 else "")


# ---------------------------------------------------------------------- the cases
@dataclass(frozen=True)
class Case:
    """One world of a robustness run: its name, scenario, effects on, and whether it takes
    the ideal case's truths."""

    name: str
    scenario: Any
    active: tuple[str, ...]
    magnitudes: dict[str, float]
    shares_truths: bool = False


def scenario_with_effects(study: Study, scenario: Any, values: dict[str, float], *, source: str) -> Any:
    """``scenario`` with ``world.effects`` set to ``values`` (``{effect: magnitude}``), validated by
    :meth:`Study.from_dict` (:func:`simcam.dotted.scenario_with`: an unknown effect is an error
    naming ``source``, and the fields the scenario derives are derived again)."""
    return scenario_with(scenario, {f"world.effects.{k}": float(v) for k, v in values.items()},
                         from_dict=study.from_dict, where=source)


def build_cases(study: Study, scenario: Any, *, source: str = "") -> list[Case]:
    """The cases of a robustness run (module docstring); a scenario without
    ``world.effects`` is a :class:`simcam.infra.errors.UserInputError`."""
    effects = scenario_effects(scenario)
    where = source or f"{study.name} scenario {getattr(scenario, 'name', '')}".strip()
    if effects is None or not effects.names():
        raise UserInputError(f"{where}: the {study.name} study's scenario has no [world.effects]: "
                             "nothing for robustness to vary")
    depends = capability(study, WorldEffects).truth_depends_on_effects(scenario)
    ideal = effects.ideal().magnitudes()
    ideal_scn = scenario_with_effects(study, scenario, ideal, source=f"{where}, case {IDEAL}")

    def shares(active: tuple[str, ...], scn: Any) -> bool:
        # outside the effects the truths depend on, or equal on every field they depend on
        # (Study.truth_fields: the hook sweeps share truths by)
        if depends is not None and not (set(active) & set(depends)):
            return True
        return capability(study, SharedTruths).truth_fields(scn) is not None and truth_identity(study, scn) == truth_identity(study, ideal_scn)

    cases = [Case(IDEAL, ideal_scn, (), ideal, False)]
    active = effects.active()
    for name in active:
        mags = effects.only(name).magnitudes()
        scn = scenario_with_effects(study, scenario, mags, source=f"{where}, case {name}")
        cases.append(Case(name, scn, (name,), mags, shares((name,), scn)))
    if len(active) >= 2:
        cases.append(Case(ALL, scenario, active, effects.magnitudes(), shares(active, scenario)))
    return cases


# ---------------------------------------------------------------------- running
class _Truths:
    """The result of one piece of one case's truths."""

    def __init__(self, case: int, index: int, value: Any):
        self.case, self.index, self.value = case, index, value


def _task(args):
    """A worker's task: a chunk of one case's trials, or one piece of one case's truths."""
    study, scenario, seed, case, ks = args
    if isinstance(ks, tuple) and ks and ks[0] == "truth":
        return _Truths(case, ks[1], capability(study, SplitTruths).truth_part(scenario, seed, ks[2]))
    out = list(zip(ks, capability(study, BatchedTrials).trial_batch(scenario, seed, list(ks))))
    for k, r in out:
        if k != 0:
            r.extra = {}
    return case, out


def _collect(results: dict[int, TrialResult]):
    ks = sorted(results)
    first = results[ks[0]]
    samples = {key: np.array([results[k].estimates[key] for k in ks], dtype=float) for key in first.estimates}
    tt = {key: np.array([results[k].truths[key] for k in ks], dtype=float) for key in first.truths}
    sg = {key: np.array([results[k].sigmas.get(key, np.nan) for k in ks], dtype=float) for key in first.sigmas}
    aux = {name: np.array([results[k].aux[name] for k in ks], dtype=float) for name in first.aux}
    return samples, tt, sg, aux


def run_robustness(study: Study, scenario: Any, *, trials: int | None = None, seed: int = 0,
                   workers: int | None = 1, scheduler: str | None = None, dask_local: int | None = None,
                   progress: bool = False, prewarm: bool = True, source: str = "") -> "RobustnessResult":
    """Run every case of ``scenario`` (:func:`build_cases`) with ``trials`` trials each (default:
    the study's) and seed ``seed``, in one executor (:func:`budget.runner.executors.make_executor`;
    results do not depend on it)."""
    t0 = time.perf_counter()
    if trials is None:
        trials = scenario.validation.trials
    if trials < 2:
        raise UserInputError(f"--trials: must be at least 2 (got {trials})")
    cases = build_cases(study, scenario, source=source)
    for c in cases:
        capability(study, CheckedScenario).check(c.scenario, where=f"{source or study.name}, case {c.name}")
        check_allocations(c.scenario, source=f"{source or study.name}, case {c.name}")
    classes = tuple(study.classes(scenario))
    n_values = sum(len(c.axes) for c in classes) * len(study.variants)
    check_memory(float(trials) * len(cases) * (300 + 3 * 100 * n_values),
                 what=f"--trials {trials} for {len(cases)} robustness cases")
    if prewarm and scheduler is None:
        capability(study, Warmup).prewarm(scenario)
    executor = make_executor(workers=workers, scheduler=scheduler, dask_local=dask_local,
                             initializer=init_worker, initargs=(study,))
    results: list[dict[int, TrialResult]] = [{} for _ in cases]
    truths: list[dict | None] = [None] * len(cases)
    own = [i for i, c in enumerate(cases) if not c.shares_truths]
    bar = None
    with executor:
        tasks: list = []
        if executor.workers <= 1:
            for i in own:
                truths[i] = study.truths(cases[i].scenario, seed)
        else:
            parts = {i: capability(study, SplitTruths).truth_parts(cases[i].scenario, seed) for i in own}
            got: dict[int, dict[int, Any]] = {i: {} for i in own}
            tasks += [(study, cases[i].scenario, seed, i, ("truth", j, p))
                      for i in own for j, p in enumerate(parts[i])]
        size = max(1, min(study.trials_per_task, trials // (2 * max(executor.workers, 1))))
        # chunk-major: the same trials of every case side by side
        for lo in range(0, trials, size):
            ks = list(range(lo, min(trials, lo + size)))
            tasks += [(study, c.scenario, seed, i, ks) for i, c in enumerate(cases)]
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=trials * len(cases), desc=f"{study.name} robustness", unit="trial", leave=False)
        try:
            for _, out in executor.map_unordered(_task, tasks):
                if isinstance(out, _Truths):
                    got[out.case][out.index] = out.value
                    if len(got[out.case]) == len(parts[out.case]):
                        i = out.case
                        truths[i] = capability(study, SplitTruths).truths_from_parts(cases[i].scenario, seed,
                                                            [got[i][j] for j in range(len(parts[i]))])
                    continue
                i, part = out
                for k, r in part:
                    results[i][k] = r
                if bar is not None:
                    bar.update(len(part))
        finally:
            if bar is not None:
                bar.close()
    per_case: dict[str, StudyResult] = {}
    for i, c in enumerate(cases):
        samples, tt, sg, aux = _collect(results[i])
        per_case[c.name] = StudyResult(
            study=study, scenario=c.scenario, seed=seed, trials=trials, stopped_by="trials", classes=classes,
            truths=truths[0] if c.shares_truths else truths[i], samples=samples, trial_truths=tt, sigmas=sg,
            example=results[i].get(0), elapsed_s=float("nan"), executor=executor.description, aux=aux)
    return RobustnessResult(study=study, scenario=scenario, seed=seed, trials=trials, cases=cases,
                            results=per_case, elapsed_s=time.perf_counter() - t0,
                            executor=executor.description)


# ---------------------------------------------------------------------- the result
@dataclass
class RobustnessResult:
    """The cases of one robustness run and their statistics (module docstring)."""

    study: Study
    scenario: Any
    seed: int
    trials: int
    cases: list[Case]
    results: dict[str, Any]
    elapsed_s: float = float("nan")
    executor: str = ""
    _cells: dict | None = field(default=None, repr=False)

    # ------------------------------------------------------------ cells
    def classes(self) -> tuple[ClassSpec, ...]:
        """The classes compared (every class but the inputs)."""
        return tuple(c for c in self.results[IDEAL].classes if c.role != "input")

    def columns(self) -> list[tuple[str, str, str]]:
        """``(class, variant, axis)`` of every compared key, variant-major, in the study's order."""
        keys = set(self.results[IDEAL].samples)
        return [(c.name, v, ax) for v in self.study.variants for c in self.classes() for ax in c.axes
                if (c.name, v, ax) in keys]

    def cells(self) -> dict[str, dict[tuple[str, str, str], dict]]:
        """``{case: {(class, variant, axis): cell}}`` (computed once)."""
        if self._cells is not None:
            return self._cells
        ideal = self.results[IDEAL]
        out: dict = {}
        for case in self.cases:
            res = self.results[case.name]
            row = {}
            for key in self.columns():
                cls, var, ax = key
                spec = res.class_spec(cls)
                st = res.statistics(key)
                cov = st.get("coverage")
                # no claim: a residual, an input, a reference variant (it estimates nothing), or an
                # axis the data cannot determine (a gauge freedom, ClassSpec.undetermined: its
                # estimate is a convention, no sigma is stated)
                no_claim = (spec.role in ("residual", "input") or st.get("determined") is False
                            or var in self.study.reference_variants)
                claim = None if no_claim else capability(self.study, WorldEffects).claim(case.scenario, cls, var)
                cell = {"bias": st["bias"], "se_bias": st["se_bias"], "std": st["std"], "mean": st["mean"],
                        "truth": st["truth"], "coverage_1sigma": cov["within_1sigma"] if cov else None,
                        "se_coverage_1sigma": cov["se_1sigma"] if cov else None,
                        "coverage_n": cov["n"] if cov else 0, "claim": claim,
                        "scale": max(abs(st["truth"]), abs(st["mean"])), "at_most": spec.at_most}
                cell["determined"] = st.get("determined") is not False
                cell["claim_holds"] = None if no_claim else claim_holds(
                    bias=cell["bias"], se_bias=cell["se_bias"], claim=claim, coverage_1sigma=cell["coverage_1sigma"],
                    coverage_n=cell["coverage_n"], scale=cell["scale"], at_most=spec.at_most)
                cell["shift"], cell["se_shift"] = self._shift(key, res, ideal, case)
                row[key] = cell
            out[case.name] = row
        self._cells = out
        return out

    def _shift(self, key, res, ideal, case) -> tuple[float, float]:
        """Change of the bias from the ideal case and its standard error from the paired
        per-trial differences (common random numbers), with the truths' own errors."""
        cls, _, ax = key
        if case.name == IDEAL:
            return 0.0, 0.0
        x, x0 = res.samples[key], ideal.samples[key]
        if key in res.trial_truths:
            d = (x - res.trial_truths[key]) - (x0 - ideal.trial_truths[key])
            t_var = 0.0
        else:
            t, t0 = res.truths[(cls, ax)], ideal.truths[(cls, ax)]
            d = (x - t.value) - (x0 - t0.value)
            t_var = 0.0 if t is t0 else t.se**2 + t0.se**2
        n = d.size
        sd = float(d.std(ddof=1)) if n > 1 else 0.0
        return float(d.mean()), math.sqrt(sd * sd / n + t_var)

    # ------------------------------------------------------------ verdicts
    def breaks(self) -> dict[tuple[str, str], dict]:
        """Per ``(class, variant)``: which single effect breaks its claim first (the failing
        single-effect case farthest past its claim, :func:`_severity`), on which axis, and the
        sentence that says it."""
        cells = self.cells()
        singles = [c.name for c in self.cases if c.name not in (IDEAL, ALL)]
        out = {}
        for spec in self.classes():
            for var in self.study.variants:
                keys = [k for k in self.columns() if k[0] == spec.name and k[1] == var]
                if not keys:
                    continue
                determined = [k for k in keys if cells[IDEAL][k]["determined"]]
                if not determined:
                    out[(spec.name, var)] = {"effect": None, "axis": None, "sentence": (
                        f"{spec.label}, {var}: not determined (a gauge freedom: the data cannot separate "
                        "it from another parameter), no claim to test.")}
                    continue
                keys = determined
                out[(spec.name, var)] = self._verdict(spec, var, keys, cells, singles)
        return out

    def _verdict(self, spec: ClassSpec, var: str, keys, cells, singles) -> dict:
        unit = "" if spec.unit in ("", "1") else f" {spec.unit}"  # a ratio's unit "1" is not written
        head = f"{spec.label}, {var}"

        def worst(case_names, failing_only=True):
            best = None
            for cn in case_names:
                for k in keys:
                    c = cells[cn][k]
                    if failing_only and c["claim_holds"] is not False:
                        continue
                    s = _severity(c)
                    if best is None or s > best[0]:
                        best = (s, cn, k)
            return best

        def said(cn, k) -> str:
            c = cells[cn][k]
            s = f"bias {fmt(c['bias'], 3, sign=True)} +- {fmt(abs(c['se_bias']), 2)}{unit}"
            if cn != IDEAL:
                s += f" (a shift of {fmt(c['shift'], 3, sign=True)} +- {fmt(abs(c['se_shift']), 2)} from the ideal world)"
            if c["claim"] is not None:
                s += f", {fmt((abs(c['bias']) + 3 * c['se_bias']) / c['claim'], 2)} times its claimed {fmt(c['claim'], 3)}"
            if c["coverage_1sigma"] is not None:
                s += (f", 1-sigma coverage {100 * c['coverage_1sigma']:.1f} % "
                      f"(68.3 +- {100 * c['se_coverage_1sigma']:.1f} % expected)")
            return s + (f" on axis {k[2]}" if len(keys) > 1 else "")

        if spec.role == "residual":
            # no verdict; which effect alone moves it most (the case "all" always would, or
            # nearly: naming it would say nothing), then all together
            s, effect, axis = f"{head}: a residual, no claim to test", None, None
            if singles:
                big = max(((cn, k) for cn in singles for k in keys), key=lambda ck: abs(cells[ck[0]][ck[1]]["shift"]))
                s += f"; of the effects alone {big[0]} changes it most: {said(*big)}"
                effect, axis = big[0], big[1][2]
            if ALL in cells:
                ka = max(keys, key=lambda k: abs(cells[ALL][k]["shift"]))
                s += f"; all together: {said(ALL, ka)}"
            return {"effect": effect, "axis": axis, "sentence": s + "."}
        w0 = worst([IDEAL])
        if w0 is not None:
            s = f"{head}: its claim fails already in the ideal world: {said(IDEAL, w0[2])}"
            w = worst(singles, failing_only=False)
            if w is not None and w[0] > w0[0]:
                s += f"; {w[1]} takes it farthest: {said(w[1], w[2])}"
            return {"effect": IDEAL, "axis": w0[2][2], "severity": w0[0], "sentence": s + "."}
        w = worst(singles)
        if w is not None:
            return {"effect": w[1], "axis": w[2][2], "severity": w[0],
                    "sentence": f"{head}: {w[1]} breaks its claim first: {said(w[1], w[2])}."}
        if ALL in cells:
            wa = worst([ALL])
            if wa is not None:
                return {"effect": ALL, "axis": wa[2][2], "severity": wa[0],
                        "sentence": f"{head}: no single effect breaks its claim; all together they do: "
                                    f"{said(ALL, wa[2])}."}
        if len(self.cases) == 1:
            return {"effect": None, "axis": None, "sentence": f"{head}: its claim holds (no effect is on)."}
        last = ALL if ALL in cells else self.cases[-1].name
        k = max(keys, key=lambda k: _severity(cells[last][k]))
        return {"effect": None, "axis": None,
                "sentence": f"{head}: no effect breaks its claim ({'all effects together' if last == ALL else last}: "
                            f"{said(last, k)})."}

    # ------------------------------------------------------------ output
    def to_json(self) -> dict:
        """JSON payload (schema ``budget.robustness/1``, module docstring)."""
        cells = self.cells()
        effects = scenario_effects(self.scenario)
        depends = capability(self.study, WorldEffects).truth_depends_on_effects(self.scenario)
        cases = {}
        for case in self.cases:
            classes: dict = {}
            for (cls, var, ax), c in cells[case.name].items():
                classes.setdefault(cls, {}).setdefault(ax, {})[var] = {
                    k: c[k] for k in ("bias", "se_bias", "std", "coverage_1sigma", "claim", "claim_holds",
                                      "shift", "se_shift", "mean", "truth")}
            cases[case.name] = {
                "active_effects": list(case.active), "effects": case.magnitudes,
                "trials": self.results[case.name].trials, "seed": self.seed,
                "scenario_hash": self.study.scenario_hash(case.scenario),
                "truths_from": IDEAL if case.shares_truths else "own",
                "classes": classes,
            }
        return {
            "schema": SCHEMA, "study": self.study.name, "title": self.study.title,
            "seed_document": self.study.seed_document, "version": simcam.__version__,
            "scenario_name": getattr(self.scenario, "name", None),
            "scenario_hash": self.study.scenario_hash(self.scenario),
            "scenario_toml": self.study.scenario_text(self.scenario),
            "seed": self.seed, "trials": self.trials, "variants": list(self.study.variants),
            "effects": {n: {"magnitude": v, "source": type(effects).sources().get(n, "")}
                        for n, v in effects.magnitudes().items()},
            "truth_depends_on_effects": None if depends is None else sorted(depends),
            "class_info": {c.name: {"label": c.label, "unit": c.unit, "role": c.role, "axes": list(c.axes),
                                    "per_trial_truth": c.per_trial_truth} for c in self.classes()},
            "claim_holds_definition": CLAIM_HOLDS_TEXT,
            "cases": cases,
            "breaks": {f"{cls}.{var}": v for (cls, var), v in self.breaks().items()},
            "elapsed_s": self.elapsed_s, "executor": self.executor,
        }

    def table_rows(self, *, markdown: bool = False) -> list[list[str]]:
        """Header and one row per case, one column per class and variant (the variant's axes
        summed up in one cell, :func:`summary_cell`: a table read at a glance, also for a
        study of ten classes and thirty axes)."""
        groups: dict[tuple[str, str], list[str]] = {}
        for c, v, a in self.columns():
            groups.setdefault((c, v), []).append(a)
        units = {c.name: c.unit for c in self.classes()}
        head = ["case"] + [f"{v} {c} ({units[c]})" if markdown else f"{v} {c}" for c, v in groups]
        rows = [head]
        cells = self.cells()
        for case in self.cases:
            rows.append([case.name] + [summary_cell([(a, cells[case.name][(c, v, a)]) for a in axes],
                                                    markdown=markdown) for (c, v), axes in groups.items()])
        return rows

    def format_table(self) -> str:
        """The table for a terminal: rows cases, columns variant x class."""
        rows = self.table_rows()
        widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
        return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows)

    def markdown_table(self) -> str:
        rows = self.table_rows(markdown=True)
        lines = ["| " + " | ".join(rows[0]) + " |", "|" + "---|" * len(rows[0])]
        lines += ["| " + " | ".join(r) + " |" for r in rows[1:]]
        return "\n".join(lines)

    def sentences(self) -> list[str]:
        """One sentence per class and variant (:meth:`breaks`)."""
        return [v["sentence"] for v in self.breaks().values()]

    def header(self) -> str:
        st = self.study
        return (f"{st.title}: robustness of scenario {getattr(self.scenario, 'name', '')} "
                f"(hash {st.scenario_hash(self.scenario)}), seed {self.seed}: {len(self.cases)} cases x "
                f"{self.trials} trials in {self.elapsed_s:.1f} s on {self.executor}")

    def write_report(self, out_dir: str | Path) -> Path:
        """Write ``report.md``, ``robustness.json`` and ``scenario.toml`` into ``out_dir``
        (a temporary sibling renamed into place: never a half-written report)."""
        with staged_report(out_dir) as tmp:
            st = self.study
            effects = scenario_effects(self.scenario)
            sources = type(effects).sources()
            depends = st.truth_depends_on_effects(self.scenario)
            lines = [f"# {st.title}: what each claim survives", "",
                     f"Study `{st.name}` (seed document {st.seed_document}); scenario "
                     f"`{getattr(self.scenario, 'name', '')}` (hash `{st.scenario_hash(self.scenario)}`), seed "
                     f"{self.seed}, {self.trials} trials in each of {len(self.cases)} cases, the same trial "
                     "seeds in every case (common random numbers: a difference between cases is the effect's).",
                     "", "## Effects of the world", "",
                     "The lab's methods model none of these; each case below switches them on or off.", ""]
            for n, v in effects.magnitudes().items():
                lines.append(f"* `{n}` = {v:g}{'' if v else ' (off)'}: {sources.get(n, '')}")
            lines += ["", "Cases: `ideal` (every effect off), each effect that is on alone at its magnitude"
                      + (", `all` (every effect on)." if any(c.name == ALL for c in self.cases) else "."),
                      "Truths: " + ("computed for every case." if depends is None else
                                    "the ideal case's, reused by every case whose effects leave them unchanged "
                                    f"(they depend on {', '.join(sorted(depends)) or 'no effect'})."),
                      "", "## Verdicts", "", self.markdown_table(), "",
                      "Each cell, one class and variant: `ok` when its claim holds on every axis, `FAIL k/n` "
                      "when it fails on k of its n axes (`--`: no claim to judge: a residual, an input, a reference "
                      "variant that estimates nothing, or an undetermined axis), "
                      "then the bias in the class's unit of the axis farthest past its claim (named in "
                      "brackets); every axis is in `robustness.json`. " + CLAIM_HOLDS_TEXT, "", "## What breaks each claim", ""]
            lines += [f"* {s}" for s in self.sentences()]
            scenario_toml = st.scenario_text(self.scenario)
            lines += ["", "## Scenario", "", "```toml", scenario_toml.rstrip(), "```", ""]
            (tmp / "scenario.toml").write_text(scenario_toml)
            write_json_atomic(tmp / "robustness.json", self.to_json())
            (tmp / "report.md").write_text("\n".join(lines))
            write_html(tmp / "report.md")  # its self-contained twin, report.html
        return Path(out_dir) / "report.md"


#: ``claim_holds`` in words (the JSON and the report carry it)
CLAIM_HOLDS_TEXT = (
    "A claim holds when the bias is within 3 combined standard errors of zero (where the method "
    "states an accuracy A: when |bias| + 3 se <= A) and, where the variant states a 1-sigma "
    "uncertainty, its 1-sigma coverage is within the binomial 3-standard-error band of 68.27 % "
    "for the trial count; a residual has no claim. A one-sided claim (a stated bound the actual "
    "stays at or below) holds when the estimate is not below the truth by more than 3 standard "
    "errors (-bias in place of |bias|).")


# ---------------------------------------------------------------------- the command
def robustness_command_for(study_name: str) -> click.Command:
    """``robustness [SCENARIO] --trials --seed --workers --scheduler --dask-local --json --report --progress``."""

    @click.command("robustness", help=f"What each {study_name} method's claim survives of the world's "
                                      "unmodelled effects: the ideal world, each effect alone and all together, "
                                      "with the same trial seeds (SCENARIO: default the embedded one).")
    @click.argument("scenario", required=False, type=click.Path(dir_okay=False))
    @click.option("--trials", type=click.IntRange(min=2), default=None,
                  help="Trials per case (default: the scenario's validation.trials).")
    @click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True)
    @click.option("--workers", type=click.IntRange(min=1), default=None,
                  help="Local worker processes (default: all cores). Results do not depend on it.")
    @click.option("--scheduler", default=None, help="Run the trials on a Dask cluster (tcp://HOST:PORT).")
    @click.option("--dask-local", type=int, default=None, help="Run on a Dask LocalCluster of N processes.")
    @click.option("--json", "json_out", type=click.Path(dir_okay=False), help="Write the results as JSON.")
    @click.option("--report", "report_dir", type=click.Path(file_okay=False),
                  help="Write a report (report.md, report.html, robustness.json, scenario.toml).")
    @overwrite_option
    @click.option("--progress/--no-progress", default=None, help="Progress bar (default: on a terminal).")
    def robustness(scenario, trials, seed, workers, scheduler, dask_local, json_out, report_dir, overwrite, progress):
        import sys

        study = get_study(study_name)
        scn = study.load_scenario(scenario)
        # the outputs are checked before the work and written together (or not at all)
        check_run_outputs(json_out=json_out, report_dir=report_dir, inputs=(scenario,), overwrite=overwrite)
        if progress is None:
            progress = sys.stderr.isatty()
        if workers is None and scheduler is None and dask_local is None:
            workers = default_workers()
        res = run_robustness(study, scn, trials=trials, seed=seed, workers=workers, scheduler=scheduler,
                             dask_local=dask_local, progress=progress,
                             source=scenario or f"embedded {study.name} default")
        click.echo(res.header())
        click.echo(res.format_table())
        for s in res.sentences():
            click.echo(f"* {s}")
        write_outputs(res, json_out=json_out, report_dir=report_dir)

    return robustness
