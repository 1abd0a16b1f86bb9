"""The knob search: :class:`ShapeSearch` finds one protocol shape's cheapest protocol meeting
every requirement (design, model, frontier, refinement; docs/planning.md, "The search"), and
:class:`PlanRun`, what every search of one plan shares, searches each shape and runs a
protocol on the re-validation's fresh seeds."""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from budget.runner.capabilities import CheckedScenario, capability
from budget.runner.plan.oracle import Oracle
from budget.runner.plan.protocols import cost_flat_knobs, dotted_value, knob_levels, knob_value, lab_time, scenario_with
from budget.runner.plan.quantiles import smooth_ratio
from budget.runner.plan.requirements import Requirement
from budget.runner.plan.result import Boundary, Evaluation, ModelCurve, PlanResult, Refusal, ShapeOutcome
from budget.runner.plan.trials import BUDGET_VALIDATIONS, SETTLE_MAX_VALIDATIONS, screening_trials, validation_seed
from budget.runner.study import Knob, Study

__all__ = ["FLAT_COARSE", "FLAT_REFINE", "PlanRun", "ShapeSearch", "resolution"]

# ---------------------------------------------------------------------- the search's numbers
#: the design's levels per knob by the number of cost-bearing knobs (:data:`DESIGN_LEVELS_MANY` beyond
#: two): 5, 3 x 3 = 9, then 2^d corners; each design protocol costs screening trials, so more knobs get
#: fewer levels to keep the design within a few validations' trials (the model needs two per knob)
DESIGN_LEVELS = {1: 5, 2: 3}
DESIGN_LEVELS_MANY = 2
#: the coarse grid's values per knob on which :meth:`~budget.runner.capabilities.Plannable.lab_time_s` is computed, by the number of
#: knobs (:data:`COARSE_VALUES_MANY` beyond three): the fine grid's lab times are interpolated
#: multilinearly from it, exact for lab times that are sums of products of knobs, so few values do and
#: the frontier's protocols are costed exactly anyway; chosen empirically: more values cost scenario
#: validations (9, 49, 125, 3^d per shape), fewer make the interpolated frontier order poorer
COARSE_VALUES = {1: 9, 2: 7, 3: 5}
COARSE_VALUES_MANY = 3
#: the fine grid's values per knob, the frontier's candidates (:data:`FINE_VALUES_MANY` beyond three):
#: 4000, 160^2, 40^3 and 12^d protocols, tens of thousands; chosen empirically: a finer grid puts the
#: frontier's protocols closer in lab time (the one-knob grid's neighbours well within the cost
#: resolution, :func:`resolution`), a coarser one keeps each frontier pass (a sort of the grid) cheaper
FINE_VALUES = {1: 4000, 2: 160, 3: 40}
FINE_VALUES_MANY = 12
#: a cost-flat knob's coarse grid (values over its range, ends included: the middle and both ends) and
#: the refinement steps after it, each halving the wider gap next to the best value; chosen
#: empirically: each value costs screening trials per candidate, which the trial budget must hold
FLAT_COARSE = 3
FLAT_REFINE = 2
#: validations' trials kept free before a candidate is run: its own completion to a validation's trials
#: and the answer's, so the answer is always judged on a validation's trials within the budget
ROOM_VALIDATIONS = 2
#: passes of the frontier: each computes the exact lab time of its frontier's protocols (interpolated
#: before) and sorts again; the interpolation being exact or nearly so, a second pass rarely changes
#: the frontier and a third settles it (chosen empirically; a frontier still moving is used as it is)
FRONTIER_PASSES = 3
#: relative slack of the cost and ratio comparisons (floating-point noise, not a difference): the
#: cheapest setting sits this much below the cheapest lab time, and a frontier protocol must predict
#: better than every cheaper one by this much
RELATIVE_SLACK = 1e-9
#: the least quantile a fit weight divides by, relative to its bound: a protocol measuring no error
#: (an exact estimate) weighs finitely instead of infinitely
WEIGHT_QUANTILE_FLOOR = 1e-6
#: the most a failing protocol's ratio ``r`` raises the lab time a meeting one needs (``r^2``, capped):
#: a protocol far off (a design corner a floor holds up, not noise) would otherwise push the lower bound
#: past every protocol; chosen empirically: a larger cap lets one far-off protocol force large jumps, a
#: smaller one weakens the bound
MAX_NEED_FACTOR = 16.0
#: a model pick within this share of the cost resolution of the cheapest protocol measured meeting is
#: taken to sit on it (their lab times could not be told apart): the search then steps just below it or
#: bisects instead
ON_ANSWER_SHARE = 0.5
#: a guard on the refinement's steps: each step runs a protocol not run before, so the trial budget
#: ends a search first (at most 4 x 19 protocols at screening trials) unless the study refuses
#: protocols, which spend no trials
MAX_REFINEMENT_STEPS = 100
#: predicted ratios equal to this many decimals are a tie between most accurate protocols (decided by
#: the measured quantile): the model's predictions differ there only by floating-point noise
TIE_DECIMALS = 9


def resolution(trials: int) -> float:
    """Relative cost resolution of the refinement: ``1 / (2 sqrt(n))``, half the relative
    standard error of a 95 % quantile of ``n`` Gaussian trials (about ``0.95 / sqrt(n)``)."""
    return 0.5 / math.sqrt(trials)


def _feature(k: Knob, x):
    """What a knob averages down: ``1 / x`` for a count (``low > 0``), else ``1 / (x - low + 1)``."""
    x = np.asarray(x, dtype=float)
    return 1.0 / x if k.low > 0 else 1.0 / (x - k.low + 1.0)


def _by_count(table: dict[int, int], many: int, d: int) -> int:
    return table.get(d, many)


@dataclass(frozen=True)
class _Bracket:
    """Where the refinement stands: the cheapest protocol measured meeting (``hi``) and the
    dearest measured failing below it (``lo``), their lab times, and the lab times averaging
    says each implies (``lo_need``: at least; ``hi_need``: at most)."""

    hi: Evaluation | None
    lo: Evaluation | None
    hi_cost: float
    lo_cost: float
    lo_need: float
    hi_need: float


# ---------------------------------------------------------------------- the search of one shape
class ShapeSearch:
    """The search of one shape over its cost-bearing knobs (docs/planning.md, "The search"):
    :meth:`search` runs the design, then the refinement (the model's frontier, bracketed by
    what averaging allows), then judges the answer on a validation's trials."""

    def __init__(self, oracle: Oracle, shape: str, scn: Any, knobs: tuple[Knob, ...], budget_s: float | None,
                 trial_cap: int, flat: tuple[Knob, ...] = (), fixed: dict | None = None):
        self.o, self.shape, self.base, self.knobs = oracle, shape, scn, knobs
        self.budget_s, self.trial_cap = budget_s, trial_cap
        #: cost-flat knobs (set per candidate by direct evaluation, :meth:`_best_flat`) and pinned ones
        self.flat, self.fixed = tuple(flat), dict(fixed or {})
        self._flat_memo: dict = {}
        self.evals: list[Evaluation] = []
        self.start_trials = oracle.trials_run
        self.where = f"plan shape {shape}"
        self.exact: set[int] = set()
        #: protocols refused (scenario model, check or trials), with the reason
        self.refused: list[Refusal] = []
        if self.knobs:
            self._grid()
        else:
            self.points, self.costs = np.zeros((1, 0)), np.array([self._cost([])])

    # ---- scenarios and costs
    def scenario(self, x, flat: dict | None = None) -> tuple[Any, dict]:
        """Protocol ``x`` (cost-bearing knob values) with the cost-flat knobs at ``flat``, and its knob values."""
        vals = {**{k.field: knob_value(k, xi) for k, xi in zip(self.knobs, x)}, **(flat or {})}
        if not vals:
            return self.base, vals
        return scenario_with(self.o.study, self.base, vals, where=self.where), vals

    def _grid(self) -> None:
        """The fine grid (frontier candidates) with costs interpolated from a coarse grid."""
        from scipy.interpolate import RegularGridInterpolator  # heavy (budget.runner.plan.quantiles)

        d = len(self.knobs)
        coarse = [knob_levels(k, _by_count(COARSE_VALUES, COARSE_VALUES_MANY, d)) for k in self.knobs]
        fine = [knob_levels(k, _by_count(FINE_VALUES, FINE_VALUES_MANY, d)) for k in self.knobs]
        cost = np.empty([len(c) for c in coarse])
        for idx in np.ndindex(*cost.shape):
            cost[idx] = self._cost([coarse[i][j] for i, j in enumerate(idx)])
        mesh = np.meshgrid(*fine, indexing="ij")
        pts = np.stack([m.ravel() for m in mesh], axis=1)
        keep = [i for i, a in enumerate(coarse) if len(a) > 1]
        if keep:
            # multilinear in the knob values: exact for lab times that are sums of products of knobs
            interp = RegularGridInterpolator([coarse[i] for i in keep], cost.reshape([len(coarse[i]) for i in keep]),
                                             method="linear")
            c = interp(pts[:, keep])
        else:
            c = np.full(len(pts), float(cost.ravel()[0]))
        self.points, self.costs = pts, c

    def _cost(self, x) -> float:
        """Lab time of protocol ``x`` (NaN where the scenario model refuses it)."""
        try:
            scn, _ = self.scenario(x)
        except ValueError:
            return float("nan")
        return lab_time(self.o.study, scn)

    def _in_budget(self, e: Evaluation) -> bool:
        return self.budget_s is None or e.cost_s <= self.budget_s

    # ---- the model
    def _fit(self):
        """Per requirement, non-negative ``(a, b_1..b_d)`` of ``(q / VALUE)^2 = a + sum b_i f_i(x_i)``:
        in units of the bound, so that no bound (1e-300 or 1e300) over- or underflows a square."""
        from scipy.optimize import nnls  # heavy (budget.runner.plan.quantiles)

        evs = list(self.evals)
        if not evs:  # nothing measured yet (every design protocol refused): no preference
            return {r.name: np.zeros(1 + len(self.knobs)) for r in self.o.reqs}
        coefs = {}
        for r in self.o.reqs:
            q2 = np.array([(e.figures[r.name]["quantile"] / r.value) ** 2 for e in evs])
            feats = np.array([[1.0] + [float(_feature(k, e.knobs[k.field])) for k in self.knobs] for e in evs])
            w = np.array([e.trials for e in evs]) / np.maximum(q2, WEIGHT_QUANTILE_FLOOR ** 2)
            sw = np.sqrt(w)
            coef, _ = nnls(feats * sw[:, None], q2 * sw)
            coefs[r.name] = coef
        return coefs

    def _features(self, pts) -> np.ndarray:
        return np.column_stack([np.ones(len(pts))] + [_feature(k, pts[:, i]) for i, k in enumerate(self.knobs)])

    def predicted_ratio(self, coefs, pts, margin: float | None = None) -> np.ndarray:
        """The model's worst quantile over its bound, times the ``sure`` margin
        (:func:`sure_margin`; default the search's)."""
        m = self.o.margin if margin is None else margin
        feats = self._features(pts)
        return m * np.max([np.sqrt(np.maximum(feats @ coefs[r.name], 0.0)) for r in self.o.reqs], axis=0)

    def frontier(self, coefs):
        """Indices into the fine grid, by cost, of protocols no cheaper protocol predicts better
        (within the budget), and every grid protocol's predicted ratio."""
        ratio = self.predicted_ratio(coefs, self.points)
        for _ in range(FRONTIER_PASSES):  # the frontier's costs exact (computed once each), then its order again
            order = np.argsort(self.costs, kind="stable")
            order = order[np.isfinite(self.costs[order])]
            if self.budget_s is not None:
                order = order[self.costs[order] <= self.budget_s]
            out, best = [], math.inf
            for i in order:
                if ratio[i] < best * (1 - RELATIVE_SLACK):
                    out.append(int(i))
                    best = ratio[i]
            new = [i for i in out if i not in self.exact]
            if not new:
                break
            for i in new:
                c = self._cost(self.points[i])
                self.costs[i] = c if math.isfinite(c) else math.inf
                self.exact.add(i)
        return np.array(out, dtype=int), ratio

    # ---- running protocols
    def spent(self) -> int:
        return self.o.trials_run - self.start_trials

    def _room(self) -> bool:
        """Whether the trial budget holds another candidate with its flat search and completions."""
        return self.spent() + self.flat_trials() + ROOM_VALIDATIONS * self.o.n <= self.trial_cap

    def run(self, x, stage) -> Evaluation | None:
        """Run protocol ``x`` (once); a protocol the scenario model, :meth:`~budget.runner.capabilities.CheckedScenario.check` or the
        study's trials refuse (a ``ValueError`` or an arithmetic error: too few poses for a fit,
        ...) is recorded in :attr:`refused` and skipped (None)."""
        vals = {k.field: knob_value(k, xi) for k, xi in zip(self.knobs, x)}
        for e in self.evals:
            if all(e.knobs.get(f) == v for f, v in vals.items()):
                return e
        if any(all(r.knobs.get(f) == v for f, v in vals.items()) for r in self.refused if not r.flat):
            return None
        if self.flat:
            ev = self._best_flat(x, stage)
            if ev is None:
                self.refused.append(Refusal({**vals, **self.fixed}, "every setting of the cost-flat knobs refused"))
                return None
        else:
            try:
                scn, vals = self.scenario(x)
                capability(self.o.study, CheckedScenario).check(scn, where=self.where)
                ev = self.o.evaluate(self.shape, {**vals, **self.fixed}, scn, stage=stage, extend=stage != "design")
            except (ValueError, ArithmeticError) as exc:
                self.refused.append(Refusal({**vals, **self.fixed}, _first_line(exc)))
                return None
        self.evals.append(ev)
        return self._settle(ev)

    def _complete(self, ev: Evaluation) -> Evaluation:
        """``ev`` extended to a validation's trials (then settled, :meth:`_settle`), in its place
        in :attr:`evals`."""
        new = self.o.complete(ev)
        if new is not ev:
            self.evals[next(i for i, e in enumerate(self.evals) if e is ev)] = new
        return self._settle(new)

    def _settle(self, ev: Evaluation) -> Evaluation:
        """Near the bound, trials added until the verdict decides ``ev`` (:meth:`Oracle.settle`),
        where it matters: ``ev`` on a validation's trials, undetermined, within the budget and
        cheaper than the cheapest protocol that holds; to at most :data:`SETTLE_MAX_VALIDATIONS`
        validations' trials and what the trial budget leaves after one more validation (the
        answer's completion). In its place in :attr:`evals`."""
        if ev.trials < self.o.n or ev.verdict != "undetermined" or not self._in_budget(ev):
            return ev
        hi = self._cheapest_meeting()
        if hi is not None and hi.cost_s <= ev.cost_s:
            return ev
        limit = min(ev.trials + max(0, self.trial_cap - self.spent() - self.o.n),
                    SETTLE_MAX_VALIDATIONS * self.o.n)
        new = self.o.settle(ev, limit)
        if new is not ev:
            self.evals[next(i for i, e in enumerate(self.evals) if e is ev)] = new
        return new

    # ---- the cost-flat knobs
    def flat_trials(self) -> int:
        """Trials :meth:`_best_flat` may spend on one candidate (screening trials each)."""
        return len(self.flat) * (FLAT_COARSE + FLAT_REFINE) * screening_trials(self.o.n)

    def _flat_key(self, x, fv: dict) -> tuple:
        return tuple(knob_value(k, xi) for k, xi in zip(self.knobs, x)), tuple(sorted(fv.items()))

    def _flat_eval(self, x, fv: dict) -> Evaluation | None:
        """Candidate ``x`` with the cost-flat knobs at ``fv``, on screening trials (memoised; the
        same seed as every candidate: common random numbers); None where refused."""
        key = self._flat_key(x, fv)
        if key not in self._flat_memo:
            try:
                scn, vals = self.scenario(x, fv)
                capability(self.o.study, CheckedScenario).check(scn, where=self.where)
                ev = self.o.evaluate(self.shape, {**vals, **self.fixed}, scn, stage="flat search", extend=False)
            except (ValueError, ArithmeticError) as exc:
                knobs = {**dict(zip([k.field for k in self.knobs], key[0])), **fv, **self.fixed}
                self.refused.append(Refusal(knobs, _first_line(exc), flat=True))
                ev = None
            self._flat_memo[key] = ev
        return self._flat_memo[key]

    def _flat_score(self, ev: Evaluation | None) -> float:
        return math.inf if ev is None else smooth_ratio(ev.figures, self.o.confidence)

    def _best_flat_value(self, x, k: Knob, fv: dict) -> tuple[Any, Evaluation | None]:
        """Flat knob ``k``'s best value for candidate ``x`` (the other flat knobs at ``fv``) and its
        evaluation: :data:`FLAT_COARSE` values over its range, then :data:`FLAT_REFINE` steps each
        halving the wider gap next to the best value, compared by :func:`smooth_ratio`."""
        score = self._flat_score
        tried: dict = {}

        def at(v):
            v = knob_value(k, v)
            if v not in tried:
                tried[v] = self._flat_eval(x, {**fv, k.field: v})
            return v

        for v in np.linspace(k.low, k.high, FLAT_COARSE):
            at(v)
        for _ in range(FLAT_REFINE):
            xs = sorted(tried)
            b = min(xs, key=lambda v: (score(tried[v]), v))
            i = xs.index(b)
            gaps = []
            if i > 0:
                gaps.append((b - xs[i - 1], -score(tried[xs[i - 1]]), 0.5 * (b + xs[i - 1])))
            if i + 1 < len(xs):
                gaps.append((xs[i + 1] - b, -score(tried[xs[i + 1]]), 0.5 * (b + xs[i + 1])))
            new = [g for g in sorted(gaps, reverse=True) if knob_value(k, g[2]) not in tried]
            if not new:
                break
            at(new[0][2])
        b = min(tried, key=lambda v: (score(tried[v]), v))
        return b, tried[b]

    def _best_flat(self, x, stage) -> Evaluation | None:
        """Candidate ``x`` with the cost-flat knobs set where its worst requirement ratio is least:
        per flat knob in turn (the others at their best so far, from the scenario's values),
        :meth:`_best_flat_value`, all on screening trials with common random numbers. The best is
        the candidate: relabelled ``stage``, and (beyond the design) extended to a validation's
        trials unless decided."""
        fv = {k.field: knob_value(k, dotted_value(self.base, k.field)) for k in self.flat}
        best = None
        for k in self.flat:
            fv[k.field], best = self._best_flat_value(x, k, fv)
        if best is None:
            return None
        # the chosen setting is the candidate (its flat-search record becomes the candidate's)
        best = self.o.relabel(best, stage)
        if stage != "design" and best.trials < self.o.n and not self.o.decided(best.figures):
            best = self.o.complete(best, quiet=True)
        self._flat_memo[self._flat_key(x, fv)] = best
        return best

    # ---- the search, step by step
    def search(self) -> ShapeOutcome:
        """The shape's outcome: design, refinement, the answer judged on a validation's trials
        (where none meets, the most accurate protocol instead)."""
        if not self.knobs:  # every knob pinned or cost-flat: one protocol, its flat knobs set
            return self._search_none()
        self._design()
        self._refine()
        best = self._answer()
        best_a = None if best is not None else self._best_achievable()
        return ShapeOutcome(self.shape, best, best_a, list(self.evals), self.spent(), list(self.refused),
                            self.model_curve(), self.boundary(), undetermined=self._undetermined(best))

    def _undetermined(self, best: Evaluation | None) -> Evaluation | None:
        """Where none holds: the cheapest protocol within the budget still undetermined on at least
        a validation's trials (the trial budget spent before its verdict settled)."""
        if best is not None:
            return None
        und = [e for e in self.evals if e.verdict == "undetermined" and e.trials >= self.o.n and self._in_budget(e)]
        return min(und, key=lambda e: e.cost_s) if und else None

    def _design(self) -> None:
        """Step 1: :data:`DESIGN_LEVELS` per knob over its range, every combination, on screening trials."""
        d = len(self.knobs)
        levels = [knob_levels(k, _by_count(DESIGN_LEVELS, DESIGN_LEVELS_MANY, d)) for k in self.knobs]
        for x in np.array(np.meshgrid(*levels, indexing="ij")).reshape(d, -1).T:
            if not self._room():
                break
            self.run(x, "design")

    def _cheapest_setting(self) -> float:
        """The lab time of the knobs' cheapest setting, a hair below (what the cost resolution
        and the averaging bounds measure lab time above)."""
        cands = [self._cost([k.low for k in self.knobs])] + [float(c) for c in self.costs if math.isfinite(c)]
        return min((c for c in cands if math.isfinite(c)), default=0.0) * (1 - RELATIVE_SLACK)

    def _cheapest_meeting(self) -> Evaluation | None:
        feas = [e for e in self.evals if e.met and self._in_budget(e)]
        return min(feas, key=lambda e: e.cost_s) if feas else None

    def _refine(self) -> None:
        """Steps 2 to 4: fit the model, take its frontier, run the next pick between the cheapest
        protocol measured meeting and the dearest measured failing below it, until their lab
        times above the cheapest setting are within :func:`resolution`, no frontier protocol
        lies between, or the trial budget is spent."""
        rho = resolution(self.o.n)
        c0 = self._cheapest_setting()
        tried: set = set()
        last_step_met = False
        for _ in range(MAX_REFINEMENT_STEPS):
            if not self._room():  # room for a last completion
                break
            front, ratio = self.frontier(self._fit())
            if len(front) == 0:
                break
            hi = self._cheapest_meeting()
            if hi is not None and hi.trials < self.o.n:
                self._complete(hi)  # the answer is judged on a validation's trials, like every candidate
                continue
            b = self._bracket(hi, c0)
            if hi is not None and b.hi_cost - c0 <= max(b.lo_cost - c0, 0.0) * (1 + rho):
                break
            choice = self._next_pick(front, ratio, b, c0, rho, tried, last_step_met)
            if choice is None:
                break
            pick, step = choice
            tried.add(pick)
            ev = self.run(self.points[pick], "search")
            last_step_met = bool(step and ev is not None and ev.met)

    def _bracket(self, hi: Evaluation | None, c0: float) -> _Bracket:
        """The bracket around the answer. Averaging (``q^2 = a + b / x``, ``a >= 0``) bounds it: a
        protocol failing by the ratio ``r`` needs at least ``r^2`` its lab time above the cheapest
        setting (:data:`MAX_NEED_FACTOR` at most); one meeting with ``r < 1`` at most ``r^2`` of
        its own would do (a safeguard against a model the design's few trials made optimistic or
        pessimistic)."""
        hi_cost = hi.cost_s if hi is not None else math.inf
        # what bounds the answer from below: a protocol measured failing on the search's path
        # (every protocol with one knob; with more, a design corner may be dear and poor)
        one = len(self.knobs) == 1
        lows = [e for e in self.evals if not e.met and (one or e.stage == "search") and e.cost_s < hi_cost]
        lo = max(lows, key=lambda e: e.cost_s) if lows else None
        lo_cost = lo.cost_s if lo is not None else 0.0
        lo_need = c0 + (lo_cost - c0) * min(lo.ratio ** 2, MAX_NEED_FACTOR) if lo is not None else 0.0
        hi_need = c0 + (hi_cost - c0) * hi.ratio ** 2 if hi is not None else math.inf
        return _Bracket(hi, lo, hi_cost, lo_cost, lo_need, hi_need)

    def _next_pick(self, front, ratio, b: _Bracket, c0: float, rho: float, tried: set, last_step_met: bool
                   ) -> tuple[int, bool | None] | None:
        """The next protocol (a fine-grid index) and whether it is a step just below the answer
        (None: the model's pick or the most accurate); None: nothing left between the bracket."""
        inside = [int(i) for i in front if b.lo_cost < self.costs[i] < b.hi_cost and int(i) not in tried]
        if not inside:
            if b.hi is None and int(front[-1]) not in tried:
                return int(front[-1]), None  # nothing meets yet: the most accurate protocol within the budget
            return None
        pick = self._model_pick(inside, ratio, b, c0, rho)
        if pick is not None:
            return pick, None
        if b.hi is None:
            return inside[-1], None
        return self._bisection_pick(inside, b, c0, rho, last_step_met), not last_step_met

    def _model_pick(self, inside: list[int], ratio, b: _Bracket, c0: float, rho: float) -> int | None:
        """The cheapest protocol inside the bracket the model predicts meeting, kept within the
        averaging bounds; None where there is none or it sits on the answer (:data:`ON_ANSWER_SHARE`)."""
        pred = [i for i in inside if ratio[i] <= 1.0]
        pick = pred[0] if pred else None
        if b.lo_need < b.hi_need:
            if pick is not None and self.costs[pick] < b.lo_need:
                pick = next((i for i in inside if self.costs[i] >= b.lo_need), pick)
            if pick is not None and self.costs[pick] > b.hi_need:
                pick = next((i for i in reversed(inside) if self.costs[i] <= b.hi_need), pick)
        if pick is not None and b.hi is not None and \
                self.costs[pick] - c0 >= (b.hi_cost - c0) / (1 + rho * ON_ANSWER_SHARE):
            return None  # the model sits on the cheapest feasible: test just below, or bisect
        return pick

    def _bisection_pick(self, inside: list[int], b: _Bracket, c0: float, rho: float, last_step_met: bool) -> int:
        """A step just below the answer (by the cost resolution), or after a step that met, the
        geometric mean of the bracket's lab times above the cheapest setting (bisection along
        cost); where averaging says less would do, its bound."""
        lo_ref = max(b.lo_cost, float(self.costs[inside[0]])) - c0
        target = c0 + ((b.hi_cost - c0) / (1 + rho) if not last_step_met
                       else math.sqrt(lo_ref * (b.hi_cost - c0)))
        if b.lo_need < b.hi_need < target:
            target = b.hi_need  # averaging says that much less would do
        below = [i for i in inside if self.costs[i] <= target]
        return below[-1] if below else inside[0]

    def _answer(self) -> Evaluation | None:
        """Step 5's part: the cheapest protocol meeting, judged on a validation's trials (where
        completing it fails it, the next cheapest)."""
        while True:
            best = self._cheapest_meeting()
            if best is None or best.trials >= self.o.n:
                return best
            self._complete(best)

    def _best_achievable(self) -> Evaluation | None:
        """Where no protocol meets: the frontier's most accurate protocol run, then the most
        accurate of every protocol run within the budget, on a validation's trials; then the
        cheapest protocol run within one standard error of it (:meth:`_within_one_se`)."""
        front, _ = self.frontier(self._fit())
        if len(front):
            self.run(self.points[front[-1]], "best achievable")
        best_a = self._most_accurate([e for e in self.evals if self._in_budget(e)])
        if best_a is None:
            return None
        return self._within_one_se(self._complete(best_a))  # its figure on a validation's trials

    def _within_one_se(self, most: Evaluation) -> Evaluation:
        """The cheapest protocol run whose quantile of every requirement, on a validation's
        trials, lies within one standard error (``most``'s) of ``most``'s: the one-standard-error
        rule (Hastie, Tibshirani & Friedman, *The Elements of Statistical Learning*, 2nd ed.,
        sec. 7.10): protocols whose accuracy the trials cannot tell apart from the most
        accurate's, the cheapest of them, not the noisy minimum. Candidates, cheapest first, are
        completed to a validation's trials while the budget holds one more completion
        (:data:`ROOM_VALIDATIONS`)."""
        def within(e: Evaluation) -> bool:
            return all(e.figures[r]["quantile"] <= f["quantile"] + f["se_quantile"] for r, f in most.figures.items())

        cheaper = sorted((e for e in self.evals if e.cost_s < most.cost_s and self._in_budget(e)),
                         key=lambda e: e.cost_s)
        def plausible(e: Evaluation) -> bool:  # a screening run not clearly outside (its own se)
            return all(e.figures[r]["quantile"] - e.figures[r]["se_quantile"] <= f["quantile"] + f["se_quantile"]
                       for r, f in most.figures.items())

        for e in cheaper:
            if not (within(e) if e.trials >= self.o.n else plausible(e)):
                continue
            if e.trials < self.o.n:
                if self.spent() + ROOM_VALIDATIONS * self.o.n > self.trial_cap:
                    continue
                e = self._complete(e)
            if within(e):
                return e
        return most

    def _search_none(self) -> ShapeOutcome:
        ev = self.run(np.zeros(0), "search")
        if ev is not None:
            ev = self._complete(ev)
        best = ev if ev is not None and ev.met and self._in_budget(ev) else None
        return ShapeOutcome(self.shape, best, None if best is not None else ev, list(self.evals), self.spent(),
                            list(self.refused), None, None)

    # ---- what the search reports
    def boundary(self) -> Boundary | None:
        """The fitted model's cheapest protocol (frontier) whose predicted quantiles sit at the
        bounds (no ``sure`` margin): what a search judging by the measured quantile alone aims
        at; and the model's at the search's margin (None where the model predicts none)."""
        coefs = self._fit()
        front, _ = self.frontier(coefs)
        out = {}
        for name, m in (("boundary", 1.0), ("sure", self.o.margin)):
            r = self.predicted_ratio(coefs, self.points[front], margin=m) if len(front) else np.array([])
            ok = np.flatnonzero(r <= 1.0)
            if not len(ok):
                return None
            i = int(front[ok[0]])
            out[name] = (float(self.costs[i]), {k.field: knob_value(k, x) for k, x in zip(self.knobs, self.points[i])})
        return Boundary(out["boundary"][0], out["boundary"][1], out["sure"][0])

    def model_curve(self) -> ModelCurve:
        """The fitted model's frontier: lab time and predicted quantile per requirement, and the
        fitted coefficients (``a``: the squared floor; ``b``: per knob)."""
        coefs = self._fit()
        front, _ = self.frontier(coefs)
        pts = self.points[front]
        feats = self._features(pts)
        reqs = self.o.reqs
        return ModelCurve(
            cost_s=[float(c) for c in self.costs[front]],
            knobs=[{k.field: knob_value(k, x) for k, x in zip(self.knobs, p)} for p in pts],
            quantile={r.name: [r.value * float(v) for v in np.sqrt(np.maximum(feats @ coefs[r.name], 0.0))]
                      for r in reqs},
            floor={r.name: r.value * float(math.sqrt(max(coefs[r.name][0], 0.0))) for r in reqs},
            # in the class's unit squared (the fit's, in units of the bound, times VALUE^2: inf past
            # the largest float, written null)
            b={r.name: {k.field: float(b) * r.value * r.value for k, b in zip(self.knobs, coefs[r.name][1:])}
               for r in reqs})

    def _most_accurate(self, cands: list[Evaluation]) -> Evaluation | None:
        """The most accurate protocol run (no protocol meets): by the fitted model's worst
        predicted quantile over its bound (no ``sure`` margin), which pools every protocol's
        trials, ties by the measured quantile. Not by the measured prediction bounds: those
        widen with fewer trials, so a protocol screened on a few trials would lose to a less
        accurate one run on more (docs/planning.md, "Infeasible plans")."""
        if not cands:
            return None
        if not self.knobs:
            return min(cands, key=lambda e: max(f["quantile"] / f["bound"] for f in e.figures.values()))
        pts = np.array([[float(e.knobs[k.field]) for k in self.knobs] for e in cands])
        pred = self.predicted_ratio(self._fit(), pts, margin=1.0)
        point = [max(f["quantile"] / f["bound"] for f in e.figures.values()) for e in cands]
        return cands[min(range(len(cands)), key=lambda i: (round(float(pred[i]), TIE_DECIMALS), point[i]))]


def _first_line(exc: BaseException) -> str:
    """What a refused protocol's exception says: its first line, else its type."""
    return str(exc).splitlines()[0] if str(exc) else type(exc).__name__


# ---------------------------------------------------------------------- every search of one plan
@dataclass
class PlanRun:
    """What every search of one plan shares: the study, scenario, requirements and settings
    (checked by :func:`budget.runner.plan.planner.plan_protocol`), the one pool of workers, the
    clocks and the cost-flat knobs found (:attr:`flat`)."""

    study: Study
    scenario: Any
    reqs: list[Requirement]
    variant: str
    confidence: float
    budget_hours: float | None
    budget_s: float | None
    seed: int
    n: int
    workers: int | None
    progress: bool
    pool: Any
    knobs: tuple[Knob, ...]
    sure: float
    fixed: dict
    t0: float
    c0: float
    #: the cost-flat knobs of every shape searched (field -> knob), filled by :meth:`search_shapes`
    flat: dict = field(default_factory=dict)

    def oracle(self, reqs: list[Requirement] | None = None, **kw) -> Oracle:
        """An oracle of ``reqs`` (default every requirement) on the plan's seed, trials and pool."""
        o = Oracle(self.study, self.reqs if reqs is None else reqs, self.variant, self.confidence, self.seed, self.n,
                   self.workers, self.progress, executor=self.pool, sure=self.sure, **kw)
        o.prewarmed = True
        return o

    def search_shapes(self, oracle: Oracle, shapes: dict[str, dict], knobs: tuple[Knob, ...],
                      budget_s: float | None, key=None) -> dict[str, ShapeOutcome]:
        """Each shape searched: its scenario (the shape's overrides and the ``--fix`` values), its
        cost-flat knobs (:func:`cost_flat_knobs`) set per candidate, the others searched by
        :class:`ShapeSearch`; ``key``: the shape's name in the plan (default its own)."""
        cap = (BUDGET_VALIDATIONS - 1) * self.n
        out = {}
        for name, overrides in shapes.items():
            k = name if key is None else key(name)
            base = scenario_with(self.study, self.scenario, {**overrides, **self.fixed},
                                 where=f"protocol shape {name}") if (overrides or self.fixed) else self.scenario
            flat = cost_flat_knobs(self.study, base, knobs)
            self.flat.update({f.field: f for f in flat})
            cost_knobs = tuple(f for f in knobs if f not in flat)
            s = ShapeSearch(oracle, k, base, cost_knobs, budget_s, cap, flat=flat, fixed=self.fixed).search()
            out[k] = dataclasses.replace(s, flat=[f.field for f in flat], overrides=dict(overrides))
        return out

    def fresh(self, shape: str, knobs: dict, scn: Any, stage: str = "validation") -> tuple[Evaluation, int]:
        """``scn`` run as one protocol on the re-validation's fresh seeds (:func:`validation_seed`),
        a validation's trials, restricted to the required classes where the study can; judged
        by the measured quantile (the real test's rule). Returns it and the truths it computed."""
        o = self.oracle(restrict=tuple(dict.fromkeys(r.cls for r in self.reqs)))
        ev = o.evaluate(shape, knobs, scn, stage=stage, seed=validation_seed(self.seed), full=True)
        return ev, o.truth_runs

    def result(self, **kw) -> PlanResult:
        """The :class:`PlanResult` with the plan's settings, clocks and cost-flat knobs."""
        return PlanResult(study=self.study, scenario=self.scenario, requirements=self.reqs, variant=self.variant,
                          confidence=self.confidence, seed=self.seed, trials_per_validation=self.n,
                          budget_hours=self.budget_hours, knobs=self.knobs, elapsed_s=time.perf_counter() - self.t0,
                          cpu_s=time.process_time() - self.c0, sure_level=self.sure, fixed=self.fixed,
                          flat=tuple(k for k in self.knobs if k.field in self.flat), **kw)
