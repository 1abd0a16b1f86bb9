"""Re-make the tables of docs/validation.md ("What it reveals") from fresh validation runs.

Runs ``budget.validate.validate`` on the embedded seed-000 default (200 trials) and on
the one-effect scenarios of ``docs/examples/scenarios`` (100 trials each), seed 1, and
prints the two Markdown tables (arcsec, 3 sigma).

Usage: ``python docs/examples/validation_findings.py [--workers W]``
"""

from __future__ import annotations

import argparse
import os
import time

from budget.validate import default_workers, validate
from simcam.scenario import load_scenario

HERE = os.path.dirname(os.path.abspath(__file__))
LABELS = {"te": "TE", "hsfe": "HSFE", "lsfe_s": "LSFE-S", "lsfe_c1": "LSFE-C1", "lsfe": "LSFE",
          "total": "single star"}
DEFAULT_ROWS = [("te", "x"), ("hsfe", "x"), ("hsfe", "y"), ("lsfe_s", "x"), ("lsfe_s", "y"),
                ("lsfe_c1", "x"), ("lsfe_c1", "y"), ("lsfe", "x"), ("lsfe", "y"), ("total", "x"), ("total", "y")]
ONE_EFFECT_ROWS = [
    ("te_only", "temporal noise only", "hsfe", "x"),
    ("hsfe_prnu", "2 % PRNU, 2 e- DSNU", "hsfe", "x"),
    ("hsfe_prnu", None, "hsfe", "y"),
    ("chromatic_only", None, "lsfe_s", "x"),
    ("chromatic_only", None, "lsfe_c1", "x"),
    ("distortion_only", None, "lsfe_c1", "x"),
    ("distortion_only", None, "lsfe_s", "x"),
]


def cell(s: dict) -> str:
    """``mean +- sd (bias %)``; no percentage when the truth is zero."""
    pct = s["bias_percent"]
    tail = "" if pct != pct else f" ({pct:+.0f} %)"  # NaN: zero truth
    return f"{s['mean']:.3f} +- {s['std']:.3f}{tail}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=default_workers())
    args = ap.parse_args()
    t0 = time.perf_counter()
    res = validate(load_scenario(None), trials=200, seed=1, workers=args.workers, keep_example=False)
    dt = time.perf_counter() - t0
    summ = res.summary()
    print(f"Default scenario, 200 trials, seed 1, {args.workers} workers: {dt:.0f} s\n")
    print("| class | axis | truth | published mean +- sd (bias) | improved mean +- sd (bias) |")
    print("|---|---|---|---|---|")
    for cls, ax in DEFAULT_ROWS:
        s = summ[cls][ax]
        print(f"| {LABELS[cls]} | {ax} | {s['published']['truth']:.3f} | {cell(s['published'])} | "
              f"{cell(s['improved'])} |")
    print("\nOne effect at a time (100 trials each, seed 1):\n")
    print("| scenario | class | truth | published mean +- sd (bias) | improved mean +- sd (bias) |")
    print("|---|---|---|---|---|")
    runs: dict = {}
    for name, note, cls, ax in ONE_EFFECT_ROWS:
        if name not in runs:
            scn = load_scenario(os.path.join(HERE, "scenarios", f"{name}.toml"))
            runs[name] = validate(scn, trials=100, seed=1, workers=args.workers, keep_example=False).summary()
        s = runs[name][cls][ax]
        label = f"`{name}`" + (f" ({note})" if note else "")
        truth = s["published"]["truth"]
        print(f"| {label} | {LABELS[cls]} {ax} | {truth:.3f} | {cell(s['published'])} | {cell(s['improved'])} |")


if __name__ == "__main__":
    main()
