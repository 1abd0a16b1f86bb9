"""The HSFE test's step patterns on seed 000's camera (docs/validation.md, "Planning the test").

The HSFE protocol alone (the same make_plan / simulate / estimate calls as a validation
trial) on ``embedded:seed000_ideal``, for seed 000's 12 diagonal poses x 30 frames, the grid
pattern with the same counts and with 10 frames per pose: the mean and sd of the published and
improved estimates over the trials, and the 95 % quantile of their error against the HSFE
truth (400 noisy frames per sub-pixel phase), all arcsec, 3 sigma.

    python docs/examples/hsfe_patterns.py --trials 40 --seed 1000
"""

from __future__ import annotations

import argparse

import numpy as np

from budget.starcam import validate as V
from budget.starcam.protocols import estimate, make_plan, simulate
from budget.starcam.truth import hsfe_truth
from simcam.starcam.scenario import load, with_updates

CASES = {"diagonal 12 x 30 (seed 000)": {},
         "grid 12 x 30": {"protocols.hsfe.pattern": "grid"},
         "grid 12 x 10": {"protocols.hsfe.pattern": "grid", "protocols.hsfe.frames": 10}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=40)
    ap.add_argument("--seed", type=int, default=1000)
    args = ap.parse_args()
    base = load("embedded:seed000_ideal")
    f = 3.0 * base.camera.scale_arcsec_per_px
    tr = hsfe_truth(V._camera(base), frames=400, seed=7)
    truth = np.array([tr.x_px, tr.y_px]) * f
    print(f"HSFE truth x/y {truth[0]:.4f}/{truth[1]:.4f} +- {tr.se_x_px * f:.4f}/{tr.se_y_px * f:.4f} arcsec")
    for name, upd in CASES.items():
        scn = with_updates(base, upd)
        est = []
        for k in range(args.trials):
            noise_seed, _, _ = V.trial_seeds(args.seed, k)
            data = simulate(make_plan("hsfe", scn, seed=noise_seed), V._camera(scn), seed=noise_seed)
            r = estimate("hsfe", data.centroids, plate_scale_arcsec=scn.camera.scale_arcsec_per_px,
                         extra_variants=False)
            est.append([r[v].sigma_x_px * f if ax == "x" else r[v].sigma_y_px * f
                        for v in ("published", "improved") for ax in ("x", "y")])
        est = np.array(est)
        q = np.quantile(np.abs(est - np.tile(truth, 2)), 0.95, axis=0)
        for i, v in enumerate(("published", "improved")):
            m, sd = est[:, 2 * i:2 * i + 2].mean(axis=0), est[:, 2 * i:2 * i + 2].std(axis=0, ddof=1)
            print(f"{name:28s} {v:9s} mean {m[0]:.4f}/{m[1]:.4f}  sd {sd[0]:.4f}/{sd[1]:.4f}  "
                  f"95 % error quantile {q[2 * i]:.4f}/{q[2 * i + 1]:.4f}")


if __name__ == "__main__":
    main()
