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

The verdicts (:mod:`budget.runner.robustness_verdicts`)
--------------------------------------------------------
Each cell, one ``(class, variant, axis)`` in one case, is judged by the one three-valued rule
(:func:`budget.runner.verdicts.judge`), exactly as ``validate`` judges the same numbers
(:func:`budget.runner.class_verdicts.class_verdict` on the case's result): the bias against a
practical tolerance (the claimed accuracy of :meth:`~budget.runner.capabilities.WorldEffects.claim`,
else the ledger's claim on the class, else 10 % of the truth's size) and,
where the variant states a 1-sigma uncertainty, the 1-sigma coverage against 68.3 % +- 5
points. ``verdict`` is ``holds`` / ``fails`` / ``undetermined`` (with ``n_to_settle``), or
``null`` for a residual, an input, a reference variant (:attr:`Study.reference_variants`)
and a gauge axis (:attr:`ClassSpec.undetermined`); ``claim_holds`` is derived from it
(true for ``holds`` only, false for ``fails`` and ``undetermined``, null without a verdict).

The result, :class:`RobustnessResult`, gives the JSON (schema ``budget.robustness/2``:
``cases[name].classes[class][axis][variant]`` with ``bias``, ``se_bias``, ``std``,
``coverage_1sigma`` (null where no sigma is stated), ``claim``, ``verdict``, ``no_verdict``,
``tolerance`` (``low``, ``high``, ``reason``, ``source``), ``coverage_verdict``,
``n_to_settle``, ``claim_holds``, ``shift`` and ``se_shift`` (the change from the ideal
case, paired), and per case its active effects, trials, seed and scenario hash), the table
(:meth:`RobustnessResult.format_table`) and ``report.md`` (:meth:`RobustnessResult.write_report`)
with one sentence per class and variant saying which effect breaks its claim first (only
for a cell that fails), or where it is undetermined and how many trials would settle it.
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
from budget.runner.capabilities import (
    BatchedTrials,
    CheckedScenario,
    SharedTruths,
    SplitTruths,
    Warmup,
    WorldEffects,
    capability,
)
from budget.runner.class_verdicts import method_rules
from budget.runner.executors import default_workers, make_executor
from budget.runner.html import write_html
from budget.runner.numbers import fmt
from budget.runner.registry import get_study
from budget.runner.report import staged_report, write_outputs
from budget.runner.robustness_verdicts import (
    COVERAGE_TOLERANCE,
    VERDICT_TEXT,
    cell_verdict,
    severity,
    summary_cell,
)
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

__all__ = ["ALL", "IDEAL", "SCHEMA", "Case", "RobustnessResult", "build_cases", "robustness_command_for",
           "run_robustness", "scenario_with_effects"]

SCHEMA = "budget.robustness/2"
#: names of the cases with every effect off and every effect on
IDEAL, ALL = "ideal", "all"


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
                   progress: bool = False, prewarm: bool = True, source: str = "") -> RobustnessResult:
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
            ledger = method_rules(res)  # the study's ledger claims, once per case
            row = {}
            for key in self.columns():
                cls, var, _ax = key
                spec = res.class_spec(cls)
                st = res.statistics(key)
                cov = st.get("coverage")
                v = cell_verdict(res, key, st, ledger)
                # the claimed accuracy where there is a verdict (WorldEffects.claim), for the record
                claim = (capability(self.study, WorldEffects).claim(case.scenario, cls, var)
                         if v["verdict"] is not None else None)
                cell = {"bias": st["bias"], "se_bias": st["se_bias"], "std": st["std"], "mean": st["mean"],
                        "truth": st["truth"], "coverage_1sigma": cov["within_1sigma"] if cov else None,
                        "se_coverage_1sigma": cov["se_1sigma"] if cov else None,
                        "coverage_n": cov["n"] if cov else 0, "claim": claim, "at_most": spec.at_most,
                        "determined": st.get("determined") is not False, **v}
                cell["claim_holds"] = None if v["verdict"] is None else v["verdict"] == "holds"
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
        """Per ``(class, variant)``: the sentence built from its cells' verdicts (a failing
        single-effect case farthest past its tolerances, :func:`~budget.runner.robustness_verdicts.severity`,
        "breaks its claim first"; an undetermined one says so with the trials to settle it),
        the effect and axis it names."""
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
                    out[(spec.name, var)] = {"effect": None, "axis": None, "verdict": None, "sentence": (
                        f"{spec.label}, {var}: not determined (a gauge freedom: the data cannot separate "
                        "it from another parameter), no claim to test.")}
                    continue
                out[(spec.name, var)] = self._verdict(spec, var, determined, cells, singles)
        return out

    def _said(self, spec: ClassSpec, keys, cells, cn: str, k) -> str:
        """One cell's numbers and verdict in words."""
        unit = "" if spec.unit in ("", "1") else f" {spec.unit}"  # a ratio's unit "1" is not written
        c = cells[cn][k]
        s = f"bias {fmt(c['bias'], 3, sign=True)} +- {fmt(abs(c['se_bias']), 2)}{unit}"
        s += f" on axis {k[2]}" if len(keys) > 1 else ""
        if cn != IDEAL:
            s += f" (a shift of {fmt(c['shift'], 3, sign=True)} +- {fmt(abs(c['se_shift']), 2)} from the ideal world)"
        bv, cv = c["bias_verdict"], c["coverage_verdict"]
        if bv is not None:
            s += f", {bv.outcome} against {bv.tolerance.describe(unit.strip())} ({bv.tolerance.reason})"
        if c["coverage_1sigma"] is not None:
            s += f", 1-sigma coverage {100 * c['coverage_1sigma']:.1f} %"
            if cv is not None:
                s += f" ({cv.outcome} against 68.3 +- 5 points)"
        if c["verdict"] == "undetermined":
            s += ("; its estimate sits on a tolerance's edge: no number of trials settles it" if c["on_edge"]
                  else f"; about {c['n_to_settle']} trials would settle it" if c["n_to_settle"]
                  else "; more trials would settle it")
        return s

    def _verdict(self, spec: ClassSpec, var: str, keys, cells, singles) -> dict:
        head = f"{spec.label}, {var}"

        def said(cn, k) -> str:
            return self._said(spec, keys, cells, cn, k)

        def worst(case_names, outcome="fails"):
            best = None
            for cn in case_names:
                for k in keys:
                    c = cells[cn][k]
                    if outcome is not None and c["verdict"] != outcome:
                        continue
                    s = severity(c)
                    if best is None or s > best[0]:
                        best = (s, cn, k)
            return best

        def answer(effect, w, sentence, verdict):
            return {"effect": effect, "axis": None if w is None else w[2][2],
                    "severity": None if w is None else w[0], "verdict": verdict, "sentence": sentence + "."}

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
            return {"effect": effect, "axis": axis, "verdict": None, "sentence": s + "."}
        names = [c.name for c in self.cases]
        if all(cells[cn][k]["verdict"] is None for cn in names for k in keys):
            return answer(None, None, f"{head}: no verdict ({cells[IDEAL][keys[0]]['no_verdict']})", None)
        w0 = worst([IDEAL])
        if w0 is not None:
            s = f"{head}: its claim fails already in the ideal world: {said(IDEAL, w0[2])}"
            w = worst(singles)
            if w is not None and w[0] > w0[0]:
                s += f"; {w[1]} takes it farthest: {said(w[1], w[2])}"
            return answer(IDEAL, w0, s, "fails")
        w = worst(singles)
        if w is not None:
            return answer(w[1], w, f"{head}: {w[1]} breaks its claim first: {said(w[1], w[2])}", "fails")
        wa = worst([ALL]) if ALL in cells else None
        if wa is not None:
            return answer(ALL, wa, f"{head}: no single effect breaks its claim; all together they do: "
                                   f"{said(ALL, wa[2])}", "fails")
        open_ = [cn for cn in names if any(cells[cn][k]["verdict"] == "undetermined" for k in keys)]
        if open_:
            wu = worst(open_, "undetermined")
            return answer(None, wu, f"{head}: no case shows its claim broken, but it is undetermined in "
                                    f"{len(open_)} of {len(names)} cases ({', '.join(open_)}); farthest out, "
                                    f"{wu[1]}: {said(wu[1], wu[2])}", "undetermined")
        if len(self.cases) == 1:
            return answer(None, None, f"{head}: its claim holds (no effect is on): {said(IDEAL, keys[0])}", "holds")
        last = ALL if ALL in cells else self.cases[-1].name
        wl = worst([last], None)
        return answer(None, None, f"{head}: its claim holds in every case "
                                  f"({'all effects together' if last == ALL else last}: {said(last, wl[2])})", "holds")

    # ------------------------------------------------------------ output
    def to_json(self) -> dict:
        """JSON payload (schema ``budget.robustness/2``, module docstring)."""
        cells = self.cells()
        effects = scenario_effects(self.scenario)
        depends = capability(self.study, WorldEffects).truth_depends_on_effects(self.scenario)
        cases = {}
        for case in self.cases:
            classes: dict = {}
            for (cls, var, ax), c in cells[case.name].items():
                classes.setdefault(cls, {}).setdefault(ax, {})[var] = _cell_json(c)
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
            "verdict_definition": VERDICT_TEXT,
            "coverage_tolerance": _tolerance_json(COVERAGE_TOLERANCE),
            "cases": cases,
            "breaks": {f"{cls}.{var}": v | {"severity": _finite(v.get("severity"))}
                       for (cls, var), v in self.breaks().items()},
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
                     (f"Study `{st.name}` (seed document {st.seed_document}); scenario "
                      f"`{getattr(self.scenario, 'name', '')}` (hash `{st.scenario_hash(self.scenario)}`), seed "
                      f"{self.seed}, {self.trials} trials in each of {len(self.cases)} cases, the same trial "
                      "seeds in every case (common random numbers: a difference between cases is the effect's)."),
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
                      "Each cell, one class and variant: `holds` when every judged axis holds, `FAILS k/n` "
                      "when k of its n judged axes fail, `undet. k/n` when none fails and k are undetermined "
                      "(`--`: no verdict: a residual, an input, a reference variant that estimates nothing, or "
                      "a gauge axis), then the bias in the class's unit of the axis farthest past its "
                      "tolerance (named in brackets); every axis, with its tolerance and the trials that "
                      "would settle it, is in `robustness.json`. " + VERDICT_TEXT, "", "## What breaks each claim", ""]
            lines += [f"* {s}" for s in self.sentences()]
            scenario_toml = st.scenario_text(self.scenario)
            lines += ["", "## Scenario", "", "```toml", scenario_toml.rstrip(), "```", ""]
            (tmp / "scenario.toml").write_text(scenario_toml)
            write_json_atomic(tmp / "robustness.json", self.to_json())
            (tmp / "report.md").write_text("\n".join(lines))
            write_html(tmp / "report.md")  # its self-contained twin, report.html
        return Path(out_dir) / "report.md"


def _finite(x):
    """``x`` where finite, else None (the JSON has no NaN or infinity)."""
    return x if isinstance(x, (int, float)) and math.isfinite(x) else None


def _tolerance_json(t) -> dict | None:
    if t is None:
        return None
    return {"low": _finite(t.low), "high": _finite(t.high), "reason": t.reason, "source": t.source}


def _cell_json(c: dict) -> dict:
    """One cell of the JSON (module docstring)."""
    out = {k: c[k] for k in ("bias", "se_bias", "std", "coverage_1sigma", "claim", "verdict", "no_verdict",
                             "n_to_settle", "claim_holds", "shift", "se_shift", "mean", "truth")}
    bv, cv = c["bias_verdict"], c["coverage_verdict"]
    out["tolerance"] = _tolerance_json(bv.tolerance if bv is not None else None)
    out["bias_verdict"] = bv.outcome if bv is not None else None
    out["coverage_verdict"] = cv.outcome if cv is not None else None
    out["significance_se"] = _finite(bv.significance_se) if bv is not None else None
    return out


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
