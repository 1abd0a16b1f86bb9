"""How many trials a plan runs and on which seeds: the trial budget, the screening trials a
candidate runs first and when they decide it, and the re-validation's fresh seed
(docs/planning.md, "The search" and "Honest verdict")."""

from __future__ import annotations

import numpy as np

__all__ = ["BUDGET_VALIDATIONS", "DECIDED", "MIN_TRIALS", "SETTLE_MAX_GROWTH", "SETTLE_MAX_VALIDATIONS", "SETTLE_SLACK",
           "VALIDATION_SPAWN_KEY", "screening_trials", "validation_seed"]

#: the search with the re-validation costs at most this many validations' trials (per shape)
BUDGET_VALIDATIONS = 20
#: the fewest trials of one validation a plan accepts (``--trials``), and the fewest a candidate screens on
MIN_TRIALS = 20
#: a candidate screens on this fraction (one over it) of a validation's trials
SCREENING_DIVISOR = 4
#: a candidate is decided by its screening trials when the posterior probability of meeting is below
#: this or above 1 - this
DECIDED = 0.001
#: settling an undetermined candidate: it is extended to this many times the trials its verdict says
#: would settle it (``n (z se / d)^2`` assumes the quantile stays where it is: a little more keeps a
#: quantile that moves a little from needing one more step)
SETTLE_SLACK = 1.2
#: ... and at most this many times its trials in one step, so that a standard error measured on few
#: trials (Maritz-Jarrett's on a tail with gaps can be several times the asymptotic one) is measured
#: again before the budget is spent on it
SETTLE_MAX_GROWTH = 3
#: ... and to at most this many validations' trials in all: a protocol whose quantile sits within a
#: hair of the bound needs unboundedly many, and the search is better served by a dearer protocol
#: than by spending its budget on one it cannot decide (chosen empirically on the one-knob toy: without
#: it, its plans answered 2.8 times the boundary protocol's frames, mean of 30 seeds, with 1.11 times)
SETTLE_MAX_VALIDATIONS = 4
#: the re-validation's spawn key: distinct from every trial's (0, 1, ...) and the truths' (2**31)
VALIDATION_SPAWN_KEY = 2**31 + 1


def screening_trials(trials: int) -> int:
    """Trials a candidate runs first: a quarter of a validation's, at least 20 (at most all)."""
    return min(trials, max(MIN_TRIALS, trials // SCREENING_DIVISOR))


def validation_seed(seed: int) -> int:
    """The re-validation's seed: the first 32-bit word of ``SeedSequence(seed,
    spawn_key=(VALIDATION_SPAWN_KEY,))``; its trials ``SeedSequence(validation_seed, (k,))``
    share no stream with the search's ``SeedSequence(seed, (k,))``."""
    return int(np.random.SeedSequence(seed, spawn_key=(VALIDATION_SPAWN_KEY,)).generate_state(1)[0])
