"""The statistics of a requirement's errors over trials: the C-quantile of ``|error|`` and its
standard error, the verdict on the requirement (:func:`requirement_verdict`: the claims' rule,
:func:`budget.runner.verdicts.judge`, on the quantile), how sure a bound is met, the
prediction bound of the quantile a re-validation will measure, and the margin the search
steers by (derivations: docs/planning.md, "Deciding a requirement", "Honest verdict" and
"How sure the answer is")."""

from __future__ import annotations

import math

import numpy as np

from budget.runner.verdicts import Tolerance, Verdict, judge

# scipy is imported inside the functions that use it: it is heavy (scipy.stats alone takes longer to
# import than matplotlib), and `budget <study> --help` imports this package to build the plan command

__all__ = ["DEFAULT_SURE", "figures_of", "prediction_bound", "quantile_rank", "quantile_rel_se",
           "requirement_tolerance", "requirement_verdict", "smooth_ratio", "sure_margin", "sure_met",
           "verdict_confidence"]

#: how sure the search wants to be that a protocol meets a requirement (the verdict's one-sided level): the
#: default ``--sure``
DEFAULT_SURE = 0.9
#: slack below ``C n`` before its ceiling: ``C n`` a whole number in exact arithmetic stays that rank
RANK_SLACK = 1e-9
#: the fewest trials for the quantile's Maritz-Jarrett standard error (NaN below)
MIN_TRIALS_FOR_SE = 3
#: Gauss-Hermite nodes of the average over the truth's own uncertainty (exact for polynomials of degree
#: 13 in its shift); chosen empirically: more nodes resolve the step-wise exceedance count finer, each
#: costing one beta distribution function
TRUTH_NODES = 7
#: the upper end of the root search for the normal fit's quantile, in standard deviations beyond the
#: bias: its coverage there is 1 within 1e-23, beyond any confidence a plan accepts
SEARCH_SDS = 10.0


def quantile_rank(n: int, confidence: float) -> int:
    """1-based rank of the C-quantile order statistic of ``n`` values: ``ceil(C n)`` (>= 1)."""
    return max(1, min(n, math.ceil(confidence * n - RANK_SLACK)))


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
    verdict on ``n`` trials to hold (:func:`requirement_verdict`; a normal error): ``1 + z_P
    r_n``, ``r_n`` :func:`quantile_rel_se`, ``z_P`` the upper edge of the verdict's interval.
    The search steers by it; the measured verdict decides."""
    if sure is None or sure <= 0.5:
        return 1.0
    from scipy import stats

    return 1.0 + float(stats.norm.ppf(sure)) * quantile_rel_se(trials, confidence)


def verdict_confidence(sure: float) -> float:
    """The two-sided confidence of the verdict's interval whose upper edge is the one-sided
    ``sure`` bound: ``2 P - 1`` (0.8 at the default 0.9; 0.95, the claims' level, at 0.975)."""
    return 2.0 * sure - 1.0


def requirement_tolerance(value: float) -> Tolerance:
    """The requirement ``CLASS.AXIS<=VALUE`` as the verdict's tolerance on the quantile."""
    return Tolerance.at_most(value, reason="the requirement", source="user")


def requirement_verdict(q: float, se: float, n: int, value: float, sure: float) -> Verdict | None:
    """The verdict (:func:`budget.runner.verdicts.judge`) on the C-quantile ``q`` of ``n`` trials
    with standard error ``se`` against the requirement ``<= value``: holds when its ``sure``
    one-sided upper bound ``q + z_P se`` is within, fails when its lower ``q - z_P se`` is
    beyond, else undetermined with the trials that would settle it. None where ``sure <= 0.5``
    (the point decides: the boundary protocol) or the standard error is not finite."""
    if sure <= 0.5 or not math.isfinite(se):
        return None
    return judge(q, se, n, requirement_tolerance(value), confidence=verdict_confidence(sure), quantity="the quantile")


def prediction_bound(q: float, se_q: float, n: int, n_future: int, truth_se: float, sure: float) -> float:
    """One-sided ``sure`` upper prediction bound of the C-quantile the re-validation will
    measure: ``q + z_P sqrt(se_q^2 (1 + n / n_future) + 2 truth_se^2)`` (docs/planning.md,
    "How sure the answer is")."""
    if sure <= 0.5:
        return q
    if not math.isfinite(se_q):
        return math.inf
    from scipy import stats

    z = float(stats.norm.ppf(sure))
    return q + z * math.sqrt(se_q**2 * (1.0 + n / n_future) + 2.0 * truth_se**2)


def figures_of(err: np.ndarray, value: float, confidence: float, truth_se: float = 0.0, *,
               sure: float | None = None, n_future: int | None = None) -> dict:
    """What ``err`` (errors of one requirement's key over trials) says about the bound
    ``value``: the C-quantile of ``|err|`` and its standard error (Maritz-Jarrett: the order
    statistics weighted by the quantile's beta distribution), exceedances, bias and spread
    with their standard errors, and how sure the bound is met (:func:`sure_met`, averaged
    over the truth's standard error ``truth_se``). ``sure``: the search's rule,
    :func:`requirement_verdict` on the quantile with its standard error and the truth's
    (``verdict``: holds, fails or undetermined; ``met`` when it holds; ``upper``: its interval's
    upper edge; ``n_to_settle``: the trials that would settle an undetermined one) and, for the
    reader, the ``sure`` :func:`prediction_bound` of the quantile a re-validation of
    ``n_future`` trials (default ``n``) will measure (``prediction``); None: ``met`` when the
    quantile itself is within (the re-validation's rule)."""
    from scipy.stats import mstats

    e = np.asarray(err, dtype=float)
    n = e.size
    a = np.sort(np.abs(e))
    q = float(a[quantile_rank(n, confidence) - 1])
    se_q = float(mstats.mjci(a, prob=[confidence])[0]) if n >= MIN_TRIALS_FOR_SE else float("nan")
    exceed = int(np.count_nonzero(a > value))
    sure_p = _sure_over_truth(e, value, confidence, truth_se) if truth_se > 0 else sure_met(exceed, n, confidence)
    sd = float(e.std(ddof=1)) if n > 1 else 0.0
    judged = {} if sure is None else _judged(q, se_q, n, value, truth_se, sure, n_future or n)
    met = judged["verdict"] == "holds" if judged else bool(q <= value)
    return {"quantile": q, "se_quantile": se_q, "bound": float(value), "n": int(n),
            "exceed": exceed, "allowed": int(n - quantile_rank(n, confidence)), "met": met,
            "sure": sure_p, **judged,
            "bias": float(e.mean()), "se_bias": float(math.sqrt(sd**2 / n + truth_se**2)), "sd": sd,
            "se_sd": sd / math.sqrt(2.0 * max(n - 1, 1)), "truth_se": float(truth_se)}


def _judged(q: float, se_q: float, n: int, value: float, truth_se: float, sure: float, n_future: int) -> dict:
    """The search's figures of :func:`figures_of`: the verdict on the quantile (its standard
    error with the truth's), its interval's upper edge and the trials to settle it."""
    se = math.sqrt(se_q**2 + truth_se**2) if math.isfinite(se_q) else se_q
    v = requirement_verdict(q, se, n, value, sure)
    if v is None:  # the point decides (sure <= 0.5), or no standard error (too few trials)
        outcome = ("holds" if q <= value else "fails") if sure <= 0.5 else "undetermined"
        return {"verdict": outcome, "upper": q if sure <= 0.5 else math.inf, "upper_sure": float(sure),
                "n_to_settle": None, "prediction": prediction_bound(q, se_q, n, n_future, truth_se, sure)}
    settle = v.n_to_settle if v.outcome == "undetermined" else None
    return {"verdict": v.outcome, "upper": float(v.high), "upper_sure": float(sure),
            "n_to_settle": None if settle is None else int(settle),
            "prediction": prediction_bound(q, se_q, n, n_future, truth_se, sure)}


def _sure_over_truth(e: np.ndarray, value: float, confidence: float, truth_se: float) -> float:
    """:func:`sure_met` averaged over a truth shifted by its standard error (Gauss-Hermite)."""
    x, w = np.polynomial.hermite_e.hermegauss(TRUTH_NODES)  # over N(0, 1)
    w = w / w.sum()
    return float(sum(wi * sure_met(int(np.count_nonzero(np.abs(e - xi * truth_se) > value)), e.size, confidence)
                     for xi, wi in zip(x, w)))


def smooth_ratio(figures: dict[str, dict], confidence: float) -> float:
    """Worst ratio of a requirement's C-quantile to its bound over ``figures`` (an evaluation's),
    the quantile that of ``|b + s Z|`` (``b``, ``s``: the errors' mean and sd, ``Z`` standard
    normal): on a screening run's few trials far steadier than the order statistic, so the
    cost-flat search compares settings by their accuracy rather than by the noise of one order
    statistic."""
    from scipy import optimize, stats

    worst = 0.0
    for f in figures.values():
        b, sd = abs(f["bias"]), max(f["sd"], 0.0)
        if sd <= 0.0:
            q = b
        else:
            def cover(q, b=b, sd=sd):
                return stats.norm.cdf((q - b) / sd) - stats.norm.cdf((-q - b) / sd) - confidence

            q = optimize.brentq(cover, 0.0, b + SEARCH_SDS * sd)
        worst = max(worst, q / f["bound"])
    return worst
