"""Cost of the study machinery: start-up, and what a second worker buys.

* **scaling**: the README's main job (``budget validate --trials 200`` on the embedded
  seed-000 scenario) with 1 and with 2 worker processes, end to end (a new process each,
  as a user runs it): wall time and the throughput ratio;
* **fixed cost**: everything but the trials' own work, with a warm numba cache (the
  second run of a command) and with an empty one (a fresh install, ``NUMBA_CACHE_DIR`` set
  to a new folder): the wall time of ``budget validate --trials 2 --workers 1`` minus twice
  the time of one warm trial measured in the same run.

Usage: ``python benchmarks/bench_runner.py [--trials 200] [--repeat 2]``
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import warnings

_HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, _HERE)
sys.path.insert(1, os.path.dirname(_HERE))
from _common import format_table, machine_description  # noqa: E402


def _run(args: list[str], env: dict | None = None) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "budget.cli", *args], check=True, env=env,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def _trial_time(repeat: int = 5) -> float:
    import numba

    from budget.runner.registry import get_study

    numba.set_num_threads(1)
    study = get_study("starcam")
    scn = study.load_scenario()
    warnings.simplefilter("ignore")
    study.trial(scn, 0, 1)
    best = float("inf")
    for k in range(2, 2 + repeat):
        t0 = time.perf_counter()
        study.trial(scn, 0, k)
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    print("machine:", ", ".join(f"{k}={v}" for k, v in machine_description().items()))
    with tempfile.TemporaryDirectory() as tmp:
        _run(["validate", "--trials", "2", "--workers", "1", "--no-progress"])  # warm the numba cache
        t_trial = _trial_time()
        warm = min(_run(["validate", "--trials", "2", "--workers", "1", "--no-progress"])
                   for _ in range(args.repeat))
        cold_env = {**os.environ, "NUMBA_CACHE_DIR": os.path.join(tmp, "numba-cache")}
        cold = _run(["validate", "--trials", "2", "--workers", "1", "--no-progress"], env=cold_env)
        one = min(_run(["validate", "--trials", str(args.trials), "--workers", "1", "--no-progress"])
                  for _ in range(args.repeat))
        two = min(_run(["validate", "--trials", str(args.trials), "--workers", "2", "--no-progress"])
                  for _ in range(args.repeat))
    print(format_table(["what", "seconds"], [
        ["one warm trial (in process, one core)", f"{t_trial:.3f}"],
        ["fixed cost, warm numba cache (2-trial run - 2 trials)", f"{warm - 2 * t_trial:.2f}"],
        ["fixed cost, empty numba cache (fresh install)", f"{cold - 2 * t_trial:.2f}"],
        [f"budget validate --trials {args.trials}, 1 worker", f"{one:.1f}"],
        [f"budget validate --trials {args.trials}, 2 workers", f"{two:.1f}"],
    ]))
    print(f"\n2 workers give {one / two:.2f}x the throughput of 1 (target >= 1.7x); fixed cost "
          f"{warm - 2 * t_trial:.2f} s warm (target <= 2 s), {cold - 2 * t_trial:.2f} s cold (target <= 8 s)")


if __name__ == "__main__":
    main()
