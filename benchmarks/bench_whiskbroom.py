"""Benchmark: the two speed figures of seed 002's study, numba beside plain numpy.

1. The 1000-trial Monte Carlo synthesis over the arrays (one mirror-rate error): draws,
   knowledge and true states, complex-step image motion at the sampled field (the centre
   plus ``field_cols_per_chip`` columns of each of the three chips at the first and last
   TDI stage: 199 points), residuals, worst column. Target: <= 1 s.
2. The pixel-level MTF of one trial: 96 stages, 4 clock phases, 1000 columns, along and
   across (64 exposure samples per phase). Target: <= 5 ms.

For reference it also times one state's image motion at every pixel of the three arrays
(3 x 96 x 4096) and the slanted-edge image of one trial.

Run: ``python benchmarks/bench_whiskbroom.py [--repeats 5] [--quick]``. JIT compilation is
warmed up first; record the machine load printed with the figures. The last line is
``RESULT {json}`` (read by ``run_all.py``).
"""

from __future__ import annotations

import os
import sys

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


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--trials", type=int, default=1000)
    args = ap.parse_args()
    if args.quick:
        args.repeats = min(args.repeats, 2)
    best = {}

    import numpy as np

    from simcam.whiskbroom import scenario as wsc
    from simcam.whiskbroom import synthesis as sy
    from simcam.whiskbroom import tdi

    sc = wsc.default()
    cam, t = sc.camera, sc.tdi
    rows = []

    def synth(backend):
        return lambda: sy.synthesize(sc, 0, trials=args.trials, backend=backend, mirror_rate_errors=[0.001])

    for name, fn in (("synthesis, numba", synth("numba")), ("synthesis, numpy", synth("numpy"))):
        wall, cpu = best_of_wall_cpu(fn, repeat=args.repeats)
        best[name] = wall
        rows.append((f"{name} ({args.trials} trials x {sy.field_points(sc)[0].size + 1} points)",
                     f"{wall * 1e3:.1f}", f"{cpu * 1e3:.1f}", "<= 1000"))

    kw = dict(n_stages=cam.tdi_stages, n_phase=cam.n_phase, n_time=t.time_samples_per_phase,
              columns=t.columns, aperture_samples=t.aperture_samples)
    a1, c1 = tdi.pixel_mtf(0.002, 0.001, **kw)
    a2, c2 = tdi.pixel_mtf_numpy(0.002, 0.001, **kw)
    assert np.allclose(a1, a2, atol=1e-10) and np.allclose(c1, c2, atol=1e-10)
    for name, fn in (("pixel MTF, numba", lambda: tdi.pixel_mtf(0.002, 0.001, **kw)),
                     ("pixel MTF, numpy", lambda: tdi.pixel_mtf_numpy(0.002, 0.001, **kw))):
        wall, cpu = best_of_wall_cpu(fn, repeat=max(args.repeats, 20))
        best[name] = wall
        rows.append((f"{name} ({cam.tdi_stages} stages x {cam.n_phase} phases x {t.columns} columns)",
                     f"{wall * 1e3:.2f}", f"{cpu * 1e3:.2f}", "<= 5"))

    # reference figures
    x1, x3 = sy.full_field_points(sc)
    p = sy.nominal_params(sc, 0.0)
    wall, cpu = best_of_wall_cpu(lambda: sy._motion(p, x1, x3, "numba"), repeat=3)
    rows.append((f"image motion of one state at all {x1.size} pixels, numba", f"{wall * 1e3:.1f}",
                 f"{cpu * 1e3:.1f}", "-"))
    wall, cpu = best_of_wall_cpu(lambda: tdi.edge_image(0.002, 0.001, n_stages=cam.tdi_stages, n_phase=cam.n_phase,
                                                        n_time=t.edge_time_samples_per_phase, angle_deg=t.edge_angle_deg,
                                                        lines=t.edge_lines, columns=t.edge_columns), repeat=3)
    rows.append((f"slanted-edge TDI image {t.edge_lines} x {t.edge_columns}, numba", f"{wall * 1e3:.1f}",
                 f"{cpu * 1e3:.1f}", "-"))

    print_machine()
    print(format_table(("what", "best wall ms", "best CPU ms", "target ms"), rows))
    full = args.trials == 1000
    emit_result("whiskbroom", [
        figure("synthesis_ms", f"Monte Carlo synthesis, {args.trials} trials (ms)",
               best["synthesis, numba"] * 1e3, "ms", peer="plain numpy",
               peer_value=best["synthesis, numpy"] * 1e3, target=1000.0 if full else None,
               target_source="project target, 1000 trials" if full else None),
        figure("pixel_mtf_ms", "pixel-level TDI MTF of one trial (ms)", best["pixel MTF, numba"] * 1e3,
               "ms", peer="plain numpy", peer_value=best["pixel MTF, numpy"] * 1e3, target=5.0,
               target_source="project target"),
    ], quick=args.quick, trials=args.trials)


if __name__ == "__main__":
    main()
