"""One trial's draw of the whiskbroom study (seed 002): its operating point, errors and
worst-column residual, shared by the study (:mod:`budget.whiskbroom.study`) and the headline
checks (:mod:`budget.whiskbroom.claims`) so that both see the same trials.

Trial ``k``: ``SeedSequence(seed, spawn_key=(k,))`` draws the 17 variables first (uniforms
mapped by :func:`simcam.whiskbroom.synthesis.standard_draws`), then the edge image's noise
from the same generator.
"""

from __future__ import annotations

import numpy as np

from budget.runner.study import trial_seed_sequence
from simcam.whiskbroom.scenario import VARIABLES

__all__ = ["field_points", "trial_draw"]


def field_points(scenario):
    """The field points the worst column is searched over: the centre first, then
    :func:`simcam.whiskbroom.synthesis.field_points` (mm)."""
    from simcam.whiskbroom import synthesis as sy   # loads numba

    x1, x3 = sy.field_points(scenario)
    return np.concatenate([[0.0], x1]), np.concatenate([[0.0], x3])


def trial_draw(scenario, seed: int, k: int, x1, x3):
    """``(rng, know, true, r)``: the trial's generator after the 17 draws, its knowledge and
    true parameter rows (1, P) and the paper's residuals at the field points
    (:func:`simcam.whiskbroom.synthesis.evaluate`)."""
    from simcam.whiskbroom import synthesis as sy   # loads numba

    rng = np.random.default_rng(trial_seed_sequence(seed, k))
    u = np.clip(rng.random(len(VARIABLES)), 1e-300, None)[None, :]
    draws = sy.standard_draws(scenario, u)
    know, true = sy.trial_params(scenario, draws, [k])
    r = sy.evaluate(know, true, x1, x3, backend="numpy")   # one state: numpy is faster
    # a scenario outside the model's domain is one error line, not NaN estimates
    sy.check_finite_residuals(scenario, r, scenario.errors.mirror_rate_deg_s.scale,
                              f"{getattr(scenario, 'source', 'scenario')}: trial {k} of seed {seed}")
    return rng, know, true, r
