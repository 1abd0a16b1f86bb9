"""Lens tracing speed (simcam.starcam.lens) on the embedded star-camera lens, beside its peers.

* **Bundle**: 100,000 rays of one field point and one wavelength through the 9 surfaces,
  Mitsuba ``llvm_ad_rgb`` intersections + double-precision refinement and refraction
  (target: at most 50 ms after warm-up). Beside it, in the same run: the plain-numpy
  reference tracer of the tests (``tests/lens_reference.py``, closed-form sphere
  intersections, float64) on the same rays, and the ``scalar_rgb`` fallback (one Mitsuba
  call per ray and surface) on 500 rays, scaled.
* **First bundle** in this process: includes compiling the Dr.Jit kernels (or loading
  them from Dr.Jit's on-disk kernel cache).
* **Table**: the full products of the prescription, 10 field points x 15 wavelengths
  (best-focus pass with 8,192 rays per bundle, then 100,000 rays per bundle: centroids,
  spots, PSF stamps), with a warm tracer (target: at most 10 s); and reading the same
  table back from the disk cache.

The last line is ``RESULT {json}`` (read by ``run_all.py``).

Usage: ``python benchmarks/bench_lens.py [--repeat 5] [--table-repeat 3] [--quick]``
"""

from __future__ import annotations

import os
import sys
import tempfile
import time

import numpy as np

if not __package__:  # run as a file (python benchmarks/bench_x.py): the repository root on the path
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks._common import (  # noqa: E402
    REPO_ROOT,
    bench_parser,
    emit_result,
    figure,
    format_table,
    print_machine,
)

sys.path.insert(1, str(REPO_ROOT / "tests"))  # the tests' plain-numpy reference tracer

from simcam.starcam.lens.prescription import load_prescription  # noqa: E402
from simcam.starcam.lens.products import LensProducts, compute_products  # noqa: E402
from simcam.starcam.lens.tracer import LensTracer, field_bundle  # noqa: E402


def timings(fn, repeat: int) -> list[float]:
    """Wall-clock seconds of ``repeat`` calls of ``fn`` (after the caller's warm-up)."""
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def span(ts, unit=1e3, fmt="{:.1f}"):
    """``best (range lo-hi)`` of a list of times, in ms by default."""
    ts = np.asarray(ts) * unit
    return f"{fmt.format(ts.min())} ({fmt.format(ts.min())}-{fmt.format(ts.max())})"


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--table-repeat", type=int, default=3)
    args = ap.parse_args()
    if args.quick:
        args.repeat, args.table_repeat = 1, 1
    import tomllib
    from importlib import resources

    import lens_reference as ref

    presc = load_prescription("embedded:star_camera")
    t0 = time.perf_counter()
    tr = LensTracer(presc)
    rays = field_bundle(presc, field_deg=2.5, n_rays=100_000)

    def bundle(wl=600.0):
        return tr.trace(x_mm=rays[0], y_mm=rays[1], z_mm=rays[2], dx=rays[3], dy=rays[4], dz=rays[5],
                        wavelength_nm=wl)

    bundle(550.0)
    first = time.perf_counter() - t0
    wl_cycle = iter(np.tile(np.linspace(400.0, 1000.0, 15), 1000))
    bundle_t = timings(lambda: bundle(next(wl_cycle)), args.repeat * 3)
    c0 = time.process_time()
    for _ in range(5):
        bundle(next(wl_cycle))
    bundle_cpu = (time.process_time() - c0) / 5

    # peer 1: the plain-numpy reference tracer on the same rays
    data = tomllib.loads(resources.files("simcam.data").joinpath("lenses").joinpath("star_camera.toml").read_text())
    data["_glass_coeffs"] = ref.GLASS_COEFFS
    surfs, indices = ref.surfaces_from_prescription_dict(data)
    idx = indices(600.0)
    ref.trace(surfs, idx, *rays)
    numpy_t = timings(lambda: ref.trace(surfs, idx, *rays), args.repeat)

    # peer 2: the scalar fallback, 500 rays
    sc = LensTracer(presc, variant="scalar_rgb")
    few = [a[:500] for a in rays]
    sc.trace(x_mm=few[0][:5], y_mm=few[1][:5], z_mm=few[2][:5], dx=few[3][:5], dy=few[4][:5], dz=few[5][:5],
             wavelength_nm=600.0)
    scalar_t = timings(lambda: sc.trace(x_mm=few[0], y_mm=few[1], z_mm=few[2], dx=few[3], dy=few[4], dz=few[5],
                                        wavelength_nm=600.0), 2)

    # the table, warm tracer
    table_t = []
    prod = None
    for _ in range(args.table_repeat):
        t1 = time.perf_counter()
        prod = compute_products(presc, tracer=tr)
        table_t.append(time.perf_counter() - t1)
    with tempfile.TemporaryDirectory() as d:
        path = prod.save(os.path.join(d, "p.nc"))
        load_t = timings(lambda: LensProducts.load(path), args.repeat)

    n_rays = 100_000
    print_machine()
    print(f"tracer: Mitsuba {tr.variant}, LLVM {'.'.join(map(str, tr.backend.llvm_version))}; "
          f"lens {presc.name}, {len(presc.surfaces)} surfaces")
    print(format_table(
        ["what", "best (range) over repeats", "per ray and surface"],
        [
            ("bundle, 100,000 rays, llvm_ad_rgb (warm)", span(bundle_t) + " ms",
             f"{min(bundle_t) / n_rays / len(presc.surfaces) * 1e9:.1f} ns"),
            ("  same, process CPU time (all threads)", f"{bundle_cpu * 1e3:.1f} ms", ""),
            ("first bundle in this process (JIT or kernel cache)", f"{first * 1e3:.0f} ms", ""),
            ("peer: plain-numpy reference tracer, 100,000 rays", span(numpy_t) + " ms",
             f"{min(numpy_t) / n_rays / len(presc.surfaces) * 1e9:.1f} ns"),
            ("peer: scalar_rgb fallback, 500 rays (x 200 = 100,000)", span(scalar_t) + " ms",
             f"{min(scalar_t) / 500 / len(presc.surfaces) * 1e9:.0f} ns"),
            ("table 10 fields x 15 wavelengths x 100,000 rays (+ focus pass)", span(table_t, 1.0, "{:.2f}") + " s", ""),
            ("table read back from the disk cache (NetCDF)", span(load_t) + " ms", ""),
        ],
    ))
    emit_result("lens", [
        figure("bundle_ms", "bundle of 100,000 rays, 9 surfaces, llvm variant, warm (ms)",
               min(bundle_t) * 1e3, "ms", peer="plain-numpy reference tracer",
               peer_value=min(numpy_t) * 1e3, target=50.0, target_source="project target"),
        figure("bundle_vs_scalar_ms", "bundle of 100,000 rays, 9 surfaces, llvm variant, warm (ms)",
               min(bundle_t) * 1e3, "ms", peer="Mitsuba scalar_rgb (500 rays, x 200)",
               peer_value=min(scalar_t) * 200 * 1e3),
        figure("table_s", "table 10 fields x 15 wavelengths x 100,000 rays (s)", min(table_t), "s",
               target=10.0, target_source="project target"),
    ], quick=args.quick, variant=tr.variant)


if __name__ == "__main__":
    main()
