"""Cost of the truths when their precision follows the question, and of a sweep point.

The truths measured here are the run's: the embedded default with one camera's pixel maps for
every trial (``validation.new_maps_per_trial = false``), since with the maps drawn per trial
(the default) TE's and HSFE's truths are each trial's camera's own, computed in the trial
(their cost is in ``bench_validate.py``'s trial), and the run has none of them to size.

* **truths at the main job's precision**: the embedded default's truths sized for 200 trials
  (the runner's pilot of the first 20 trials gives the trials' spread; the truths' target
  is a quarter of the bias standard error, :func:`budget.runner.scheduler.truth_targets`), in
  this process on one core: the sizing (its 64-frame pilot) and the truths, wall and CPU
  (best of 3); beside them the fixed-size truths (the scenario's 2000 HSFE frames per phase,
  1000 TE frames), **plain vs reduced side by side**: the plain estimators
  (``control_variate=False``) and the variance-reduced ones (control variates,
  :mod:`budget.starcam.kernels_truth`) on the same frames, with the HSFE and TE standard
  errors each reaches, and what the plain estimators would cost at the main job's
  precision (the plain HSFE and TE truths' fixed-size CPU times, each times its
  ``max (se / target)^2`` over the axes: an extrapolation, the standard error going as
  ``1 / sqrt(frames)``);
* **budget validate --trials 2, warm**: end to end in a new process (numba cache warm),
  wall and CPU of the child;
* **a camera sweep point**: one ``validate`` point of that scenario (``--trials``, 200) as a
  sweep runs it (:func:`budget.sweeps.evaluate.evaluate_point`, one core), with its own
  truths and with a truth shared from another point (what each further point of a group
  costs, :func:`budget.sweeps.run.share_truths`): CPU time.

The machine may be shared: CPU times are the figures to compare, wall times are given too.
The last line is ``RESULT {json}`` (read by ``run_all.py``).

Usage: ``python benchmarks/bench_truths.py [--trials 200] [--quick]``
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import time
import warnings

if not __package__:  # run as a file (python benchmarks/bench_x.py): the repository root on the path
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks._common import bench_parser, emit_result, figure, format_table, print_machine  # noqa: E402
from budget.runner.capabilities import capability, SizedTruths


def _timed(fn):
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - t0, time.process_time() - c0


def _validate_small() -> tuple[float, float]:
    """(wall, CPU of the child) of ``budget validate --trials 2 --workers 1``."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "budget.cli", "validate", "--trials", "2", "--workers", "1",
                    "--no-progress"], check=True, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--trials", type=int, default=200)
    args = ap.parse_args()
    if args.quick:
        args.trials = 20
    print_machine()
    import numba

    from budget.runner.registry import get_study
    from budget.runner.scheduler import PILOT_TRIALS, trial_arrays, truth_targets
    from budget.sweeps.evaluate import PointTask, evaluate_point

    numba.set_num_threads(1)
    warnings.simplefilter("ignore")
    _validate_small()  # numba's cache warm, the scenes' code imported
    small = min((_validate_small() for _ in range(2)), key=lambda x: x[0])
    from simcam.starcam.scenario import with_updates

    study = get_study("starcam")
    scn = with_updates(study.load_scenario(), {"validation.new_maps_per_trial": False})  # the run's truths
    pilot = {k: study.trial(scn, 0, k) for k in range(min(PILOT_TRIALS, args.trials))}
    arrays = trial_arrays(pilot)
    samples, tt = arrays.samples, arrays.trial_truths
    targets = truth_targets(study.classes(scn), samples=samples, trial_truths=tt, trials=args.trials)
    from budget.starcam.validate import truths as starcam_truths

    study.truths(capability(study, SizedTruths).truth_size_for(scn, 2, targets), 2)  # the truth kernels' cache warm
    runs = []
    for rep in range(3):   # best of 3 (CPU); other seeds each time: no scene cached twice
        sized, size_wall, size_cpu = _timed(lambda: capability(study, SizedTruths).truth_size_for(scn, 10 + rep, targets))
        ada, ada_wall, ada_cpu = _timed(lambda: study.truths(sized, 10 + rep))
        runs.append((size_cpu + ada_cpu, sized, size_wall, size_cpu, ada, ada_wall, ada_cpu))
    _, sized, size_wall, size_cpu, ada, ada_wall, ada_cpu = min(runs, key=lambda r: r[0])
    fix, fix_wall, fix_cpu = _timed(lambda: study.truths(scn, 1))
    setup = study.prepared(scn)
    plain_raw, pl_wall, pl_cpu = _timed(lambda: starcam_truths(scn, seed=1, control_variate=False, setup=setup))
    plain = study._contract_truths(scn, plain_raw)
    from budget.starcam.truth import te_truth

    # the plain TE truth alone (its share of the plain truths' CPU; HSFE is nearly all the rest)
    cam = study.prepared(scn).camera()
    _, _, te_cpu = _timed(lambda: te_truth(cam, frames=scn.validation.te_truth_frames, seed=3, control_variate=False))
    keys = [(c, a) for c in ("hsfe", "te") for a in ("x", "y")]

    def _ratio(cls):
        return max((plain[(cls, a)].se / targets[(cls, a)]) ** 2 for a in ("x", "y") if (cls, a) in targets)

    equiv = (pl_cpu - te_cpu) * _ratio("hsfe") + te_cpu * _ratio("te")
    task = PointTask("grid", 0, "starcam", "validate", scn, 7, args.trials, None, 7)
    _, own_wall, own_cpu = _timed(lambda: evaluate_point(task))
    from dataclasses import replace

    shared = study.truths(scn, 8)
    _, sh_wall, sh_cpu = _timed(lambda: evaluate_point(replace(task, seed=9, truth_seed=8, truths=shared)))
    v = sized.validation
    print(format_table(["what", "wall s", "CPU s"], [
        [f"sizing for {args.trials} trials (64-frame pilot): HSFE {v.hsfe_truth_frames} frames/phase, "
         f"TE {v.te_truth_frames}", f"{size_wall:.2f}", f"{size_cpu:.2f}"],
        ["the default's truths, sized, reduced (one core, best of 3)", f"{ada_wall:.2f}", f"{ada_cpu:.2f}"],
        ["the default's truths, fixed sizes, reduced (one core)", f"{fix_wall:.2f}", f"{fix_cpu:.2f}"],
        ["the default's truths, fixed sizes, plain (one core)", f"{pl_wall:.2f}", f"{pl_cpu:.2f}"],
        ["plain at the main job's precision (extrapolated)", "", f"{equiv:.0f}"],
        ["budget validate --trials 2 --workers 1, warm, end to end", f"{small[0]:.2f}", f"{small[1]:.2f}"],
        [f"sweep point, {args.trials} trials, its own truths", f"{own_wall:.1f}", f"{own_cpu:.1f}"],
        [f"sweep point, {args.trials} trials, a shared truth", f"{sh_wall:.1f}", f"{sh_cpu:.1f}"],
    ]))
    print(format_table(["class", "axis", "target se", "reduced, sized: se", "reduced, fixed: se", "plain, fixed: se"], [
        [c, a, f"{targets.get((c, a), float('nan')):.2e}", f"{ada[(c, a)].se:.2e}", f"{fix[(c, a)].se:.2e}",
         f"{plain[(c, a)].se:.2e}"] for c, a in keys]))
    emit_result("truths", [
        figure("truths_sized_cpu_s", f"default's truths at the precision of {args.trials} trials, sizing "
               "included, one core (CPU s)", size_cpu + ada_cpu, "s", target=1.0, target_source="project target"),
        figure("truths_fixed_cpu_s", "default's truths, fixed sizes, reduced, one core (CPU s)", fix_cpu, "s"),
        figure("truths_plain_fixed_cpu_s", "default's truths, fixed sizes, plain estimators, one core (CPU s)",
               pl_cpu, "s"),
        figure("truths_plain_equivalent_cpu_s", f"plain estimators at the precision of {args.trials} trials, "
               "extrapolated from their fixed-size standard errors (CPU s)", equiv, "s"),
        figure("validate_trials2_s", "budget validate --trials 2, warm, end to end (wall s)", small[0], "s",
               target=2.0, target_source="project target"),
        figure("validate_trials2_cpu_s", "budget validate --trials 2, warm, end to end (CPU s)", small[1], "s"),
        figure("sweep_point_cpu_s", f"camera sweep point, {args.trials} trials, with its truths (CPU s)",
               own_cpu, "s", target=7.0 if args.trials == 200 else None,
               target_source="project target" if args.trials == 200 else None),
        figure("sweep_point_shared_cpu_s", f"camera sweep point, {args.trials} trials, truth shared (CPU s)",
               sh_cpu, "s"),
    ], quick=args.quick, trials=args.trials, hsfe_truth_frames=v.hsfe_truth_frames,
        te_truth_frames=v.te_truth_frames)


if __name__ == "__main__":
    main()
