"""Full-frame detector noise chain: simcam's counter-based numba kernel vs plain numpy.

Both do, on a 2048 x 4096 (rows x cols) two-chip mosaic: PRNU (1 + 1 % N(0,1)), dark
signal 2 e- with DSNU 0.5 e- rms and 1e-4 hot pixels, Poisson shot noise, full-well
clip, read noise, per-chip gain/offset ADC to uint16. The expected signal is a 3 e-
background plus 25 Gaussian stars of 1e5 e- each.

The PRNU, DSNU and hot-pixel maps are a property of the detector: a sequence of frames of
one camera computes them once (:func:`simcam.detector.detector_maps`, 16 bytes per pixel)
and each frame draws only its Poisson counts and read noise (``expose(..., maps=...)``).
So ours is timed per frame with the maps computed once (the marginal frame), beside the
first frame with the maps' cost and the maps alone, and the fused chain that draws the
maps in every frame (``expose`` without ``maps``). The numpy peer is timed the same way:
its maps drawn once from one ``numpy.random.Generator`` and per frame one ``Generator``
drawing Poisson + normal + ADC; its old figure with the maps drawn every frame is kept,
labelled.

Peers in the same run, each optional (reported as "not installed" when absent):

* GalSim ``CCDNoise`` (Poisson shot noise, Gaussian read noise 5 e-, gain 2 e-/DN) added
  to a ``galsim.ImageD`` of the same expected signal (a copy made per frame, since the
  noise is added in place): fewer effects than ours (no PRNU, dark, full well, ADC);
* one pyxel exposure of a 2048 x 4096 CMOS through an 11-model pipeline built in code
  (:func:`pyxel_yaml`): the same expected signal loaded as photons (``load_image`` of a
  ``.npy``), shot noise, conversion, dark current 2 e-/s, collection, fixed-pattern
  noise 1 %, full well, measurement, CMOS output-node noise 5 e-, amplifier, 16-bit ADC.
  Best of ``--pyxel-repeat`` runs of ``pyxel.run_mode`` (nothing written to disk).

Times are best of ``--repeat`` after a warm-up call (JIT / cache load): wall-clock ms per
frame and CPU ms per frame (all threads; steadier on a shared machine). Peak memory is
the tracemalloc peak of one frame (output + temporaries), MB, and the growth of the
process's maximum resident set over the whole run, MB. The last line is
``RESULT {json}`` (read by ``run_all.py``).

Usage: ``python benchmarks/bench_detector_noise.py [--repeat 5] [--pyxel-repeat 2] [--quick]``
"""

from __future__ import annotations

import os
import resource
import sys
import tempfile
import time

import numba
import numpy as np

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

from simcam.detector import DetectorParams, detector_maps, expose  # noqa: E402
from simcam.rng import key_from_seed  # noqa: E402

ROWS, COLS, CHIP_COLS = 2048, 4096, 2048
PARAMS = DetectorParams(
    gain_e_per_dn=(2.0, 2.1), offset_dn=(100.0, 110.0), read_noise_e=(5.0, 5.5),
    full_well_e=(6.0e4, 6.2e4), adc_bits=16, prnu_rms=0.01, dark_e=2.0, dsnu_rms_e=0.5,
    hot_pixel_fraction=1e-4, hot_pixel_dark_e=200.0,
)


def make_signal(seed: int = 1) -> np.ndarray:
    """3 e- background + 25 Gaussian stars (sigma 1.2 px, 1e5 e- each), float64."""
    rng = np.random.default_rng(seed)
    sig = np.full((ROWS, COLS), 3.0)
    for _ in range(25):
        y0, x0 = rng.uniform(16, ROWS - 16), rng.uniform(16, COLS - 16)
        r, c = int(y0), int(x0)
        yy, xx = np.mgrid[r - 8:r + 9, c - 8:c + 9]
        s2 = 1.2**2
        r2 = (yy - y0) ** 2 + (xx - x0) ** 2
        sig[r - 8:r + 9, c - 8:c + 9] += 1e5 * np.exp(-r2 / (2 * s2)) / (2 * np.pi * s2)
    return sig


def simcam_maps():
    """The detector's fixed pattern (PRNU factor, dark signal), computed once per camera."""
    return detector_maps(shape=(ROWS, COLS), row0=0, col0=0, mosaic_cols=COLS, params=PARAMS,
                         detector_key=key_from_seed(7, 0))


def simcam_frame(sig: np.ndarray, frame: int, maps=None) -> np.ndarray:
    """One frame; with ``maps`` only the frame's draws (the same pixels as without)."""
    return expose(signal_e=sig, row0=0, col0=0, mosaic_cols=COLS, chip_cols=CHIP_COLS,
                  params=PARAMS, frame_key=key_from_seed(7, 1, frame),
                  detector_key=key_from_seed(7, 0), maps=maps)


def numpy_maps(shape=(ROWS, COLS), rng=None):
    """numpy's PRNU factor and dark signal (DSNU + hot pixels), drawn once (from ``rng``,
    default the maps' own stream)."""
    p = PARAMS
    if rng is None:
        rng = np.random.default_rng(np.random.SeedSequence(7, spawn_key=(0,)))
    g = rng.standard_normal(shape)
    g *= p.prnu_rms
    g += 1.0
    np.maximum(g, 0.0, out=g)
    dark = rng.standard_normal(shape)
    dark *= p.dsnu_rms_e
    dark += p.dark_e
    np.maximum(dark, 0.0, out=dark)
    dark[rng.random(shape) < p.hot_pixel_fraction] += p.hot_pixel_dark_e
    return g, dark


def numpy_frame_maps(sig: np.ndarray, frame: int, maps, rng=None) -> np.ndarray:
    """numpy, maps given: per frame Poisson + full well + read normal + ADC only."""
    g_map, dark = maps
    if rng is None:
        rng = np.random.default_rng(np.random.SeedSequence(7, spawn_key=(1, frame)))
    lam = sig * g_map
    lam += dark
    e = rng.poisson(lam).astype(np.float64)
    del lam
    return _numpy_read_adc(rng, e)


def _numpy_read_adc(rng, e: np.ndarray) -> np.ndarray:
    """numpy's full well, read noise and per-chip ADC of the charge ``e`` (float64, the
    Poisson counts; modified in place)."""
    p = PARAMS
    chip = np.arange(COLS) // CHIP_COLS
    g = np.asarray(p.gain_e_per_dn)[chip]
    off = np.asarray(p.offset_dn)[chip]
    rn = np.asarray(p.read_noise_e)[chip]
    fw = np.asarray(p.full_well_e)[chip]
    np.minimum(e, fw, out=e)
    noise = rng.standard_normal(e.shape)
    noise *= rn
    e += noise
    del noise
    e /= g
    e += off + 0.5
    np.floor(e, out=e)
    np.clip(e, 0, p.max_dn, out=e)
    return e.astype(np.uint16)


def numpy_frame(sig: np.ndarray, frame: int) -> np.ndarray:
    """numpy drawing the maps in every frame too (the old peer figure): :func:`numpy_maps`
    and :func:`numpy_frame_maps` from the frame's one stream."""
    rng = np.random.default_rng(np.random.SeedSequence(7, spawn_key=(1, frame)))
    return numpy_frame_maps(sig, frame, numpy_maps(sig.shape, rng), rng)


def galsim_frame(galsim, sig: np.ndarray, frame: int):
    """GalSim's CCD noise (Poisson + read noise + gain) on a copy of the expected signal."""
    img = galsim.ImageD(sig.copy())
    img.addNoise(galsim.CCDNoise(galsim.BaseDeviate(1000 + frame), sky_level=0.0,
                                 gain=PARAMS.gain_e_per_dn[0], read_noise=PARAMS.read_noise_e[0]))
    return img


def pyxel_yaml(image_file: str, *, seed: int = 7) -> str:
    """pyxel configuration of one CMOS exposure of the signal in ``image_file`` (e-/s, 1 s).

    Nominal conversion: 1e-6 V/e-, x 76.29, 16-bit ADC over 0-10 V, i.e. 2.0 e-/DN as chip 0.
    The models are pyxel's own (no offset; its dark-current and output-node noise models),
    so its image is not expected to match ours pixel for pixel; it is timed as the peer
    the issue names.
    """
    p = PARAMS
    return f"""
exposure:
  readout:
    times: [1.0]
    non_destructive: false
  pipeline_seed: {seed}
cmos_detector:
  geometry:
    row: {ROWS}
    col: {COLS}
    total_thickness: 40.0
    pixel_vert_size: 10.0
    pixel_horz_size: 10.0
    pixel_scale: 5.5
  environment:
    temperature: 293.0
  characteristics:
    quantum_efficiency: 1.0
    charge_to_volt:
      value: 1.0e-06
    pre_amplification: 76.29
    full_well_capacity: {int(p.full_well_e[0])}
    adc_bit_resolution: {p.adc_bits}
    adc_voltage_range: [0.0, 10.0]
pipeline:
  photon_collection:
    - name: load_image
      func: pyxel.models.photon_collection.load_image
      enabled: true
      arguments:
        image_file: {image_file}
        convert_to_photons: false
    - name: shot_noise
      func: pyxel.models.photon_collection.shot_noise
      enabled: true
      arguments:
        type: poisson
  charge_generation:
    - name: simple_conversion
      func: pyxel.models.charge_generation.simple_conversion
      enabled: true
      arguments:
        quantum_efficiency: 1.0
        binomial_sampling: false
    - name: simple_dark_current
      func: pyxel.models.charge_generation.simple_dark_current
      enabled: true
      arguments:
        dark_rate: {p.dark_e}
  charge_collection:
    - name: simple_collection
      func: pyxel.models.charge_collection.simple_collection
      enabled: true
    - name: fixed_pattern_noise
      func: pyxel.models.charge_collection.fixed_pattern_noise
      enabled: true
      arguments:
        fixed_pattern_noise_factor: {p.prnu_rms}
    - name: simple_full_well
      func: pyxel.models.charge_collection.simple_full_well
      enabled: true
  charge_measurement:
    - name: simple_measurement
      func: pyxel.models.charge_measurement.simple_measurement
      enabled: true
    - name: output_node_noise_cmos
      func: pyxel.models.charge_measurement.output_node_noise_cmos
      enabled: true
      arguments:
        readout_noise: {p.read_noise_e[0]}
        readout_noise_std: 0.5
  readout_electronics:
    - name: simple_amplifier
      func: pyxel.models.readout_electronics.simple_amplifier
      enabled: true
    - name: simple_adc
      func: pyxel.models.readout_electronics.simple_adc
      enabled: true
      arguments:
        data_type: uint16
"""


def time_pyxel(pyxel, sig: np.ndarray, repeat: int) -> tuple[float, float, np.ndarray]:
    """Best wall and CPU seconds of ``repeat`` pyxel exposures (after one warm-up); image."""
    cwd = os.getcwd()
    with tempfile.TemporaryDirectory(prefix="bench_pyxel_") as d:
        path = os.path.join(d, "signal.npy")
        np.save(path, sig)
        cfg = pyxel.loads(pyxel_yaml(path))
        os.chdir(d)  # should pyxel write anything, it lands in the temporary folder
        try:
            wall, cpu = best_of_wall_cpu(lambda: pyxel.run_mode(cfg), repeat=repeat, warmup=1)
            img = np.asarray(pyxel.run_mode(cfg)["/bucket/image"])[0]
        finally:
            os.chdir(cwd)
    return wall, cpu, img


def main(argv=None) -> int:
    ap = bench_parser(__doc__)
    ap.add_argument("--repeat", type=int, default=5, help="timed repeats (best is reported)")
    ap.add_argument("--pyxel-repeat", type=int, default=2, help="timed pyxel exposures")
    args = ap.parse_args(argv)
    if args.quick:
        args.repeat, args.pyxel_repeat = min(args.repeat, 2), 1
    galsim = optional_import("galsim")
    pyxel = optional_import("pyxel")

    print_machine(galsim=galsim.__version__ if galsim else "not installed",
                  pyxel=pyxel.__version__ if pyxel else "not installed")
    sig = make_signal()
    npix = sig.size
    t0 = time.perf_counter()
    simcam_frame(sig, 0)
    print(f"first simcam call (JIT compile or cache load): {time.perf_counter() - t0:.2f} s")

    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
    maps_s = best_of_wall_cpu(simcam_maps, repeat=max(2, args.repeat // 2))
    maps = simcam_maps()
    assert np.array_equal(simcam_frame(sig, 1, maps), simcam_frame(sig, 1))  # the same pixels
    rows = []
    max_threads = numba.get_num_threads()
    for n_threads in sorted({max_threads, 1}, reverse=True):
        numba.set_num_threads(n_threads)
        frame = iter(range(1, 10**6))
        wall, cpu = best_of_wall_cpu(lambda: simcam_frame(sig, next(frame), maps), repeat=args.repeat)
        if n_threads == max_threads:
            ours_wall, ours_cpu = wall, cpu
        rows.append(["simcam, maps computed once: per frame", n_threads, f"{wall * 1e3:.0f}",
                     f"{cpu * 1e3:.0f}", f"{npix / wall / 1e6:.1f}",
                     f"{peak_traced_mb(lambda: simcam_frame(sig, 0, maps)):.0f}"])
        if n_threads == max_threads:
            wall1, cpu1 = best_of_wall_cpu(lambda: simcam_frame(sig, next(frame), simcam_maps()),
                                           repeat=max(2, args.repeat // 2))
            rows.append(["simcam, first frame (maps + frame)", n_threads, f"{wall1 * 1e3:.0f}",
                         f"{cpu1 * 1e3:.0f}", f"{npix / wall1 / 1e6:.1f}",
                         f"{peak_traced_mb(lambda: simcam_frame(sig, 0, simcam_maps())):.0f}"])
            rows.append(["simcam, the maps alone (detector_maps)", n_threads, f"{maps_s[0] * 1e3:.0f}",
                         f"{maps_s[1] * 1e3:.0f}", f"{npix / maps_s[0] / 1e6:.1f}",
                         f"{peak_traced_mb(simcam_maps):.0f}"])
        wallf, cpuf = best_of_wall_cpu(lambda: simcam_frame(sig, next(frame)), repeat=args.repeat)
        if n_threads == max_threads:
            fused_wall = wallf
        rows.append(["simcam, fused: maps drawn every frame", n_threads, f"{wallf * 1e3:.0f}",
                     f"{cpuf * 1e3:.0f}", f"{npix / wallf / 1e6:.1f}",
                     f"{peak_traced_mb(lambda: simcam_frame(sig, 0)):.0f}"])
    numba.set_num_threads(max_threads)
    rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
    nmaps = numpy_maps()
    frame = iter(range(1, 10**6))
    wall, cpu = best_of_wall_cpu(lambda: numpy_frame_maps(sig, next(frame), nmaps), repeat=args.repeat)
    rows.append(["numpy, maps drawn once: per frame (poisson+normal+ADC)", 1, f"{wall * 1e3:.0f}",
                 f"{cpu * 1e3:.0f}", f"{npix / wall / 1e6:.1f}",
                 f"{peak_traced_mb(lambda: numpy_frame_maps(sig, 0, nmaps)):.0f}"])
    numpy_wall = wall
    numpy_mb = float(rows[-1][5])
    del nmaps
    wall, cpu = best_of_wall_cpu(lambda: numpy_frame(sig, next(frame)), repeat=args.repeat)
    rows.append(["numpy, maps drawn every frame (old peer)", 1, f"{wall * 1e3:.0f}",
                 f"{cpu * 1e3:.0f}", f"{npix / wall / 1e6:.1f}",
                 f"{peak_traced_mb(lambda: numpy_frame(sig, 0)):.0f}"])
    rss2 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
    numpy_every_wall = wall
    ours_mb = float(rows[0][5])
    galsim_wall = pyxel_wall = None
    if galsim is not None:
        frame = iter(range(1, 10**6))
        galsim_wall, cpu = best_of_wall_cpu(lambda: galsim_frame(galsim, sig, next(frame)),
                                            repeat=args.repeat)
        rows.append(["GalSim CCDNoise (shot+read+gain only)", 1, f"{galsim_wall * 1e3:.0f}",
                     f"{cpu * 1e3:.0f}", f"{npix / galsim_wall / 1e6:.1f}", ""])
    else:
        rows.append(["GalSim CCDNoise: not installed", "", "", "", "", ""])
    if pyxel is not None:
        pyxel_wall, cpu, pimg = time_pyxel(pyxel, sig, args.pyxel_repeat)
        rows.append(["pyxel 3 CMOS exposure, 11 models", "", f"{pyxel_wall * 1e3:.0f}",
                     f"{cpu * 1e3:.0f}", f"{npix / pyxel_wall / 1e6:.1f}", ""])
    else:
        rows.append(["pyxel CMOS exposure: not installed", "", "", "", "", ""])
    print(f"full frame {ROWS} x {COLS} = {npix / 1e6:.2f} Mpix, best of {args.repeat} "
          f"(load average before: {os.getloadavg()[0]:.2f}):")
    print(format_table(["method", "threads", "wall ms/frame", "cpu ms/frame", "Mpix/s",
                        "peak MB"], rows))
    print(f"(pyxel: best of {args.pyxel_repeat} after a warm-up)" if pyxel is not None else "")
    print(f"maps kept in memory: {maps.nbytes / 1e6:.0f} MB (16 bytes per pixel); peak MB is the "
          f"tracemalloc peak of the call (the maps' own when they are computed in it)")
    print(f"max RSS growth: simcam runs {rss1 - rss0:.0f} MB, then numpy runs {rss2 - rss1:.0f} MB "
          f"(RSS before: {rss0:.0f} MB, includes the 67 MB input)")

    a = simcam_frame(sig, 3, maps).astype(float)
    b = numpy_frame(sig, 3).astype(float)
    bg = sig < 3.5
    print(f"sanity (background pixels, DN): simcam mean {a[bg].mean():.3f} sd {a[bg].std():.3f}; "
          f"numpy mean {b[bg].mean():.3f} sd {b[bg].std():.3f}")
    if pyxel is not None:
        c = pimg.astype(float)
        # not comparable with ours: no offset, other dark and read-noise models (and in pyxel
        # 3.0.2 output_node_noise_cmos adds a draw centred on the signal to the signal)
        print(f"pyxel background (its own models, not comparable): mean {c[bg].mean():.3f} "
              f"sd {c[bg].std():.3f} DN")

    def ms(v):
        return None if v is None else v * 1e3

    chain = "detector chain, full 2048x4096 frame, maps computed once: per frame (wall ms)"
    emit_result("detector_noise", [
        figure("chain_vs_numpy_ms", chain, ours_wall * 1e3, "ms",
               peer="plain numpy Generator, maps drawn once", peer_value=numpy_wall * 1e3,
               target=60.0, target_source="speed target"),
        figure("chain_fused_vs_numpy_ms", "detector chain, full frame, maps drawn every frame (wall ms)",
               fused_wall * 1e3, "ms", peer="plain numpy Generator, maps drawn every frame",
               peer_value=numpy_every_wall * 1e3),
        figure("chain_first_frame_ms", "detector chain, first frame: maps + frame (wall ms)",
               wall1 * 1e3, "ms"),
        figure("chain_maps_ms", "detector maps alone (PRNU factor, dark signal; wall ms)",
               maps_s[0] * 1e3, "ms"),
        figure("chain_vs_galsim_ms", chain, ours_wall * 1e3, "ms", peer="GalSim CCDNoise",
               peer_value=ms(galsim_wall), peer_status=None if galsim else "not installed"),
        figure("chain_vs_pyxel_ms", chain, ours_wall * 1e3, "ms", peer="pyxel CMOS exposure (11 models)",
               peer_value=ms(pyxel_wall), peer_status=None if pyxel else "not installed"),
        figure("chain_peak_mb", "detector chain, peak memory of one frame, maps given (MB, tracemalloc; "
               "the maps: 134 MB more, kept)", ours_mb, "MB", peer="plain numpy Generator, maps given",
               peer_value=numpy_mb),
    ], quick=args.quick, galsim=galsim.__version__ if galsim else None,
                  pyxel=pyxel.__version__ if pyxel else None)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
