"""Per-trial truths of classes that combine others: what the trials cannot give alone.

A class declared with ``rss_of`` (:class:`budget.runner.study.ClassSpec`) has as its truth the
root-sum-square of its parts' truths (independent error sources; seed 000 eq 31 and eq 32
combine so). When one part's truth is drawn per trial (an instrument per trial) and another is
a run's fixed truth (sampled once from many frames), the combination exists per trial only
once the fixed truths are known, so no trial can return it: :func:`combined_trial_truths`
computes it from both, for every trial,

    T_k = sqrt(sum_p t_pk^2),    t_pk = the part's own truth in trial k, or its fixed truth T_p,

and the standard error the fixed parts' sampling carries into it, common to every trial
(delta method): ``se = sqrt(sum_p (t_p se_p)^2) / mean_k T_k`` with ``t_p`` a part's mean
truth and ``se_p`` its standard error. :class:`budget.runner.result.StudyResult` applies it
when built, so every reader of ``trial_truths`` sees the combined classes too.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["combined_trial_truths"]


def combined_trial_truths(classes, truths: dict | None, samples: dict, trial_truths: dict,
                          trial_truth_se: dict | None = None) -> tuple[dict, dict]:
    """``(trial_truths, trial_truth_se)`` with the per-trial truths of every class that has
    ``per_trial_truth`` and ``rss_of``, for each of its keys in ``samples`` (``(class,
    variant, axis)``), added in class order (a combination may be part of a later one).

    ``truths``: the run's fixed truths by ``(class, axis)`` (None: not known yet, nothing is
    added); ``trial_truths``: arrays by key, in trial order; ``trial_truth_se``: standard errors
    already known by key. A part found in neither raises ``ValueError`` naming it."""
    tt = dict(trial_truths)
    se = dict(trial_truth_se or {})
    if truths is None:
        return tt, se
    for c in classes:
        if not (c.per_trial_truth and c.rss_of):
            continue
        for key in samples:
            if key[0] != c.name or key in trial_truths:
                continue
            _, var, ax = key
            n = len(samples[key])
            square = np.zeros(n)
            spread = 0.0
            for p in c.rss_of:
                if (p, var, ax) in tt:
                    t = np.asarray(tt[(p, var, ax)], dtype=float)
                    square += t * t
                    spread += (float(np.mean(t)) * se.get((p, var, ax), 0.0)) ** 2
                elif (p, ax) in truths:
                    part = truths[(p, ax)]
                    square += part.value**2
                    spread += (part.value * part.se) ** 2
                else:
                    raise ValueError(f"class {c.name!r}: its part {p!r} has no truth on axis {ax!r} "
                                     f"(neither per trial nor fixed)")
            total = np.sqrt(square)
            tt[key] = total
            mean = float(np.mean(total)) if n else 0.0
            se[key] = math.sqrt(spread) / mean if mean > 0 else math.sqrt(spread)
    return tt, se
