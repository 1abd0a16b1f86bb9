"""What seed 002's claims survive (docs/whiskbroom.md, "What its claim survives"): the
validation study on the ideal world, each world effect alone at its sourced magnitude, and
all together, with the same trial seeds in every case (common random numbers: the 17
draws, the edge noise and each effect's phases come from per-trial streams that do not
move when another effect is switched), through the one runner.

Per case and variant: bias (estimate - truth) with its standard error, and whether the
claim holds: ``|bias| <= claim + 2 se`` with the study's claimed accuracy
(:meth:`budget.whiskbroom.study.WhiskbroomStudy.claim`: 0.005 in MTF, 5 % of the array's
stages in the stage limit).

Run from the repository root: ``python docs/examples/whiskbroom_effects_cases.py [TRIALS]``
(default 100 trials per case; ~1 min per case on one core).
"""

from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))

from budget.runner.run import run_study  # noqa: E402
from budget.whiskbroom.study import STUDY  # noqa: E402
from simcam.whiskbroom import scenario as wsc  # noqa: E402


def with_effects(sc, effects):
    data = sc.model_dump(mode="json")
    data["world"]["effects"] = effects.model_dump()
    return wsc.from_dict(data, source="case")


def main(trials: int = 100):
    sc = wsc.default()
    eff = sc.world.effects
    cases = {"ideal": eff.ideal()}
    cases.update({n: eff.only(n) for n in eff.names()})
    cases["all"] = eff
    keys = [("mtf_nyquist", "along", v) for v in ("published", "improved", "edge")]
    keys += [("mtf_nyquist", "cross", v) for v in ("published", "improved")]
    keys += [("stage_limit", "along", v) for v in ("published", "improved")]
    print(f"{trials} trials per case, seed 0; cell: bias +- se (claim holds: ok / NO)")
    print("case".ljust(28) + "".join(f"{'/'.join((c[:5], a, v)):>26}" for c, a, v in keys))
    for name, e in cases.items():
        case = with_effects(sc, e)
        res = run_study(STUDY, case, trials=trials, seed=0, workers=1, prewarm=False)
        cells = []
        for c, a, v in keys:
            st = res.statistics((c, v, a))
            claim = STUDY.claim(case, c, v)
            ok = abs(st["bias"]) <= claim + 2 * st["se_bias"]
            cells.append(f"{st['bias']:+.4g}+-{st['se_bias']:.1g} {'ok' if ok else 'NO'}")
        print(name.ljust(28) + "".join(f"{x:>26}" for x in cells), flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100)
