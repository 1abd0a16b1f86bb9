"""Per-trial truths of classes that combine others (:mod:`budget.runner.combined_truths`),
against the root-sum-square and the delta-method standard error computed here by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from budget.runner.combined_truths import combined_trial_truths
from budget.runner.stats import key_statistics
from budget.runner.study import ClassSpec, Truth

CLASSES = (ClassSpec("a", "a", "u"), ClassSpec("b", "b", "u", per_trial_truth=True),
           ClassSpec("ab", "a and b", "u", per_trial_truth=True, rss_of=("a", "b")),
           ClassSpec("abc", "ab and c", "u", per_trial_truth=True, rss_of=("ab", "c")),
           ClassSpec("c", "c", "u"))


def _inputs():
    b = np.array([1.0, 2.0, 3.0])
    samples = {(c, "v", "x"): np.zeros(3) for c in ("a", "b", "ab", "abc", "c")}
    truths = {("a", "x"): Truth(4.0, 0.1), ("c", "x"): Truth(2.0, 0.3)}
    return samples, truths, {("b", "v", "x"): b}


def test_a_combination_is_the_rss_of_fixed_and_per_trial_parts_in_class_order():
    samples, truths, tt = _inputs()
    out, se = combined_trial_truths(CLASSES, truths, samples, tt)
    ab = np.sqrt(16.0 + np.array([1.0, 4.0, 9.0]))
    np.testing.assert_allclose(out[("ab", "v", "x")], ab, rtol=1e-15)
    np.testing.assert_allclose(out[("abc", "v", "x")], np.sqrt(ab**2 + 4.0), rtol=1e-15)
    # the fixed parts' sampling, delta method: sqrt(sum (t se)^2) / mean T
    assert se[("ab", "v", "x")] == pytest.approx(4.0 * 0.1 / ab.mean(), rel=1e-12)
    abc = np.sqrt(ab**2 + 4.0)
    want = math.sqrt((ab.mean() * se[("ab", "v", "x")]) ** 2 + (2.0 * 0.3) ** 2) / abc.mean()
    assert se[("abc", "v", "x")] == pytest.approx(want, rel=1e-12)
    assert out[("b", "v", "x")] is tt[("b", "v", "x")]  # the trials' own are left as they are


def test_nothing_is_combined_before_the_fixed_truths_are_known_and_a_missing_part_is_named():
    samples, truths, tt = _inputs()
    out, se = combined_trial_truths(CLASSES, None, samples, tt)
    assert set(out) == set(tt) and se == {}
    with pytest.raises(ValueError, match="'abc': its part 'c' has no truth"):
        combined_trial_truths(CLASSES, {("a", "x"): Truth(4.0, 0.1)}, samples, tt)


def test_the_shared_truth_error_enters_the_bias_standard_error_in_quadrature():
    rng = np.random.default_rng(5)
    x, t = rng.normal(1.0, 0.2, 50), rng.normal(1.0, 0.1, 50)
    plain = key_statistics(x, trial_truths=t)
    shared = key_statistics(x, trial_truths=t, truth_se=0.05)
    assert shared["se_bias"] == pytest.approx(math.hypot(plain["se_bias"], 0.05), rel=1e-12)
    assert shared["bias"] == plain["bias"] and shared["truth_se"] == 0.05
