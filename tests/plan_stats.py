"""The sampling statistics the planner's tests derive their tolerances from (independent of
budget.runner.plan's own formulas)."""

from __future__ import annotations

import math

from scipy import stats


def quantile_rel_se(n: int, c: float) -> float:
    """Relative standard error of the sample c-quantile of |e|, e ~ N(0, s^2): the asymptotic
    sqrt(c (1 - c) / n) / f(q) with f(q) = 2 phi(z) / s the density of |e| at q = z s."""
    z = stats.norm.ppf(0.5 + c / 2)
    return math.sqrt(c * (1 - c) / n) / (2 * stats.norm.pdf(z) * z)
