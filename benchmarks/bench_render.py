"""Rendering speed of the simulator on the embedded seed-000 scenario, beside plain numpy.

* **Full frame**: one 2048 x 4096 two-chip mosaic with the 25-star target and every
  detector effect (PRNU, dark + DSNU, shot noise, read noise, full well, per-chip ADC),
  from a cached scene (PSF stamps computed once, as for a sequence of frames): the
  expected-signal image (background + stamps) and the detector chain. Beside it, plain
  numpy doing the same noise on the same expected image with one ``Generator``
  (``poisson`` + ``normal`` + ADC ops, maps drawn per frame as the kernel does).
* **Scene**: computing the 25 stars' spectra, distortion, colour and PSF stamps once.
* **Windows**: 11x11 windows (noise included) per second for 25 stars x 2000 frames,
  numba serial and threaded.
* **Memory**: tracemalloc peak of rendering one full frame, and the growth of the
  process's maximum resident set over one frame.

Usage: ``python benchmarks/bench_render.py [--repeat 5]``
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import time

import numpy as np

_HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, _HERE)
sys.path.insert(1, os.path.dirname(_HERE))
from _common import best_of_wall_cpu, format_table, machine_description, peak_traced_mb  # noqa: E402

from simcam.render import Placement, StarCamera  # noqa: E402
from simcam.scenario import default_scenario  # noqa: E402
from simcam.targets import star_grid  # noqa: E402


def numpy_frame(expected_e: np.ndarray, scn, seed: int) -> np.ndarray:
    """The same detector chain in plain numpy (one Generator)."""
    rng = np.random.default_rng(seed)
    det = scn.detector
    rows, cols = expected_e.shape
    prnu = np.clip(1.0 + det.prnu_rms * rng.standard_normal((rows, cols)), 0, None)
    dark = np.clip(det.dark_current_e_per_s * scn.camera.exposure_s + det.dsnu_rms_e * rng.standard_normal((rows, cols)), 0, None)
    e = rng.poisson(expected_e * prnu + dark).astype(np.float64)
    out = np.empty((rows, cols), dtype=np.uint16)
    cc = det.chip_cols
    for k, chip in enumerate(det.chips):
        sl = np.s_[:, k * cc:(k + 1) * cc]
        v = np.minimum(e[sl], chip.full_well_e) + chip.read_noise_e * rng.standard_normal((rows, cc))
        v = np.floor(v / chip.gain_e_per_dn + chip.offset_dn + 0.5)
        out[sl] = np.clip(v, 0, 2**det.bits - 1)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    scn = default_scenario()
    cam = StarCamera(scn)
    placement = Placement(layout=star_grid(scn))
    t0 = time.perf_counter()
    scene = cam.scene(placement)  # includes JIT load of the PSF kernel
    first_scene = time.perf_counter() - t0
    cam2 = StarCamera(scn)
    scene_s = best_of_wall_cpu(lambda: cam2._scene(placement), repeat=args.repeat)

    counter = iter(range(10**9))

    def sim_frame():
        exp = cam.expected_frame_e(scene)
        return cam.render_frame(scene, frame=next(counter), seed=1, expected_e=exp)

    expected = cam.expected_frame_e(scene)
    full = best_of_wall_cpu(sim_frame, repeat=args.repeat)
    nump = best_of_wall_cpu(lambda: numpy_frame(expected, scn, next(counter)), repeat=max(2, args.repeat // 2))
    peak_mb = peak_traced_mb(sim_frame)
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    sim_frame()
    rss_growth = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0) / 1024.0

    frames = 2000
    rows = []
    for par in (False, True):
        c = StarCamera(scn, parallel=par)
        sc = c.scene(placement)
        c.render_windows(sc, frames=2, seed=0)
        w, _ = best_of_wall_cpu(lambda: c.render_windows(sc, frames=frames, seed=3), repeat=3)
        rows.append((f"windows 11x11, numba {'threads' if par else 'serial'}", f"{frames * 25 / w:,.0f} windows/s",
                     f"{w / (frames * 25) * 1e6:.2f} us/window"))

    print("machine:", ", ".join(f"{k}={v}" for k, v in machine_description().items()))
    print(format_table(
        ["what", "wall", "CPU (all threads)"],
        [
            ("full frame 2048x4096, 25 stars, simcam", f"{full[0] * 1e3:.0f} ms", f"{full[1] * 1e3:.0f} ms"),
            ("same noise, plain numpy Generator", f"{nump[0] * 1e3:.0f} ms", f"{nump[1] * 1e3:.0f} ms"),
            ("scene: spectra, distortion, colour, 25 PSF stamps", f"{scene_s[0] * 1e3:.1f} ms",
             f"{scene_s[1] * 1e3:.1f} ms"),
            ("first scene in this process (JIT cache load)", f"{first_scene * 1e3:.0f} ms", ""),
            *[(a, b, c_) for a, b, c_ in rows],
            ("peak memory, one full frame (tracemalloc)", f"{peak_mb:.0f} MB", ""),
            ("max RSS growth over one full frame", f"{rss_growth:.0f} MB", ""),
        ],
    ))


if __name__ == "__main__":
    main()
