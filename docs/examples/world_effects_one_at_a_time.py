"""Seed 000 in the realistic world, one world effect at a time (docs/validation.md,
"What its claim survives").

For each group of ``[world.effects]`` (distortion beyond the cubic, non-linearity, hexapod,
drift) alone and for the ideal world, the same trials (common random numbers: trial k draws
the same noise in every case) through the lab's estimators, and the truths of each case
(recomputed only where ``StarCameraStudy.truth_depends_on_effects`` says they change).
Prints the mean estimate minus the truth per class, axis and variant, arcsec 3 sigma.

    python docs/examples/world_effects_one_at_a_time.py --trials 40 --workers 2
"""

from __future__ import annotations

import argparse
import json
from concurrent.futures import ProcessPoolExecutor

import numpy as np

GROUPS = {
    "ideal": (),
    "distortion": ("distortion_r5_px_at_corner", "distortion_r7_px_at_corner"),
    "nonlinearity": ("nonlinearity_beta",),
    "hexapod": ("hexapod_repeatability_arcsec", "hexapod_backlash_arcsec"),
    "drift": ("drift_rate_arcsec_per_h", "drift_random_arcsec"),
}


def case(name):
    from simcam.starcam.scenario import default, with_updates

    real = default()
    eff = real.world.effects.ideal().model_dump()
    for n in GROUPS[name]:
        eff[n] = getattr(real.world.effects, n)
    return with_updates(real, {"world.effects": eff})


def one(args):
    name, seed, k = args
    from budget.starcam.validate import run_trial, worker_init

    worker_init()
    r = run_trial(case(name), seed, k)["values"]
    return name, k, {"|".join(key): v for key, v in r.items()}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=40)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    from budget.starcam.study import STUDY
    from budget.starcam.validate import truths

    jobs = [(n, a.seed, k) for n in GROUPS for k in range(a.trials)]
    with ProcessPoolExecutor(a.workers) as ex:
        res = list(ex.map(one, jobs, chunksize=4))
    dep = STUDY.truth_depends_on_effects(case("ideal"))
    tr = {}
    for n in GROUPS:
        if n == "ideal" or set(GROUPS[n]) & dep:
            tr[n] = truths(case(n), seed=a.seed)
        else:
            tr[n] = tr["ideal"]
    f = 3 * 5.5
    out = {}
    for n in GROUPS:
        vals = [r for name, _, r in res if name == n]
        for cls in ("te", "hsfe", "lsfe_s", "lsfe_c1", "total"):
            for ax in ("x", "y"):
                t = getattr(tr[n][cls], f"{ax}_px") * f
                for var in ("published", "improved"):
                    v = np.array([r[f"{cls}|{var}|{ax}"] for r in vals]) * f
                    out[f"{n}|{cls}|{ax}|{var}"] = {"truth": t, "mean": float(v.mean()),
                                                    "se": float(v.std(ddof=1) / np.sqrt(v.size))}
    for key, v in out.items():
        print(f"{key:40s} truth {v['truth']:.4f} mean {v['mean']:.4f} +- {v['se']:.4f} bias {v['mean'] - v['truth']:+.4f}")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
