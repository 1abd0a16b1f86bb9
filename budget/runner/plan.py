"""Plan a test before booking the lab: the cheapest protocol that meets the required accuracy.

``budget <study> plan [SCENARIO] --require CLASS.AXIS<=VALUE ... [--variant V]
[--confidence C] [--fix FIELD=VALUE ...] [--budget-hours H] --json OUT --report DIR`` (Python: :func:`budget.plan`)
searches the protocol knobs a study declares (:meth:`Study.protocol_knobs`: frames, poses,
faces, passes, ...) for the protocol of least lab time (:meth:`Study.lab_time_s`, summed)
whose estimates meet every requirement, for each named protocol shape the study offers
(:meth:`Study.protocol_shapes`), and re-validates the answer on fresh trials.

Requirements
------------
``CLASS.AXIS<=VALUE`` (VALUE in the class's unit) bounds the error ``e = estimate - truth``
of the chosen variant (``--variant``; default the study's last variant that estimates,
:func:`default_variant`), spread and bias together: it is met when the ``C``-quantile of
``|e|`` over trials is at most VALUE (``--confidence C``, default 0.95): 95 % of the tests
run with this protocol land within VALUE. The C-quantile of ``n`` trials is the order
statistic ``|e|_(ceil(C n))``, so a protocol *measures* feasible when at most
``n - ceil(C n)`` of its trials exceed VALUE.

How sure (``--sure P``, default :data:`DEFAULT_SURE`): the search counts a protocol as
meeting a requirement only when the one-sided ``P`` upper prediction bound of the quantile
the re-validation will measure is within VALUE (:func:`prediction_bound`: ``q + z_P
sqrt(se_q^2 (1 + n_s / n) + 2 se_truth^2)``, Maritz-Jarrett ``se_q``), so the recommendation
passes the re-validation (fresh trials, the measured quantile) with probability about ``P``;
``P = 0.5`` gives the boundary protocol. :attr:`PlanResult.premium` states what the margin
costs over the boundary protocol. Only a class of role ``result`` (an estimate
of a truth) or ``residual`` (what a compensation leaves) can be required; an ``input``
(taken as given), a ``stated`` uncertainty, a reference variant, an axis the data cannot
determine, an unknown class, axis or variant (a class of the study that the scenario does not
compute: why, naming the field, :meth:`Study.uncomputed_class`), a value that is not a positive
number and a second requirement on the same class and axis are each one ``error:`` line
(:func:`parse_requirements`). The margin is per requirement: with ``k`` requirements each aimed
``P`` sure, all pass together with probability at least ``1 - k (1 - P)`` (Bonferroni).

The oracle and common random numbers
------------------------------------
Each candidate protocol is the scenario with its knobs set by the sweeps' dotted keys
(:func:`budget.sweeps.dotted.set_dotted`, validated by :meth:`Study.from_dict`) and run by
the one runner (:func:`budget.runner.run.run_study`) with the *same* seed for every
candidate: trial ``k`` of every candidate draws from ``SeedSequence(seed, spawn_key=(k,))``
(common random numbers), so two candidates differ by their protocol, not by their noise,
and a requirement's measured quantile moves smoothly with the knobs. The truths are
computed once per distinct :func:`budget.runner.study.truth_identity` (and seed) and given
to every candidate that shares it; they are sized (:meth:`Study.truth_size_for`) so that a
sampled truth's standard error is :data:`budget.runner.run.TRUTH_SE_FRACTION` of the bias
standard error ``(VALUE / z_C) / sqrt(n)`` a protocol at the requirement would give.

Adaptive stopping: a candidate first runs :func:`screening_trials` trials (a quarter of
a validation's, at least 20); where the exceedance count already decides the candidate
(Jeffreys posterior probability that the exceedance rate is within ``1 - C`` below
:data:`DECIDED` or above ``1 - DECIDED``), it stops there; otherwise trials
``n_screen .. n - 1`` (the same seeds as a longer run would draw) are added until it has a
validation's ``n``.

The search
----------
For each shape (the scenario's own when the study names none):

1. design: 3 levels per knob (its low, high and their geometric mean; 5 for a single
   knob, 2 for more than two knobs), screening trials each;
2. model: per requirement, the physics of averaging, ``q^2 = a + sum_i b_i / x_i``
   (independent noise averaged over each count, ``a`` a floor no count removes), fitted
   to the measured C-quantiles ``q`` by non-negative least squares in relative terms,
   weighted by each protocol's trials (:func:`scipy.optimize.nnls`);
3. frontier: the protocols of a fine grid over the knobs (log-spaced, whole numbers for
   ``int`` knobs) whose predicted worst ratio ``max_r q_r / VALUE_r`` no cheaper protocol
   beats, their lab time interpolated multilinearly in the knob values (exact for lab times
   that are sums of products of knobs) from :meth:`Study.lab_time_s` on a coarse grid and
   computed exactly for every frontier protocol; ``--budget-hours`` removes the protocols
   above it;
4. refinement: the cheapest frontier protocol the model predicts feasible is run; then,
   between the cheapest protocol measured feasible (on a validation's ``n`` trials) and the
   dearest frontier protocol measured infeasible below it, the model's new prediction
   (refitted to every protocol run) where it falls strictly inside, else a step just below
   the feasible one, else the frontier protocol at the geometric mean of their lab times
   above the cheapest setting (bisection along cost). Averaging bounds every pick: a
   protocol failing by the ratio ``r = q / VALUE`` needs at least ``r^2`` its lab time above
   the cheapest setting, one meeting with ``r < 1`` at most ``r^2`` of its own. It stops
   when the two lab times above the cheapest setting are within :func:`resolution`
   (``1 / (2 sqrt(n))``: finer than the quantile's relative standard error can tell apart),
   no frontier protocol lies between, or the trial budget (:data:`BUDGET_VALIDATIONS`
   validations per shape, the re-validation included) is spent. A protocol the study
   refuses (its scenario model, :meth:`Study.check` or its trials raise a ``ValueError`` or
   an arithmetic error) is skipped and listed;
5. shapes: the cheapest shape's best protocol is the recommendation; the report lists
   every shape's best and its cost.

Cost-flat and fixed knobs
-------------------------
A knob whose lab time does not change with it (a magnitude limit: more stars, no more time;
accuracy not necessarily monotone in it) is *cost-flat* (:func:`cost_flat_knobs`: the summed
:meth:`Study.lab_time_s` unchanged across its low, middle and high value, with the other
knobs at the scenario's values, all low and all high). It is not in the averaging model: the
design, the model, the frontier and the refinement run over the cost-bearing knobs, and each
candidate of those has its cost-flat knobs set where its worst requirement ratio is least
(:meth:`_ShapeSearch._best_flat`: per flat knob a coarse grid of :data:`FLAT_COARSE` values
over its range, then :data:`FLAT_REFINE` steps halving the wider gap next to the best value,
whole numbers for ``int`` knobs; screening trials, common random numbers, memoised; compared
by :func:`_smooth_ratio`, the quantile of the errors' normal fit). The search keeps room for a
candidate's flat search within the trial budget. ``--fix FIELD=VALUE`` (Python
``fix={field: value}``, :func:`parse_fixes`) pins a knob: the shapes' scenarios carry it and
the search leaves it out; where every knob is fixed or cost-flat the one protocol is run
with its flat knobs set, and judged.

Honest verdict
--------------
The recommendation is re-validated on ``n`` fresh trials with fresh truths: seed
:func:`validation_seed` (the 32-bit state of ``SeedSequence(seed, spawn_key=(2**31 + 1,))``,
a spawn key no trial (0, 1, ...) nor truth (``2**31``) of the search uses), so no trial of
the verdict was seen by the search. Per requirement, the verdict's C-quantile with its
standard error (Maritz-Jarrett: the order statistics weighted by the quantile's beta distribution), bias
and spread with theirs, and how sure the requirement is met: the posterior probability
(Jeffreys prior) that the exceedance rate is at most ``1 - C`` given the re-validation's
exceedance count, averaged over the truth's own uncertainty (Gauss-Hermite over a truth
shifted by its standard error). Over several requirements, the Bonferroni bound
``1 - sum (1 - sure_r)``. Where no protocol (within the budget) meets every requirement,
the answer says so and gives the best achievable figure (the frontier's most accurate
protocol within the budget, run): the protocol run whose worst requirement the fitted model
predicts lowest (:meth:`_ShapeSearch._most_accurate`; not by prediction bounds, which widen
with fewer trials), completed to a validation's trials.

Separable plans
---------------
Most of a lab test is separable: each protocol's knobs change only its own classes, and lab
time is additive. A study says so with :meth:`Study.field_classes` (for each knob and shape
field, the classes it can change; a field not listed can change every class) and may offer
:meth:`Study.restrict_classes` (a scenario computing only some classes). Where it declares
field classes, :func:`decompose` links each required class to every free knob and shape field
that can change it; the connected components over the required classes are independent
groups (a requirement on a class every field changes, a total, makes one group: the
whole-test plan). A knob no required class depends on is not searched: it stays at the
scenario's value (or its ``--fix``) and the plan lists it (:attr:`PlanResult.unsearched`). A
group's shapes are the declared shapes projected on its shape fields, those with equal
projections collapsed into one search, labelled by what its members share
(:func:`_collapsed_labels`: their common comma-separated name parts, else the shape fields'
values; ``(any)`` where no shape field touches the group). Each group is searched as above with its own oracle:
its requirements only, its candidates' trials on ``restrict_classes(candidate, group's
classes)`` where the study can (common random numbers within the group: the same seed), its
own budget of :data:`BUDGET_VALIDATIONS` per shape; a candidate's cost is always the lab time
of the unrestricted scenario with every knob's current value (the other groups' at the
scenario's). Lab time being additive and each group's fields changing only its own items, the
groups' cheapest protocols together are the cheapest protocol meeting every requirement. The
recommendation is their union (:func:`_union`: every group's knobs, in a declared shape that
agrees with every group's chosen shape fields; where several do (they differ only in fields no
requirement depends on), the one keeping the scenario's own values of those fields
(:meth:`Study.shape_value`), as an unsearched knob keeps its value, then the cheapest; a
declared shape the scenario model refuses is skipped), run once as one protocol on fresh seeds
(restricted to the union of the required classes where the study can; the re-validation) and
costed by its full lab time. The groups' search figures are not the union's: a coupling the
field classes leave out (the star camera's realistic world, whose drift and hexapod follow the
lab run's timeline, moves a later protocol's draws with an earlier protocol's counts) shows only
in that run of the whole protocol. ``--budget-hours`` bounds the whole plan: with one group it
bounds the search as above; with several, each group is searched without it and the union's lab
time is checked against it (over it, no protocol within the budget meets every requirement:
:attr:`PlanResult.over_budget`). A group no protocol meets makes the plan infeasible. In either
case the plan's best achievable (:attr:`PlanResult.best_achievable`) is the union of every
group's part (its answer, or where none meets its most accurate protocol), run as one protocol
on the re-validation's fresh seeds (stage :data:`REVALIDATED_BEST`, judged by the measured
quantile; :attr:`PlanResult.best_achievable_revalidated`). The premium is the recommendation's
lab time over the same union with each group's part at its model boundary, a group with no
knob to search (all fixed or cost-flat) counting its one protocol as its boundary. Without
:meth:`Study.field_classes` (the default) the plan is the whole-test plan, unchanged.

The result, :class:`PlanResult`, writes JSON (schema ``budget.plan/1``), ``report.md`` and
``report.html`` with the trade curve and the recommended scenario (``recommended.toml``,
ready for ``budget <study> validate``) (:mod:`budget.runner.plan_report`).
"""

from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass, field
from typing import Any

import click
import numpy as np

from budget.runner.study import Knob, Study, truth_identity
from simcam.infra.errors import UserInputError
from simcam.infra.cli import overwrite_option

__all__ = ["BUDGET_VALIDATIONS", "DECIDED", "DEFAULT_CONFIDENCE", "DEFAULT_SURE", "FRESH_STAGES", "REVALIDATED_BEST",
           "SCHEMA", "VALIDATION_SPAWN_KEY", "Evaluation", "PlanGroup", "PlanResult", "Requirement",
           "cost_flat_knobs", "decompose", "default_variant", "parse_fixes", "parse_requirements",
           "plan_command_for", "plan_protocol", "quantile_rel_se", "resolution", "screening_trials", "sure_margin",
           "sure_met", "validation_seed"]

SCHEMA = "budget.plan/1"
DEFAULT_CONFIDENCE = 0.95
#: how sure the search wants a protocol to pass the real test (the re-validation): the default ``--sure``
DEFAULT_SURE = 0.9
#: the re-validation's spawn key: distinct from every trial's (0, 1, ...) and the truths' (2**31)
VALIDATION_SPAWN_KEY = 2**31 + 1
#: a candidate is decided by its screening trials when the posterior probability of meeting is below
#: this or above 1 - this
DECIDED = 0.001
#: the search with the re-validation costs at most this many validations' trials (per shape)
BUDGET_VALIDATIONS = 20
#: a cost-flat knob's coarse grid (values over its range, ends included) and refinement steps
FLAT_COARSE = 3
FLAT_REFINE = 2
#: the stage of a separable plan's best achievable (its groups' parts together) run as one protocol on
#: the re-validation's fresh seeds; it and the re-validation are judged by the measured quantile
REVALIDATED_BEST = "best achievable, re-validated"
FRESH_STAGES = ("validation", REVALIDATED_BEST)
_REQ = re.compile(r"^\s*([A-Za-z_][\w-]*)\.([A-Za-z_][\w-]*)\s*<=\s*(\S+)\s*$")


# ---------------------------------------------------------------------- requirements
@dataclass(frozen=True)
class Requirement:
    """``CLASS.AXIS<=VALUE``: the C-quantile of ``|estimate - truth|`` at most ``value`` (``unit``)."""

    cls: str
    axis: str
    value: float
    unit: str = ""
    label: str = ""

    @property
    def name(self) -> str:
        return f"{self.cls}.{self.axis}"

    @property
    def text(self) -> str:
        return f"{self.name}<={self.value:g}"


def default_variant(study: Study) -> str:
    """The variant a plan judges by default: the study's last variant that estimates (the
    variants are in report order, the improved method last)."""
    own = [v for v in study.variants if v not in study.reference_variants]
    return own[-1] if own else study.variants[-1]


def parse_requirements(study: Study, scenario: Any, texts, variant: str | None = None
                       ) -> tuple[list[Requirement], str]:
    """The requirements and the variant, checked (module docstring); a bad one is a
    :class:`UserInputError` naming it."""
    if variant is None:
        variant = default_variant(study)
    if variant not in study.variants:
        raise UserInputError(f"--variant {variant}: unknown; the {study.name} variants are "
                             f"{', '.join(study.variants)}")
    if variant in study.reference_variants:
        raise UserInputError(f"--variant {variant}: a reference (it estimates nothing); choose one of "
                             f"{', '.join(v for v in study.variants if v not in study.reference_variants)}")
    texts = list(texts or [])
    if not texts:
        raise UserInputError("--require: give at least one requirement CLASS.AXIS<=VALUE (e.g. "
                             f"{_example(study, scenario)})")
    specs = {c.name: c for c in study.classes(scenario)}
    out: list[Requirement] = []
    for t in texts:
        m = _REQ.match(str(t))
        if not m:
            raise UserInputError(f"--require {t!r}: expected CLASS.AXIS<=VALUE (e.g. {_example(study, scenario)})")
        cls, ax, raw = m.groups()
        spec = specs.get(cls)
        if spec is None:
            why = study.uncomputed_class(scenario, cls)
            if why:
                raise UserInputError(f"--require {t!r}: {why}")
            raise UserInputError(f"--require {t!r}: unknown class {cls!r}; the {study.name} classes are "
                                 f"{', '.join(specs)}")
        if ax not in spec.axes:
            raise UserInputError(f"--require {t!r}: class {cls} has no axis {ax!r} (axes: {', '.join(spec.axes)})")
        if spec.role not in ("result", "residual"):
            why = {"input": "an input the method takes as given, not a figure it measures",
                   "stated": "an uncertainty the method states, not an error it makes"}.get(spec.role, spec.role)
            raise UserInputError(f"--require {t!r}: class {cls} is {why}; require a result or a residual")
        if ax in spec.undetermined:
            raise UserInputError(f"--require {t!r}: the data do not determine {cls}.{ax} (a convention, no error)")
        try:
            value = float(raw)
        except ValueError:
            raise UserInputError(f"--require {t!r}: {raw!r} is not a number") from None
        if not (math.isfinite(value) and value > 0):
            raise UserInputError(f"--require {t!r}: the bound must be a positive number in {spec.unit}")
        if any(r.cls == cls and r.axis == ax for r in out):
            raise UserInputError(f"--require {t!r}: {cls}.{ax} is required twice; give one bound")
        out.append(Requirement(cls, ax, value, spec.unit, spec.label))
    return out, variant


def _example(study: Study, scenario: Any) -> str:
    for c in study.classes(scenario):
        if c.role in ("result", "residual"):
            ax = next((a for a in c.axes if a not in c.undetermined), c.axes[0])
            return f"{c.name}.{ax}<=VALUE"
    return "CLASS.AXIS<=VALUE"


# ---------------------------------------------------------------------- seeds and statistics
def validation_seed(seed: int) -> int:
    """The re-validation's seed: the first 32-bit word of ``SeedSequence(seed,
    spawn_key=(VALIDATION_SPAWN_KEY,))``; its trials ``SeedSequence(validation_seed, (k,))``
    share no stream with the search's ``SeedSequence(seed, (k,))``."""
    return int(np.random.SeedSequence(seed, spawn_key=(VALIDATION_SPAWN_KEY,)).generate_state(1)[0])


def resolution(trials: int) -> float:
    """Relative cost resolution of the refinement: ``1 / (2 sqrt(n))``, half the relative
    standard error of a 95 % quantile of ``n`` Gaussian trials (about ``0.95 / sqrt(n)``)."""
    return 0.5 / math.sqrt(trials)


def screening_trials(trials: int) -> int:
    """Trials a candidate runs first: a quarter of a validation's, at least 20 (at most all)."""
    return min(trials, max(20, trials // 4))


def _rank(n: int, confidence: float) -> int:
    """1-based rank of the C-quantile order statistic of ``n`` values: ``ceil(C n)`` (>= 1)."""
    return max(1, min(n, math.ceil(confidence * n - 1e-9)))


def sure_met(exceed: int, n: int, confidence: float) -> float:
    """Posterior probability (Jeffreys prior ``Beta(1/2, 1/2)``) that the exceedance rate is
    at most ``1 - confidence``, given ``exceed`` of ``n`` trials beyond the bound."""
    from scipy import stats

    return float(stats.beta.cdf(1.0 - confidence, exceed + 0.5, n - exceed + 0.5))


def quantile_rel_se(trials: int, confidence: float) -> float:
    """Relative standard error of the sample C-quantile of ``|e|``, ``e ~ N(0, s^2)``, over ``n``
    trials: the asymptotic ``sqrt(C (1 - C) / n) / (f(q) q)`` with ``q = z s``, ``z =
    Phi^-1((1 + C) / 2)`` and ``f(q) = 2 phi(z) / s`` the density of ``|e|`` at ``q`` (about
    ``0.95 / sqrt(n)`` at C = 0.95)."""
    from scipy import stats

    z = float(stats.norm.ppf(0.5 + confidence / 2.0))
    return math.sqrt(confidence * (1 - confidence) / trials) / (2.0 * float(stats.norm.pdf(z)) * z)


def sure_margin(sure: float | None, trials: int, confidence: float) -> float:
    """The factor by which a protocol's true C-quantile must sit below the bound for its
    :func:`prediction_bound` to meet it (a normal error, ``n`` trials searched and ``n``
    re-validated): ``1 + z_P sqrt(2) r_n``, ``r_n`` :func:`quantile_rel_se`. The search steers by
    it; the measured bound decides."""
    if sure is None or sure <= 0.5:
        return 1.0
    from scipy import stats

    return 1.0 + float(stats.norm.ppf(sure)) * math.sqrt(2.0) * quantile_rel_se(trials, confidence)


def prediction_bound(q: float, se_q: float, n: int, n_future: int, truth_se: float, sure: float) -> float:
    """One-sided ``sure`` upper prediction bound of the C-quantile the re-validation will
    measure: ``q + z_P sqrt(se_q^2 (1 + n / n_future) + 2 truth_se^2)``. The re-validation
    draws fresh trials (``n_future``; its quantile's variance ``se_q^2 n / n_future``) and fresh
    truths (their standard error as this run's), independent of this run's, so ``q_future - q``
    has the summed variance; a bound on the true quantile alone (``q + z_P se``) would be
    passed by the re-validation only at ``Phi(z_P / sqrt(2))`` (82 % for P = 0.9)."""
    from scipy import stats

    if sure <= 0.5:
        return q
    if not math.isfinite(se_q):
        return math.inf
    z = float(stats.norm.ppf(sure))
    return q + z * math.sqrt(se_q**2 * (1.0 + n / n_future) + 2.0 * truth_se**2)


def figures_of(err: np.ndarray, value: float, confidence: float, truth_se: float = 0.0, *,
               sure: float | None = None, n_future: int | None = None) -> dict:
    """What ``err`` (errors of one requirement's key over trials) says about the bound
    ``value``: the C-quantile of ``|err|`` and its standard error, exceedances, bias and spread
    with their standard errors (the quantile's: Maritz-Jarrett), and how sure the bound is met (:func:`sure_met`, averaged
    over the truth's standard error ``truth_se``). ``sure``: ``met`` when the ``sure``
    :func:`prediction_bound` (``upper``; the re-validation has ``n_future`` trials, default
    ``n``) is within ``value``; None: when the quantile itself is (the re-validation's rule)."""
    e = np.asarray(err, dtype=float)
    n = e.size
    a = np.sort(np.abs(e))
    q = float(a[_rank(n, confidence) - 1])
    # its standard error: Maritz-Jarrett (order statistics weighted by the quantile's beta distribution)
    from scipy.stats import mstats

    se_q = float(mstats.mjci(a, prob=[confidence])[0]) if n >= 3 else float("nan")
    exceed = int(np.count_nonzero(a > value))
    if truth_se > 0:
        x, w = np.polynomial.hermite_e.hermegauss(7)  # over N(0, 1)
        w = w / w.sum()
        sure_p = float(sum(wi * sure_met(int(np.count_nonzero(np.abs(e - xi * truth_se) > value)), n, confidence)
                           for xi, wi in zip(x, w)))
    else:
        sure_p = sure_met(exceed, n, confidence)
    sd = float(e.std(ddof=1)) if n > 1 else 0.0
    out_sure = sure
    sure = sure_p
    upper = q if out_sure is None else prediction_bound(q, se_q, n, n_future or n, truth_se, out_sure)
    return {"quantile": q, "se_quantile": se_q, "bound": float(value), "n": int(n),
            "exceed": exceed, "allowed": int(n - _rank(n, confidence)), "met": bool(upper <= value), "sure": sure,
            **({} if out_sure is None else {"upper": upper, "upper_sure": float(out_sure)}),
            "bias": float(e.mean()), "se_bias": float(math.sqrt(sd**2 / n + truth_se**2)), "sd": sd,
            "se_sd": sd / math.sqrt(2.0 * max(n - 1, 1)), "truth_se": float(truth_se)}


# ---------------------------------------------------------------------- the oracle
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
        return self._study.trial_batch(scenario, seed, [k + self._offset for k in ks])


@dataclass
class Evaluation:
    """One protocol run by the search (or the re-validation): its knobs, cost and figures."""

    shape: str
    knobs: dict[str, float]
    cost_s: float
    cost_items: dict[str, float]
    seed: int
    trials: int
    figures: dict[str, dict]
    stage: str  # "design", "flat search", "search", "best achievable", REVALIDATED_BEST or "validation"
    scenario: Any = field(default=None, repr=False)
    errors: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    truth_se: dict[str, float] = field(default_factory=dict, repr=False)
    #: the scenario its trials ran on where the study restricted it (:meth:`Study.restrict_classes`)
    run_scenario: Any = field(default=None, repr=False)
    #: the sub-plan it belongs to (None: a plan that does not decompose)
    group: str | None = None

    @property
    def met(self) -> bool:
        return all(f["met"] for f in self.figures.values())

    @property
    def ratio(self) -> float:
        """Worst measured quantile (its prediction bound where the search judged by one) over its bound."""
        return max(f.get("upper", f["quantile"]) / f["bound"] for f in self.figures.values())

    def to_json(self) -> dict:
        return {"shape": self.shape, "knobs": dict(self.knobs), "cost_s": self.cost_s,
                "cost_items": dict(self.cost_items), "seed": self.seed, "trials": self.trials,
                "stage": self.stage, "met": self.met, "figures": self.figures,
                **({} if self.group is None else {"group": self.group})}


class _Oracle:
    """Runs candidates with common random numbers and shared truths, counting trials."""

    def __init__(self, study, requirements, variant, confidence, seed, trials, workers, progress, executor=None,
                 sure=None, restrict=None, group=None):
        self.study, self.reqs, self.variant = study, requirements, variant
        #: the classes the trials must compute (a sub-plan's; None: the whole scenario), and the sub-plan
        self.restrict, self.group = (None if restrict is None else frozenset(restrict)), group
        #: whether the study restricted a candidate's scenario (:meth:`Study.restrict_classes`)
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
        from scipy import stats

        self.z = float(stats.norm.ppf(0.5 + confidence / 2.0))
        self.margin = sure_margin(sure, trials, confidence)

    # the truths, once per truth identity and seed
    def truths_for(self, scn, seed):
        from budget.runner.run import TRUTH_SE_FRACTION, sized_truths_scenario, with_targets

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
        from budget.runner.run import run_study

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

    def evaluate(self, shape, knobs, scn, *, stage, seed=None, full=False, extend=True) -> Evaluation:
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
        if extend and n0 < self.n and not self._decided(ev.figures):
            self.complete(ev, quiet=True)
        self.evaluations.append(ev)
        self._echo(ev)
        return ev

    def complete(self, ev: Evaluation, *, quiet: bool = False) -> Evaluation:
        """Extend ``ev`` to ``n`` trials (trials ``ev.trials .. n - 1``, the same seed)."""
        if ev.trials >= self.n:
            return ev
        scn = ev.scenario if ev.run_scenario is None else ev.run_scenario
        more, _ = self._run(scn, ev.seed, ev.trials, self.n, self.truths_for(scn, ev.seed))
        ev.errors = {k: np.concatenate([ev.errors[k], more[k]]) for k in ev.errors}
        ev.trials = self.n
        ev.figures = self._figures(ev.errors, ev.truth_se, point=ev.stage in FRESH_STAGES)
        if not quiet:
            self._echo(ev, "extended")
        return ev

    def run_scenario(self, scn):
        """The scenario a candidate's trials run on: ``scn`` restricted to the sub-plan's classes
        where the study can (:meth:`Study.restrict_classes`), else ``scn``."""
        if self.restrict is None:
            return scn
        r = self.study.restrict_classes(scn, self.restrict)
        if r is None:
            return scn
        self.restricted = True
        return r

    def _echo(self, ev, what=None):
        if self.progress:
            click.echo(f"  {ev.shape} {what or ev.stage}: {_knobs_text(ev.knobs)}: {_hours(ev.cost_s)}, "
                       f"{ev.trials} trials, worst quantile/bound {ev.ratio:.3g} ({'meets' if ev.met else 'fails'})",
                       err=True)

    def _decided(self, figs) -> bool:
        s = [sure_met(f["exceed"], f["n"], self.confidence) for f in figs.values()]
        # meeting is decided only where the search's rule (the prediction bound) already says so
        return (min(s) > 1 - DECIDED and all(f["met"] for f in figs.values())) or min(s) < DECIDED


# ---------------------------------------------------------------------- scenarios of a protocol
def _with_values(study: Study, scenario: Any, values: dict[str, Any], *, where: str) -> Any:
    """``scenario`` with dotted ``values`` set (sweeps' rule), validated."""
    from budget.sweeps.dotted import set_dotted

    resolved = scenario.model_dump(mode="json", exclude_none=True)
    raw = scenario.model_dump(mode="json", exclude_none=True)
    for k, v in values.items():
        set_dotted(raw, resolved, k, v, where=where)
    return study.from_dict(raw, source=where)


def _smooth_ratio(ev: Evaluation, confidence: float) -> float:
    """Worst ratio of a requirement's C-quantile to its bound, the quantile that of ``|b + s Z|``
    (``b``, ``s``: the errors' mean and sd, ``Z`` standard normal): on a screening run's few
    trials far steadier than the order statistic, so the cost-flat search compares settings by
    their accuracy rather than by the noise of one order statistic."""
    from scipy import optimize, stats

    worst = 0.0
    for f in ev.figures.values():
        b, sd = abs(f["bias"]), max(f["sd"], 0.0)
        if sd <= 0.0:
            q = b
        else:
            def cover(q, b=b, sd=sd):
                return stats.norm.cdf((q - b) / sd) - stats.norm.cdf((-q - b) / sd) - confidence

            q = optimize.brentq(cover, 0.0, b + 10.0 * sd)
        worst = max(worst, q / f["bound"])
    return worst


def _dotted_get(scenario: Any, key: str):
    """The value of dotted ``key`` in ``scenario``."""
    obj = scenario
    for part in key.split("."):
        obj = obj[part] if isinstance(obj, dict) else getattr(obj, part)
    return obj


def _knob_value(k: Knob, x: float):
    return int(round(x)) if k.kind == "int" else float(x)


def _knobs_text(knobs: dict) -> str:
    """``frames 100, positions 4``: each knob by its last name, by its dotted field where two
    knobs share a last name (``te.frames 10, distortion.frames 20``)."""
    last = [f.rsplit(".", 1)[-1] for f in knobs]
    return ", ".join(f"{f if last.count(n) > 1 else n} {_num(v)}" for f, n, v in zip(knobs, last, knobs.values()))


def _num(v) -> str:
    return f"{v:d}" if isinstance(v, int) else f"{v:.4g}"


def _hours(s: float) -> str:
    return f"{s / 3600:.3g} h" if s >= 360 else f"{s / 60:.3g} min"


def _levels(k: Knob, count: int) -> np.ndarray:
    """``count`` values over ``[low, high]``, log-spaced where ``low > 0`` (whole for int knobs)."""
    if k.low == k.high:
        return np.array([k.low])
    v = np.geomspace(k.low, k.high, count) if k.low > 0 else np.linspace(k.low, k.high, count)
    if k.kind == "int":
        v = np.unique(np.round(v))
    return v


def _feature(k: Knob, x):
    """What a knob averages down: ``1 / x`` for a count (``low > 0``), else ``1 / (x - low + 1)``."""
    x = np.asarray(x, dtype=float)
    return 1.0 / x if k.low > 0 else 1.0 / (x - k.low + 1.0)


# ---------------------------------------------------------------------- the search of one shape
class _ShapeSearch:
    def __init__(self, oracle: _Oracle, shape: str, scn: Any, knobs: tuple[Knob, ...], budget_s: float | None,
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
        self.refused: list[dict] = []
        if self.knobs:
            self._grid()
        else:
            self.points, self.costs = np.zeros((1, 0)), np.array([self._cost([])])

    # ---- scenarios and costs
    def scenario(self, x, flat: dict | None = None) -> Any:
        vals = {**{k.field: _knob_value(k, xi) for k, xi in zip(self.knobs, x)}, **(flat or {})}
        if not vals:
            return self.base, vals
        return _with_values(self.o.study, self.base, vals, where=self.where), vals

    def _grid(self) -> None:
        """The fine grid (frontier candidates) with costs interpolated from a coarse grid."""
        from scipy.interpolate import RegularGridInterpolator

        d = len(self.knobs)
        coarse_n = {1: 9, 2: 7, 3: 5}.get(d, 3)
        fine_n = {1: 4000, 2: 160, 3: 40}.get(d, 12)
        coarse = [_levels(k, coarse_n) for k in self.knobs]
        fine = [_levels(k, fine_n) for k in self.knobs]
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
        return float(sum(self.o.study.lab_time_s(scn).values()))

    # ---- the model
    def _fit(self):
        """Per requirement, non-negative ``(a, b_1..b_d)`` of ``q^2 = a + sum b_i f_i(x_i)``."""
        from scipy.optimize import nnls

        evs = [e for e in self.evals]
        if not evs:  # nothing measured yet (every design protocol refused): no preference
            return {r.name: np.zeros(1 + len(self.knobs)) for r in self.o.reqs}
        coefs = {}
        for r in self.o.reqs:
            q2 = np.array([e.figures[r.name]["quantile"] ** 2 for e in evs])
            feats = np.array([[1.0] + [float(_feature(k, e.knobs[k.field])) for k in self.knobs] for e in evs])
            w = np.array([e.trials for e in evs]) / np.maximum(q2, (1e-6 * r.value) ** 2)
            sw = np.sqrt(w)
            coef, _ = nnls(feats * sw[:, None], q2 * sw)
            coefs[r.name] = coef
        return coefs

    def predicted_ratio(self, coefs, pts, margin: float | None = None) -> np.ndarray:
        """The model's worst quantile over its bound, times the ``sure`` margin
        (:func:`sure_margin`; default the search's)."""
        m = self.o.margin if margin is None else margin
        feats = np.column_stack([np.ones(len(pts))] + [_feature(k, pts[:, i]) for i, k in enumerate(self.knobs)])
        return m * np.max([np.sqrt(np.maximum(feats @ coefs[r.name], 0.0)) / r.value for r in self.o.reqs], axis=0)

    def frontier(self, coefs):
        """Indices into the fine grid, by cost, of protocols no cheaper protocol predicts better
        (within the budget)."""
        ratio = self.predicted_ratio(coefs, self.points)
        for _ in range(3):  # the frontier's costs exact (computed once each), then its order again
            order = np.argsort(self.costs, kind="stable")
            order = order[np.isfinite(self.costs[order])]
            if self.budget_s is not None:
                order = order[self.costs[order] <= self.budget_s]
            out, best = [], math.inf
            for i in order:
                if ratio[i] < best * (1 - 1e-9):
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

    # ---- the loop
    def spent(self) -> int:
        return self.o.trials_run - self.start_trials

    def run(self, x, stage) -> Evaluation | None:
        """Run protocol ``x`` (once); a protocol the scenario model, :meth:`Study.check` or the
        study's trials refuse (a ``ValueError`` or an arithmetic error: too few poses for a fit,
        ...) is recorded in :attr:`refused` and skipped (None)."""
        vals = {k.field: _knob_value(k, xi) for k, xi in zip(self.knobs, x)}
        for e in self.evals:
            if all(e.knobs.get(f) == v for f, v in vals.items()):
                return e
        if any(all(r["knobs"].get(f) == v for f, v in vals.items()) for r in self.refused if not r.get("flat")):
            return None
        if self.flat:
            ev = self._best_flat(x, stage)
            if ev is None:
                self.refused.append({"knobs": {**vals, **self.fixed},
                                     "error": "every setting of the cost-flat knobs refused"})
                return None
        else:
            try:
                scn, vals = self.scenario(x)
                self.o.study.check(scn, where=self.where)
                ev = self.o.evaluate(self.shape, {**vals, **self.fixed}, scn, stage=stage, extend=stage != "design")
            except (ValueError, ArithmeticError) as exc:
                self.refused.append({"knobs": {**vals, **self.fixed},
                                     "error": str(exc).splitlines()[0] if str(exc) else type(exc).__name__})
                return None
        self.evals.append(ev)
        return ev

    # ---- the cost-flat knobs
    def flat_trials(self) -> int:
        """Trials :meth:`_best_flat` may spend on one candidate (screening trials each)."""
        return len(self.flat) * (FLAT_COARSE + FLAT_REFINE) * screening_trials(self.o.n)

    def _flat_eval(self, x, fv: dict) -> Evaluation | None:
        """Candidate ``x`` with the cost-flat knobs at ``fv``, on screening trials (memoised; the
        same seed as every candidate: common random numbers); None where refused."""
        key = (tuple(_knob_value(k, xi) for k, xi in zip(self.knobs, x)), tuple(sorted(fv.items())))
        if key not in self._flat_memo:
            try:
                scn, vals = self.scenario(x, fv)
                self.o.study.check(scn, where=self.where)
                ev = self.o.evaluate(self.shape, {**vals, **self.fixed}, scn, stage="flat search", extend=False)
            except (ValueError, ArithmeticError) as exc:
                self.refused.append({"knobs": {**dict(zip([k.field for k in self.knobs], key[0])), **fv,
                                               **self.fixed}, "flat": True,
                                     "error": str(exc).splitlines()[0] if str(exc) else type(exc).__name__})
                ev = None
            self._flat_memo[key] = ev
        return self._flat_memo[key]

    def _best_flat(self, x, stage) -> Evaluation | None:
        """Candidate ``x`` with the cost-flat knobs set where its worst requirement ratio is least:
        per flat knob in turn (the others at their best so far, from the scenario's values), a
        coarse grid of :data:`FLAT_COARSE` values over its range, then :data:`FLAT_REFINE` steps
        each halving the wider gap next to the best value (whole numbers for ``int`` knobs), all
        on screening trials with common random numbers, compared by :func:`_smooth_ratio`. The
        best is the candidate: relabelled ``stage``, and (beyond the design) extended to a
        validation's trials unless decided."""
        def score(ev):
            return math.inf if ev is None else _smooth_ratio(ev, self.o.confidence)

        fv = {k.field: _knob_value(k, _dotted_get(self.base, k.field)) for k in self.flat}
        best = None
        for k in self.flat:
            tried: dict = {}

            def at(v, k=k):
                v = _knob_value(k, v)
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
                new = [g for g in sorted(gaps, reverse=True) if _knob_value(k, g[2]) not in tried]
                if not new:
                    break
                at(new[0][2])
            b = min(tried, key=lambda v: (score(tried[v]), v))
            fv[k.field] = b
            best = tried[b]
        if best is None:
            return None
        # the chosen setting is the candidate (its flat-search record becomes the candidate's)
        best.stage = stage
        if stage != "design" and best.trials < self.o.n and not self.o._decided(best.figures):
            self.o.complete(best, quiet=True)
        return best

    def search(self) -> dict:
        d = len(self.knobs)
        if d == 0:  # every knob pinned or cost-flat: one protocol, its flat knobs set
            return self._search_none()
        count = {1: 5, 2: 3}.get(d, 2)
        levels = [_levels(k, count) for k in self.knobs]
        for x in np.array(np.meshgrid(*levels, indexing="ij")).reshape(d, -1).T:
            if self.spent() + self.flat_trials() + 2 * self.o.n > self.trial_cap:
                break
            self.run(x, "design")
        rho = resolution(self.o.n)
        # lab time the knobs add above their cheapest setting: what the resolution applies to
        cands = [self._cost([k.low for k in self.knobs])] + [float(c) for c in self.costs if math.isfinite(c)]
        c0 = min((c for c in cands if math.isfinite(c)), default=0.0) * (1 - 1e-9)
        tried: set = set()
        last_step_met = False
        for _ in range(100):
            if self.spent() + self.flat_trials() + 2 * self.o.n > self.trial_cap:  # room for a last completion
                break
            front, ratio = self.frontier(self._fit())
            if len(front) == 0:
                break
            feas = [e for e in self.evals if e.met and self._in_budget(e)]
            hi = min(feas, key=lambda e: e.cost_s) if feas else None
            if hi is not None and hi.trials < self.o.n:
                self.o.complete(hi)  # the answer is judged on a validation's trials, like every candidate
                continue
            hi_cost = hi.cost_s if hi is not None else math.inf
            # what bounds the answer from below: a protocol measured failing on the search's path
            # (every protocol with one knob; with more, a design corner may be dear and poor)
            lows = [e for e in self.evals if not e.met and (d == 1 or e.stage == "search") and e.cost_s < hi_cost]
            lo = max(lows, key=lambda e: e.cost_s) if lows else None
            lo_cost = lo.cost_s if lo is not None else 0.0
            # what averaging allows (q^2 = a + b / x, a >= 0): a protocol failing by the ratio r needs at
            # least r^2 its lab time above the cheapest setting; one meeting with r < 1 at most r^2 of its
            # own would do. The model's pick is kept within these bounds (a safeguard against a model
            # that the design's few trials made optimistic or pessimistic)
            lo_need = c0 + (lo_cost - c0) * min(lo.ratio ** 2, 16.0) if lo is not None else 0.0
            hi_need = c0 + (hi_cost - c0) * hi.ratio ** 2 if hi is not None else math.inf
            if hi is not None and hi_cost - c0 <= max(lo_cost - c0, 0.0) * (1 + rho):
                break
            inside = [int(i) for i in front if lo_cost < self.costs[i] < hi_cost and int(i) not in tried]
            step = None
            if not inside:
                if hi is None and int(front[-1]) not in tried:
                    pick = int(front[-1])  # nothing meets yet: the most accurate protocol within the budget
                else:
                    break
            else:
                pred = [i for i in inside if ratio[i] <= 1.0]
                pick = pred[0] if pred else None
                if lo_need < hi_need:
                    if pick is not None and self.costs[pick] < lo_need:
                        pick = next((i for i in inside if self.costs[i] >= lo_need), pick)
                    if pick is not None and self.costs[pick] > hi_need:
                        pick = next((i for i in reversed(inside) if self.costs[i] <= hi_need), pick)
                if pick is not None and hi is not None and self.costs[pick] - c0 >= (hi_cost - c0) / (1 + rho / 2):
                    pick = None  # the model sits on the cheapest feasible: test just below, or bisect
                if pick is None:
                    if hi is None:
                        pick = inside[-1]
                    else:
                        lo_ref = max(lo_cost, float(self.costs[inside[0]])) - c0
                        target = c0 + ((hi_cost - c0) / (1 + rho) if not last_step_met
                                       else math.sqrt(lo_ref * (hi_cost - c0)))
                        if lo_need < hi_need < target:
                            target = hi_need  # averaging says that much less would do
                        below = [i for i in inside if self.costs[i] <= target]
                        pick = below[-1] if below else inside[0]
                        step = not last_step_met
            tried.add(pick)
            ev = self.run(self.points[pick], "search")
            last_step_met = bool(step and ev is not None and ev.met)
        while True:  # the answer judged on a validation's trials
            feas = [e for e in self.evals if e.met and self._in_budget(e)]
            best = min(feas, key=lambda e: e.cost_s) if feas else None
            if best is None or best.trials >= self.o.n:
                break
            self.o.complete(best)
        out = {"shape": self.shape, "best": best, "best_achievable": None}
        if best is None:
            front, _ = self.frontier(self._fit())
            if len(front):
                self.run(self.points[front[-1]], "best achievable")
            cands = [e for e in self.evals if self._in_budget(e)]
            best_a = self._most_accurate(cands)
            if best_a is not None:
                self.o.complete(best_a)  # its figure on a validation's trials
            out["best_achievable"] = best_a
        out["evaluations"], out["trials"], out["refused"] = list(self.evals), self.spent(), list(self.refused)
        out["model"] = self.model_curve()
        out["boundary"] = self.boundary()
        return out

    def _search_none(self) -> dict:
        ev = self.run(np.zeros(0), "search")
        if ev is not None:
            self.o.complete(ev)
        best = ev if ev is not None and ev.met and self._in_budget(ev) else None
        return {"shape": self.shape, "best": best, "best_achievable": None if best is not None else ev,
                "evaluations": list(self.evals), "trials": self.spent(), "refused": list(self.refused),
                "model": None, "boundary": None}

    def boundary(self) -> dict | None:
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
            out[name] = {"cost_s": float(self.costs[i]),
                         "knobs": {k.field: _knob_value(k, x) for k, x in zip(self.knobs, self.points[i])}}
        return {"cost_s": out["boundary"]["cost_s"], "knobs": out["boundary"]["knobs"],
                "model_sure_cost_s": out["sure"]["cost_s"]}

    def model_curve(self) -> dict:
        """The fitted model's frontier: lab time and predicted quantile per requirement, and the
        fitted coefficients (``a``: the squared floor; ``b``: per knob)."""
        coefs = self._fit()
        front, _ = self.frontier(coefs)
        pts = self.points[front]
        feats = np.column_stack([np.ones(len(pts))] + [_feature(k, pts[:, i]) for i, k in enumerate(self.knobs)])
        return {"cost_s": [float(c) for c in self.costs[front]],
                "knobs": [{k.field: _knob_value(k, x) for k, x in zip(self.knobs, p)} for p in pts],
                "quantile": {r.name: [float(v) for v in np.sqrt(np.maximum(feats @ coefs[r.name], 0.0))]
                             for r in self.o.reqs},
                "floor": {r.name: float(math.sqrt(max(coefs[r.name][0], 0.0))) for r in self.o.reqs},
                "b": {r.name: {k.field: float(b) for k, b in zip(self.knobs, coefs[r.name][1:])} for r in self.o.reqs}}

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
        return cands[min(range(len(cands)), key=lambda i: (round(float(pred[i]), 9), point[i]))]

    def _in_budget(self, e: Evaluation) -> bool:
        return self.budget_s is None or e.cost_s <= self.budget_s


# ---------------------------------------------------------------------- the result
@dataclass
class PlanResult:
    """A plan: the recommendation, its re-validation, every shape's best and every protocol run."""

    study: Study
    scenario: Any
    requirements: list[Requirement]
    variant: str
    confidence: float
    seed: int
    trials_per_validation: int
    budget_hours: float | None
    knobs: tuple[Knob, ...]
    shapes: dict[str, dict]
    recommended: Evaluation | None
    validation: Evaluation | None
    best_achievable: Evaluation | None
    evaluations: list[Evaluation]
    search_trials: int
    truth_runs: int
    elapsed_s: float = float("nan")
    cpu_s: float = float("nan")
    #: how sure the search wanted the recommendation to pass the re-validation (``--sure``)
    sure_level: float = DEFAULT_SURE
    #: knobs pinned by ``--fix`` (field -> value)
    fixed: dict = field(default_factory=dict)
    #: cost-flat knobs (set per candidate by direct evaluation, not in the averaging model)
    flat: tuple = ()
    #: the sub-plans of a separable plan (:func:`decompose`; empty: a whole-test plan), each a dict:
    #: ``group`` (:class:`PlanGroup`), ``best`` and ``best_achievable`` (:class:`Evaluation`),
    #: ``best_shape``, ``shapes`` (its keys in :attr:`shapes`), ``trials``, ``protocols``, ``restricted``
    groups: list = field(default_factory=list)
    #: knobs no required class depends on: left at the scenario's value, not searched
    unsearched: tuple = ()
    #: every group met its requirements but their protocols together exceed ``--budget-hours``
    #: (:attr:`best_achievable` is that protocol, re-validated)
    over_budget: bool = False

    # ---- verdicts
    @property
    def feasible(self) -> bool:
        """A protocol (within the budget) met every requirement in the search."""
        return self.recommended is not None

    @property
    def confirmed(self) -> bool:
        """The re-validation met every requirement too."""
        return self.validation is not None and self.validation.met

    @property
    def sure(self) -> float:
        """Bonferroni bound over the requirements of the re-validation's :func:`sure_met`."""
        if self.validation is None:
            return float("nan")
        return max(0.0, 1.0 - sum(1.0 - f["sure"] for f in self.validation.figures.values()))

    @property
    def premium(self) -> dict | None:
        """What aiming ``sure_level`` costs: the recommendation's lab time over that of the
        boundary protocol (the fitted model's cheapest whose predicted quantiles equal the
        bounds, in the recommended shape); None without a recommendation or a model boundary."""
        if self.recommended is None:
            return None
        if self.groups:
            return self._groups_premium()
        b = self.shapes.get(self.recommended.shape, {}).get("boundary")
        if not b or not b["cost_s"] > 0:
            return None
        return {"sure": self.sure_level, "factor": self.recommended.cost_s / b["cost_s"],
                "boundary_cost_s": b["cost_s"], "boundary_knobs": dict(b["knobs"]),
                "model_factor": b["model_sure_cost_s"] / b["cost_s"]}

    def _groups_premium(self) -> dict | None:
        """A separable plan's premium: lab time being additive over the groups, the boundary
        protocol is the recommendation with each group's part replaced by its boundary
        protocol's (the fitted model's, in the group's chosen shape); a group with no knob to
        search (every knob fixed or cost-flat, or none changes its classes) has no other
        protocol, so its boundary is its answer."""
        rec = self.recommended
        bound, model, knobs = rec.cost_s, rec.cost_s, dict(rec.knobs)
        for go in self.groups:
            s = self.shapes[go["best_shape"]]
            if s.get("model") is None:  # nothing searched: the answer is the only protocol
                continue
            b = s.get("boundary")
            if not b:
                return None
            bound -= go["best"].cost_s - b["cost_s"]
            model -= go["best"].cost_s - b["model_sure_cost_s"]
            knobs.update(b["knobs"])
        if not bound > 0:
            return None
        return {"sure": self.sure_level, "factor": rec.cost_s / bound, "boundary_cost_s": bound,
                "boundary_knobs": knobs, "model_factor": model / bound}

    @property
    def validation_seed(self) -> int:
        return validation_seed(self.seed)

    @property
    def best_achievable_revalidated(self) -> bool:
        """The best achievable is a separable plan's union run as one protocol on the
        re-validation's fresh seeds (stage :data:`REVALIDATED_BEST`), not a search's protocol."""
        return self.best_achievable is not None and self.best_achievable.stage == REVALIDATED_BEST

    @property
    def fresh_run(self) -> Evaluation | None:
        """The run on the re-validation's fresh seeds: the recommendation's re-validation, or a
        separable plan's best achievable union (:attr:`best_achievable_revalidated`)."""
        return self.validation if self.validation is not None else (
            self.best_achievable if self.best_achievable_revalidated else None)

    @property
    def total_trials(self) -> int:
        return self.search_trials + (self.fresh_run.trials if self.fresh_run is not None else 0)

    def recommended_scenario(self):
        return None if self.recommended is None else self.recommended.scenario

    def recommended_toml(self) -> str | None:
        """The recommended protocol's scenario as TOML, ready for ``budget <study> validate``."""
        if self.recommended is None:
            return None
        req = "; ".join(r.text for r in self.requirements)
        head = (f"# {self.study.title}: the cheapest protocol found by `budget {self.study.name} plan` for "
                f"{req} ({self.variant}, {100 * self.confidence:.0f} % of tests), "
                f"lab time {_hours(self.recommended.cost_s)}.\n")
        return head + self.study.scenario_text(self.recommended.scenario)

    def answer(self) -> str:
        """The plan's answer in one paragraph (what the report and the command print first)."""
        from budget.runner.plan_report import answer_text

        return answer_text(self)

    def sentences(self) -> list[str]:
        from budget.runner.plan_report import findings_sentences

        return findings_sentences(self)

    def to_json(self) -> dict:
        from budget.runner.plan_report import plan_json

        return plan_json(self)

    def to_dataframe(self):
        """Every protocol run, tidy (pandas): shape, stage, knobs, cost, trials, requirement,
        quantile (+ se), bound, met, bias (+ se), sd (+ se), sure."""
        import pandas as pd

        rows = []
        for e in self.evaluations + ([self.fresh_run] if self.fresh_run is not None else []):
            for name, f in e.figures.items():
                rows.append({"shape": e.shape, "stage": e.stage, **{k.rsplit('.', 1)[-1]: v for k, v in e.knobs.items()},
                             "cost_h": e.cost_s / 3600.0, "trials": e.trials, "seed": e.seed, "requirement": name,
                             **{k: f[k] for k in ("quantile", "se_quantile", "bound", "met", "bias", "se_bias", "sd",
                                                  "se_sd", "sure")}})
        return pd.DataFrame(rows)

    def write_report(self, out_dir):
        from budget.runner.plan_report import write_plan_report

        return write_plan_report(self, out_dir)

    def __repr__(self) -> str:
        return f"<PlanResult {self.study.name}: {self.answer()}>"

    def _repr_html_(self) -> str:
        import html

        from budget.runner.html import markdown_to_html
        from budget.runner.plan_report import summary_markdown

        return (f"<div><p><strong>{html.escape(self.study.title)}</strong>: plan</p>"
                f"{markdown_to_html(summary_markdown(self))}</div>")


# ---------------------------------------------------------------------- the planner
def plan_protocol(study: Study, scenario: Any, requirements, *, variant: str | None = None,
                  confidence: float = DEFAULT_CONFIDENCE, budget_hours: float | None = None, seed: int = 0,
                  trials: int | None = None, workers: int | None = 1, progress: bool = False,
                  sure: float = DEFAULT_SURE, fix=None) -> PlanResult:
    """Plan ``study``'s protocol on ``scenario`` (module docstring). ``requirements``: texts
    ``CLASS.AXIS<=VALUE`` or :class:`Requirement`; ``trials``: a validation's trials (default
    the scenario's ``validation.trials``); ``sure``: a candidate meets when the ``sure`` upper
    prediction bound of the quantile the re-validation will measure is within the bound
    (:func:`prediction_bound`; 0.5: the measured quantile itself, the boundary protocol);
    ``fix``: knobs pinned, ``{field: value}`` or texts ``FIELD=VALUE`` (:func:`parse_fixes`)."""
    t0, c0 = time.perf_counter(), time.process_time()
    knobs = tuple(study.protocol_knobs(scenario))
    if not knobs:
        raise UserInputError(f"plan: the {study.name} study declares no protocol knobs on this scenario")
    if not study.lab_time_s(scenario):
        raise TypeError(f"{type(study).__name__} declares protocol knobs but no lab time (Study.lab_time_s): "
                        "a plan has no cost to minimise")
    fixed = parse_fixes(knobs, fix)
    if not (0.5 <= confidence < 1.0):
        raise UserInputError(f"--confidence {confidence}: must be in [0.5, 1)")
    if not (0.5 <= sure < 1.0):
        raise UserInputError(f"--sure {sure}: must be in [0.5, 1)")
    if budget_hours is not None and not (math.isfinite(budget_hours) and budget_hours > 0):
        raise UserInputError(f"--budget-hours {budget_hours}: must be a positive number")
    if requirements and all(isinstance(r, Requirement) for r in requirements):
        reqs, variant = list(requirements), variant or default_variant(study)
    else:
        reqs, variant = parse_requirements(study, scenario, requirements, variant)
    n = int(trials) if trials is not None else int(study.default_trials(scenario))
    if n < 20:
        raise UserInputError(f"--trials {n}: a plan needs at least 20 trials per validation")
    budget_s = None if budget_hours is None else 3600.0 * budget_hours
    from budget.runner.executors import make_executor
    from budget.runner.run import _worker_init

    # one pool for every candidate (the study's kernels compiled first, so its workers load them
    # from the cache): starting workers per candidate would cost more than the toy's trials
    study.prewarm(scenario)
    with make_executor(workers=workers, initializer=_worker_init, initargs=(study,)) as pool:
        run = _Run(study, scenario, reqs, variant, confidence, budget_hours, budget_s, seed, n, workers, progress,
                   pool, knobs, sure, fixed, t0, c0)
        # the whole-test search where the study declares no field classes (every field may change
        # every class), else the separable plan
        return _plan_groups(run) if study.field_classes(scenario) else _plan_joint(run)


@dataclass
class _Run:
    """What every search of one plan shares: the study, scenario, requirements and settings
    (checked by :func:`plan_protocol`), the one pool of workers, the clocks and the cost-flat
    knobs found (:attr:`flat`)."""

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
    #: the cost-flat knobs of every shape searched (field -> knob)
    flat: dict = field(default_factory=dict)

    def oracle(self, reqs: list[Requirement] | None = None, **kw) -> _Oracle:
        """An oracle of ``reqs`` (default every requirement) on the plan's seed, trials and pool."""
        o = _Oracle(self.study, self.reqs if reqs is None else reqs, self.variant, self.confidence, self.seed, self.n,
                    self.workers, self.progress, executor=self.pool, sure=self.sure, **kw)
        o.prewarmed = True
        return o

    def search_shapes(self, oracle: _Oracle, shapes: dict[str, dict], knobs: tuple[Knob, ...],
                      budget_s: float | None, key=None) -> dict[str, dict]:
        """Each shape searched (module docstring, "The search"): its scenario (the shape's
        overrides and the ``--fix`` values), its cost-flat knobs (:func:`cost_flat_knobs`) set per
        candidate, the others searched by :class:`_ShapeSearch`; ``key``: the shape's name in the
        plan (default its own)."""
        cap = (BUDGET_VALIDATIONS - 1) * self.n
        out = {}
        for name, overrides in shapes.items():
            k = name if key is None else key(name)
            base = _with_values(self.study, self.scenario, {**overrides, **self.fixed},
                                where=f"protocol shape {name}") if (overrides or self.fixed) else self.scenario
            flat = cost_flat_knobs(self.study, base, knobs)
            self.flat.update({f.field: f for f in flat})
            cost_knobs = tuple(f for f in knobs if f not in flat)
            s = _ShapeSearch(oracle, k, base, cost_knobs, budget_s, cap, flat=flat, fixed=self.fixed).search()
            s["flat"] = [f.field for f in flat]
            s["overrides"] = dict(overrides)
            out[k] = s
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


def _plan_joint(run: _Run) -> PlanResult:
    """The whole-test plan: every shape searched over every free knob with every requirement."""
    oracle = run.oracle()
    shapes = run.study.protocol_shapes(run.scenario) or {"scenario": {}}
    free = tuple(k for k in run.knobs if k.field not in run.fixed)
    results = run.search_shapes(oracle, shapes, free, run.budget_s)
    bests = [s["best"] for s in results.values() if s["best"] is not None]
    rec = min(bests, key=lambda e: e.cost_s) if bests else None
    search_trials = oracle.trials_run
    validation = best_ach = None
    if rec is not None:
        vseed = validation_seed(run.seed)
        validation = oracle.evaluate(rec.shape, rec.knobs, rec.scenario, stage="validation", seed=vseed, full=True)
        oracle.evaluations.remove(validation)
    else:
        cands = [s.get("best_achievable") for s in results.values() if s.get("best_achievable") is not None]
        best_ach = min(cands, key=lambda e: e.ratio) if cands else None
    return run.result(shapes=results, recommended=rec, validation=validation, best_achievable=best_ach,
                      evaluations=list(oracle.evaluations), search_trials=search_trials, truth_runs=oracle.truth_runs)


# ---------------------------------------------------------------------- separable plans
_UNSET = object()


@dataclass
class PlanGroup:
    """One independent sub-plan (:func:`decompose`): required classes, the knobs and shape fields
    that can change them and nothing else required, and its shapes collapsed to those that
    differ in its shape fields."""

    name: str
    classes: tuple[str, ...]
    requirements: list[Requirement]
    knobs: tuple[Knob, ...]
    shape_fields: tuple[str, ...]
    #: collapsed shape name -> the overrides of its shape fields (the group's projection)
    shapes: dict[str, dict[str, Any]]
    #: collapsed shape name -> the declared shapes it stands for
    members: dict[str, list[str]]

    def key(self, shape: str, several: bool) -> str:
        """The shape's name in the plan (``group/shape`` where the plan has several groups)."""
        return f"{self.name}/{shape}" if several else shape


def decompose(study: Study, scenario: Any, reqs, knobs, shapes: dict[str, dict], fixed: dict | None = None
              ) -> tuple[list[PlanGroup], tuple[Knob, ...]]:
    """The plan's independent sub-plans and the knobs no requirement depends on.

    A graph links each required class to every free knob field and shape field that can change
    it (:meth:`Study.field_classes`; a field not listed can change every class); its connected
    components over the required classes are the groups (in the order of the requirements).
    A knob that changes no required class is not searched (it stays at the scenario's value,
    or its ``--fix`` value); a group's shapes are the declared shapes projected on the group's
    shape fields, those with equal projections collapsed into one (searched once)."""
    fixed = dict(fixed or {})
    fc = {f: tuple(c) for f, c in (study.field_classes(scenario) or {}).items()}
    all_classes = [c.name for c in study.classes(scenario)]
    req_classes = list(dict.fromkeys(r.cls for r in reqs))

    def rel(f):
        cl = fc.get(f)
        cl = set(all_classes) if cl is None else set(cl)
        return [c for c in req_classes if c in cl]

    parent = {c: c for c in req_classes}

    def find(c):
        while parent[c] != c:
            parent[c] = parent[parent[c]]
            c = parent[c]
        return c

    free = [k for k in knobs if k.field not in fixed]
    shape_fields = list(dict.fromkeys(f for ov in shapes.values() for f in ov))
    for f in [k.field for k in free] + shape_fields:
        r = rel(f)
        for c in r[1:]:
            parent[find(c)] = find(r[0])
    roots = list(dict.fromkeys(find(c) for c in req_classes))
    groups = []
    for root in roots:
        cls = tuple(c for c in req_classes if find(c) == root)
        gk = tuple(k for k in free if rel(k.field) and find(rel(k.field)[0]) == root)
        gf = tuple(f for f in shape_fields if rel(f) and find(rel(f)[0]) == root)
        proj: dict[tuple, list[str]] = {}
        for name, ov in shapes.items():
            key = tuple((f, repr(ov.get(f, _UNSET)) if f in ov else "<unset>") for f in gf)
            proj.setdefault(key, []).append(name)
        gshapes, members = {}, {}
        labels = _collapsed_labels(list(proj.values()), gf, shapes)
        for (key, names), label in zip(proj.items(), labels):
            ov = {f: shapes[names[0]][f] for f in gf if f in shapes[names[0]]}
            gshapes[label], members[label] = ov, list(names)
        groups.append(PlanGroup(",".join(cls), cls, [r for r in reqs if r.cls in cls], gk, gf, gshapes, members))
    searched = {k.field for g in groups for k in g.knobs}
    unsearched = tuple(k for k in free if k.field not in searched)
    return groups, unsearched


def _collapsed_labels(projs: list[list[str]], gf: tuple, shapes: dict) -> list[str]:
    """A label per collapsed shape of one group, by what its declared members share (module
    docstring, "Separable plans"): one member keeps its name; several, the comma-separated parts
    of the name common to every member ("diagonal" for "diagonal, filters 500/600" and "diagonal,
    filters 600/800"), else the group's shape fields' values ("pattern diagonal"); a group no
    shape field touches (one collapsed shape of every declared one) is "(any)". Labels are unique
    within the group and hold no "|" (a markdown cell); the JSON keeps the members."""
    if len(projs) == 1 and len(projs[0]) > 1 and not gf:
        return ["(any)"]

    def common(names):
        parts = [[p.strip() for p in n.split(",")] for n in names]
        return ", ".join(p for p in parts[0] if p and all(p in q for q in parts[1:]))

    last = [f.rsplit(".", 1)[-1] for f in gf]
    short = {f: (s if last.count(s) == 1 else f) for f, s in zip(gf, last)}  # "pattern", or the field where two share it

    def by_fields(names):
        ov = shapes[names[0]]
        return ", ".join(f"{short[f]} {ov[f] if f in ov else 'unset'}".replace("|", "/") for f in gf)

    first = [n[0].replace("|", "/") if len(n) == 1 else (common(n).replace("|", "/") or by_fields(n))
             for n in projs]
    if len(set(first)) == len(first) and all(first):
        return first
    second = [n[0].replace("|", "/") if len(n) == 1 else by_fields(n) for n in projs]
    if len(set(second)) == len(second) and all(second):
        return second
    return [f"{lab or 'shape'} ({i + 1})" for i, lab in enumerate(second)]


def _plan_groups(run: _Run) -> PlanResult:
    """The separable plan (module docstring, "Separable plans"): each group searched on its own
    (its classes only where the study can restrict, its own trial budget per shape, common
    random numbers within it), the union of the answers run as one protocol on fresh seeds:
    the recommendation's re-validation, or (a group infeasible, or the union over the budget)
    the best achievable's."""
    study, scenario = run.study, run.scenario
    declared = study.protocol_shapes(scenario) or {"scenario": {}}
    groups, unsearched = decompose(study, scenario, run.reqs, run.knobs, declared, run.fixed)
    several = len(groups) > 1
    results: dict[str, dict] = {}
    group_out: list[dict] = []
    evaluations: list[Evaluation] = []
    search_trials = truth_runs = 0
    for g in groups:
        oracle = run.oracle(g.requirements, restrict=g.classes, group=g.name if several else None)
        # one group: the budget bounds its protocols as in a whole-test plan; several: the sum is checked
        gres = run.search_shapes(oracle, g.shapes, g.knobs, None if several else run.budget_s,
                                 key=lambda sname, g=g: g.key(sname, several))
        for sname, s in zip(g.shapes, gres.values()):
            s["members"] = list(g.members[sname])
            s["group"] = g.name
        results.update(gres)
        bests = [s["best"] for s in gres.values() if s["best"] is not None]
        best = min(bests, key=lambda e: e.cost_s) if bests else None
        ach = None
        if best is None:
            cands = [s.get("best_achievable") for s in gres.values() if s.get("best_achievable") is not None]
            ach = min(cands, key=lambda e: e.ratio) if cands else None
        best_sname = None if best is None else next(sn for sn in g.shapes
                                                     if gres[g.key(sn, several)]["best"] is best)
        group_out.append({"group": g, "best": best, "best_achievable": ach, "shapes": list(gres),
                          "best_shape": None if best is None else g.key(best_sname, several),
                          "best_sname": best_sname,
                          "trials": oracle.trials_run, "protocols": len(oracle.evaluations),
                          "restricted": oracle.restricted, "truth_runs": oracle.truth_runs})
        evaluations += oracle.evaluations
        search_trials += oracle.trials_run
        truth_runs += oracle.truth_runs
    rec = validation = best_ach = None
    over_budget = False
    # each group's part: its answer, else its most accurate protocol (None: none could be run)
    parts = [go["best"] if go["best"] is not None else go["best_achievable"] for go in group_out]
    if any(p is not None for p in parts):
        union = _union(run, declared, groups, parts, several)
        feasible = all(go["best"] is not None for go in group_out)
        # lab time is additive over the groups: over the budget, no cheaper protocol meets every requirement
        over_budget = feasible and run.budget_s is not None and union.cost_s > run.budget_s
        if feasible and not over_budget:
            rec = union
            validation, t = run.fresh(rec.shape, rec.knobs, rec.scenario)
        else:
            # the best achievable: the union itself, run as one protocol on the fresh seeds (not the
            # groups' search figures put together)
            best_ach, t = run.fresh(union.shape, union.knobs, union.scenario, stage=REVALIDATED_BEST)
        truth_runs += t
    return run.result(shapes=results, recommended=rec, validation=validation, best_achievable=best_ach,
                      evaluations=evaluations, search_trials=search_trials, truth_runs=truth_runs, groups=group_out,
                      unsearched=unsearched, over_budget=over_budget)


def _union(run: _Run, declared, groups, parts, several: bool) -> Evaluation:
    """Every group's part (its answer, or its most accurate protocol) in one protocol: the parts'
    knobs, every other knob at the scenario's value (those no requirement depends on, and a group's
    that has no part) or its ``--fix`` value; among the declared shapes that agree with every
    part's shape fields, those keeping the scenario's own values of the other shape fields (no
    requirement depends on them; :meth:`Study.shape_value`) first, then the cheapest (a declared
    shape the scenario model refuses is skipped); where none agrees, the parts' shape fields
    together. Its figures are the parts' (search) figures; its cost the full lab time."""
    study, scenario = run.study, run.scenario
    vals = {k.field: _knob_value(k, _dotted_get(scenario, k.field)) for k in run.knobs}
    vals.update(run.fixed)
    picks, members, names, fields = {}, set(declared), [], set()
    for g, part in zip(groups, parts):
        fields.update(g.shape_fields)
        if part is None:
            continue
        vals.update({f: v for f, v in part.knobs.items() if f not in run.fixed})
        sname = next(sn for sn in g.shapes if g.key(sn, several) == part.shape)
        picks.update(g.shapes[sname])
        members &= set(g.members[sname])
        names.append(sname)
    where = "plan: the recommended protocol"
    costed = []
    for name in (n for n in declared if n in members):
        try:
            scn = _with_values(study, scenario, {**declared[name], **vals}, where=where)
        except ValueError:
            continue  # the scenario model refuses this combination of fields no requirement depends on
        changed = sum(study.shape_value(scn, f) != study.shape_value(scenario, f)
                      for f in declared[name] if f not in fields)
        costed.append((changed, float(sum(study.lab_time_s(scn).values())), name, scn))
    if costed:
        _, _, shape, scn = min(costed, key=lambda t: t[:2])
    else:
        shape = "+".join(dict.fromkeys(names))
        scn = _with_values(study, scenario, {**picks, **vals}, where=where)
    items = {k: float(v) for k, v in study.lab_time_s(scn).items()}
    figs, errs, tse = {}, {}, {}
    for part in parts:
        if part is not None:
            figs.update(part.figures)
            errs.update(part.errors)
            tse.update(part.truth_se)
    knob_vals = {k.field: vals[k.field] for k in run.knobs}
    return Evaluation(shape, knob_vals, float(sum(items.values())), items, run.seed, run.n, figs, "search", scn,
                      errs, tse)


# ---------------------------------------------------------------------- fixed and cost-flat knobs
def parse_fixes(knobs: tuple[Knob, ...], fix) -> dict[str, Any]:
    """The knobs pinned by ``--fix FIELD=VALUE`` (texts) or ``{field: value}``, checked: the
    field one of the study's knobs, given once, the value of the knob's kind (a whole number for
    an ``int`` knob) within its bounds; a bad one is a :class:`UserInputError` naming it."""
    if not fix:
        return {}
    by_field = {k.field: k for k in knobs}
    items = []
    if isinstance(fix, dict):
        items = [(str(f), v, f"{f}={v}") for f, v in fix.items()]
    else:
        for t in ([fix] if isinstance(fix, str) else list(fix)):
            f, eq, v = str(t).partition("=")
            if not eq or not f.strip() or not v.strip():
                raise UserInputError(f"--fix {t!r}: expected FIELD=VALUE (e.g. {knobs[0].field}={knobs[0].low:g})")
            items.append((f.strip(), v.strip(), str(t)))
    out: dict[str, Any] = {}
    for f, v, t in items:
        k = by_field.get(f)
        if k is None:
            raise UserInputError(f"--fix {t!r}: {f!r} is not a protocol knob; the knobs are {', '.join(by_field)}")
        if f in out:
            raise UserInputError(f"--fix {t!r}: {f} is fixed twice; give one value")
        try:
            x = float(v)
        except (TypeError, ValueError):
            raise UserInputError(f"--fix {t!r}: {v!r} is not a number") from None
        if isinstance(v, bool) or not math.isfinite(x):
            raise UserInputError(f"--fix {t!r}: {v!r} is not a number")
        if k.kind == "int":
            if x != round(x) or (isinstance(v, str) and not re.fullmatch(r"[+-]?\d+", v)):
                raise UserInputError(f"--fix {t!r}: {f} takes a whole number ({k.unit})")
            x = int(round(x))
        if not (k.low <= x <= k.high):
            raise UserInputError(f"--fix {t!r}: {f} must be within [{k.low:g}, {k.high:g}] {k.unit}")
        out[f] = x
    return out


def cost_flat_knobs(study: Study, scenario: Any, knobs: tuple[Knob, ...]) -> tuple[Knob, ...]:
    """The knobs whose lab time does not change with them (a magnitude limit, a threshold): by
    :meth:`Study.lab_time_s` itself, at the knob's low, middle and high value, with the other
    knobs at the scenario's values, all low and all high; unchanged (relative 1e-9) at every
    setting the scenario model accepts (at least one with two values) makes it cost-flat."""
    out = []
    for k in knobs:
        others = [o for o in knobs if o is not k]
        settings = [{}] + ([{o.field: _knob_value(o, o.low) for o in others},
                            {o.field: _knob_value(o, o.high) for o in others}] if others else [])
        vals = sorted({_knob_value(k, v) for v in (k.low, 0.5 * (k.low + k.high), k.high)})
        flat, seen = True, 0
        for st in settings:
            costs = []
            for v in vals:
                try:
                    scn = _with_values(study, scenario, {**st, k.field: v}, where="plan: cost-flat check")
                    costs.append(float(sum(study.lab_time_s(scn).values())))
                except (ValueError, ArithmeticError):
                    continue
            if len(costs) >= 2:
                seen += 1
                if max(costs) - min(costs) > 1e-9 * max(1.0, abs(max(costs))):
                    flat = False
                    break
        if flat and seen and len(vals) > 1:
            out.append(k)
    return tuple(out)


# ---------------------------------------------------------------------- the command
def has_knobs(study: Study) -> bool:
    """Whether the study's default scenario declares protocol knobs (then it has ``plan``); a
    study that keeps the default hook has none (no scenario loaded to say so)."""
    if getattr(type(study), "protocol_knobs", None) is Study.protocol_knobs:
        return False
    try:
        return bool(study.protocol_knobs(study.load_scenario()))
    except Exception:  # noqa: BLE001 - a study without a loadable default has no plan command
        return False


def plan_command_for(study_name: str, *, get_study=None) -> click.Command:
    """``plan [SCENARIO] --require ... --variant --confidence --sure --fix --budget-hours --trials
    --seed --workers --json --report``; ``get_study``: how to find the study (default the registry)."""

    @click.command("plan", help=f"Plan the {study_name} test before booking the lab: the cheapest protocol "
                                "(knobs and shapes the study declares) whose estimates meet every --require "
                                "CLASS.AXIS<=VALUE (the --confidence quantile of |estimate - truth|, in the "
                                "class's unit), re-validated on fresh trials (SCENARIO: default the embedded one).")
    @click.argument("scenario", required=False, type=click.Path(dir_okay=False))
    @click.option("--require", "require", multiple=True, metavar="CLASS.AXIS<=VALUE",
                  help="A requirement (repeat for several): the error's quantile at most VALUE.")
    @click.option("--variant", default=None, help="The estimator judged (default: the study's last that estimates).")
    @click.option("--confidence", type=float, default=DEFAULT_CONFIDENCE, show_default=True,
                  help="The share of tests that must land within VALUE (the quantile).")
    @click.option("--sure", "sure", type=float, default=DEFAULT_SURE, show_default=True,
                  help="How sure the recommended protocol should be to meet each requirement on the real test "
                       "(the re-validation's fresh trials), per requirement: K requirements all pass together "
                       "with probability at least 1 - K (1 - SURE) (for a joint P give 1 - (1 - P) / K); "
                       "0.5: the boundary protocol.")
    @click.option("--fix", "fix", multiple=True, metavar="FIELD=VALUE",
                  help="Pin a protocol knob (repeat for several; FIELD one of the study's knobs, VALUE within "
                       "its bounds): the search leaves it at VALUE.")
    @click.option("--budget-hours", "budget_hours", type=float, default=None,
                  help="Lab time allowed: protocols above it are not considered.")
    @click.option("--trials", type=click.IntRange(min=20), default=None,
                  help="Trials of one validation (default: the scenario's validation.trials); the search "
                       f"uses at most {BUDGET_VALIDATIONS - 1} times as many per shape.")
    @click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True)
    @click.option("--workers", type=click.IntRange(min=1), default=None,
                  help="Local worker processes (default: all cores). Results do not depend on it.")
    @click.option("--json", "json_out", type=click.Path(dir_okay=False), help="Write the plan as JSON.")
    @click.option("--report", "report_dir", type=click.Path(file_okay=False),
                  help="Write a report (report.md, report.html, trade_curve.png, recommended.toml).")
    @overwrite_option
    @click.option("--progress/--no-progress", default=None, help="Each protocol run on stderr (default: on a terminal).")
    def plan(scenario, require, variant, confidence, sure, fix, budget_hours, trials, seed, workers, json_out,
             report_dir, overwrite, progress):
        import sys

        from simcam.infra.outputs import check_run_outputs

        if get_study is None:
            from budget.runner.registry import get_study as lookup
        else:
            lookup = get_study
        study = lookup(study_name)
        scn = study.load_scenario(scenario)
        parse_requirements(study, scn, require, variant)  # a bad requirement before any work
        parse_fixes(tuple(study.protocol_knobs(scn)), list(fix))  # a bad --fix too
        check_run_outputs(json_out=json_out, report_dir=report_dir, inputs=(scenario,), overwrite=overwrite)
        if progress is None:
            progress = sys.stderr.isatty()
        if workers is None:
            from budget.runner.executors import default_workers

            workers = default_workers()
        res = plan_protocol(study, scn, list(require), variant=variant, confidence=confidence,
                            budget_hours=budget_hours, seed=seed, trials=trials, workers=workers, progress=progress,
                            sure=sure, fix=list(fix))
        click.echo(res.answer())
        for s in res.sentences():
            click.echo(f"* {s}")
        from budget.runner.report import write_outputs

        write_outputs(res, json_out=json_out, report_dir=report_dir)

    return plan
