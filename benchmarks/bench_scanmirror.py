"""Speed of the scan-mirror study (seed 003).

* the full default timeline (two area scans of 120 lines, the star dwell, 590 s) with ground
  points every 0.1 s: world construction (J2-J4 propagation with DOP853), plan, PD attitude,
  deviation, nominal and true ground points; target <= 0.5 s. Side by side: PROJ's ``geos``
  inverse (pyproj) for the same nominal points, the peer for the nominal mapping alone;
* one validation trial (CPU, after warm-up) and ``--trials`` (default 1000) trials on
  ``--workers`` (default 2) processes through the shared runner, wall time including worker
  start-up; target <= 20 s on 2 cores.

The last line is ``RESULT {json}`` (read by ``run_all.py``).

Usage: ``python benchmarks/bench_scanmirror.py [--trials 1000] [--workers 2] [--repeat 5] [--quick]``
"""

from __future__ import annotations

import os
import sys
import time
import warnings

if not __package__:  # run as a file (python benchmarks/bench_x.py): the repository root on the path
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks._common import (  # noqa: E402
    bench_parser,
    best_of_wall_cpu,
    emit_result,
    figure,
    format_table,
    print_machine,
)

import numpy as np  # noqa: E402


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--trials", type=int, default=1000)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    if args.quick:
        args.trials, args.repeat = min(args.trials, 20), min(args.repeat, 2)
    warnings.simplefilter("ignore")
    import pyproj

    from budget.runner.run import run_study
    from budget.scanmirror.study import STUDY
    from simcam.scanmirror.world import World

    scn = STUDY.load_scenario()
    print_machine()
    rows = []
    wall, cpu = best_of_wall_cpu(lambda: World(scn).timeline(0.1), repeat=args.repeat)
    tl = World(scn).timeline(0.1)
    n = tl["t_s"].size
    rows.append(("timeline 590 s every 0.1 s (ours, numpy)", n, f"{wall:.3f}", f"{cpu:.3f}", "<= 0.5"))
    w = World(scn)
    h = (w.R0_km - w.earth.radius_km) * 1e3
    proj = pyproj.Proj(f"+proj=geos +h={h} +lon_0={scn.orbit.nominal_longitude_deg} +sweep=x "
                       f"+R={w.earth.radius_km * 1e3} +units=m +no_defs")
    x = 2 * (tl["beta_rad"] + np.pi / 4) * h
    y = tl["alpha_rad"] * h
    wall_p, cpu_p = best_of_wall_cpu(lambda: proj(x, y, inverse=True), repeat=args.repeat)
    rows.append(("nominal mapping only (pyproj geos inverse)", n, f"{wall_p:.4f}", f"{cpu_p:.4f}", "peer"))
    wall_n, cpu_n = best_of_wall_cpu(lambda: w.latlon(w.nominal_ground(tl["alpha_rad"], tl["beta_rad"])),
                                     repeat=args.repeat)
    rows.append(("nominal mapping only (ours)", n, f"{wall_n:.4f}", f"{cpu_n:.4f}", ""))
    STUDY.trial(scn, 0, 0)
    wall_t, cpu_t = best_of_wall_cpu(lambda: STUDY.trial(scn, 0, 1), repeat=max(args.repeat, 20))
    rows.append(("one validation trial (after set-up)", 1, f"{wall_t:.4f}", f"{cpu_t:.4f}", ""))
    import resource

    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    c0, t0 = time.process_time(), time.perf_counter()
    res = run_study(STUDY, scn, trials=args.trials, seed=1, workers=args.workers)
    total = time.perf_counter() - t0
    ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    # CPU of the parent plus the worker processes (children are counted once they exit)
    cpu_all = (time.process_time() - c0) + (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
    rows.append((f"{args.trials} trials, {args.workers} processes (run_study)", res.trials, f"{total:.2f}",
                 f"{cpu_all:.2f}", "<= 20"))
    print(format_table(("what", "points/trials", "wall s", "cpu s", "target s"), rows))
    print("load after:", " ".join(f"{x:.2f}" for x in os.getloadavg()))
    print("cpu s of the run: all processes; on an idle 2-core machine the wall time is about cpu / 2")
    full = args.trials == 1000 and args.workers == 2
    emit_result("scanmirror", [
        figure("timeline_s", "full default timeline every 0.1 s (s)", wall, "s", target=0.5,
               target_source="project target"),
        figure("nominal_mapping_ms", "nominal mapping of the timeline's points (ms)", wall_n * 1e3, "ms",
               peer="pyproj geos inverse", peer_value=wall_p * 1e3),
        figure("trials_s", f"{args.trials} validation trials, {args.workers} processes (s)", total, "s",
               target=20.0 if full else None, target_source="project target, 1000 trials on 2 cores" if full else None),
    ], quick=args.quick, trials=args.trials, workers=args.workers)


if __name__ == "__main__":
    main()
