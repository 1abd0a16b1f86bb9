"""Attitude chain speed and accuracy: the default star camera on the real sky, beside tetra3 (cedar-solve).

* **Whole chain**, per pointing, for the embedded seed-000 camera at random attitudes
  (uniform on the sphere, random roll; epoch 2026-03-21, geocentre at rest): the Hipparcos
  stars in view at their apparent places down to V 7.5 (the onboard catalogue; the camera
  itself detects to V ~12, ``simcam.starcam.sky_view.detection_limit``), their windows rendered
  by ``StarCamera`` (each star's own spectrum, PSF stamps, detector maps, non-linearity,
  noise), exposed and centroided in one pass as the lab's trial does, reported through the
  camera's onboard correction, and the attitude solved (``budget.attitude.solve``, equal
  weights of 0.1 px): pointings per second (one frame each, one process; numba compiled
  first) and the time of each stage; the star count N and the attitude error against the
  truth (rms of cross-boresight x, y and roll, arcsec).
* **Our solve beside tetra3's** ``solve_from_centroids`` (cedar-solve, optional; "not
  installed" otherwise) on the same reported centroids of a subset of the pointings: the
  centroids put into one virtual undistorted image (the mosaic's focal plane with its chip
  gap, ``budget.attitude.solve.focal_from_mosaic``), brightest first, with the horizontal
  field of view as its estimate; tetra3's database generated for this camera (max_fov 6.4
  deg) from a ``hip_main``-format file written from the same apparent places (V <= 7.5),
  so that both solve against the same directions (the shipped database covers 10-30 deg
  fields only). The database is cached in the temporary folder (``--quick``: a sparser
  lattice, fewer patterns). Accuracy on the pointings tetra3 solves, time per solve. Not like
  for like in time: tetra3 identifies the stars (a lost-in-space pattern search), ours is
  given them. cedar-solve 0.5.1 pins numpy < 2 and calls ``np.math.factorial``; it is
  installed without its pins (``pip install --no-deps cedar-solve``) and given
  ``np.math = math`` in this process.

The last line is ``RESULT {json}`` (read by ``run_all.py``).

Usage: ``python benchmarks/bench_attitude.py [--pointings 1000] [--tetra3-pointings 200] [--seed 1] [--quick]``
"""

from __future__ import annotations

import hashlib
import logging
import math
import os
import sys
import tempfile
import time
import warnings

import numpy as np

if not __package__:  # run as a file (python benchmarks/bench_x.py): the repository root on the path
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from benchmarks._common import (  # noqa: E402
    bench_parser,
    emit_result,
    figure,
    format_table,
    optional_import,
    print_machine,
)

EPOCH = "2026-03-21T00:00:00"
V_MAX_MAG = 7.5
SIGMA_PX = 0.1
THRESHOLD_SIGMA = 3.0
#: the issue's target: 10,000 pointings of the default camera in at most 60 s on 2 cores
TARGET_POINTINGS_PER_S = 10_000 / 60.0


def _setup():
    from astropy.time import Time

    from budget.attitude.chain import camera_model
    from simcam.starcam.render import StarCamera
    from simcam.starcam.scenario import default
    from simcam.starcam.sky_view import detection_limit, sky_stars

    scn = default()
    cam = StarCamera(scn)
    t0 = time.perf_counter()
    sky = sky_stars(cam, Time(EPOCH, scale="utc"), catalogue_v_max_mag=V_MAX_MAG)
    setup_s = time.perf_counter() - t0
    return cam, sky, detection_limit(cam, threshold_sigma=THRESHOLD_SIGMA), camera_model(scn), setup_s


def run_chain(cam, sky, det, model, attitudes, *, seed: int):
    """Every pointing through the chain (``budget.attitude.chain.observe`` then ``solve_frame``):
    per pointing (N, error x, y, roll; NaN unsolved), the seconds spent observing and solving,
    and the observations (for the peer)."""
    from budget.attitude.chain import observe, solve_frame
    from budget.attitude.solve import attitude_error

    rows, kept = [], []
    t_obs = t_solve = 0.0
    for k, att in enumerate(attitudes):
        t0 = time.perf_counter()
        obs = observe(cam, sky, att, detection=det, pointing=k, seed=seed, frames=1, threshold_sigma=THRESHOLD_SIGMA)
        t1 = time.perf_counter()
        sol = solve_frame(obs, model, frame=0, sigma_px=SIGMA_PX)
        t_solve += time.perf_counter() - t1
        t_obs += t1 - t0
        if sol is None:
            rows.append((obs.view.n_stars, np.nan, np.nan, np.nan))
            continue
        e = attitude_error(sol.attitude, att)
        rows.append((obs.view.n_stars, e.x_arcsec, e.y_arcsec, e.roll_arcsec))
        kept.append(obs)
    return np.array(rows), {"observe": t_obs, "solve": t_solve}, kept


def stage_times(cam, sky, det, attitudes) -> dict[str, float]:
    """Seconds of the observation's first two stages over ``attitudes``, run again on their own:
    the stars in view and the scene (each star's PSF stamp for its spectrum)."""
    from simcam.starcam.sky_view import sky_scene, stars_in_view

    t_view = t_scene = 0.0
    for k, att in enumerate(attitudes):
        t0 = time.perf_counter()
        view = stars_in_view(cam, sky, att, detection=det)
        t1 = time.perf_counter()
        if view.n_stars:
            sky_scene(cam, view, pointing=k)
        t_view += t1 - t0
        t_scene += time.perf_counter() - t1
    return {"stars in view": t_view, "scene (stamps)": t_scene}


def _hip_main_file(sky) -> str:
    """A tetra3 ``hip_main.dat`` (pipe-separated: HIP field 1, magnitude 5, RA and Dec in degrees
    8-9, proper motions 12-13) holding the sky's apparent places; in a folder of its own named
    by the content's hash."""
    d = sky.direction
    ra = np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 360.0
    dec = np.degrees(np.arcsin(np.clip(d[:, 2], -1.0, 1.0)))
    lines = [f"H|{h:6d}| | |x|{v:5.2f}| | |{r:12.8f}|{de:12.8f}| | |0.0|0.0|\n"
             for h, v, r, de in zip(sky.hip.tolist(), sky.v_mag.tolist(), ra.tolist(), dec.tolist())]
    text = "".join(lines)
    folder = os.path.join(tempfile.gettempdir(), "simcam-bench-tetra3",
                          hashlib.sha256(text.encode()).hexdigest()[:16])
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, "hip_main.dat")
    if not os.path.exists(path):
        with open(path, "w", encoding="ascii") as fh:
            fh.write(text)
    return path


def tetra3_solver(tetra3, sky, *, fov_deg: float, oversampling: int):
    """A Tetra3 with this camera's database (generated once, then loaded from the cache); the
    generation time (s, 0 when cached)."""
    catalogue = _hip_main_file(sky)
    db = os.path.join(os.path.dirname(catalogue), f"db_fov{fov_deg:.2f}_lattice{oversampling}.npz")
    t = tetra3.Tetra3(load_database=None)
    gen_s = 0.0
    if not os.path.exists(db):
        t0 = time.perf_counter()
        t.generate_database(max_fov=fov_deg, star_catalog=catalogue, epoch_proper_motion=None,
                            star_max_magnitude=V_MAX_MAG, lattice_field_oversampling=oversampling, save_as=db)
        gen_s = time.perf_counter() - t0
    t.load_database(db)
    return t, gen_s




def compare_tetra3(t3, observations, model):
    """Our solve and tetra3's on the same centroids: per pointing tetra3 solved, the errors
    (ours x, y, roll; tetra3's) and the times (s); and the count of pointings it did not solve."""
    from budget.attitude.chain import solve_frame
    from budget.attitude.frame_solve import tetra3_attitude
    from budget.attitude.solve import attitude_error, focal_from_mosaic

    width = model.n_chips * model.chip_cols + (model.n_chips - 1) * model.gap_px
    height = model.chip_rows
    fov_deg = math.degrees(2.0 * math.atan(width / 2.0 / model.focal_length_px))
    ours, theirs, t_ours, t_theirs, failed = [], [], [], [], 0
    for obs in observations:
        good = np.isfinite(obs.x_px[0])
        t0 = time.perf_counter()
        sol = solve_frame(obs, model, frame=0, sigma_px=SIGMA_PX)
        t_ours.append(time.perf_counter() - t0)
        u, v = focal_from_mosaic(obs.x_px[0][good], obs.y_px[0][good], model)
        order = np.argsort(-obs.flux_dn[0][good])
        centroids = np.column_stack([v + height / 2.0, u + width / 2.0])[order]
        t0 = time.perf_counter()
        res = t3.solve_from_centroids(centroids, size=(height, width), fov_estimate=fov_deg, fov_max_error=0.05,
                                      distortion=0.0)
        t_theirs.append(time.perf_counter() - t0)
        if res["RA"] is None:
            failed += 1
            continue
        a = attitude_error(sol.attitude, obs.attitude)
        b = attitude_error(tetra3_attitude(res), obs.attitude)
        ours.append((a.x_arcsec, a.y_arcsec, a.roll_arcsec))
        theirs.append((b.x_arcsec, b.y_arcsec, b.roll_arcsec))
    return np.array(ours).reshape(-1, 3), np.array(theirs).reshape(-1, 3), np.array(t_ours), np.array(t_theirs), failed


def _rms(a) -> np.ndarray:
    return np.sqrt(np.nanmean(np.asarray(a) ** 2, axis=0))


def main() -> None:
    ap = bench_parser(__doc__)
    ap.add_argument("--pointings", type=int, default=1000)
    ap.add_argument("--tetra3-pointings", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    oversampling = 100
    if args.quick:
        args.pointings, args.tetra3_pointings, oversampling = 40, 20, 10
    tetra3 = optional_import("tetra3")
    print_machine(**{"cedar-solve (tetra3)": _version("cedar-solve") if tetra3 else "not installed"})
    from budget.attitude.chain import random_attitudes

    cam, sky, det, model, setup_s = _setup()
    warnings.simplefilter("ignore")  # saturated or lost stars are counted, not warned about
    run_chain(cam, sky, det, model, random_attitudes(3, seed=args.seed + 1), seed=args.seed)  # numba compiled
    attitudes = random_attitudes(args.pointings, seed=args.seed)
    c0, t0 = time.process_time(), time.perf_counter()
    rows, spent, kept = run_chain(cam, sky, det, model, attitudes, seed=args.seed)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    stages = stage_times(cam, sky, det, attitudes)
    stages["windows + centroids + correction"] = max(spent["observe"] - sum(stages.values()), 0.0)
    stages["solve"] = spent["solve"]
    n = rows[:, 0]
    rate = args.pointings / wall
    print(f"default camera, {args.pointings} random pointings, 1 frame each, V <= {V_MAX_MAG} "
          f"({len(sky)} stars; apparent places computed once in {setup_s:.2f} s)")
    print(f"whole chain: {rate:.0f} pointings/s (wall {wall:.2f} s, CPU {cpu:.2f} s); "
          f"10,000 pointings in {10_000 / rate:.0f} s\n")
    print(format_table(["stage", "ms per pointing"],
                       [[k, f"{v / args.pointings * 1e3:.3f}"] for k, v in stages.items()]))
    solved = np.isfinite(rows[:, 1])
    err = _rms(rows[solved, 1:])
    print(f"\nstars in view N: mean {n.mean():.1f}, median {np.median(n):.0f}, min {n.min():.0f}, max {n.max():.0f}; "
          f"N < 3 at {np.mean(n < 3) * 100:.1f} % of pointings; solved {solved.sum()} of {args.pointings}")
    print(f"attitude error against the truth (rms): x {err[0]:.3f}\", y {err[1]:.3f}\", roll {err[2]:.2f}\"\n")
    figures = [figure("pointings_per_s", "whole chain (stars in view, windows, centroids, solve), default camera, "
                      "1 frame, 1 process", rate, "pointings/s", better="higher", target=TARGET_POINTINGS_PER_S,
                      target_source="issue 34 (10,000 in 60 s on 2 cores)"),
               figure("rms_cross_arcsec", "rms cross-boresight error (x and y), all solved pointings",
                      float(np.sqrt((err[0] ** 2 + err[1] ** 2) / 2)), "arcsec"),
               figure("rms_roll_arcsec", "rms roll error, all solved pointings", float(err[2]), "arcsec")]
    figures += _peer_figures(tetra3, sky, model, kept[: args.tetra3_pointings], oversampling)
    emit_result("attitude", figures, quick=args.quick, pointings=args.pointings, v_max_mag=V_MAX_MAG)


def _version(dist: str) -> str:
    from importlib.metadata import version

    return version(dist)


def _peer_figures(tetra3, sky, model, observations, oversampling: int) -> list[dict]:
    """tetra3 beside our solve on the same centroids (printed), as RESULT figures."""
    what_t = "time per solve on the same centroids (ms; tetra3 also identifies the stars)"
    what_a = "rms cross-boresight error on the pointings tetra3 solves (arcsec)"
    if tetra3 is None:
        return [figure("solve_ms", what_t, None, "ms", peer="tetra3", peer_status="not installed"),
                figure("peer_rms_cross_arcsec", what_a, None, "arcsec", peer="tetra3", peer_status="not installed")]
    if not hasattr(np, "math"):
        np.math = math  # cedar-solve 0.5.1 calls np.math.factorial, removed in numpy 2
    quiet = logging.getLogger("tetra3.Tetra3")  # with a handler, Tetra3 adds no INFO console handler of its own
    quiet.addHandler(logging.NullHandler())
    quiet.setLevel(logging.WARNING)
    width = model.n_chips * model.chip_cols + (model.n_chips - 1) * model.gap_px
    fov_deg = math.degrees(2.0 * math.atan(width / 2.0 / model.focal_length_px))
    t3, gen_s = tetra3_solver(tetra3, sky, fov_deg=round(fov_deg + 0.1, 1), oversampling=oversampling)
    ours, theirs, t_ours, t_theirs, failed = compare_tetra3(t3, observations, model)
    print(f"tetra3 database for max_fov {round(fov_deg + 0.1, 1)} deg, lattice oversampling {oversampling}: "
          + (f"generated in {gen_s:.0f} s" if gen_s else "cached") + f", {t3.num_patterns} patterns")
    a, b = _rms(ours), _rms(theirs)
    rows = [["ours (identities given)", len(observations), f"{np.median(t_ours) * 1e3:.3f}",
             f"{a[0]:.3f}", f"{a[1]:.3f}", f"{a[2]:.2f}"],
            ["tetra3 solve_from_centroids", len(observations) - failed, f"{np.median(t_theirs) * 1e3:.3f}",
             f"{b[0]:.3f}", f"{b[1]:.3f}", f"{b[2]:.2f}"]]
    print(format_table(["solver", "solved", "median ms", "rms x \"", "rms y \"", "rms roll \""], rows))
    print(f"(errors on the {len(ours)} pointings both solved; tetra3 did not solve {failed})")
    cross = [float(np.sqrt((v[0] ** 2 + v[1] ** 2) / 2)) for v in (a, b)]
    return [figure("solve_ms", what_t, float(np.median(t_ours) * 1e3), "ms", peer="tetra3",
                   peer_value=float(np.median(t_theirs) * 1e3)),
            figure("peer_rms_cross_arcsec", what_a, cross[0], "arcsec", peer="tetra3", peer_value=cross[1]),
            figure("peer_rms_roll_arcsec", "rms roll error on the pointings tetra3 solves (arcsec)", float(a[2]),
                   "arcsec", peer="tetra3", peer_value=float(b[2]))]


if __name__ == "__main__":
    main()
