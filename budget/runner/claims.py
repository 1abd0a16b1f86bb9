"""The claims ledger: what a study's source document claims, and what the simulation says of it.

A study declares the claims of its source document (:class:`Claim`, through the
:class:`budget.runner.capabilities.Claims` capability); :func:`evaluate_claims` judges each
claim from runs already made (:class:`budget.runner.result.StudyResult`, nothing is run here)
in two worlds, with the one rule of :mod:`budget.runner.verdicts`, and :func:`ledger_markdown`
writes the ledger as a table: the paper's figure beside ours, the verdict in words.

Kinds of claim (:data:`KINDS`), and what is judged:

``method``
    a method's claim to measure a quantity: the bias of the variant's estimate against the
    class's truth (mean estimate less truth, with its standard error and trials,
    :func:`budget.runner.stats.key_statistics`), against a tolerance about 0 whose width the
    claim's :class:`ToleranceRule` takes relative to the truth;
``performance``
    an instrument's figure: the simulated instrument's truth of the class (with its Monte
    Carlo standard error) against the paper's figure, the tolerance about the figure;
``bound``
    a combination or bound: the truth at or below the paper's figure (one-sided; the figure
    plus the rule's slack).

A claim the simulation cannot test names no class and carries ``untestable`` (one line: why);
its results have no verdict. So has a method claim on a reference variant (one that
estimates nothing, :attr:`budget.runner.study.Study.reference_variants`) or on an input
class: :attr:`ClaimResult.no_verdict` says why.

Worlds (:data:`WORLDS`): ``"seed"``, the seed's own world, is the ideal world (every
``[world.effects]`` magnitude 0) of the scenario the claim names; ``"realistic"`` is that
scenario as given (the embedded defaults are the realistic world). A study without world
effects has one world, which serves as both. :func:`world_scenario` builds each scenario and
:func:`ledger_runs` lists the runs a ledger needs. The rule and the ledger's kinds are
derived in ``docs/claims.md``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from budget.runner.capabilities import Claims, capability
from budget.runner.findings import unit_prose
from budget.runner.numbers import fmt
from budget.runner.verdicts import (
    DEFAULT_CONFIDENCE,
    SOURCES,
    Tolerance,
    Verdict,
    judge,
)
from simcam.effects import scenario_effects
from simcam.infra.errors import ScenarioError, UserInputError

if TYPE_CHECKING:
    from budget.runner.result import StudyResult
    from budget.runner.study import Study

__all__ = ["KINDS", "NOT_RUN_HERE", "WORLDS", "WORLD_LABELS", "Claim", "ClaimResult", "ToleranceRule",
           "evaluate_claims", "evaluate_run", "ledger_markdown", "ledger_runs", "paper_figure", "run_worlds",
           "study_claims", "verdict_words", "world_scenario"]

#: what a claim states (module docstring)
KINDS = ("method", "performance", "bound")
#: the worlds a claim is judged in (module docstring)
WORLDS = ("seed", "realistic")
#: how a report names each world
WORLD_LABELS = {"seed": "seed's own world", "realistic": "realistic world"}
#: a ledger's cell for a world the run did not simulate (a validate report)
NOT_RUN_HERE = "not run here: `budget claims` runs both"


def _one_line(value: Any) -> bool:
    return isinstance(value, str) and bool(value.strip()) and "\n" not in value


@dataclass(frozen=True)
class ToleranceRule:
    """How wide a claim's tolerance is, and why, before the reference value is known.

    The half-width is ``max(relative |reference|, absolute)`` in the claim's unit, the
    reference the truth for a ``method`` claim and the paper's figure otherwise; a ``bound``
    claim's tolerance is every value up to the figure plus that half-width.

    Parameters
    ----------
    reason : str
        One line: why this tolerance ("10 % of the truth").
    source : {"paper", "user", "default"}
        The paper's stated bound, a user's requirement, or a declared default.
    relative : float
        Fraction of the reference (0.1: 10 %).
    absolute : float
        A floor in the claim's unit.
    """

    reason: str
    source: str = "default"
    relative: float = 0.0
    absolute: float = 0.0

    def __post_init__(self) -> None:
        if not _one_line(self.reason):
            raise ValueError(f"tolerance reason: one line saying why, got {self.reason!r}")
        if self.source not in SOURCES:
            raise ValueError(f"tolerance source: one of {SOURCES}, got {self.source!r}")
        for name in ("relative", "absolute"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v >= 0):
                raise ValueError(f"tolerance {name}: a finite number >= 0, got {v!r}")

    def half_width(self, reference: float) -> float:
        """``max(relative |reference|, absolute)``."""
        return max(self.relative * abs(reference), self.absolute)

    def resolve(self, kind: str, *, figure: float | None, truth: float | None) -> Tolerance:
        """The tolerance of a claim of ``kind`` (:data:`KINDS`) with the paper's ``figure``
        and the simulation's ``truth``."""
        ref = truth if kind == "method" else figure
        if ref is None or not math.isfinite(ref):
            raise ValueError(f"tolerance: a {kind} claim needs a finite "
                             f"{'truth' if kind == 'method' else 'figure'}, got {ref!r}")
        w = self.half_width(ref)
        if kind == "bound":
            return Tolerance.at_most(ref + w, reason=self.reason, source=self.source)
        if not w > 0:
            raise ValueError(f"tolerance: {self.relative:g} of a zero reference is no tolerance: give an absolute one")
        return Tolerance.around(0.0 if kind == "method" else ref, w, reason=self.reason, source=self.source)


@dataclass(frozen=True)
class Claim:
    """One claim of a study's source document (module docstring).

    Parameters
    ----------
    id : str
        Unique within the study ("te.x.performance").
    words : str
        The paper's claim in one line.
    figures : tuple of float
        The paper's figure(s), in ``unit`` (one for a testable performance or bound claim;
        a method claim may quote the figure the paper measured with it).
    unit : str
        The figures' unit; for a testable claim the unit of the study's class.
    axis : str
        The axis of the figure (the study's axis for a testable claim; "x, y" for a pair).
    condition : str
        Under what the paper states it ("30 frames, the paper's camera").
    section : str
        Where in the source document ("eqs 1-2, section 2").
    kind : {"method", "performance", "bound"}
    scenario : str
        The scenario whose two worlds judge it ("embedded:seed000_noisy"); "" if untestable.
    class_name : str or None
        The study's class it maps to; None if untestable.
    variant : str or None
        The variant whose estimate a method claim judges; None for the other kinds.
    tolerance : ToleranceRule or None
        Its tolerance rule; None if untestable.
    untestable : str or None
        One line: why the simulation cannot test it (then nothing is mapped).
    """

    id: str
    words: str
    figures: tuple[float, ...]
    unit: str
    axis: str
    condition: str
    section: str
    kind: str
    scenario: str = ""
    class_name: str | None = None
    variant: str | None = None
    tolerance: ToleranceRule | None = None
    untestable: str | None = None

    def __post_init__(self) -> None:
        if not _one_line(self.id):
            raise ValueError(f"claim id: a non-empty one-line name, got {self.id!r}")
        where = f"claim {self.id!r}"
        for name in ("words", "unit", "axis", "section"):
            if not _one_line(getattr(self, name)):
                raise ValueError(f"{where}: {name}: one non-empty line, got {getattr(self, name)!r}")
        if not isinstance(self.condition, str) or "\n" in self.condition:
            raise ValueError(f"{where}: condition: one line, got {self.condition!r}")
        if self.kind not in KINDS:
            raise ValueError(f"{where}: kind: one of {KINDS}, got {self.kind!r}")
        if not isinstance(self.figures, tuple) or not all(
                isinstance(f, (int, float)) and not isinstance(f, bool) and math.isfinite(f) for f in self.figures):
            raise ValueError(f"{where}: figures: a tuple of finite numbers, got {self.figures!r}")
        if self.untestable is not None:
            if not _one_line(self.untestable):
                raise ValueError(f"{where}: untestable: one line saying why, got {self.untestable!r}")
            if self.class_name is not None or self.variant is not None or self.tolerance is not None or self.scenario:
                raise ValueError(f"{where}: untestable: an untestable claim names no scenario, class, variant "
                                 "or tolerance")
            return
        self._check_testable(where)

    def _check_testable(self, where: str) -> None:
        if not _one_line(self.scenario):
            raise ValueError(f"{where}: scenario: the scenario whose worlds judge it (or give untestable)")
        if not _one_line(self.class_name):
            raise ValueError(f"{where}: class_name: the study's class it maps to (or give untestable)")
        if not isinstance(self.tolerance, ToleranceRule):
            raise ValueError(f"{where}: tolerance: a ToleranceRule with its reason (or give untestable)")
        if self.kind == "method":
            if not _one_line(self.variant):
                raise ValueError(f"{where}: variant: a method claim names the variant whose estimate is judged")
        else:
            if self.variant is not None:
                raise ValueError(f"{where}: variant: a {self.kind} claim judges the truth, which has no variant")
            if len(self.figures) != 1:
                raise ValueError(f"{where}: figures: a {self.kind} claim compares one figure, got {self.figures!r}")

    @property
    def testable(self) -> bool:
        """Whether the simulation judges it (no ``untestable`` reason)."""
        return self.untestable is None


@dataclass(frozen=True)
class ClaimResult:
    """What one world's run says of one claim.

    Attributes
    ----------
    claim : Claim
    world : {"seed", "realistic"}
    verdict : Verdict or None
        None for an untestable claim, a reference variant or an input class.
    no_verdict : str
        Why there is no verdict ("" when there is one).
    truth, truth_se : float or None
        The class's truth in this world and its standard error.
    mean : float or None
        A method claim's mean estimate.
    trials : int or None
        The run's trials.
    """

    claim: Claim
    world: str
    verdict: Verdict | None
    no_verdict: str = ""
    truth: float | None = None
    truth_se: float | None = None
    mean: float | None = None
    trials: int | None = None

    def __post_init__(self) -> None:
        if self.world not in WORLDS:
            raise ValueError(f"world: one of {WORLDS}, got {self.world!r}")
        if (self.verdict is None) == (not self.no_verdict):
            raise ValueError(f"claim {self.claim.id!r}: a result has a verdict or says why not (no_verdict), "
                             "never both or neither")

    @property
    def ours(self) -> str:
        """The simulation's answer in a few words: a method claim's estimate against its truth
        and the bias; the truth with its standard error otherwise; "-" without numbers."""
        if self.claim.kind == "method" and self.mean is not None and self.truth is not None:
            bias = self.mean - self.truth
            s = f"{fmt(self.mean)} vs truth {fmt(self.truth)}: bias {fmt(bias, sign=True)}"
            if self.verdict is not None:
                s += f" +- {fmt(self.verdict.se)}"
            if self.truth != 0:
                s += f" ({100 * bias / abs(self.truth):+.1f} %)"
            return s
        if self.truth is not None:  # a truth without sampling error has no "+- 0"
            return f"{fmt(self.truth)} +- {fmt(self.truth_se)}" if self.truth_se else fmt(self.truth)
        return "-"

    @property
    def sentence(self) -> str:
        """The verdict's sentence (:attr:`Verdict.sentence`), or why there is none."""
        return self.verdict.sentence if self.verdict is not None else f"no verdict: {self.no_verdict}"


def study_claims(study: Study, scenario: Any) -> tuple[Claim, ...]:
    """The claims ``study`` declares for ``scenario`` (none without :class:`Claims`), their
    ids checked unique."""
    claims = tuple(capability(study, Claims).claims(scenario))
    _check_unique(claims)
    return claims


def _check_unique(claims) -> None:
    seen: set[str] = set()
    for c in claims:
        if not isinstance(c, Claim):
            raise ValueError(f"claims: Claim objects, got {type(c).__name__}")
        if c.id in seen:
            raise ValueError(f"claims: id {c.id!r} given twice")
        seen.add(c.id)


def ledger_runs(claims) -> tuple[tuple[str, str], ...]:
    """The runs ``(scenario, world)`` that :func:`evaluate_claims` needs for ``claims``, in
    the order the claims first name them."""
    out: dict[tuple[str, str], None] = {}
    for c in claims:
        if c.testable:
            for w in WORLDS:
                out[(c.scenario, w)] = None
    return tuple(out)


def world_scenario(study: Study, scenario: Any, world: str) -> Any:
    """``scenario`` in ``world``: itself for ``"realistic"`` (and for a study without world
    effects, or with every effect already off), its ideal world (every ``world.effects``
    magnitude 0) for ``"seed"``."""
    if world not in WORLDS:
        raise ValueError(f"world: one of {WORLDS}, got {world!r}")
    effects = scenario_effects(scenario)
    if world == "realistic" or effects is None or not effects.active():
        return scenario
    data = scenario.model_dump(mode="json", exclude_none=True)
    data.setdefault("world", {})["effects"] = effects.ideal().magnitudes()
    return study.from_dict(data, source=f"{getattr(scenario, 'source', 'scenario')} (the seed's own world)")


def _content(scenario: Any) -> Any:
    """What a scenario simulates: its content less the Monte Carlo settings and its name."""
    return scenario.model_dump(mode="json", exclude={"validation", "name"})


def run_worlds(study: Study, claims, scenario: Any) -> dict[str, tuple[str, ...]]:
    """``{claim scenario: worlds}``: which worlds of which of ``claims``' scenarios
    ``scenario`` is (its content, the Monte Carlo settings aside); a study without world
    effects is both worlds of its scenario at once."""
    runs = ledger_runs(claims)
    if not runs:
        return {}
    here = _content(scenario)
    out: dict[str, tuple[str, ...]] = {}
    for name, world in runs:
        try:
            named = study.load_scenario(name)
        except (UserInputError, ScenarioError, OSError):  # a name this study cannot load: not this run
            continue
        if _content(world_scenario(study, named, world)) == here:
            out[name] = out.get(name, ()) + (world,)
    return out


def evaluate_run(study: Study, claims, result: StudyResult, *,
                 confidence: float = DEFAULT_CONFIDENCE) -> tuple[ClaimResult, ...]:
    """The claims of ``claims`` whose scenario ``result`` ran (:func:`run_worlds`), judged in
    the world(s) it ran; the other world has no result (:data:`NOT_RUN_HERE` in the table)."""
    claims = tuple(claims)
    _check_unique(claims)
    worlds = run_worlds(study, claims, result.scenario)
    out = []
    for c in claims:
        for world in worlds.get(c.scenario, ()) if c.testable else ():
            out.append(_evaluate(c, world, result, confidence))
    return tuple(out)


def evaluate_claims(claims, runs: Mapping[tuple[str, str], StudyResult], *,
                    confidence: float = DEFAULT_CONFIDENCE) -> tuple[ClaimResult, ...]:
    """A :class:`ClaimResult` per claim and world (:data:`WORLDS` order), judged from
    ``runs[(claim.scenario, world)]`` (:func:`ledger_runs`); nothing is run. A missing run, a
    seed's-world run with a world effect on, or a claim naming what the run lacks is a
    ValueError naming it."""
    claims = tuple(claims)
    _check_unique(claims)
    for (scn, world), res in runs.items():
        eff = scenario_effects(res.scenario)
        if world == "seed" and eff is not None and eff.active():
            raise ValueError(f"runs[{scn!r}, 'seed']: the seed's own world has every world effect off; "
                             f"this run has {', '.join(eff.active())} on")
    out = []
    for c in claims:
        for world in WORLDS:
            if not c.testable:
                out.append(ClaimResult(c, world, None, f"untestable: {c.untestable}"))
                continue
            if (c.scenario, world) not in runs:
                raise ValueError(f"claim {c.id!r}: no run of {c.scenario} in the {WORLD_LABELS[world]} "
                                 f"(runs[{c.scenario!r}, {world!r}])")
            out.append(_evaluate(c, world, runs[(c.scenario, world)], confidence))
    return tuple(out)


def _evaluate(c: Claim, world: str, result: StudyResult, confidence: float) -> ClaimResult:
    where = f"claim {c.id!r}, {WORLD_LABELS[world]}"
    try:
        spec = result.class_spec(c.class_name)
    except KeyError:
        raise ValueError(f"{where}: class_name: the run has no class {c.class_name!r}") from None
    if c.axis not in spec.axes:
        raise ValueError(f"{where}: axis: class {c.class_name!r} has axes {spec.axes}, not {c.axis!r}")
    if c.unit != spec.unit:
        raise ValueError(f"{where}: unit: {c.unit!r} is not the class's unit {spec.unit!r}")
    unit = unit_prose(c.unit)
    if c.kind == "method":
        key = (c.class_name, c.variant, c.axis)
        if key not in result.samples:
            raise ValueError(f"{where}: variant: the run has no estimates of {key}")
        st = result.statistics(key)
        numbers = dict(truth=st["truth"], truth_se=st.get("truth_se"), mean=st["mean"], trials=st["n"])
        if c.variant in result.study.reference_variants:
            return ClaimResult(c, world, None, "a reference variant: it estimates nothing", **numbers)
        if spec.role == "input":
            return ClaimResult(c, world, None, "an input of the method, taken as given", **numbers)
        tol = c.tolerance.resolve(c.kind, figure=None, truth=st["truth"])
        v = judge(st["bias"], st["se_bias"], st["n"], tol, confidence=confidence, unit=unit, quantity="the bias")
        return ClaimResult(c, world, v, **numbers)
    value, se, n = _truth(c, result, where)
    tol = c.tolerance.resolve(c.kind, figure=c.figures[0], truth=value)
    v = judge(value, se, n, tol, confidence=confidence, unit=unit, quantity="the truth")
    return ClaimResult(c, world, v, truth=value, truth_se=se, trials=result.trials)


def _truth(c: Claim, result: StudyResult, where: str) -> tuple[float, float, int | None]:
    """The class's truth on the claim's axis: a fixed truth with its Monte Carlo standard
    error (its samples are not the run's trials: n None), or the mean of per-trial truths
    with ``sd / sqrt(n)`` over the run's n trials (and the standard error a combination of
    fixed truths carries, :mod:`budget.runner.combined_truths`, in quadrature)."""
    t = result.truths.get((c.class_name, c.axis))
    if t is not None:
        return float(t.value), float(t.se), None
    for key, arr in result.trial_truths.items():
        if key[0] == c.class_name and key[2] == c.axis:
            a = [float(v) for v in arr]
            n = len(a)
            mean = sum(a) / n
            sd = math.sqrt(sum((v - mean) ** 2 for v in a) / (n - 1)) if n > 1 else 0.0
            shared = float(result.trial_truth_se.get(key, 0.0))  # what combined fixed truths carry
            return mean, math.sqrt(sd**2 / n + shared**2), n
    raise ValueError(f"{where}: the run has no truth of {c.class_name!r} on axis {c.axis!r}")


# ---------------------------------------------------------------------------- the table
def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def paper_figure(c: Claim) -> str:
    """The paper's figure(s) of ``c`` in words, with the unit."""
    figs = " / ".join(fmt(f) for f in c.figures)
    unit = unit_prose(c.unit)
    if c.kind == "method":
        return "its estimate equals the truth" + (f" (the paper measured {figs} {unit} with it)" if figs else "")
    if c.kind == "bound" and c.testable:
        return f"at most {figs} {unit}"
    return f"{figs} {unit}"


def verdict_words(seed: ClaimResult | None, real: ClaimResult | None) -> str:
    """Both worlds' verdicts in words, with the tolerance and what would settle an
    undetermined one."""
    pair = [(w, r) for w, r in (("seed", seed), ("realistic", real)) if r is not None]
    judged = [(w, r) for w, r in pair if r.verdict is not None]
    if not judged:
        reasons = {r.no_verdict for _, r in pair}
        return "; ".join(sorted(reasons)) or "-"
    outcomes = {r.verdict.outcome for _, r in judged}
    if len(judged) == len(WORLDS) and len(outcomes) == 1:
        s = f"{outcomes.pop()} in both worlds"
    else:
        s = ", ".join(f"{r.verdict.outcome if r.verdict else 'no verdict (' + r.no_verdict + ')'} in the "
                      f"{WORLD_LABELS[w]}" for w, r in pair)
    same = len(judged) == 2 and judged[0][1].verdict == judged[1][1].verdict  # one run served both worlds
    for w, r in judged[:1] if same else judged:
        v = r.verdict
        w_ = "both worlds (one run)" if same else WORLD_LABELS[w]
        if v.outcome == "undetermined":
            s += (f"; {w_}: on the tolerance's edge, no number of trials settles it" if v.on_edge
                  else f"; {w_}: about {v.n_to_settle} trials would settle it" if v.n_to_settle
                  else f"; {w_}: about {fmt(v.growth_to_settle, 2)} times the truth's samples "
                       "would settle it")
    tols = {r.verdict.tolerance.describe() for _, r in judged}
    first = judged[0][1].verdict.tolerance
    s += f" (tolerance {tols.pop()}: {first.reason})" if len(tols) == 1 else f" (tolerance: {first.reason})"
    return s


def ledger_markdown(results) -> str:
    """The ledger as a Markdown table, one row per claim in the order given: the claim, the
    paper's figure, ours in the seed's own world and in the realistic world, the verdict in
    words (:class:`ClaimResult`; its unit is the paper column's)."""
    rows: dict[str, dict[str, ClaimResult]] = {}
    claims: dict[str, Claim] = {}
    for r in results:
        claims.setdefault(r.claim.id, r.claim)
        rows.setdefault(r.claim.id, {})[r.world] = r
    lines = ["| claim | paper's figure | ours (seed's own world) | ours (realistic world) | verdict |",
             "|---|---|---|---|---|"]
    for cid, by_world in rows.items():
        c = claims[cid]
        seed, real = by_world.get("seed"), by_world.get("realistic")
        if c.testable:
            verdict = verdict_words(seed, real)
            ours = [r.ours if r is not None else NOT_RUN_HERE for r in (seed, real)]
        else:
            verdict, ours = f"untestable: {c.untestable}", ["-", "-"]
        head = f"{c.words} ({c.kind}, {c.axis}; {c.section})"
        lines.append("| " + " | ".join(_cell(t) for t in (head, paper_figure(c), *ours, verdict)) + " |")
    return "\n".join(lines)
