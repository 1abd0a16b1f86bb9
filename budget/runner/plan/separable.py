"""Separable plans: the requirements split into independent sub-plans (:func:`decompose`, by
the study's :meth:`~budget.runner.capabilities.SeparablePlans.field_classes`), each searched on its own, and their answers put
together into one protocol (:func:`union_protocol`) and run on fresh seeds
(:func:`plan_separable`; docs/planning.md, "Separable plans")."""

from __future__ import annotations

import dataclasses
from typing import Any

from budget.runner.capabilities import ProtocolShapes, SeparablePlans, capability
from budget.runner.plan.protocols import dotted_value, knob_value, lab_time, scenario_with
from budget.runner.plan.result import REVALIDATED_BEST, Evaluation, GroupOutcome, PlanGroup, PlanResult
from budget.runner.plan.search import PlanRun
from budget.runner.study import Knob, Study

__all__ = ["collapsed_labels", "decompose", "plan_separable", "union_protocol"]

_UNSET = object()


def decompose(study: Study, scenario: Any, reqs, knobs, shapes: dict[str, dict], fixed: dict | None = None
              ) -> tuple[list[PlanGroup], tuple[Knob, ...]]:
    """The plan's independent sub-plans and the knobs no requirement depends on.

    A graph links each required class to every free knob field and shape field that can change
    it (:meth:`~budget.runner.capabilities.SeparablePlans.field_classes`; a field not listed can change every class); its connected
    components over the required classes are the groups (in the order of the requirements).
    A knob that changes no required class is not searched (it stays at the scenario's value,
    or its ``--fix`` value); a group's shapes are the declared shapes projected on the group's
    shape fields, those with equal projections collapsed into one (searched once)."""
    fixed = dict(fixed or {})
    fc = {f: tuple(c) for f, c in (capability(study, SeparablePlans).field_classes(scenario) or {}).items()}
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
        gshapes, members = _group_shapes(shapes, gf)
        groups.append(PlanGroup(",".join(cls), cls, [r for r in reqs if r.cls in cls], gk, gf, gshapes, members))
    searched = {k.field for g in groups for k in g.knobs}
    unsearched = tuple(k for k in free if k.field not in searched)
    return groups, unsearched


def _group_shapes(shapes: dict[str, dict], gf: tuple) -> tuple[dict, dict]:
    """A group's shapes: the declared ``shapes`` projected on its shape fields ``gf``, equal
    projections collapsed into one (labelled by :func:`collapsed_labels`): label -> overrides,
    and label -> the declared members."""
    proj: dict[tuple, list[str]] = {}
    for name, ov in shapes.items():
        key = tuple((f, repr(ov.get(f, _UNSET)) if f in ov else "<unset>") for f in gf)
        proj.setdefault(key, []).append(name)
    gshapes, members = {}, {}
    labels = collapsed_labels(list(proj.values()), gf, shapes)
    for names, label in zip(proj.values(), labels):
        ov = {f: shapes[names[0]][f] for f in gf if f in shapes[names[0]]}
        gshapes[label], members[label] = ov, list(names)
    return gshapes, members


def collapsed_labels(projs: list[list[str]], gf: tuple, shapes: dict) -> list[str]:
    """A label per collapsed shape of one group, by what its declared members share
    (docs/planning.md, "Separable plans"): one member keeps its name; several, the
    comma-separated parts of the name common to every member ("diagonal" for "diagonal, filters
    500/600" and "diagonal, filters 600/800"), else the group's shape fields' values ("pattern
    diagonal"); a group no shape field touches (one collapsed shape of every declared one) is
    "(any)". Labels are unique within the group and hold no "|" (a markdown cell); the JSON
    keeps the members."""
    if len(projs) == 1 and len(projs[0]) > 1 and not gf:
        return ["(any)"]

    def common(names):
        parts = [[p.strip() for p in n.split(",")] for n in names]
        return ", ".join(p for p in parts[0] if p and all(p in q for q in parts[1:]))

    last = [f.rsplit(".", 1)[-1] for f in gf]
    # "pattern", or the field where two share it
    short = {f: (s if last.count(s) == 1 else f) for f, s in zip(gf, last)}

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


def _search_group(run: PlanRun, g: PlanGroup, several: bool) -> tuple[GroupOutcome, dict, list[Evaluation]]:
    """Group ``g`` searched on its own: its requirements, its classes only where the study can
    restrict, its own trial budget per shape, common random numbers within it; with several
    groups the budget is checked on their union instead. Returns its outcome, its shapes'
    outcomes (by their keys in the plan) and every protocol it ran."""
    oracle = run.oracle(g.requirements, restrict=g.classes, group=g.name if several else None)
    gres = run.search_shapes(oracle, g.shapes, g.knobs, None if several else run.budget_s,
                             key=lambda sname: g.key(sname, several))
    gres = {k: dataclasses.replace(s, members=list(g.members[sname]), group=g.name)
            for sname, (k, s) in zip(g.shapes, gres.items())}
    bests = [s.best for s in gres.values() if s.best is not None]
    best = min(bests, key=lambda e: e.cost_s) if bests else None
    ach = None
    if best is None:
        cands = [s.best_achievable for s in gres.values() if s.best_achievable is not None]
        ach = min(cands, key=lambda e: e.ratio) if cands else None
    label = None if best is None else next(sn for sn in g.shapes if gres[g.key(sn, several)].best is best)
    out = GroupOutcome(group=g, best=best, best_achievable=ach, shapes=list(gres),
                       best_shape=None if best is None else g.key(label, several), best_label=label,
                       trials=oracle.trials_run, protocols=len(oracle.evaluations), restricted=oracle.restricted,
                       truth_runs=oracle.truth_runs)
    return out, gres, oracle.evaluations


def plan_separable(run: PlanRun) -> PlanResult:
    """The separable plan: each group searched on its own (:func:`_search_group`), the union of
    the answers run as one protocol on fresh seeds: the recommendation's re-validation, or (a
    group infeasible, or the union over the budget) the best achievable's."""
    declared = capability(run.study, ProtocolShapes).protocol_shapes(run.scenario) or {"scenario": {}}
    groups, unsearched = decompose(run.study, run.scenario, run.reqs, run.knobs, declared, run.fixed)
    several = len(groups) > 1
    results: dict = {}
    group_out: list[GroupOutcome] = []
    evaluations: list[Evaluation] = []
    for g in groups:
        go, gres, evs = _search_group(run, g, several)
        results.update(gres)
        group_out.append(go)
        evaluations += evs
    search_trials = sum(go.trials for go in group_out)
    truth_runs = sum(go.truth_runs for go in group_out)
    rec = validation = best_ach = None
    over_budget = False
    # each group's part: its answer, else its most accurate protocol (None: none could be run)
    parts = [go.best if go.best is not None else go.best_achievable for go in group_out]
    if any(p is not None for p in parts):
        union = union_protocol(run, declared, groups, parts, several)
        feasible = all(go.best is not None for go in group_out)
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


def union_protocol(run: PlanRun, declared: dict[str, dict], groups: list[PlanGroup], parts: list,
                   several: bool) -> Evaluation:
    """Every group's part (its answer, or its most accurate protocol) in one protocol: the parts'
    knobs, every other knob at the scenario's value (those no requirement depends on, and a group's
    that has no part) or its ``--fix`` value; among the declared shapes that agree with every
    part's shape fields, those keeping the scenario's own values of the other shape fields (no
    requirement depends on them; :meth:`~budget.runner.capabilities.ProtocolShapes.shape_value`) first, then the cheapest (a declared
    shape the scenario model refuses is skipped); where none agrees, the parts' shape fields
    together. Its figures are the parts' (search) figures; its cost the full lab time."""
    study, scenario = run.study, run.scenario
    vals = {k.field: knob_value(k, dotted_value(scenario, k.field)) for k in run.knobs}
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
    shape, scn = _union_shape(run, declared, vals, members, fields, picks, names)
    items = {k: float(v) for k, v in study.lab_time_s(scn).items()}
    figs, errs, tse = {}, {}, {}
    for part in parts:
        if part is not None:
            figs.update(part.figures)
            errs.update(part.errors)
            tse.update(part.truth_se)
    knob_vals = {k.field: vals[k.field] for k in run.knobs}
    # its trials: the parts' (a part settled near its bound ran more than a validation's)
    trials = max((p.trials for p in parts if p is not None), default=run.n)
    return Evaluation(shape, knob_vals, float(sum(items.values())), items, run.seed, trials, figs, "search", scn,
                      errs, tse)


def _union_shape(run: PlanRun, declared: dict[str, dict], vals: dict, members: set, fields: set, picks: dict,
                 names: list[str]) -> tuple[str, Any]:
    """The union's shape and scenario (:func:`union_protocol`): the declared ``members`` that
    agree with every part, fewest changed fields no requirement depends on first, then the
    cheapest; where none does, the parts' shape fields ``picks`` together (named by ``names``)."""
    study, scenario = run.study, run.scenario
    where = "plan: the recommended protocol"
    costed = []
    for name in (n for n in declared if n in members):
        try:
            scn = scenario_with(study, scenario, {**declared[name], **vals}, where=where)
        except ValueError:
            continue  # the scenario model refuses this combination of fields no requirement depends on
        changed = sum(capability(study, ProtocolShapes).shape_value(scn, f) != capability(study, ProtocolShapes).shape_value(scenario, f)
                      for f in declared[name] if f not in fields)
        costed.append((changed, lab_time(study, scn), name, scn))
    if costed:
        _, _, shape, scn = min(costed, key=lambda t: t[:2])
        return shape, scn
    return "+".join(dict.fromkeys(names)), scenario_with(study, scenario, {**picks, **vals}, where=where)
