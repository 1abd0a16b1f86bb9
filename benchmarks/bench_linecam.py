"""Speed of the line-camera calibration (seed 004), the three figures it names.

1. **Star selection and identification for a 10 deg strip** (target <= 50 ms): the lab's
   catalogue stars of one pass of the default strip (Hipparcos cone, V <= 8), their
   apparent places through astropy/ERFA (:mod:`simcam.sky`), and the identification of the
   pass's centroids (nearest catalogue star by a KD-tree) -- beside the same
   identification by a plain numpy brute-force angular-distance matrix.
2. **One calibration of a few hundred star observations** (target <= 20 ms): the published
   (exterior/interior alternation) and the improved (joint Gauss-Newton, gauge removed)
   estimators on trial 0's identified stars -- beside scipy.optimize.least_squares on the
   same residuals (eight separable parameters).
3. **1000 validation trials on 2 cores** (target <= 60 s): ``run_study(trials=1000,
   workers=2)`` wall time, process start-up and the sky set-up included.

The JIT is warmed up before timing; best of ``--repeat``. The machine is shared: the load
is printed with the figures (``machine_description``).

The last line is ``RESULT {json}`` (read by ``run_all.py``).

Run: ``python benchmarks/bench_linecam.py [--repeat 7] [--trials 1000] [--skip-validation | --only-validation] [--quick]``
"""

from __future__ import annotations

import math
import os
import sys
import time

import numpy as np

if not __package__:  # run as a file (python benchmarks/bench_x.py): the repository root on the path
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks._common import (  # noqa: E402
    bench_parser,
    best_of,
    emit_result,
    figure,
    format_table,
    print_machine,
)


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--trials", type=int, default=1000)
    ap.add_argument("--skip-validation", action="store_true")
    ap.add_argument("--only-validation", action="store_true")
    args = ap.parse_args()
    if args.quick:
        args.repeat, args.trials = min(args.repeat, 2), min(args.trials, 20)
    figs = []

    import numba
    from astropy.time import Time
    from scipy.optimize import least_squares
    from scipy.spatial import cKDTree

    from budget.linecam.calibrate import calibrate_joint, calibrate_published
    from budget.linecam.model import NominalCamera, residuals
    from budget.linecam.study import STUDY
    from budget.linecam.trial import region, simulate
    from budget.runner.study import trial_seed_sequence
    from simcam.linecam.attitude import orbit_state, scan_plan
    from simcam.linecam.scenario import PARAMETERS
    from simcam.linecam.world import strip_radius_rad
    from simcam.sky.apparent import apparent_directions
    from simcam.sky.catalogue import hipparcos

    numba.set_num_threads(1)
    scn = STUDY.load_scenario()
    rows = []

    if args.only_validation:
        figs.append(_validation(args, rows, STUDY, scn))
        print_machine()
        print(format_table(["what", "size", "ms"], rows))
        emit_result("linecam", figs, quick=args.quick, trials=args.trials)
        return

    # ------------------------------------------------------------ 1. selection + identification
    reg = region(scn)
    cat_all = hipparcos()
    plan = scan_plan(scn, ra_deg=reg.ra_deg, dec_deg=reg.dec_deg)
    ra, dec = math.radians(reg.ra_deg), math.radians(reg.dec_deg)
    centre = np.array([math.cos(dec) * math.cos(ra), math.cos(dec) * math.sin(ra), math.sin(dec)])
    epoch = Time(scn.orbit.epoch_utc, scale="utc")
    sim = simulate(scn, trial_seed_sequence(0, 0))
    idf = sim.identified
    cam = NominalCamera.from_model(scn.camera)
    sel0 = idf.obs.pass_index == 0
    sample, att = idf.obs.sample[sel0], idf.attitude[sel0]
    c = np.column_stack([np.full(sample.size, cam.x_line_px), cam.y_px(sample), np.full(sample.size, -cam.f_px)])
    c /= np.linalg.norm(c, axis=1, keepdims=True)
    w = np.einsum("nij,nj->ni", att, c)
    import astropy.units as u

    pos, vel = orbit_state(scn, plan.t_mid_s[0])

    def select():
        cat = cat_all.cone(centre, strip_radius_rad(scn), mag_limit=scn.stars.mag_limit)
        return cat, apparent_directions(cat, epoch + plan.t_mid_s[0] * u.s, observer_position_km=pos,
                                        observer_velocity_km_s=vel)

    cat, dirs = select()

    def identify_kd():
        d, j = cKDTree(dirs).query(w, k=2)
        return j[:, 0]

    def identify_brute():
        return np.argmax(w @ dirs.T, axis=1)

    assert np.array_equal(identify_kd(), identify_brute())
    t_sel, _ = best_of(select, repeat=args.repeat)
    t_kd, _ = best_of(identify_kd, repeat=args.repeat)
    t_bf, _ = best_of(identify_brute, repeat=args.repeat)
    rows.append(["selection + apparent places (astropy), 10 deg strip", f"{len(cat)} stars", f"{t_sel * 1e3:.1f}"])
    rows.append(["identification, KD-tree", f"{sample.size} centroids", f"{t_kd * 1e3:.2f}"])
    rows.append(["identification, numpy brute force (peer)", f"{sample.size} centroids", f"{t_bf * 1e3:.2f}"])
    rows.append(["-> selection and identification (target <= 50 ms)", "", f"{(t_sel + t_kd) * 1e3:.1f}"])
    figs += [
        figure("select_identify_ms", "star selection and identification, 10 deg strip (ms)",
               (t_sel + t_kd) * 1e3, "ms", target=50.0, target_source="project target"),
        figure("identify_ms", "identification of one pass's centroids, KD-tree (ms)", t_kd * 1e3, "ms",
               peer="numpy brute force", peer_value=t_bf * 1e3),
    ]

    # ------------------------------------------------------------ 2. one calibration
    obs = idf.obs
    t_pub, _ = best_of(lambda: calibrate_published(cam, obs, coverage_bins=scn.lab.coverage_bins,
                                                   max_iter=scn.lab.max_iter), repeat=args.repeat)
    t_joint, _ = best_of(lambda: calibrate_joint(cam, obs, rcond=scn.lab.rcond), repeat=args.repeat)
    sub = ("roll", "pitch", "yaw", "df", "k1", "k2", "p1", "p2")
    idx = [PARAMETERS.index(p) for p in sub]

    def fun(x):
        th = np.zeros(10)
        th[idx] = x
        return residuals(cam, th, obs)

    t_ls, _ = best_of(lambda: least_squares(fun, np.zeros(len(sub)),
                                            x_scale=np.array([1e-4] * 3 + [0.1] + [1e-4] * 4)),
                      repeat=args.repeat)
    n = len(obs)
    rows.append(["calibration, published (exterior/interior)", f"{n} stars", f"{t_pub * 1e3:.2f}"])
    rows.append(["calibration, improved (joint, gauge removed)", f"{n} stars", f"{t_joint * 1e3:.2f}"])
    rows.append(["scipy least_squares, 8 parameters (peer)", f"{n} stars", f"{t_ls * 1e3:.2f}"])
    figs += [
        figure("calibration_joint_ms", f"one calibration, improved (joint), {n} stars (ms)", t_joint * 1e3,
               "ms", peer="scipy least_squares, 8 parameters", peer_value=t_ls * 1e3, target=20.0,
               target_source="project target"),
        figure("calibration_published_ms", f"one calibration, published, {n} stars (ms)", t_pub * 1e3,
               "ms", target=20.0, target_source="project target"),
    ]

    # ------------------------------------------------------------ 3. validation
    if not args.skip_validation:
        figs.append(_validation(args, rows, STUDY, scn))

    print_machine()
    print(format_table(["what", "size", "ms"], rows))
    emit_result("linecam", figs, quick=args.quick, trials=args.trials)


def _validation(args, rows, STUDY, scn) -> dict:
    """Figure 3: run_study(trials, workers=2): wall time and the workers' CPU time; its figure."""
    import resource

    from budget.runner.run import run_study

    c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    res = run_study(STUDY, scn, trials=args.trials, workers=2)
    wall = time.perf_counter() - t0
    c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    # CPU seconds of the worker processes (user + system, counted when the pool exits):
    # on an idle 2-core machine the run takes about this / 2 plus the parent's set-up
    cpu = (c1.ru_utime - c0.ru_utime) + (c1.ru_stime - c0.ru_stime)
    rows.append([f"validation, {res.trials} trials, 2 worker processes (target <= 60 s)", res.executor,
                 f"{wall * 1e3:.0f}"])
    per = wall / res.trials
    rows.append(["  per trial (wall, 2 workers)", "", f"{per * 1e3:.1f}"])
    rows.append(["  CPU of the 2 workers, total (idle 2-core estimate: half)", "", f"{cpu * 1e3:.0f}"])
    full = res.trials == 1000
    return figure("validation_s", f"validation, {res.trials} trials, 2 worker processes (s)", wall, "s",
                  target=60.0 if full else None,
                  target_source="project target, 1000 trials on 2 cores" if full else None)


if __name__ == "__main__":
    main()
