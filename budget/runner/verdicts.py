"""The one rule that turns a quantity and its uncertainty into a verdict on a claim.

A claim is judged on one quantity (a bias, a truth, a residual) known by its point estimate
``x``, its standard error ``s`` and the number ``n`` of trials behind it, against a
:class:`Tolerance`: an interval of acceptable values with its reason (the paper's stated
bound, a user's requirement, or a declared default such as 10 % of the truth).
:func:`judge` forms the two-sided confidence interval ``x -+ z s`` at a stated confidence
``c`` (default 95 %, ``z`` the normal quantile of ``(1 + c) / 2``) and says

``holds``
    the whole interval lies inside the tolerance (edges included);
``fails``
    the whole interval lies outside it (beyond one edge);
``undetermined``
    the interval straddles an edge; the :class:`Verdict` then carries the number of trials
    that would settle it, ``n (z s / d)^2`` with ``d`` the distance of the estimate to the
    nearest edge (the interval shrinks as ``1 / sqrt(n)``), or says that no number of trials
    settles it when the estimate sits on the edge (``d = 0``).

A one-sided claim ("at most X") has a tolerance with one infinite edge
(:meth:`Tolerance.at_most`, :meth:`Tolerance.at_least`). The distance of the estimate from
the value the claim states, in standard errors (:attr:`Verdict.significance_se`), is reported
as a number only: it never decides. Each verdict's sentence (:attr:`Verdict.sentence`) is
built from its own numbers, so it cannot contradict them.

A quantity that estimates nothing (a reference variant,
:attr:`budget.runner.study.Study.reference_variants`) has no verdict: the caller does not call
:func:`judge` for it and records ``None`` with its reason
(:class:`budget.runner.claims.ClaimResult` does, in ``no_verdict``).

The derivation (the interval's coverage, the trials to settle, why more trials turn a
verdict from one decision to the other only at the error rate) is in ``docs/claims.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist

from budget.runner.numbers import fmt

__all__ = ["DEFAULT_CONFIDENCE", "OUTCOMES", "SOURCES", "Tolerance", "Verdict", "judge", "z_for"]

#: what a verdict can say
OUTCOMES = ("holds", "fails", "undetermined")
#: where a tolerance comes from: the paper's stated bound, a user's requirement, a declared default
SOURCES = ("paper", "user", "default")
#: the confidence of the interval a verdict is read from (two-sided)
DEFAULT_CONFIDENCE = 0.95


def z_for(confidence: float) -> float:
    """The normal quantile ``z`` of a two-sided interval of ``confidence``: ``x -+ z s``
    covers the true value with that probability (1.96 for 95 %)."""
    if not (isinstance(confidence, (int, float)) and 0.0 < confidence < 1.0):
        raise ValueError(f"confidence: a probability strictly between 0 and 1, got {confidence!r}")
    return NormalDist().inv_cdf(0.5 + confidence / 2.0)


def _finite_or_inf(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: a number, got {value!r}") from None
    if math.isnan(v):
        raise ValueError(f"{name}: a number, got NaN")
    return v


@dataclass(frozen=True)
class Tolerance:
    """The acceptable values of a judged quantity, ``low <= value <= high``, with its reason.

    Parameters
    ----------
    low, high : float
        The edges, in the quantity's unit; one may be infinite (a one-sided claim), not both.
    reason : str
        Why this tolerance, in one line ("10 % of the paper's figure, at least 0.1 arcsec").
    source : {"paper", "user", "default"}
        The paper's stated bound, a user's requirement, or a declared default.
    target : float or None
        The value the claim states (the centre of :meth:`around`); the verdict reports its
        distance from it in standard errors. None for a bound.
    """

    low: float
    high: float
    reason: str
    source: str
    target: float | None = None

    def __post_init__(self) -> None:
        low, high = _finite_or_inf("tolerance low", self.low), _finite_or_inf("tolerance high", self.high)
        if not low < high:
            raise ValueError(f"tolerance: low ({fmt(low)}) must be below high ({fmt(high)})")
        if math.isinf(low) and math.isinf(high):
            raise ValueError("tolerance: at least one edge must be finite")
        if not isinstance(self.reason, str) or not self.reason.strip() or "\n" in self.reason:
            raise ValueError(f"tolerance reason: one line saying why, got {self.reason!r}")
        if self.source not in SOURCES:
            raise ValueError(f"tolerance source: one of {SOURCES}, got {self.source!r}")
        if self.target is not None:
            t = _finite_or_inf("tolerance target", self.target)
            if not (math.isfinite(t) and low <= t <= high):
                raise ValueError(f"tolerance target: a finite value inside [{fmt(low)}, {fmt(high)}], "
                                 f"got {self.target!r}")

    @classmethod
    def around(cls, target: float, half_width: float, *, reason: str, source: str) -> Tolerance:
        """``target -+ half_width`` (a two-sided claim)."""
        w = _finite_or_inf("tolerance half_width", half_width)
        if not (math.isfinite(w) and w > 0):
            raise ValueError(f"tolerance half_width: a finite number above 0, got {half_width!r}")
        t = _finite_or_inf("tolerance target", target)
        return cls(t - w, t + w, reason, source, t)

    @classmethod
    def at_most(cls, bound: float, *, reason: str, source: str) -> Tolerance:
        """Every value up to ``bound`` (a one-sided claim: "at most X")."""
        return cls(-math.inf, bound, reason, source)

    @classmethod
    def at_least(cls, bound: float, *, reason: str, source: str) -> Tolerance:
        """Every value from ``bound`` up (a one-sided claim: "at least X")."""
        return cls(bound, math.inf, reason, source)

    @property
    def edges(self) -> tuple[float, ...]:
        """The finite edges."""
        return tuple(e for e in (self.low, self.high) if math.isfinite(e))

    def describe(self, unit: str = "") -> str:
        """The interval in words: ``"1.026 to 1.254 arcsec"``, ``"at most 0.56 arcsec"``."""
        u = f" {unit}" if unit else ""
        if math.isinf(self.low):
            return f"at most {fmt(self.high)}{u}"
        if math.isinf(self.high):
            return f"at least {fmt(self.low)}{u}"
        return f"{fmt(self.low)} to {fmt(self.high)}{u}"


@dataclass(frozen=True)
class Verdict:
    """What :func:`judge` says of one quantity against its tolerance (module docstring).

    Attributes
    ----------
    outcome : {"holds", "fails", "undetermined"}
    estimate, se : float
        The judged quantity's point estimate and standard error.
    n : int or None
        The trials behind the standard error (None: not a count of trials, e.g. a truth's
        own sampling; the trials to settle are then given as a growth factor only).
    tolerance : Tolerance
    confidence : float
        Of the two-sided interval ``low .. high``.
    low, high : float
        The confidence interval ``estimate -+ z se``.
    on_edge : bool
        The estimate sits on an edge of the tolerance with a non-zero standard error: no
        number of trials settles it.
    growth_to_settle : float or None
        For an undetermined verdict off the edge: by how many times the trials must grow
        for the interval to clear the nearest edge, ``(z se / d)^2``; None otherwise.
    n_to_settle : int or None
        ``ceil(n growth_to_settle)`` where ``n`` is known; None otherwise.
    unit : str
        The quantity's unit, as the sentence writes it.
    quantity : str
        What is judged, as the sentence names it ("the bias", "the truth").
    """

    outcome: str
    estimate: float
    se: float
    n: int | None
    tolerance: Tolerance
    confidence: float
    low: float
    high: float
    on_edge: bool
    growth_to_settle: float | None
    n_to_settle: int | None
    unit: str = ""
    quantity: str = "the estimate"

    @property
    def significance_se(self) -> float:
        """``(estimate - target) / se``: how many standard errors the estimate lies from the
        value the claim states (NaN without a target or with a zero standard error). A
        number for the reader, never the verdict."""
        t = self.tolerance.target
        if t is None or not self.se > 0:
            return float("nan")
        return (self.estimate - t) / self.se

    @property
    def sentence(self) -> str:
        """The verdict in one sentence, every number in it taken from the verdict."""
        u = f" {self.unit}" if self.unit else ""
        pct = f"{100 * self.confidence:g} %"
        trials = f", {self.n} trials" if self.n is not None else ""
        interval = (f"{self.quantity} {fmt(self.estimate)} +- {fmt(self.se)}{u}{trials} "
                    f"({pct} interval {fmt(self.low)} to {fmt(self.high)})")
        tol = f"the tolerance, {self.tolerance.describe(self.unit)} ({self.tolerance.reason})"
        if self.outcome == "holds":
            s = f"holds: {interval} lies wholly inside {tol}"
        elif self.outcome == "fails":
            side = "above" if self.low > self.tolerance.high else "below"
            s = f"fails: {interval} lies wholly {side} {tol}"
        else:
            edge = self._nearest_edge()
            s = f"undetermined: {interval} straddles the edge {fmt(edge)}{u} of {tol}"
            if self.on_edge:
                s += "; the estimate sits on that edge, so no number of trials settles it"
            elif self.n_to_settle is not None:
                s += f"; about {self.n_to_settle} trials would settle it"
            else:
                s += f"; about {fmt(self.growth_to_settle, 2)} times its samples would settle it"
        z = self.significance_se
        if math.isfinite(z):
            s += f" ({fmt(z, 2, sign=True)} standard errors from {fmt(self.tolerance.target)}{u})"
        return s

    def _nearest_edge(self) -> float:
        return min(self.tolerance.edges, key=lambda e: abs(self.estimate - e))


def judge(estimate: float, se: float, n: int | None, tolerance: Tolerance, *,
          confidence: float = DEFAULT_CONFIDENCE, unit: str = "", quantity: str = "the estimate") -> Verdict:
    """The verdict on a quantity with point estimate ``estimate``, standard error ``se`` and
    ``n`` trials behind it (None where its samples are not trials) against ``tolerance``
    (module docstring). A NaN or infinite estimate, a negative or NaN standard error or a
    count below 1 is a ValueError naming it."""
    x = _finite_or_inf("estimate", estimate)
    if not math.isfinite(x):
        raise ValueError(f"estimate: a finite number, got {estimate!r}")
    s = _finite_or_inf("se", se)
    if not (math.isfinite(s) and s >= 0):
        raise ValueError(f"se: a finite standard error >= 0, got {se!r}")
    if n is not None and (isinstance(n, bool) or not isinstance(n, int) or n < 1):
        raise ValueError(f"n: a whole number of trials >= 1 (or None), got {n!r}")
    if not isinstance(tolerance, Tolerance):
        raise ValueError(f"tolerance: a Tolerance, got {type(tolerance).__name__}")
    z = z_for(confidence)
    low, high = x - z * s, x + z * s
    on_edge, growth, n_settle = False, None, None
    if tolerance.low <= low and high <= tolerance.high:
        outcome = "holds"
    elif low > tolerance.high or high < tolerance.low:
        outcome = "fails"
    else:
        outcome = "undetermined"
        d = min(abs(x - e) for e in tolerance.edges)
        if d == 0.0:
            on_edge = True
        else:
            growth = (z * s / d) ** 2
            n_settle = math.ceil(n * growth) if n is not None else None
    return Verdict(outcome, x, s, n, tolerance, float(confidence), low, high, on_edge, growth, n_settle,
                   unit, quantity)
