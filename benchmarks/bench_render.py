"""Rendering speed of the simulator on the embedded seed-000 scenario, beside plain numpy.

* **Full frame**: one 2048 x 4096 mosaic (two 2048 x 2048 chips: "2 x 2048^2") with the
  25-star target and every detector effect of the default (realistic) world: PRNU, dark +
  DSNU, the integral non-linearity (``nonlinearity_beta`` 0.008), shot noise, read noise,
  full well, per-chip ADC; from a cached scene (PSF stamps computed once, as for a
  sequence of frames): the expected-signal image (background + stamps) and the detector
  chain, with the detector's fixed-pattern maps (PRNU, DSNU) computed on the camera's first
  frame and kept (``StarCamera.frame_maps``: a property of the detector, 134 MB). Beside
  it, plain numpy doing the same noise on the same expected image with one ``Generator``
  (``poisson`` + ``normal`` + ADC ops, no non-linearity), its PRNU and DSNU maps drawn
  once as ours are; and, labelled, with the maps drawn every frame (the old peer figure).
* **Detector chain alone** on the cached expected image (``simcam.detector.expose`` with
  the maps of ``simcam.detector.detector_maps`` computed once: per frame one numba pass
  drawing only the frame's Poisson counts and read noise), realistic (non-linearity on)
  and ideal (the same scenario with ``nonlinearity_beta`` 0); the fused chain that draws
  the maps in every frame (``expose`` without maps, the same pixels) and the maps alone.
  Its **random-number floor**: the frame's draws alone, with the maps precomputed (the
  Poisson count of each pixel's true mean charge and the read-noise normal, their first
  words in a loop of their own as the chain does), in the same chunked loops over rows on
  the same threads, and nothing else (no arithmetic, no output frame); and the old floor,
  labelled, which also draws the maps' PRNU and DSNU normals every frame.
* **Scene**: computing the 25 stars' spectra, distortion, colour and PSF stamps once.
* **Windows**: 11x11 windows (noise included) per second for 25 stars x 2000 frames,
  numba serial and threaded.
* **Memory**: tracemalloc peak of rendering one full frame, and the growth of the
  process's maximum resident set over one frame.
* **Peer**, optional (reported as "not installed" when absent): GalSim drawing 25 Airy
  stars (FWHM 1.5 px, 33 x 33 px stamps, 1e5 e- each) on a 4096 x 2048 ``ImageD`` with
  the same background level as our expected image, then ``CCDNoise`` (Poisson + read
  noise + gain of chip 0); and the 25 stars alone.

The last line is ``RESULT {json}`` (read by ``run_all.py``).

Usage: ``python benchmarks/bench_render.py [--repeat 5] [--quick]``
"""

from __future__ import annotations

import os
import resource
import sys
import time

import dataclasses

import numpy as np
from numba import njit, prange

if not __package__:  # run as a file (python benchmarks/bench_x.py): the repository root on the path
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks._common import (  # noqa: E402
    bench_parser,
    best_of_wall_cpu,
    emit_result,
    figure,
    format_table,
    optional_import,
    peak_traced_mb,
    print_machine,
)

from simcam.detector import detector_maps, expose, window_chain  # noqa: E402
from simcam.kernels.detector import (  # noqa: E402
    SLOT_DSNU, SLOT_HOT, SLOT_PRNU, SLOT_READ, SLOT_SHOT, slot_counter,
)
from simcam.rng import random_bits64, std_normal, std_normal_from_word, uniform01  # noqa: E402
from simcam.rng_poisson import poisson, poisson_from_word  # noqa: E402
from simcam.starcam.render import Placement, StarCamera  # noqa: E402
from simcam.starcam.scenario import default  # noqa: E402
from simcam.starcam.targets import star_grid  # noqa: E402


def numpy_maps(shape, scn, seed: int):
    """numpy's PRNU factor and dark signal (DSNU) of the detector."""
    rng = np.random.default_rng(seed)
    det = scn.detector
    prnu = np.clip(1.0 + det.prnu_rms * rng.standard_normal(shape), 0, None)
    dark = np.clip(det.dark_current_e_per_s * scn.camera.exposure_s + det.dsnu_rms_e * rng.standard_normal(shape), 0, None)
    return prnu, dark


def numpy_frame(expected_e: np.ndarray, scn, seed: int, maps=None) -> np.ndarray:
    """The same detector chain in plain numpy (one Generator); ``maps`` from
    :func:`numpy_maps` (computed once), else drawn in this frame."""
    rng = np.random.default_rng(seed)
    det = scn.detector
    rows, cols = expected_e.shape
    prnu, dark = numpy_maps((rows, cols), scn, seed + 10**9) if maps is None else maps
    e = rng.poisson(expected_e * prnu + dark).astype(np.float64)
    out = np.empty((rows, cols), dtype=np.uint16)
    cc = det.chip_cols
    for k, chip in enumerate(det.chips):
        sl = np.s_[:, k * cc:(k + 1) * cc]
        v = np.minimum(e[sl], chip.full_well_e) + chip.read_noise_e * rng.standard_normal((rows, cc))
        v = np.floor(v / chip.gain_e_per_dn + chip.offset_dn + 0.5)
        out[sl] = np.clip(v, 0, 2**det.bits - 1)
    return out


@njit(parallel=True)
def _draws_floor(mean_e, mosaic_cols, prnu, dsnu, hot, frame_key, detector_key, sums):
    """The old floor (the maps drawn every frame): the random numbers of a full frame alone: per pixel the draws the detector chain
    makes (PRNU and DSNU normals, hot-pixel uniform when ``hot``, the Poisson count of the
    pixel's mean charge ``mean_e``, the read-noise normal) with the same generator, keys
    and counters, in 512-pixel chunks of rows on numba threads as the chain does; the sum
    of each row's draws into ``sums`` (so that nothing is optimised away)."""
    h, w = mean_e.shape
    for i in prange(h):
        base = i * mosaic_cols
        acc = 0.0
        for j0 in range(0, w, 512):
            j1 = min(w, j0 + 512)
            if prnu:
                for j in range(j0, j1):
                    acc += std_normal(detector_key, slot_counter(base + j, SLOT_PRNU))
            if dsnu:
                for j in range(j0, j1):
                    acc += std_normal(detector_key, slot_counter(base + j, SLOT_DSNU))
            if hot:
                for j in range(j0, j1):
                    acc += uniform01(detector_key, slot_counter(base + j, SLOT_HOT))
            for j in range(j0, j1):
                acc += poisson(mean_e[i, j], frame_key, slot_counter(base + j, SLOT_SHOT))
            for j in range(j0, j1):
                acc += std_normal(frame_key, slot_counter(base + j, SLOT_READ))
        sums[i] = acc


@njit(parallel=True)
def _frame_draws_floor(mean_e, mosaic_cols, frame_key, sums):
    """The random numbers of one frame with the maps precomputed: per pixel the Poisson
    count of its mean charge ``mean_e`` and the read-noise normal, as the per-frame pass
    draws them (first words in a loop of their own, then the samplers given their word),
    in 512-pixel chunks of rows on numba threads; the sum of each row's draws into ``sums``."""
    h, w = mean_e.shape
    for i in prange(h):
        base = i * mosaic_cols
        acc = 0.0
        wp = np.empty(512, dtype=np.uint64)
        wr = np.empty(512, dtype=np.uint64)
        for j0 in range(0, w, 512):
            j1 = min(w, j0 + 512)
            for j in range(j0, j1):
                wp[j - j0] = random_bits64(frame_key, slot_counter(base + j, SLOT_SHOT))
                wr[j - j0] = random_bits64(frame_key, slot_counter(base + j, SLOT_READ))
            for j in range(j0, j1):
                acc += poisson_from_word(mean_e[i, j], wp[j - j0], frame_key, slot_counter(base + j, SLOT_SHOT))
            for j in range(j0, j1):
                acc += std_normal_from_word(wr[j - j0], frame_key, slot_counter(base + j, SLOT_READ))
        sums[i] = acc


def galsim_frame(galsim, scn, shape: tuple[int, int], background_e: float, seed: int, *,
                 noise: bool = True):
    """25 Airy stars on a full frame with GalSim, then its CCD noise (chip 0's gain, read noise)."""
    det = scn.detector
    rows, cols = shape
    img = galsim.ImageD(cols, rows, scale=1.0, init_value=background_e)
    psf = galsim.Airy(lam_over_diam=1.5 / 1.028).withFlux(1e5)       # FWHM = 1.028 lambda/D = 1.5 px
    for x in np.linspace(300.0, cols - 300.0, 5):
        for y in np.linspace(200.0, rows - 200.0, 5):
            stamp = psf.drawImage(nx=33, ny=33, scale=1.0, center=galsim.PositionD(x + 0.3, y + 0.7))
            b = stamp.bounds & img.bounds
            img[b] += stamp[b]
    if noise:
        chip = det.chips[0]
        img.addNoise(galsim.CCDNoise(galsim.BaseDeviate(seed), sky_level=0.0,
                                     gain=chip.gain_e_per_dn, read_noise=chip.read_noise_e))
    return img


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--frames", type=int, default=2000, help="frames of the windows benchmark")
    args = ap.parse_args()
    if args.quick:
        args.repeat, args.frames = min(args.repeat, 2), min(args.frames, 200)
    galsim = optional_import("galsim")
    scn = default()
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
    # a fresh camera's first frame computes the maps (kept for the next frames)
    cam_first = StarCamera(scn)
    first_peak_mb = peak_traced_mb(lambda: cam_first.render_frame(scene, frame=0, seed=1, expected_e=expected))
    del cam_first
    full = best_of_wall_cpu(sim_frame, repeat=args.repeat)

    # the detector chain alone (realistic and ideal) and the random numbers alone
    params = cam.detector_params
    ideal = dataclasses.replace(params, nonlinearity_beta=0.0)
    rows_, cols_ = expected.shape

    def make_maps():
        return detector_maps(shape=(rows_, cols_), row0=0, col0=0, mosaic_cols=cols_, params=params,
                             detector_key=cam.detector_key)

    maps_s = best_of_wall_cpu(make_maps, repeat=max(2, args.repeat // 2))
    maps = make_maps()  # the same for the ideal scenario (beta does not enter the maps)

    def chain(p, m=None):
        return lambda: expose(signal_e=expected, row0=0, col0=0, mosaic_cols=cols_,
                              chip_cols=cam.mosaic.chip_cols, params=p,
                              frame_key=cam.frame_key(seed=1, condition=0, frame=next(counter)),
                              detector_key=cam.detector_key, maps=m)

    chain_real = best_of_wall_cpu(chain(params, maps), repeat=args.repeat)
    chain_ideal = best_of_wall_cpu(chain(ideal, maps), repeat=args.repeat)
    chain_fused = best_of_wall_cpu(chain(params), repeat=args.repeat)
    mean_e = window_chain(signal_e=expected[None], row0=[0], col0=[0], mosaic_cols=cols_,
                          chip_cols=cam.mosaic.chip_cols, params=params,
                          detector_key=cam.detector_key).mean_e[0]
    sums = np.empty(rows_)

    def floor():
        _draws_floor(mean_e, cols_, params.prnu_rms != 0.0, params.dsnu_rms_e > 0.0,
                     params.hot_pixel_fraction > 0.0, cam.frame_key(seed=1, condition=0, frame=next(counter)),
                     cam.detector_key, sums)

    old_floor_s = best_of_wall_cpu(floor, repeat=args.repeat)
    floor_s = best_of_wall_cpu(lambda: _frame_draws_floor(mean_e, cols_, cam.frame_key(
        seed=1, condition=0, frame=next(counter)), sums), repeat=args.repeat)
    nmaps = numpy_maps(expected.shape, scn, 7)
    nump = best_of_wall_cpu(lambda: numpy_frame(expected, scn, next(counter), nmaps), repeat=max(2, args.repeat // 2))
    del nmaps
    nump_every = best_of_wall_cpu(lambda: numpy_frame(expected, scn, next(counter)), repeat=max(2, args.repeat // 2))
    peak_mb = peak_traced_mb(sim_frame)
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    sim_frame()
    rss_growth = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0) / 1024.0

    frames = args.frames
    rows = []
    for par in (False, True):
        c = StarCamera(scn, parallel=par)
        sc = c.scene(placement)
        c.render_windows(sc, frames=2, seed=0)
        w, _ = best_of_wall_cpu(lambda: c.render_windows(sc, frames=frames, seed=3), repeat=3)
        rows.append((f"windows 11x11, numba {'threads' if par else 'serial'}", f"{frames * 25 / w:,.0f} windows/s",
                     f"{w / (frames * 25) * 1e6:.2f} us/window"))
        rate = frames * 25 / w
        if not par:
            rate_serial = rate
        else:
            rate_threads = rate

    gal = gal_stars = None
    if galsim is not None:
        bg = float(np.median(expected))
        gal = best_of_wall_cpu(lambda: galsim_frame(galsim, scn, expected.shape, bg, next(counter)),
                               repeat=max(2, args.repeat // 2))
        gal_stars = best_of_wall_cpu(lambda: galsim_frame(galsim, scn, expected.shape, bg, 0, noise=False),
                                     repeat=args.repeat)
        peer_rows = [("peer: GalSim 25 Airy stars + CCDNoise, full frame", f"{gal[0] * 1e3:.0f} ms",
                      f"{gal[1] * 1e3:.0f} ms"),
                     ("peer: GalSim 25 Airy stars alone (no noise)", f"{gal_stars[0] * 1e3:.1f} ms",
                      f"{gal_stars[1] * 1e3:.1f} ms")]
    else:
        peer_rows = [("peer: GalSim not installed", "", "")]

    import numba

    print_machine(numba_threads=numba.get_num_threads())
    print(format_table(
        ["what", "wall", "CPU (all threads)"],
        [
            ("full frame 2048x4096 (2 x 2048^2), 25 stars, realistic chain: expected image + detector",
             f"{full[0] * 1e3:.0f} ms", f"{full[1] * 1e3:.0f} ms"),
            ("detector chain alone, realistic (non-linearity on), maps computed once: per frame",
             f"{chain_real[0] * 1e3:.0f} ms", f"{chain_real[1] * 1e3:.0f} ms"),
            ("detector chain alone, ideal (non-linearity off), maps computed once: per frame",
             f"{chain_ideal[0] * 1e3:.0f} ms", f"{chain_ideal[1] * 1e3:.0f} ms"),
            ("detector maps alone (PRNU factor, dark signal; once per camera)", f"{maps_s[0] * 1e3:.0f} ms",
             f"{maps_s[1] * 1e3:.0f} ms"),
            ("detector chain alone, realistic, fused: maps drawn every frame", f"{chain_fused[0] * 1e3:.0f} ms",
             f"{chain_fused[1] * 1e3:.0f} ms"),
            ("random-number floor: the frame's draws alone (Poisson + read normal, maps precomputed)",
             f"{floor_s[0] * 1e3:.0f} ms", f"{floor_s[1] * 1e3:.0f} ms"),
            ("old random-number floor: the frame's and the maps' draws (every frame)",
             f"{old_floor_s[0] * 1e3:.0f} ms", f"{old_floor_s[1] * 1e3:.0f} ms"),
            ("same noise, plain numpy Generator, maps drawn once: per frame", f"{nump[0] * 1e3:.0f} ms",
             f"{nump[1] * 1e3:.0f} ms"),
            ("same noise, plain numpy Generator, maps drawn every frame (old peer)",
             f"{nump_every[0] * 1e3:.0f} ms", f"{nump_every[1] * 1e3:.0f} ms"),
            ("scene: spectra, distortion, colour, 25 PSF stamps", f"{scene_s[0] * 1e3:.1f} ms",
             f"{scene_s[1] * 1e3:.1f} ms"),
            ("first scene in this process (JIT cache load)", f"{first_scene * 1e3:.0f} ms", ""),
            *[(a, b, c_) for a, b, c_ in rows],
            ("peak memory, one full frame, maps kept (tracemalloc)", f"{peak_mb:.0f} MB", ""),
            ("peak memory, a camera's first full frame, maps computed in it (tracemalloc)",
             f"{first_peak_mb:.0f} MB", ""),
            ("detector maps kept by the camera", f"{maps.nbytes / 1e6:.0f} MB", ""),
            ("max RSS growth over one full frame", f"{rss_growth:.0f} MB", ""),
            *peer_rows,
        ],
    ))
    gstat = None if galsim is not None else "not installed"
    what = "full 2048x4096 frame, 25 stars, every detector effect of the realistic world (wall ms)"
    emit_result("render", [
        figure("full_frame_ms", what, full[0] * 1e3, "ms",
               peer="plain numpy Generator (same noise, maps drawn once)", peer_value=nump[0] * 1e3, target=150.0, target_source="project target"),
        figure("full_frame_vs_galsim_ms", what, full[0] * 1e3, "ms",
               peer="GalSim 25 Airy stars + CCDNoise", peer_value=None if gal is None else gal[0] * 1e3,
               peer_status=gstat, target=150.0, target_source="project target"),
        figure("chain_ms", "detector chain alone, full 2048x4096 frame, realistic, maps computed once: "
               "per frame (wall ms)", chain_real[0] * 1e3, "ms",
               peer="random-number floor (the frame's draws alone, maps precomputed)",
               peer_value=floor_s[0] * 1e3, target=60.0, target_source="project target"),
        figure("chain_ideal_ms", "detector chain alone, full 2048x4096 frame, ideal, maps computed once: "
               "per frame (wall ms)", chain_ideal[0] * 1e3, "ms",
               peer="random-number floor (the frame's draws alone, maps precomputed)",
               peer_value=floor_s[0] * 1e3, target=60.0, target_source="project target"),
        figure("chain_cpu_ms", "detector chain alone, realistic, maps computed once (CPU ms, all threads)",
               chain_real[1] * 1e3, "ms", peer="random-number floor (CPU ms)", peer_value=floor_s[1] * 1e3),
        figure("chain_fused_ms", "detector chain alone, realistic, fused: maps drawn every frame (wall ms)",
               chain_fused[0] * 1e3, "ms", peer="old random-number floor (the frame's and the maps' draws)",
               peer_value=old_floor_s[0] * 1e3),
        figure("chain_maps_ms", "detector maps alone, once per camera (wall ms)", maps_s[0] * 1e3, "ms"),
        figure("scene_ms", "scene: 25 stars' spectra, distortion, colour, PSF stamps (ms)",
               scene_s[0] * 1e3, "ms", peer="GalSim 25 Airy stars drawn (monochromatic)",
               peer_value=None if gal_stars is None else gal_stars[0] * 1e3, peer_status=gstat),
        figure("windows_per_s_serial", "noisy 11x11 windows per second, one core", rate_serial,
               "windows/s", better="higher", target=100_000, target_source="project target"),
        figure("windows_per_s_threads", "noisy 11x11 windows per second, numba threads",
               rate_threads, "windows/s", better="higher", target=100_000, target_source="project target"),
        figure("peak_mb", "peak memory, one full frame, maps kept (MB, tracemalloc)", peak_mb, "MB",
               target=300.0, target_source="project target"),
        figure("first_frame_peak_mb", "peak memory, a camera's first full frame, maps computed in it "
               "(MB, tracemalloc)", first_peak_mb, "MB", target=300.0, target_source="project target"),
    ], quick=args.quick, galsim=galsim.__version__ if galsim else None)


if __name__ == "__main__":
    main()
