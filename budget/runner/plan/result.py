"""What a plan hands back: every protocol run (:class:`Evaluation`), what the search of one
shape found (:class:`ShapeOutcome`), a separable plan's sub-plans (:class:`PlanGroup`,
:class:`GroupOutcome`), the plan (:class:`PlanResult`) and its JSON, schema ``budget.plan/1``
(:func:`plan_json`: the one payload the command's ``--json``, the report's ``plan.json`` and
the Python API's ``to_json()`` write)."""

from __future__ import annotations

import html
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from budget.runner.html import markdown_to_html
from budget.runner.plan.quantiles import DEFAULT_SURE
from budget.runner.plan.report import answer_text, findings_sentences, summary_markdown, write_plan_report
from budget.runner.plan.requirements import Requirement
from budget.runner.plan.text import lab_time_text
from budget.runner.plan.trials import validation_seed
from budget.runner.study import Knob, Study
from simcam import __version__
from simcam.units import SECONDS_PER_HOUR

__all__ = ["FRESH_STAGES", "REVALIDATED_BEST", "SCHEMA", "Boundary", "Evaluation", "GroupOutcome", "ModelCurve",
           "PlanGroup", "PlanResult", "Refusal", "ShapeOutcome", "plan_json"]

SCHEMA = "budget.plan/1"
#: the stage of a separable plan's best achievable (its groups' parts together) run as one protocol on
#: the re-validation's fresh seeds; it and the re-validation are judged by the measured quantile
REVALIDATED_BEST = "best achievable, re-validated"
FRESH_STAGES = ("validation", REVALIDATED_BEST)
#: the most protocols of a fitted model's frontier the JSON keeps (evenly by index)
MODEL_JSON_POINTS = 200


@dataclass(frozen=True, eq=False)
class Evaluation:
    """One protocol run by the search (or the re-validation): its knobs, cost and figures.
    Compared by identity: each is one run (extending it to more trials makes a new one)."""

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
    #: the scenario its trials ran on where the study restricted it (:meth:`~budget.runner.capabilities.SeparablePlans.restrict_classes`)
    run_scenario: Any = field(default=None, repr=False)
    #: the sub-plan it belongs to (None: a plan that does not decompose)
    group: str | None = None

    @property
    def met(self) -> bool:
        return all(f["met"] for f in self.figures.values())

    @property
    def verdict(self) -> str:
        """The protocol's verdict on every requirement together: ``fails`` where one fails,
        ``holds`` where every one holds (met), else ``undetermined`` (figures without a verdict,
        the re-validation's, are judged by ``met``)."""
        outcomes = [f.get("verdict", "holds" if f["met"] else "fails") for f in self.figures.values()]
        if "fails" in outcomes:
            return "fails"
        return "holds" if all(o == "holds" for o in outcomes) else "undetermined"

    @property
    def n_to_settle(self) -> int | None:
        """The trials that would settle every undetermined requirement (the most of theirs;
        None where none is undetermined or one sits on its bound: no number settles it)."""
        need = [f.get("n_to_settle") for f in self.figures.values() if f.get("verdict") == "undetermined"]
        return None if not need or any(n is None for n in need) else max(need)

    @property
    def ratio(self) -> float:
        """Worst measured quantile (its verdict's upper edge where the search judged by one) over its bound."""
        return max(f.get("upper", f["quantile"]) / f["bound"] for f in self.figures.values())

    def to_json(self) -> dict:
        return {"shape": self.shape, "knobs": dict(self.knobs), "cost_s": self.cost_s,
                "cost_items": dict(self.cost_items), "seed": self.seed, "trials": self.trials,
                "stage": self.stage, "met": self.met, "figures": self.figures,
                **({} if self.group is None else {"group": self.group})}


@dataclass(frozen=True)
class Refusal:
    """A protocol the study refused (its scenario model, :meth:`~budget.runner.capabilities.CheckedScenario.check` or its trials)."""

    knobs: dict[str, Any]
    #: the first line of the study's message (or the exception's type)
    error: str
    #: one setting of the cost-flat knobs refused in a candidate's flat search (the candidate may still run)
    flat: bool = False

    def to_json(self) -> dict:
        return {"knobs": dict(self.knobs), **({"flat": True} if self.flat else {}), "error": self.error}


@dataclass(frozen=True)
class ModelCurve:
    """The fitted model's frontier: per protocol its lab time, knobs and predicted quantile per
    requirement; the fitted coefficients (``floor``: ``sqrt(a)``, what no count removes; ``b``:
    per knob)."""

    cost_s: list[float]
    knobs: list[dict[str, Any]]
    quantile: dict[str, list[float]]
    floor: dict[str, float]
    b: dict[str, dict[str, float]]

    def to_json(self, most: int = MODEL_JSON_POINTS) -> dict:
        """The curve for the JSON, at most ``most`` protocols (evenly by index)."""
        n = len(self.cost_s)
        idx = sorted(set(round(i * (n - 1) / (most - 1)) for i in range(most))) if n > most else list(range(n))
        return {"cost_s": [self.cost_s[i] for i in idx], "knobs": [self.knobs[i] for i in idx],
                "quantile": {k: [v[i] for i in idx] for k, v in self.quantile.items()},
                "floor": self.floor, "b": self.b}


@dataclass(frozen=True)
class Boundary:
    """The fitted model's cheapest protocol whose predicted quantiles sit at the bounds (no
    ``sure`` margin), and the lab time of the model's cheapest at the search's margin."""

    cost_s: float
    knobs: dict[str, Any]
    model_sure_cost_s: float


@dataclass(frozen=True)
class ShapeOutcome:
    """What the search of one shape found: its cheapest protocol meeting every requirement
    (``best``) or, where none does, its most accurate (``best_achievable``), every protocol it
    ran, the trials it spent, what the study refused, the fitted model and its boundary."""

    shape: str
    best: Evaluation | None
    best_achievable: Evaluation | None
    evaluations: list[Evaluation]
    trials: int
    refused: list[Refusal]
    model: ModelCurve | None
    boundary: Boundary | None
    #: its cost-flat knobs (fields) and the shape's overrides of the scenario
    flat: list[str] = field(default_factory=list)
    overrides: dict[str, Any] = field(default_factory=dict)
    #: a separable plan's: the declared shapes this searched shape stands for, and its group's name
    members: list[str] | None = None
    group: str | None = None
    #: where none holds: the cheapest protocol still undetermined when the trial budget was spent
    #: (its ``n_to_settle``: the trials that would settle it)
    undetermined: Evaluation | None = None


@dataclass(frozen=True)
class PlanGroup:
    """One independent sub-plan (:func:`budget.runner.plan.separable.decompose`): required
    classes, the knobs and shape fields that can change them and nothing else required, and its
    shapes collapsed to those that differ in its shape fields."""

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


@dataclass(frozen=True)
class GroupOutcome:
    """What the search of one sub-plan found: its answer (``best``, in its shape ``best_label``,
    the plan's key ``best_shape``) or its most accurate protocol, its shapes' keys in
    :attr:`PlanResult.shapes`, the trials, protocols and truths it ran, whether its trials were
    restricted to its classes."""

    group: PlanGroup
    best: Evaluation | None
    best_achievable: Evaluation | None
    shapes: list[str]
    best_shape: str | None
    best_label: str | None
    trials: int
    protocols: int
    restricted: bool
    truth_runs: int


@dataclass(frozen=True)
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
    shapes: dict[str, ShapeOutcome]
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
    #: the sub-plans of a separable plan (empty: a whole-test plan)
    groups: list[GroupOutcome] = field(default_factory=list)
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
    def undetermined(self) -> Evaluation | None:
        """Where no protocol met every requirement: the cheapest protocol of any shape whose
        verdict was still undetermined when its search's trial budget was spent (its
        ``n_to_settle``: the trials that would settle it); None otherwise."""
        if self.recommended is not None:
            return None
        cands = [s.undetermined for s in self.shapes.values() if s.undetermined is not None]
        return min(cands, key=lambda e: e.cost_s) if cands else None

    @property
    def confirmed(self) -> bool:
        """The re-validation met every requirement too."""
        return self.validation is not None and self.validation.met

    @property
    def sure(self) -> float:
        """Bonferroni bound over the requirements of the re-validation's sureness."""
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
        s = self.shapes.get(self.recommended.shape)
        b = None if s is None else s.boundary
        if b is None or not b.cost_s > 0:
            return None
        return {"sure": self.sure_level, "factor": self.recommended.cost_s / b.cost_s,
                "boundary_cost_s": b.cost_s, "boundary_knobs": dict(b.knobs),
                "model_factor": b.model_sure_cost_s / b.cost_s}

    def _groups_premium(self) -> dict | None:
        """A separable plan's premium: lab time being additive over the groups, the boundary
        protocol is the recommendation with each group's part replaced by its boundary
        protocol's (the fitted model's, in the group's chosen shape); a group with no knob to
        search (every knob fixed or cost-flat, or none changes its classes) has no other
        protocol, so its boundary is its answer."""
        rec = self.recommended
        bound, model, knobs = rec.cost_s, rec.cost_s, dict(rec.knobs)
        for go in self.groups:
            s = self.shapes[go.best_shape]
            if s.model is None:  # nothing searched: the answer is the only protocol
                continue
            b = s.boundary
            if b is None:
                return None
            bound -= go.best.cost_s - b.cost_s
            model -= go.best.cost_s - b.model_sure_cost_s
            knobs.update(b.knobs)
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
                f"lab time {lab_time_text(self.recommended.cost_s)}.\n")
        return head + self.study.scenario_text(self.recommended.scenario)

    def answer(self) -> str:
        """The plan's answer in one paragraph (what the report and the command print first)."""
        return answer_text(self)

    def sentences(self) -> list[str]:
        return findings_sentences(self)

    def to_json(self) -> dict:
        return plan_json(self)

    def to_dataframe(self):
        """Every protocol run, tidy (pandas): shape, stage, knobs, cost, trials, requirement,
        quantile (+ se), bound, met, bias (+ se), sd (+ se), sure."""
        import pandas as pd  # heavy, and only this view needs it

        rows = []
        for e in self.evaluations + ([self.fresh_run] if self.fresh_run is not None else []):
            for name, f in e.figures.items():
                rows.append({"shape": e.shape, "stage": e.stage,
                             **{k.rsplit('.', 1)[-1]: v for k, v in e.knobs.items()},
                             "cost_h": e.cost_s / SECONDS_PER_HOUR, "trials": e.trials, "seed": e.seed, "requirement": name,
                             **{k: f[k] for k in ("quantile", "se_quantile", "bound", "met", "bias", "se_bias", "sd",
                                                  "se_sd", "sure")}})
        return pd.DataFrame(rows)

    def write_report(self, out_dir):
        return write_plan_report(self, out_dir)

    def __repr__(self) -> str:
        return f"<PlanResult {self.study.name}: {self.answer()}>"

    def _repr_html_(self) -> str:
        return (f"<div><p><strong>{html.escape(self.study.title)}</strong>: plan</p>"
                f"{markdown_to_html(summary_markdown(self))}</div>")


# ---------------------------------------------------------------------- the JSON
def _evaluation_summary(e: Evaluation | None) -> dict | None:
    return None if e is None else {"shape": e.shape, "knobs": dict(e.knobs), "cost_s": e.cost_s,
                                   "met": e.met, "ratio": e.ratio}


def _groups_json(res: PlanResult) -> list[dict]:
    """The sub-plans (a plan that does not decompose: one, every requirement, knob and shape)."""
    n = res.trials_per_validation
    if not res.groups:
        free = [k.field for k in res.knobs if k.field not in (res.fixed or {})]
        return [{"name": ",".join(dict.fromkeys(r.cls for r in res.requirements)),
                 "classes": list(dict.fromkeys(r.cls for r in res.requirements)),
                 "requirements": [r.text for r in res.requirements], "knobs": free,
                 "shape_fields": sorted({f for s in res.shapes.values() for f in s.overrides}),
                 "shapes": {k: [k] for k in res.shapes}, "restricted": False, "feasible": res.feasible,
                 "best_shape": None if res.recommended is None else res.recommended.shape,
                 "best": _evaluation_summary(res.recommended),
                 "best_achievable": _evaluation_summary(res.best_achievable),
                 "trials": res.search_trials, "validations": res.search_trials / n,
                 "protocols": len(res.evaluations)}]
    out = []
    for go in res.groups:
        g = go.group
        out.append({"name": g.name, "classes": list(g.classes), "requirements": [r.text for r in g.requirements],
                    "knobs": [k.field for k in g.knobs], "shape_fields": list(g.shape_fields),
                    "shapes": {k: list(v) for k, v in g.members.items()}, "restricted": go.restricted,
                    "feasible": go.best is not None, "best_shape": go.best_shape,
                    "best": _evaluation_summary(go.best), "best_achievable": _evaluation_summary(go.best_achievable),
                    "trials": go.trials, "validations": go.trials / n, "protocols": go.protocols})
    return out


def _shape_json(s: ShapeOutcome) -> dict:
    return {"overrides": s.overrides, "trials": s.trials, "refused": [r.to_json() for r in s.refused],
            "model": None if s.model is None else s.model.to_json(), "protocols": len(s.evaluations),
            "best": None if s.best is None else s.best.to_json(),
            "best_achievable": None if s.best_achievable is None else s.best_achievable.to_json()}


def plan_json(res: PlanResult) -> dict:
    """The plan as JSON (schema ``budget.plan/1``; docs/planning.md, "Output")."""
    st = res.study
    return {
        "schema": SCHEMA, "study": st.name, "title": st.title, "version": __version__,
        "scenario_name": getattr(res.scenario, "name", None), "scenario_hash": st.scenario_hash(res.scenario),
        "seed": res.seed, "validation_seed": validation_seed(res.seed), "confidence": res.confidence,
        "variant": res.variant, "budget_hours": res.budget_hours,
        "requirements": [{"class": r.cls, "axis": r.axis, "value": r.value, "unit": r.unit, "text": r.text}
                         for r in res.requirements],
        "knobs": [{"field": k.field, "kind": k.kind, "low": k.low, "high": k.high, "unit": k.unit,
                   "description": k.description} for k in res.knobs],
        "fixed": dict(res.fixed or {}),
        "flat_knobs": [k.field for k in res.flat],
        "feasible": res.feasible, "confirmed": res.confirmed,
        "sure": None if res.validation is None else res.sure,
        "sure_level": res.sure_level, "premium": res.premium,
        "answer": answer_text(res), "findings": findings_sentences(res),
        "recommended": None if res.recommended is None else {
            **res.recommended.to_json(), "scenario_hash": st.scenario_hash(res.recommended.scenario),
            "scenario_toml": res.recommended_toml()},
        "validation": None if res.validation is None else res.validation.to_json(),
        "best_achievable": None if res.best_achievable is None else res.best_achievable.to_json(),
        "undetermined": None if res.undetermined is None else {
            **res.undetermined.to_json(), "n_to_settle": res.undetermined.n_to_settle},
        "shapes": {name: _shape_json(s) for name, s in res.shapes.items()},
        "evaluations": [e.to_json() for e in res.evaluations],
        "best_achievable_revalidated": res.best_achievable_revalidated,
        "trials": {"per_validation": res.trials_per_validation, "search": res.search_trials,
                   "validation": 0 if res.fresh_run is None else res.fresh_run.trials,
                   "total": res.total_trials},
        "truths_computed": res.truth_runs, "elapsed_s": res.elapsed_s, "cpu_s": res.cpu_s,
        "groups": _groups_json(res), "unsearched_knobs": [k.field for k in res.unsearched],
        "over_budget": bool(res.over_budget),
    }
