"""Plan a test before booking the lab: the cheapest protocol (the knobs and shapes a study
declares) whose estimates meet the required accuracy, re-validated on fresh trials
(``budget <study> plan``, :func:`budget.plan`; how it works: docs/planning.md).

Modules: :mod:`.requirements` (``--require``, ``--fix``), :mod:`.quantiles` (the statistics of
a requirement's errors), :mod:`.trials` (trial counts and seeds), :mod:`.protocols` (a
protocol as a scenario, cost-flat knobs), :mod:`.oracle` (runs a candidate), :mod:`.search`
(the search of each shape), :mod:`.separable` (independent sub-plans and their union),
:mod:`.planner` (:func:`plan_protocol`), :mod:`.result` (what a plan hands back, its JSON),
:mod:`.report` (its words, report and figure), :mod:`.text` (how it writes lab time and
knobs), :mod:`.cli` (the command).
"""

from __future__ import annotations

from budget.runner.plan.cli import has_knobs, plan_command_for
from budget.runner.plan.planner import check_estimated, plan_joint, plan_protocol
from budget.runner.plan.protocols import cost_flat_knobs, dotted_value, scenario_with
from budget.runner.plan.quantiles import (DEFAULT_SURE, figures_of, prediction_bound, quantile_rel_se,
                                          requirement_tolerance, requirement_verdict, sure_margin, sure_met,
                                          verdict_confidence)
from budget.runner.plan.report import answer_text, findings_sentences, summary_markdown, write_plan_report
from budget.runner.plan.requirements import (DEFAULT_CONFIDENCE, Requirement, default_variant, parse_fixes,
                                             parse_requirements)
from budget.runner.plan.result import (FRESH_STAGES, REVALIDATED_BEST, SCHEMA, Boundary, Evaluation, GroupOutcome,
                                       ModelCurve, PlanGroup, PlanResult, Refusal, ShapeOutcome, plan_json)
from budget.runner.plan.search import PlanRun, ShapeSearch, resolution
from budget.runner.plan.separable import collapsed_labels, decompose, plan_separable, union_protocol
from budget.runner.plan.trials import (BUDGET_VALIDATIONS, DECIDED, VALIDATION_SPAWN_KEY, screening_trials,
                                       validation_seed)

__all__ = ["BUDGET_VALIDATIONS", "DECIDED", "DEFAULT_CONFIDENCE", "DEFAULT_SURE", "FRESH_STAGES", "REVALIDATED_BEST",
           "SCHEMA", "VALIDATION_SPAWN_KEY", "Boundary", "Evaluation", "GroupOutcome", "ModelCurve", "PlanGroup",
           "PlanResult", "PlanRun", "Refusal", "Requirement", "ShapeOutcome", "ShapeSearch", "answer_text",
           "check_estimated", "collapsed_labels", "cost_flat_knobs", "decompose", "default_variant", "dotted_value",
           "figures_of", "findings_sentences", "has_knobs", "parse_fixes", "parse_requirements", "plan_command_for",
           "plan_joint", "plan_json", "plan_protocol", "plan_separable", "prediction_bound", "quantile_rel_se",
           "requirement_tolerance", "requirement_verdict", "resolution", "scenario_with", "screening_trials",
           "summary_markdown", "sure_margin", "sure_met", "union_protocol", "validation_seed", "verdict_confidence",
           "write_plan_report"]
