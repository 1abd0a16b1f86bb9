"""What one run of one study gives: :class:`StudyResult`, its statistics and its faces.

A :class:`StudyResult` holds the trials' values in trial order, the truths and how the run
went (:func:`budget.runner.run.run_study` builds it). It gives

* the statistics of each ``(class, variant, axis)`` (:meth:`StudyResult.statistics`,
  :func:`budget.runner.stats.key_statistics` annotated by :func:`budget.runner.findings.annotate`);
* the JSON payload, schema ``budget.study-result/1`` (:meth:`StudyResult.to_json`:
  ``classes[class][axis][variant]`` holds the statistics, ``class_info[class]`` the label,
  unit and description, ``details`` the study's own figures, :meth:`~budget.runner.capabilities.Presented.details`, empty
  for most studies), built once per result: what ``budget <study> validate --json`` writes,
  the report's ``summary.json`` and ``budget.validate(...).to_json()`` are the same payload;
* a short ``repr``, a notebook view (``_repr_html_``: the findings and the table) and a
  tidy table (:meth:`StudyResult.to_dataframe`).

The report itself is :func:`budget.runner.report.write_report`.
"""

from __future__ import annotations

import copy
import html
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from budget.runner.capabilities import Presented, capability
from budget.runner.combined_truths import combined_trial_truths
from budget.runner.findings import annotate, findings_json, findings_markdown
from budget.runner.html import markdown_to_html
from budget.runner.report import format_table
from budget.runner.stats import key_statistics
from budget.runner.study import ClassSpec, Key, Study, TrialResult, Truth
from simcam import __version__
from simcam.effects import scenario_effects

__all__ = ["SCHEMA", "STATISTICS", "StudyResult"]

SCHEMA = "budget.study-result/1"
#: the numeric statistics of each key in :meth:`StudyResult.to_dataframe`, in its order
STATISTICS = ("n", "truth", "truth_se", "truth_sd", "mean", "bias", "bias_percent", "se_bias", "std", "se_std",
              "rms_error")
#: the coverage figures of a key with stated sigmas in :meth:`StudyResult.to_dataframe`
_COVERAGE = ("within_1sigma", "within_2sigma", "se_1sigma", "sd_normalised_error", "mean_stated_sigma")


@dataclass(frozen=True)
class StudyResult:
    """Trials, truths and statistics of one run of one study."""

    study: Study
    scenario: Any
    seed: int
    trials: int
    stopped_by: str
    classes: tuple[ClassSpec, ...]
    truths: dict[tuple[str, str], Truth]
    samples: dict[Key, np.ndarray]
    trial_truths: dict[Key, np.ndarray] = field(default_factory=dict)
    sigmas: dict[Key, np.ndarray] = field(default_factory=dict)
    example: TrialResult | None = None
    elapsed_s: float = float("nan")
    executor: str = ""
    #: per-trial scalars of :attr:`TrialResult.aux`, in trial order
    aux: dict[str, np.ndarray] = field(default_factory=dict)
    #: how the truths were sized: "adaptive", "fixed" or "given" (computed before the run)
    truth_size: str = "fixed"
    #: the standard error a per-trial truth carries from fixed truths it combines, by key
    #: (:func:`budget.runner.combined_truths.combined_trial_truths`, applied when built: its
    #: combined classes are in :attr:`trial_truths` too)
    trial_truth_se: dict[Key, float] = field(default_factory=dict, init=False)

    def __post_init__(self) -> None:
        tt, se = combined_trial_truths(self.classes, self.truths, self.samples, self.trial_truths)
        object.__setattr__(self, "trial_truths", tt)
        object.__setattr__(self, "trial_truth_se", se)

    def __repr__(self) -> str:
        """One short line: study, scenario, trials, and the recommendation (the samples are in
        :attr:`samples`)."""
        f = findings_json(self)
        name = getattr(self.scenario, "name", "") or ""
        return (f"<StudyResult {self.study.name}: scenario {name!r}, seed {self.seed}, {self.trials} trials "
                f"({self.stopped_by}), {len(self.keys())} keys; {f['recommendation'] or ''}>")

    def _repr_html_(self) -> str:
        """For notebooks: the header, the findings and the table (no figures)."""
        f = findings_json(self)
        name = getattr(self.scenario, "name", "") or ""
        head = (f"<p><strong>{html.escape(self.study.title)}</strong>: scenario <code>{html.escape(name)}</code>, "
                f"seed {self.seed}, {self.trials} trials (stopped by {html.escape(self.stopped_by)})</p>")
        return (f"<div>{head}<details open><summary>Findings</summary>"
                f"{markdown_to_html(chr(10).join(findings_markdown(self, f)))}</details>"
                f"<details><summary>Table</summary><pre>{html.escape(format_table(self))}</pre></details></div>")

    def to_dataframe(self):
        """Tidy statistics (pandas): one row per (class, axis, variant, statistic) with its
        value and unit; :data:`STATISTICS`, ``bias_significant`` as 0 or 1, and the coverage
        figures as ``coverage_within_1sigma`` etc.; the findings' rule, not numeric, is left
        to :func:`budget.runner.findings.findings_json`."""
        import pandas as pd  # heavy, and only this face needs it

        rows = []
        for key in self.keys():
            cls, var, ax = key
            st = self.statistics(key)
            unit = self.class_spec(cls).unit
            unit = "" if unit.strip() in ("1", "-") else unit  # dimensionless
            for name in STATISTICS:
                if name in st:
                    rows.append((cls, ax, var, name, float(st[name]), unit))
            rows.append((cls, ax, var, "bias_significant", float(bool(st["bias_significant"])), ""))
            for name in _COVERAGE:
                if "coverage" in st and name in st["coverage"]:
                    rows.append((cls, ax, var, f"coverage_{name}", float(st["coverage"][name]),
                                 unit if name == "mean_stated_sigma" else ""))
        return pd.DataFrame(rows, columns=["class", "axis", "variant", "statistic", "value", "unit"])

    def details(self) -> dict:
        """:meth:`~budget.runner.capabilities.Presented.details` of this result (computed once: the JSON and the report share it)."""
        return self._study_details

    @cached_property
    def _study_details(self) -> dict:
        return capability(self.study, Presented).details(self)

    def class_spec(self, name: str) -> ClassSpec:
        """The :class:`ClassSpec` called ``name``."""
        for c in self.classes:
            if c.name == name:
                return c
        raise KeyError(name)

    def keys(self) -> list[Key]:
        """Every (class, variant, axis) with estimates, in the study's class order."""
        order = {c.name: i for i, c in enumerate(self.classes)}
        var = {v: i for i, v in enumerate(self.study.variants)}
        return sorted(self.samples, key=lambda k: (order.get(k[0], 999), k[2], var.get(k[1], 999), k[1]))

    def statistics(self, key: Key) -> dict:
        """:func:`key_statistics` of one key, with its role and the findings' annotations
        (:func:`budget.runner.findings.annotate`: numerical floor, reference variant,
        undetermined axis)."""
        cls, var, ax = key
        if key in self.trial_truths:
            st = key_statistics(self.samples[key], trial_truths=self.trial_truths[key],
                                truth_se=self.trial_truth_se.get(key, 0.0), sigmas=self.sigmas.get(key))
        else:
            t = self.truths[(cls, ax)]
            st = key_statistics(self.samples[key], truth=t.value, truth_se=t.se, sigmas=self.sigmas.get(key))
        role = self.class_spec(cls).role if cls in {c.name for c in self.classes} else "result"
        st["role"] = role
        if role == "input":
            # given to the method, not measured by it: nothing to validate
            st.update(bias_percent=float("nan"), bias_significant=False)
        return annotate(self, key, st)

    def summary(self) -> dict:
        """``{class: {axis: {variant: statistics}}}``."""
        out: dict = {}
        for key in self.keys():
            cls, var, ax = key
            out.setdefault(cls, {}).setdefault(ax, {})[var] = self.statistics(key)
        return out

    def to_json(self) -> dict:
        """The JSON payload (schema ``budget.study-result/1``; module docstring), a copy of the
        one built for this result (a caller may change its copy)."""
        return copy.deepcopy(self._payload)

    @cached_property
    def _payload(self) -> dict:
        s = self.summary()
        info = {c.name: {"label": c.label, "unit": c.unit, "description": c.description,
                         "per_trial_truth": c.per_trial_truth, "axes": list(c.axes), "role": c.role}
                for c in self.classes if c.name in s}
        details = self.details()
        f = findings_json(self)
        effects = scenario_effects(self.scenario)
        return {
            "schema": SCHEMA, "study": self.study.name, "title": self.study.title,
            "seed_document": self.study.seed_document, "version": __version__,
            "scenario_name": getattr(self.scenario, "name", None),
            "world_effects_on": None if effects is None else list(effects.active()),
            "scenario_hash": self.study.scenario_hash(self.scenario),
            "scenario_toml": self.study.scenario_text(self.scenario),
            "seed": self.seed, "trials": self.trials, "stopped_by": self.stopped_by,
            "truth_size": self.truth_size,
            "variants": list(self.study.variants),
            "truths": {f"{c}.{a}": {"value": t.value, "se": t.se,
                                    **{k: v for k, v in t.details.items() if isinstance(v, (int, float, str, bool))}}
                       for (c, a), t in self.truths.items()},
            "class_info": info,
            "classes": s,
            "details": details,
            "findings": f["findings"],
            "findings_summary": {"variants": f["variants"], "recommendation": f["recommendation"]},
            "elapsed_s": self.elapsed_s, "executor": self.executor,
        }
