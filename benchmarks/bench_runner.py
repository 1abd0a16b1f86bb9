"""Cost of the study machinery: start-up, and what a second worker buys.

* **scaling**: the README's main job (``budget validate --trials 200`` on the embedded
  seed-000 scenario) with 1 and with 2 worker processes, end to end (a new process each,
  as a user runs it): wall time and the throughput ratio. The runs alternate (1, 2, 1,
  2, ...) and each count's best is taken: a shared virtual machine's speed drifts by
  10-20 % within minutes, and a block of 1-worker runs followed by a block of 2-worker
  runs would put that drift into the ratio;
* **fixed cost**: everything but the work itself, with a warm numba cache (the second run
  of a command) and with an empty one (a fresh install, ``NUMBA_CACHE_DIR`` set to a new
  folder): the wall time of ``budget validate SCENARIO --trials 2 --workers 1`` minus the
  truths' work and twice the time of one warm trial, both measured in this run on the same
  scenario. SCENARIO is the embedded default with ``hsfe_truth_frames = 16``: the default's
  truths are real work (its HSFE truth exposes and centroids 128,000 noisy frames, 10-20 s
  on one core, reported on their own line), and subtracting that much work, measured in
  another process, would leave a fixed cost of a second or two drowned in its noise. The
  fixed cost so holds the interpreter and the imports, the scenario's loading, numba's
  cache loads (or, cold, its compilation), and the first trial's rendering of the scenes
  every later trial reuses (a process's own cache: the "warm trial" subtracted is a later
  one). Each is also given in CPU seconds (the command's process and its children), which
  other jobs on a shared machine disturb less than the wall time.

The last line is ``RESULT {json}`` (read by ``run_all.py``).

Usage: ``python benchmarks/bench_runner.py [--trials 200] [--repeat 3] [--quick]``
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
import warnings

if not __package__:  # run as a file (python benchmarks/bench_x.py): the repository root on the path
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks._common import (  # noqa: E402
    bench_parser,
    emit_result,
    figure,
    format_table,
    print_machine,
)


#: the fixed-cost runs' scenario: the default with a light HSFE truth (see the docstring)
LIGHT_HSFE_TRUTH_FRAMES = 16


def _light_scenario(folder: str) -> str:
    """The embedded default with ``hsfe_truth_frames = LIGHT_HSFE_TRUTH_FRAMES``, as a file."""
    import re

    from budget.runner.registry import get_study

    text = get_study("starcam").default_text()
    light, n = re.subn(r"(?m)^hsfe_truth_frames\s*=\s*\d+", f"hsfe_truth_frames = {LIGHT_HSFE_TRUTH_FRAMES}", text)
    if n != 1:
        raise SystemExit("bench_runner: the default scenario has no single hsfe_truth_frames line")
    path = os.path.join(folder, "light_truth.toml")
    with open(path, "w") as f:
        f.write(light)
    return path


def _user_env(**extra: str) -> dict:
    """The environment a user's shell gives a command: Python writes its bytecode cache
    (some sandboxes set PYTHONDONTWRITEBYTECODE, which recompiles every module of the
    project, about 0.15 s, on every start)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env.update(extra)
    return env


def _run(args: list[str], env: dict | None = None) -> tuple[float, float]:
    """(wall, CPU of the command's process and its children) of ``budget ARGS``, s."""
    import resource

    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "budget.cli", *args], check=True, env=env or _user_env(),
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def _work_times(scenario_path: str | None = None, repeat: int = 5) -> tuple[float, float, float, float]:
    """(one warm trial, the truths) of a scenario (default: the embedded one) in this
    process on one core, wall then CPU, s. The truths are timed once, after the trials (so
    the imports, numba cache loads and scenes they share with a trial are not counted as
    their work), and never twice: a second call would find the scenes the first rendered
    in their caches."""
    import numba

    from budget.runner.registry import get_study

    numba.set_num_threads(1)
    study = get_study("starcam")
    scn = study.load_scenario(scenario_path)
    warnings.simplefilter("ignore")
    study.trial(scn, 0, 1)
    best = best_cpu = float("inf")
    for k in range(2, 2 + repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        study.trial(scn, 0, k)
        best, best_cpu = min(best, time.perf_counter() - t0), min(best_cpu, time.process_time() - c0)
    t0, c0 = time.perf_counter(), time.process_time()
    study.truths(scn, 0)
    return best, time.perf_counter() - t0, best_cpu, time.process_time() - c0


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    if args.quick:
        args.trials, args.repeat = min(args.trials, 10), 1
    print_machine()
    with tempfile.TemporaryDirectory() as tmp:
        light = _light_scenario(tmp)
        small = ["validate", light, "--trials", "2", "--workers", "1", "--no-progress"]
        _run(small)  # warm the numba cache
        t_trial, t_truth, c_trial, c_truth = _work_times(light)
        _, t_truth_default, _, _ = _work_times(repeat=1)
        warm_runs = [_run(small) for _ in range(max(args.repeat, 3))]
        warm, warm_cpu = min(w for w, _ in warm_runs), min(c for _, c in warm_runs)
        cold_env = _user_env(NUMBA_CACHE_DIR=os.path.join(tmp, "numba-cache"))
        cold, cold_cpu = _run(small, env=cold_env)
        one_runs, two_runs = [], []
        for _ in range(args.repeat):  # alternated: the machine's drift falls on both counts alike
            for runs, n in ((one_runs, "1"), (two_runs, "2")):
                runs.append(_run(["validate", "--trials", str(args.trials), "--workers", n, "--no-progress"]))
        one, one_cpu = min(w for w, _ in one_runs), min(c for _, c in one_runs)
        two, two_cpu = min(w for w, _ in two_runs), min(c for _, c in two_runs)
    fixed_warm = warm - t_truth - 2 * t_trial
    fixed_cold = cold - t_truth - 2 * t_trial
    fixed_warm_cpu = warm_cpu - c_truth - 2 * c_trial
    fixed_cold_cpu = cold_cpu - c_truth - 2 * c_trial
    print(format_table(["what", "seconds"], [
        ["one warm trial (in process, one core)", f"{t_trial:.3f}"],
        [f"the truths with hsfe_truth_frames = {LIGHT_HSFE_TRUTH_FRAMES} (in process, one core)", f"{t_truth:.2f}"],
        ["the default scenario's truths (in process, one core)", f"{t_truth_default:.2f}"],
        ["budget validate LIGHT --trials 2 --workers 1, warm numba cache", f"{warm:.2f}"],
        ["fixed cost, warm numba cache (that - truths - 2 trials)", f"{fixed_warm:.2f}"],
        ["fixed cost, empty numba cache (fresh install)", f"{fixed_cold:.2f}"],
        ["fixed cost, warm numba cache, CPU (process and children)", f"{fixed_warm_cpu:.2f}"],
        ["fixed cost, empty numba cache, CPU (process and children)", f"{fixed_cold_cpu:.2f}"],
        [f"budget validate --trials {args.trials}, 1 worker", f"{one:.1f}"],
        [f"budget validate --trials {args.trials}, 2 workers", f"{two:.1f}"],
        [f"budget validate --trials {args.trials}, 1 worker, CPU", f"{one_cpu:.1f}"],
        [f"budget validate --trials {args.trials}, 2 workers, CPU (process and workers)", f"{two_cpu:.1f}"],
    ]))
    print(f"\n2 workers give {one / two:.2f}x the throughput of 1 (target >= 1.8x); fixed cost "
          f"{fixed_warm:.2f} s warm (target <= 2 s), {fixed_cold:.2f} s cold (target <= 8 s)")
    main_job = args.trials == 200
    emit_result("runner", [
        figure("two_worker_speedup", f"throughput of 2 workers / 1 worker, budget validate --trials {args.trials}",
               one / two, "x", better="higher", target=1.8 if main_job else None,
               target_source="project target, 200 trials" if main_job else None),
        figure("fixed_cost_warm_s", "fixed cost of budget validate, warm numba cache (s; truths' work excluded)",
               fixed_warm, "s", target=2.0, target_source="project target"),
        figure("fixed_cost_cold_s", "fixed cost of budget validate, empty numba cache (s; truths' work excluded)",
               fixed_cold, "s", target=8.0, target_source="project target"),
        figure("fixed_cost_warm_cpu_s", "fixed cost of budget validate, warm numba cache, CPU incl. children (s)",
               fixed_warm_cpu, "s"),
        figure("fixed_cost_cold_cpu_s", "fixed cost of budget validate, empty numba cache, CPU incl. children (s)",
               fixed_cold_cpu, "s"),
        figure("two_workers_cpu_overhead", f"CPU of 2 workers / CPU of 1, budget validate --trials {args.trials}",
               two_cpu / one_cpu, "x"),
        figure("truths_s", "seed-000 truths of the default scenario, one core (s)", t_truth_default, "s"),
        figure("one_worker_s", f"budget validate --trials {args.trials}, 1 worker (s)", one, "s"),
        figure("two_workers_s", f"budget validate --trials {args.trials}, 2 workers (s)", two, "s",
               target=5.0 if main_job else None, target_source="speed target, main job" if main_job else None),
    ], quick=args.quick, trials=args.trials)


if __name__ == "__main__":
    main()
