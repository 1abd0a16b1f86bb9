"""Statistics of a validation: what the trials say about an estimator against its truth.

For each key ``(class, variant, axis)`` with estimates ``x_k`` (k = 1..n):

* fixed truth ``T`` with its Monte Carlo standard error ``s_T`` (:meth:`Study.truths`):
  bias ``b = mean(x) - T``, its standard error ``sqrt(s^2 / n + s_T^2)`` with ``s`` the
  sample standard deviation of the estimates (the truth's own sampling error enters the
  significance test: a truth from few frames must not make a bias "significant");
* per-trial truths ``T_k`` (an error drawn per trial): the errors ``e_k = x_k - T_k``,
  bias ``mean(e)``, standard error ``sqrt(sd(e)^2 / n + s_T^2)``, rms error
  ``sqrt(mean(e^2))``, with ``s_T`` the standard error the truths share (0, or what a
  combination of fixed truths carries: :mod:`budget.runner.combined_truths`);
* spread: the sample standard deviation of the estimates (of the errors for per-trial
  truths), with the standard error ``s / sqrt(2 (n - 1))`` (normal approximation);
* a bias is *significant* when ``|b| > 3`` standard errors (the runner also asks it to
  exceed the class's numerical floor, :mod:`budget.runner.findings`);
* the bias in percent of the truth only where the truth is far from zero against its
  spread: a fixed truth beyond 3 ``s_T``; per-trial truths all of one sign, or their mean
  beyond 2 sd of them (``truth_sd``); a percentage of a truth near zero says nothing;
* coverage, where the estimator states a 1-sigma uncertainty ``u_k``: the fraction of trials
  with ``|e_k| <= u_k`` (expected 0.6827) and ``<= 2 u_k`` (expected 0.9545), each with its
  binomial standard error, and the sd of ``e_k / u_k`` (1 when the stated uncertainty is
  right).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["key_statistics", "converged"]

#: a truth below this (in the class's unit) is zero to rounding: no relative bias
_ZERO_TRUTH = 1e-9


def key_statistics(estimates, *, truth: float | None = None, truth_se: float = 0.0,
                   trial_truths=None, sigmas=None) -> dict:
    """Statistics of one key (see the module docstring); ``truth`` or ``trial_truths``."""
    x = np.asarray(estimates, dtype=float)
    n = x.size
    if trial_truths is not None:
        t = np.asarray(trial_truths, dtype=float)
        e = x - t
        truth_value = float(t.mean())
        bias = float(e.mean())
        spread = float(e.std(ddof=1)) if n > 1 else 0.0
        se_bias = math.sqrt(spread**2 / n + truth_se**2)
        truth_spread = float(t.std(ddof=1)) if n > 1 else 0.0
        # truths of one sign (an rms, a stage count) are far from zero whatever their spread
        if np.all(t > 0) or np.all(t < 0):
            truth_spread = 0.0
        else:
            truth_spread *= 2.0 / 3.0  # else the mean beyond 2 sd of the trials' truths
        extra = {"rms_error": float(math.sqrt(np.mean(e * e))), "truth_se": float(truth_se),
                 "truth_sd": float(t.std(ddof=1)) if n > 1 else 0.0, "per_trial_truth": True}
    else:
        e = x - truth
        truth_value = float(truth)
        mean = float(x.mean())
        bias = mean - truth_value
        spread = float(x.std(ddof=1)) if n > 1 else 0.0
        se_bias = math.sqrt(spread**2 / n + truth_se**2)
        truth_spread = float(truth_se)
        extra = {"truth_se": float(truth_se), "per_trial_truth": False}
    q = np.quantile(x, [0.025, 0.16, 0.84, 0.975])
    out = {
        "n": int(n), "truth": truth_value, "mean": float(x.mean()), "bias": bias,
        # a percentage only where the truth is far from zero against its own spread (the
        # trials' truths' sd, or a fixed truth's standard error): 3 of them
        "bias_percent": (100.0 * bias / abs(truth_value)
                         if abs(truth_value) > max(_ZERO_TRUTH, 3.0 * truth_spread)
                         else (0.0 if abs(bias) <= 1e-12 and abs(truth_value) <= _ZERO_TRUTH else float("nan"))),
        "se_bias": se_bias, "std": spread,
        "se_std": spread / math.sqrt(2 * (n - 1)) if n > 1 else float("inf"),
        "bias_significant": bool(abs(bias) > 3.0 * se_bias) if se_bias > 0 else bool(abs(bias) > 0),
        "interval_68": [float(q[1]), float(q[2])], "interval_95": [float(q[0]), float(q[3])],
        "truth_in_95": bool(q[0] <= truth_value <= q[3]),
        **extra,
    }
    if sigmas is not None:
        u = np.asarray(sigmas, dtype=float)
        ok = np.isfinite(u) & (u > 0)
        if ok.any():
            z = e[ok] / u[ok]
            m = int(ok.sum())
            c1 = float(np.mean(np.abs(z) <= 1.0))
            c2 = float(np.mean(np.abs(z) <= 2.0))
            out["coverage"] = {
                "n": m, "within_1sigma": c1, "within_2sigma": c2,
                "se_1sigma": math.sqrt(0.6827 * 0.3173 / m), "se_2sigma": math.sqrt(0.9545 * 0.0455 / m),
                "expected_1sigma": 0.6827, "expected_2sigma": 0.9545,
                "sd_normalised_error": float(z.std(ddof=1)) if m > 1 else float("nan"),
                "mean_stated_sigma": float(u[ok].mean()),
            }
    return out


def converged(samples: dict, trial_truths: dict, tolerance: float, *, min_trials: int = 10) -> bool:
    """Adaptive stopping (JCGM 101:2008, 7.9): every bias and spread standard error below ``tolerance``."""
    for key, x in samples.items():
        x = np.asarray(x, dtype=float)
        n = x.size
        if n < min_trials:
            return False
        if key in trial_truths:
            x = x - np.asarray(trial_truths[key], dtype=float)
        s = float(x.std(ddof=1))
        if s / math.sqrt(n) > tolerance or s / math.sqrt(2 * (n - 1)) > tolerance:
            return False
    return True
