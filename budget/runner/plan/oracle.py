"""The oracle a search asks: runs a candidate protocol on the study's own Monte Carlo
(:func:`budget.runner.run.run_study`) with common random numbers and shared truths, screening
trials first and more only where they do not decide it, and judges each requirement
(docs/planning.md, "The search")."""

from __future__ import annotations

import dataclasses
import math
import sys
from typing import Any

import numpy as np

from budget.runner.capabilities import BatchedTrials, SeparablePlans, capability
from budget.runner.numbers import fmt
from budget.runner.plan.quantiles import figures_of, sure_margin, sure_met
from budget.runner.plan.requirements import Requirement
from budget.runner.plan.result import FRESH_STAGES, Evaluation
from budget.runner.plan.text import knobs_text, lab_time_text
from budget.runner.plan.trials import DECIDED, SETTLE_MAX_GROWTH, SETTLE_SLACK, screening_trials
from budget.runner.run import run_study
from budget.runner.scheduler import TRUTH_SE_FRACTION, sized_truths_scenario, with_targets
from budget.runner.study import Study, truth_identity

__all__ = ["Oracle"]


class _Shifted:
    """``study`` with trial ``k`` replaced by trial ``k + offset`` (the same seed): the runner
    runs the trials that extend an earlier run of a candidate, nothing twice."""

    def __init__(self, study: Study, offset: int):
        self.__dict__.update(_study=study, _offset=offset)

    def __getattr__(self, name):
        d = self.__dict__
        if "_study" not in d:
            raise AttributeError(name)
        return getattr(d["_study"], name)

    def __getstate__(self):
        return dict(self.__dict__)

    def __setstate__(self, state):
        self.__dict__.update(state)

    def trial(self, scenario, seed, k):
        return self._study.trial(scenario, seed, k + self._offset)

    def trial_batch(self, scenario, seed, ks):
        return capability(self._study, BatchedTrials).trial_batch(scenario, seed, [k + self._offset for k in ks])


class Oracle:
    """Runs candidates with common random numbers and shared truths, counting trials; keeps
    every evaluation it ran (:attr:`evaluations`, in order, each replaced by its extension)."""

    def __init__(self, study: Study, requirements: list[Requirement], variant: str, confidence: float, seed: int,
                 trials: int, workers: int | None, progress: bool, executor=None, sure: float | None = None,
                 restrict=None, group: str | None = None):
        self.study, self.reqs, self.variant = study, requirements, variant
        #: the classes the trials must compute (a sub-plan's; None: the whole scenario), and the sub-plan
        self.restrict, self.group = (None if restrict is None else frozenset(restrict)), group
        #: whether the study restricted a candidate's scenario (:meth:`~budget.runner.capabilities.SeparablePlans.restrict_classes`)
        self.restricted = False
        #: the one executor every candidate's run uses (started by :func:`plan_protocol`)
        self.executor = executor
        #: the search's level: a candidate meets when its quantile's P prediction bound is within (None: the point)
        self.sure = sure
        self.confidence, self.seed, self.n, self.workers = confidence, seed, trials, workers
        self.progress = progress
        self.truths: dict = {}
        self.truth_runs = 0
        self.trials_run = 0
        self.evaluations: list[Evaluation] = []
        self.prewarmed = False
        from scipy import stats  # heavy (budget.runner.plan.quantiles)

        self.z = float(stats.norm.ppf(0.5 + confidence / 2.0))
        self.margin = sure_margin(sure, trials, confidence)

    # ---- the truths, once per truth identity and seed
    def truths_for(self, scn, seed):
        key = (truth_identity(self.study, scn), seed)
        if key not in self.truths:
            targets = {(r.cls, r.axis): TRUTH_SE_FRACTION * (r.value / self.z) / math.sqrt(self.n) for r in self.reqs}
            spec = {c.name: c for c in self.study.classes(scn)}
            targets = {k: v for k, v in targets.items() if not spec[k[0]].per_trial_truth}
            tscn = sized_truths_scenario(self.study, scn, seed, targets)
            t = self.study.truths(tscn, seed)
            self.truths[key] = with_targets(t, targets) if targets else t
            self.truth_runs += 1
        return self.truths[key]

    # ---- running trials
    def _errors(self, res) -> tuple[dict, dict]:
        errs, tse = {}, {}
        for r in self.reqs:
            key = (r.cls, self.variant, r.axis)
            x = res.samples[key]
            if key in res.trial_truths:
                errs[r.name], tse[r.name] = x - res.trial_truths[key], 0.0
            else:
                t = res.truths[(r.cls, r.axis)]
                errs[r.name], tse[r.name] = x - t.value, float(t.se)
        return errs, tse

    def _run(self, scn, seed, k0, k1, truths):
        study = self.study if k0 == 0 else _Shifted(self.study, k0)
        res = run_study(study, scn, trials=k1 - k0, seed=seed, workers=self.workers, truths=truths,
                        prewarm=not self.prewarmed, executor=self.executor)
        self.prewarmed = True
        self.trials_run += k1 - k0
        return self._errors(res)

    def _figures(self, errs, tse, point=False):
        """Per requirement; the search's judged by the ``sure`` prediction bound, the
        re-validation's (``point``) by the quantile itself."""
        sure = None if point or self.sure is None or self.sure <= 0.5 else self.sure
        return {r.name: figures_of(errs[r.name], r.value, self.confidence, tse[r.name], sure=sure, n_future=self.n)
                for r in self.reqs}

    def run_scenario(self, scn):
        """The scenario a candidate's trials run on: ``scn`` restricted to the sub-plan's classes
        where the study can (:meth:`~budget.runner.capabilities.SeparablePlans.restrict_classes`), else ``scn``."""
        if self.restrict is None:
            return scn
        r = capability(self.study, SeparablePlans).restrict_classes(scn, self.restrict)
        if r is None:
            return scn
        self.restricted = True
        return r

    # ---- candidates
    def evaluate(self, shape: str, knobs: dict, scn: Any, *, stage: str, seed: int | None = None, full: bool = False,
                 extend: bool = True) -> Evaluation:
        """Run ``scn``: screening trials, then (``extend``) up to ``n`` unless they decide it;
        ``full``: ``n`` at once."""
        seed = self.seed if seed is None else seed
        run_scn = self.run_scenario(scn)
        truths = self.truths_for(run_scn, seed)
        n0 = self.n if full else screening_trials(self.n)
        errs, tse = self._run(run_scn, seed, 0, n0, truths)
        # the lab time of the whole protocol, never of a restricted scenario
        items = {k: float(v) for k, v in self.study.lab_time_s(scn).items()}
        ev = Evaluation(shape, dict(knobs), float(sum(items.values())), items, seed, n0,
                        self._figures(errs, tse, point=stage in FRESH_STAGES), stage, scn, errs, tse,
                        run_scenario=None if run_scn is scn else run_scn, group=self.group)
        if extend and n0 < self.n and not self.decided(ev.figures):
            ev = self._extended(ev)
        self.evaluations.append(ev)
        self._echo(ev)
        return ev

    def _extended(self, ev: Evaluation, to: int | None = None) -> Evaluation:
        """``ev`` with trials ``ev.trials .. to - 1`` added (default ``n``; the same seed)."""
        to = self.n if to is None else to
        scn = ev.scenario if ev.run_scenario is None else ev.run_scenario
        more, _ = self._run(scn, ev.seed, ev.trials, to, self.truths_for(scn, ev.seed))
        errors = {k: np.concatenate([ev.errors[k], more[k]]) for k in ev.errors}
        return dataclasses.replace(ev, errors=errors, trials=to,
                                   figures=self._figures(errors, ev.truth_se, point=ev.stage in FRESH_STAGES))

    def settle(self, ev: Evaluation, limit: int) -> Evaluation:
        """``ev`` (on at least a validation's trials) extended while it is undetermined
        (:attr:`Evaluation.verdict`), to the trials its verdict says would settle it
        (:data:`SETTLE_SLACK` more, at most :data:`SETTLE_MAX_GROWTH` times its trials a step:
        the standard error is re-measured on the way), never beyond ``limit`` trials; in its
        place in :attr:`evaluations`. Where it is still undetermined at ``limit`` (the budget
        is spent) or sits on its bound (no number settles it), it stays undetermined."""
        cur = ev
        while cur.trials >= self.n and cur.verdict == "undetermined" and cur.trials < limit:
            need = cur.n_to_settle
            if need is None:
                break
            to = min(limit, math.ceil(SETTLE_SLACK * need), SETTLE_MAX_GROWTH * cur.trials)
            to = max(to, cur.trials + 1)
            new = self._extended(cur, to)
            self.replace(cur, new)
            self._echo(new, "settling")
            cur = new
        return cur

    def complete(self, ev: Evaluation, *, quiet: bool = False) -> Evaluation:
        """``ev`` extended to ``n`` trials (trials ``ev.trials .. n - 1``, the same seed), in its
        place in :attr:`evaluations`."""
        if ev.trials >= self.n:
            return ev
        new = self._extended(ev)
        self.replace(ev, new)
        if not quiet:
            self._echo(new, "extended")
        return new

    def relabel(self, ev: Evaluation, stage: str) -> Evaluation:
        """``ev`` as a candidate of ``stage`` (a cost-flat search's best setting), in its place."""
        new = dataclasses.replace(ev, stage=stage)
        self.replace(ev, new)
        return new

    def replace(self, old: Evaluation, new: Evaluation) -> None:
        """Put ``new`` in the place of ``old`` in :attr:`evaluations`."""
        i = next(i for i, e in enumerate(self.evaluations) if e is old)
        self.evaluations[i] = new

    def decided(self, figs: dict[str, dict]) -> bool:
        """Whether screening figures ``figs`` already decide a candidate (:data:`DECIDED`; the
        verdict on its quantile settles it later, :meth:`settle`)."""
        s = [sure_met(f["exceed"], f["n"], self.confidence) for f in figs.values()]
        # meeting is decided only where the search's rule (the verdict on the quantile) already holds
        return (min(s) > 1 - DECIDED and all(f["met"] for f in figs.values())) or min(s) < DECIDED

    def _echo(self, ev, what=None):
        if self.progress:
            print(f"  {ev.shape} {what or ev.stage}: {knobs_text(ev.knobs)}: {lab_time_text(ev.cost_s)}, "
                  f"{ev.trials} trials, worst quantile/bound {fmt(ev.ratio, 3)} ({_word(ev)})",
                  file=sys.stderr, flush=True)


def _word(ev: Evaluation) -> str:
    """What a progress line says of ``ev``: meets, fails or undetermined."""
    v = ev.verdict
    return "meets" if v == "holds" else v
