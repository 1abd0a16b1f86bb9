"""Re-make the tables of docs/validation.md ("What it reveals") from fresh validation runs.

1. Both embedded cameras (``embedded:default``, ``embedded:seed000_noisy``) through
   the seed-000 study through the runner (``budget validate``): every class, truth with its Monte Carlo standard error,
   published and improved estimates (mean +- sd, bias %, significance against the
   combined standard error of the mean estimate and the truth).
2. LSFE-C1 on calibrated cameras whose true remaining displacement is 0, below, at and
   above eq 29's marker floor sqrt(9/31) x 0.5" = 0.27", and on an uncalibrated camera
   (distortion protocol only: the truth of budget.starcam.truth.lsfe_c1_truth, the estimates of
   budget.starcam.protocols.estimate, trial k seeded as in budget.starcam.validate).
3. LSFE-S with the lab's spectral model exact and with the default stated errors
   (chromatic protocol only).
4. The one-effect scenarios of ``docs/examples/scenarios``.

Usage: ``python docs/examples/validation_findings.py [--workers W] [--trials K] [--small-trials K2]``
(defaults 100 and 40: modest counts that finish on a loaded 2-core machine).
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

import numpy as np

from budget.starcam.protocols import estimate, make_plan, simulate, spectral_design
from budget.starcam.truth import lsfe_c1_truth, lsfe_s_truth
from budget.runner.executors import default_workers
from budget.runner.run import run_study
from budget.starcam.study import STUDY
from budget.starcam.validate import trial_seeds
from simcam.starcam.render import StarCamera
from simcam.starcam.scenario import load, with_updates

HERE = os.path.dirname(os.path.abspath(__file__))
LABELS = {"te": "TE", "hsfe": "HSFE", "lsfe_s": "LSFE-S", "lsfe_c1": "LSFE-C1", "lsfe_c2": "LSFE-C2",
          "lsfe": "LSFE", "total": "single star"}
ROWS = [(c, a) for c in ("te", "hsfe", "lsfe_s", "lsfe_c1", "lsfe_c2", "lsfe", "total") for a in ("x", "y")]
ONE_EFFECT = [("te_only", "hsfe"), ("hsfe_prnu", "hsfe"), ("chromatic_only", "lsfe_s"),
              ("chromatic_only", "lsfe_c1"), ("distortion_only", "lsfe_c1"), ("distortion_only", "lsfe_s")]
C1_CASES = [
    ("0 (quintic correction, error-free, 8 x 16 points)",
     {"optics.distortion_correction.order": 5, "optics.distortion_correction.rows": 8,
      "optics.distortion_correction.cols": 16, "optics.distortion_correction.marker_error_3sigma_arcsec": 0.0,
      "optics.distortion_correction.centroid_noise_px": 0.0}),
    ("below (cubic, 0.15\" markers)", {"optics.distortion_correction.marker_error_3sigma_arcsec": 0.15}),
    ("at (cubic, 0.5\" markers: the default)", {}),
    ("above (cubic, 1.5\" markers)", {"optics.distortion_correction.marker_error_3sigma_arcsec": 1.5}),
    ("uncalibrated camera (kind = none)", {"optics.distortion_correction.kind": "none"}),
]
EXACT_KNOWLEDGE = {"lab.knowledge.qe_peak_nm_error": 0.0, "lab.knowledge.filter_center_nm_error": 0.0,
                   "lab.knowledge.filter_width_nm_error": 0.0, "lab.knowledge.lamp_temperature_k_error": 0.0,
                   "lab.knowledge.star_teff_fraction_error": 0.0}


def cell(s: dict) -> str:
    """``mean +- sd (bias %, * if significant)``; ``input`` for a given value."""
    if s.get("role") == "input":
        return f"{s['mean']:.3f} (input)"
    pct = s["bias_percent"]
    mark = "*" if s["bias_significant"] else ""
    tail = "" if pct != pct else f" ({pct:+.0f} %{mark})"  # NaN: zero truth
    return f"{s['mean']:.3f} +- {s['std']:.3f}{tail}"


def camera_table(name: str, trials: int, workers: int) -> None:
    scn = load(f"embedded:{name}")
    t0 = time.perf_counter()
    res = run_study(STUDY, scn, trials=trials, seed=1, workers=workers)
    dt = time.perf_counter() - t0
    s = res.summary()
    te = res.truths[("te", "x")]
    f = 3 * scn.camera.scale_arcsec_per_px
    print(f"\n### `embedded:{name}`: {trials} trials, seed 1, {workers} workers, {dt:.0f} s\n")
    print(f"TE Cramer-Rao bound: x {te.details['cramer_rao_x_px'] * f:.3f}, y {te.details['cramer_rao_y_px'] * f:.3f}\n")
    print("| class | axis | truth +- se | published mean +- sd (bias) | improved mean +- sd (bias) |")
    print("|---|---|---|---|---|")
    for cls, ax in ROWS:
        d = s[cls][ax]
        p = d["published"]
        print(f"| {LABELS[cls]} | {ax} | {p['truth']:.3f} +- {p['truth_se']:.4f} | {cell(p)} | {cell(d['improved'])} |")


def protocol_trials(scn, proto: str, trials: int, *, calibrated: bool) -> np.ndarray:
    """(trials, 4): published x, y and improved x, y (arcsec 3 sigma) of one protocol."""
    cam = StarCamera(scn)
    ps = scn.camera.scale_arcsec_per_px
    spectral = spectral_design(scn) if proto == "chromatic" else None
    out = []
    for k in range(trials):
        ns, _, ms = trial_seeds(1, k)
        d = simulate(make_plan(proto, scn, seed=ns), cam, seed=ns, marker_seed=ms)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = estimate(proto, d.centroids, plate_scale_arcsec=ps, reference=d.reference,
                         reference_filter_nm=scn.protocols.chromatic.reference_filter_nm,
                         marker_3sigma_arcsec=scn.lab.calibration_target.marker_error_3sigma_arcsec,
                         spectral=spectral, extra_variants=False, camera_corrects_distortion=calibrated)
        out.append([r["published"].sigma_x_px, r["published"].sigma_y_px,
                    r["improved"].sigma_x_px, r["improved"].sigma_y_px])
    return np.array(out) * 3 * ps


def ms(v: np.ndarray) -> str:
    return f"{v.mean():.3f} +- {v.std(ddof=1):.3f}"


def c1_table(trials: int) -> None:
    print(f"\n### LSFE-C1 against the camera's true remaining displacement ({trials} trials, seed 1)\n")
    print("| camera's remaining displacement | truth x / y | eq 29 x | eq 29 y | improved x | improved y |")
    print("|---|---|---|---|---|---|")
    base = load(None)
    f = 3 * base.camera.scale_arcsec_per_px
    for label, upd in C1_CASES:
        scn = with_updates(base, upd) if upd else base
        t = lsfe_c1_truth(StarCamera(scn))
        v = protocol_trials(scn, "distortion", trials, calibrated=scn.optics.distortion_correction.kind != "none")
        print(f"| {label} | {t.x_px * f:.3f} / {t.y_px * f:.3f} | {ms(v[:, 0])} | {ms(v[:, 1])} | "
              f"{ms(v[:, 2])} | {ms(v[:, 3])} |")


def s_table(trials: int) -> None:
    print(f"\n### LSFE-S with the lab's spectral model exact and mismatched ({trials} trials, seed 1)\n")
    print("| lab's spectral model | truth x / y | published x | published y | improved x | improved y |")
    print("|---|---|---|---|---|---|")
    base = load(None)
    f = 3 * base.camera.scale_arcsec_per_px
    for label, scn in (("exact (all stated errors 0)", with_updates(base, EXACT_KNOWLEDGE)),
                       ("default stated errors (QE peak +20 nm, filters +3/+2 nm, lamp +50 K, Teff +3 %)", base)):
        t = lsfe_s_truth(StarCamera(scn))
        v = protocol_trials(scn, "chromatic", trials, calibrated=True)
        print(f"| {label} | {t.x_px * f:.3f} / {t.y_px * f:.3f} | {ms(v[:, 0])} | {ms(v[:, 1])} | "
              f"{ms(v[:, 2])} | {ms(v[:, 3])} |")


def one_effect_table(trials: int, workers: int) -> None:
    print(f"\n### One effect at a time ({trials} trials each, seed 1)\n")
    print("| scenario | class | axis | truth +- se | published mean +- sd (bias) | improved mean +- sd (bias) |")
    print("|---|---|---|---|---|---|")
    runs: dict = {}
    for name, cls in ONE_EFFECT:
        if name not in runs:
            scn = load(os.path.join(HERE, "scenarios", f"{name}.toml"))
            runs[name] = run_study(STUDY, scn, trials=trials, seed=1, workers=workers).summary()
        for ax in ("x", "y"):
            d = runs[name][cls][ax]
            p = d["published"]
            print(f"| `{name}` | {LABELS[cls]} | {ax} | {p['truth']:.3f} +- {p['truth_se']:.4f} | {cell(p)} | "
                  f"{cell(d['improved'])} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=default_workers())
    ap.add_argument("--trials", type=int, default=100, help="trials of the two camera runs")
    ap.add_argument("--small-trials", type=int, default=40, help="trials of the C1, S and one-effect runs")
    ap.add_argument("--only", choices=("cameras", "c1", "s", "one"), default=None)
    args = ap.parse_args()
    print("arcsec, 3 sigma; * = bias significant (|bias| > 3 standard errors of mean and truth combined)")
    if args.only in (None, "cameras"):
        for name in ("default", "seed000_noisy"):
            camera_table(name, args.trials, args.workers)
    if args.only in (None, "c1"):
        c1_table(args.small_trials)
    if args.only in (None, "s"):
        s_table(args.small_trials)
    if args.only in (None, "one"):
        one_effect_table(args.small_trials, args.workers)


if __name__ == "__main__":
    main()
