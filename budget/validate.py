"""Monte Carlo validation of the seed-000 lab methods: what each recovers of what was injected.

Each trial runs the four protocols (TE, HSFE, chromatic, distortion) on the simulator
with independent temporal noise (and, where the scenario says so, new PRNU/DSNU maps,
new marker errors, new hexapod positioning errors), through the same estimators as real
data (:func:`budget.protocols.estimate`). For every class, axis and estimator variant the
trials give the distribution of the estimate, which is compared with the class's truth
(:mod:`budget.truth`): mean, bias (absolute and %), spread, 68 % and 95 % intervals,
Monte Carlo standard errors and whether the bias is significant.

Randomness: trial ``k`` draws everything from ``SeedSequence(seed, spawn_key=(k,))``, so a
trial's result does not depend on how many workers run or in which order they finish.

Adaptive stopping (in the spirit of JCGM 101:2008 section 7.9): with a tolerance ``T``
(3 sigma arcsec), batches of trials run until the Monte Carlo standard error of every
bias (``s / sqrt(K)``) and every spread (``s / sqrt(2 (K - 1))``, Gaussian approximation)
is below ``T``, or until ``max_trials``.
"""

from __future__ import annotations

import math
import multiprocessing
import os
import warnings
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from budget.protocols import PROTOCOLS, estimate, make_plan, simulate
from simcam.lifecycle import worker_initializer

CLASSES = ("te", "hsfe", "lsfe_s", "lsfe_c1", "lsfe_c2", "lsfe", "total")
VARIANTS = ("published", "improved")
AXES = ("x", "y")
#: classes whose value is given to the lab, not measured by it: reported, never "validated"
#: (LSFE-C2, the marker calibration error of the grid target, seed 000 section 1.4.3)
INPUT_CLASSES = ("lsfe_c2",)
#: protocol producing each measured class
CLASS_PROTOCOL = {"te": "te", "hsfe": "hsfe", "lsfe_s": "chromatic", "lsfe_c1": "distortion"}

_CACHE: dict = {}
#: trials per task sent to a worker process
_CHUNK_TRIALS = 10
#: numba threads inside this process's kernels (False in worker processes: one per core)
_PARALLEL: bool | None = None


def worker_init() -> None:
    """Worker processes run single-threaded kernels: the processes are the parallelism.

    Pools pass it through :func:`simcam.lifecycle.worker_initializer`, which first makes
    the worker exit when its parent dies.
    """
    global _PARALLEL
    import numba

    numba.set_num_threads(1)
    _PARALLEL = False


def trial_seeds(seed: int, k: int) -> tuple[int, int, int]:
    """(noise seed, map seed, marker seed) of trial ``k``: ``SeedSequence(seed, spawn_key=(k,))``."""
    s = np.random.SeedSequence(seed, spawn_key=(k,)).generate_state(3, dtype=np.uint32)
    return int(s[0]), int(s[1]), int(s[2])


def _camera(scenario, detector_seed=None):
    from simcam.render import StarCamera

    key = (scenario.hash, detector_seed)
    cam = _CACHE.get(key)
    if cam is None:
        if len(_CACHE) > 4:
            _CACHE.clear()
        cam = StarCamera(scenario, detector_seed=detector_seed, parallel=_PARALLEL)
        _CACHE[key] = cam
    return cam


def _spectral(scenario):
    from budget.protocols import spectral_design

    key = ("spectral", scenario.hash)
    if key not in _CACHE:
        _CACHE[key] = spectral_design(scenario)
    return _CACHE[key]


def run_trial(scenario, seed: int, k: int, *, keep: bool = False) -> dict:
    """One validation trial: every protocol through the published and improved estimators.

    Returns ``{"k": k, "values": {(class, variant, axis): sigma_px}}``; with ``keep``
    also ``"kept"``: the estimate objects and data of each protocol (for the report).
    """
    noise_seed, map_seed, marker_seed = trial_seeds(seed, k)
    val = scenario.validation
    cam = _camera(scenario, map_seed if val.new_maps_per_trial else None)
    ps = scenario.camera.scale_arcsec_per_px
    values: dict = {}
    kept: dict = {}
    spectral = _spectral(scenario)
    with warnings.catch_warnings():
        # clipped variances and flagged stars are expected in some trials; counted via flags
        warnings.simplefilter("ignore")
        for proto in PROTOCOLS:
            plan = make_plan(proto, scenario, seed=noise_seed, dark_frames=val.dark_frames)
            data = simulate(plan, cam, seed=noise_seed, method=val.centroid_method,
                            threshold_sigma=val.threshold_sigma,
                            marker_seed=marker_seed if val.new_markers_per_trial else None)
            res = estimate(proto, data.centroids, plate_scale_arcsec=ps, reference=data.reference,
                           reference_filter_nm=scenario.protocols.chromatic.reference_filter_nm,
                           marker_3sigma_arcsec=scenario.lab.calibration_target.marker_error_3sigma_arcsec,
                           spectral=spectral, extra_variants=keep,
                           camera_corrects_distortion=scenario.optics.distortion_correction.kind != "none")
            cls = {"te": "te", "hsfe": "hsfe", "chromatic": "lsfe_s", "distortion": "lsfe_c1"}[proto]
            for var in VARIANTS:
                values[(cls, var, "x")] = res[var].sigma_x_px
                values[(cls, var, "y")] = res[var].sigma_y_px
            if keep:
                kept[proto] = {"estimates": res, "data": data}
    c2 = scenario.lab.calibration_target.marker_error_3sigma_arcsec / 3.0 / ps
    for var in VARIANTS:
        for ax in AXES:
            values[("lsfe_c2", var, ax)] = c2
            s, c1 = values[("lsfe_s", var, ax)], values[("lsfe_c1", var, ax)]
            if var == "published":  # seed 000 eq 31: C1 and C2 added linearly
                lsfe = math.sqrt(s**2 + (c1 + c2) ** 2)
            else:  # independent sources: root-sum-square
                lsfe = math.sqrt(s**2 + c1**2 + c2**2)
            values[("lsfe", var, ax)] = lsfe
            values[("total", var, ax)] = math.sqrt(values[("te", var, ax)] ** 2 + values[("hsfe", var, ax)] ** 2 + lsfe**2)
    out = {"k": k, "values": values}
    if keep:
        out["kept"] = kept
    return out


def _run_chunk(args):
    scenario, seed, ks = args
    return [run_trial(scenario, seed, k) for k in ks]


@dataclass
class ValidationResult:
    """Trials, truths and summary statistics of a validation run."""

    scenario: object
    seed: int
    truths: dict
    samples: dict  # (class, variant, axis) -> np.ndarray of sigma_px per trial
    trials: int
    stopped_by: str
    example: dict = field(default_factory=dict)

    def summary(self) -> dict:
        """Per class/axis/variant statistics in arcsec (3 sigma): truth, mean, bias, std, intervals, ..."""
        f = 3.0 * self.scenario.camera.scale_arcsec_per_px
        out: dict = {}
        for cls in CLASSES:
            out[cls] = {}
            for ax in AXES:
                out[cls][ax] = {}
                truth = getattr(self.truths[cls], f"{ax}_px") * f
                se_truth = getattr(self.truths[cls], f"se_{ax}_px", 0.0) * f
                for var in VARIANTS:
                    v = np.asarray(self.samples[(cls, var, ax)]) * f
                    n = v.size
                    mean = float(v.mean())
                    std = float(v.std(ddof=1)) if n > 1 else 0.0
                    se_mean = std / math.sqrt(n)
                    # the truth is itself a Monte Carlo estimate (TE, HSFE): its standard
                    # error adds to that of the mean estimate (independent samples)
                    se_bias = math.hypot(se_mean, se_truth)
                    se_std = std / math.sqrt(2 * (n - 1)) if n > 1 else float("inf")
                    bias = mean - truth
                    q = np.quantile(v, [0.025, 0.16, 0.84, 0.975])
                    entry = {
                        "truth": truth, "se_truth": se_truth, "mean": mean, "bias": bias,
                        # a truth below 1e-9 arcsec is zero to rounding: a relative bias is
                        # then meaningless, reported as NaN
                        "bias_percent": (100.0 * bias / truth if truth > 1e-9
                                         else (0.0 if abs(bias) <= 1e-12 else float("nan"))),
                        "std": std, "interval_68": [float(q[1]), float(q[2])],
                        "interval_95": [float(q[0]), float(q[3])],
                        "se_mean": se_mean, "se_bias": se_bias, "se_std": se_std,
                        "bias_significant": bool(abs(bias) > 3.0 * se_bias) if se_bias > 0 else bool(bias != 0),
                        "truth_in_95": bool(q[0] <= truth <= q[3]),
                        "role": "result",
                    }
                    if cls in INPUT_CLASSES:
                        # LSFE-C2 is the given marker calibration error: both variants are set
                        # to it, so there is nothing to validate (an input, not a result)
                        entry.update(role="input", bias_percent=float("nan"), bias_significant=False)
                    out[cls][ax][var] = entry
        return out

    def to_json(self) -> dict:
        """JSON payload: scenario, hash, seed, version, trials, truths and the summary."""
        from simcam import __version__
        from simcam.scenario import scenario_to_toml

        f = 3.0 * self.scenario.camera.scale_arcsec_per_px
        return {
            "scenario_name": self.scenario.name, "scenario_hash": self.scenario.hash,
            "scenario_toml": scenario_to_toml(self.scenario), "seed": self.seed, "version": __version__,
            "trials": self.trials, "stopped_by": self.stopped_by, "units": "arcsec, 3 sigma",
            "plate_scale_arcsec": self.scenario.camera.scale_arcsec_per_px,
            "truth_details": {k: {"x": t.x_px * f, "y": t.y_px * f,
                                  **{d: v for d, v in t.details.items() if not isinstance(v, list)}}
                              for k, t in self.truths.items()},
            "classes": self.summary(),
        }


def _truth_seed(seed: int) -> int:
    return int(np.random.SeedSequence(seed, spawn_key=(2**31,)).generate_state(1)[0])


def truth_parts(scenario, *, seed: int) -> list[tuple]:
    """The independent pieces of :func:`truths`, computable anywhere and in any order:
    ``("rest",)`` (TE, LSFE-S, LSFE-C1, LSFE-C2) and one ``("hsfe", map, phase)`` per
    sub-pixel phase of the HSFE truth (``map`` None for the scenario's pixel maps, or the
    trial 0-3 whose maps are used when ``validation.new_maps_per_trial``)."""
    val = scenario.validation
    maps = list(range(4)) if val.new_maps_per_trial else [None]
    return [("rest",)] + [("hsfe", m, p) for m in maps for p in range(val.hsfe_phase_grid**2)]


def truth_part(scenario, *, seed: int, part: tuple):
    """One piece of :func:`truths` (see :func:`truth_parts`)."""
    from budget.truth import hsfe_phase_cell, lsfe_c1_truth, lsfe_c2_truth, lsfe_s_truth, te_truth

    ts = _truth_seed(seed)
    val = scenario.validation
    if part[0] == "rest":
        cam = _camera(scenario)
        return {"te": te_truth(cam, frames=val.te_truth_frames, seed=ts), "lsfe_s": lsfe_s_truth(cam),
                "lsfe_c1": lsfe_c1_truth(cam), "lsfe_c2": lsfe_c2_truth(scenario)}
    _, m, p = part
    if m is None:
        cam = _camera(scenario)
        hs = int(np.random.SeedSequence(ts, spawn_key=(2,)).generate_state(1)[0])
    else:
        cam = _camera(scenario, trial_seeds(seed, m)[1])
        hs = int(np.random.SeedSequence(ts, spawn_key=(3, m)).generate_state(1)[0])
    return hsfe_phase_cell(cam, frames=val.hsfe_truth_frames, seed=hs, phase=p)


def truths_from_parts(scenario, *, seed: int, results: list) -> dict:
    """:func:`truths` from the results of :func:`truth_parts`, in their order."""
    from budget.truth import ClassTruth, combine, hsfe_from_cells

    parts = truth_parts(scenario, seed=seed)
    val = scenario.validation
    out = dict(results[0])
    cells: dict = {}
    for part, r in zip(parts[1:], results[1:]):
        cells.setdefault(part[1], []).append(r)
    if not val.new_maps_per_trial:
        out["hsfe"] = hsfe_from_cells(_camera(scenario), cells[None], frames=val.hsfe_truth_frames)
    else:
        hs = [hsfe_from_cells(_camera(scenario, trial_seeds(seed, k)[1]), cells[k], frames=val.hsfe_truth_frames)
              for k in range(4)]
        vals = {}
        for ax in AXES:
            h2 = np.array([getattr(h, f"{ax}_px") ** 2 for h in hs])
            # the truth is the rms over map realisations: the 4 maps sample it (se of a mean
            # of 4 squares) and each map's own truth has its frame-sampling error
            se_h2 = math.sqrt(h2.var(ddof=1) / h2.size
                              + np.sum([(2 * getattr(h, f"{ax}_px") * getattr(h, f"se_{ax}_px")) ** 2
                                        for h in hs]) / h2.size**2)
            v = math.sqrt(h2.mean())
            vals[ax] = (v, se_h2 / (2 * v) if v > 0 else math.sqrt(se_h2))
        out["hsfe"] = ClassTruth("hsfe", vals["x"][0], vals["y"][0], {**hs[0].details, "map_realisations": len(hs)},
                                 se_x_px=vals["x"][1], se_y_px=vals["y"][1])
    return combine({k: out[k] for k in ("te", "hsfe", "lsfe_s", "lsfe_c1", "lsfe_c2")})


def truths(scenario, *, seed: int) -> dict:
    """Every class's truth (:class:`budget.truth.ClassTruth`) of a validation run with ``seed``.

    The truth seed is ``SeedSequence(seed, spawn_key=(2**31,))``. With
    ``validation.new_maps_per_trial`` the static pixel error changes from trial to trial:
    the HSFE truth is then the rms over the maps of trials 0-3, and the total follows.
    Computed piece by piece (:func:`truth_parts`), so that a runner can spread the pieces
    over its workers and get the same numbers.
    """
    parts = truth_parts(scenario, seed=seed)
    return truths_from_parts(scenario, seed=seed, results=[truth_part(scenario, seed=seed, part=p) for p in parts])


def validate(scenario, *, trials: int | None = None, tolerance_3sigma_arcsec: float | None = None,
             seed: int = 0, workers: int = 1, progress: bool = False, keep_example: bool = True) -> ValidationResult:
    """Run the Monte Carlo validation (see module docstring).

    Parameters
    ----------
    scenario : simcam.scenario.Scenario
    trials : int, optional
        Fixed number of trials (default: the scenario's ``validation.trials``, unless a
        tolerance is given).
    tolerance_3sigma_arcsec : float, optional
        Adaptive stopping tolerance on the Monte Carlo standard errors (3 sigma arcsec).
    seed : int
        Run seed.
    workers : int
        Processes (1: in this process). Results do not depend on it.
    """
    val = scenario.validation
    tol = tolerance_3sigma_arcsec if tolerance_3sigma_arcsec is not None else (
        val.tolerance_3sigma_arcsec if trials is None else None)
    if trials is not None and tolerance_3sigma_arcsec is not None:
        raise ValueError("trials and tolerance: give one of them")
    if workers < 1:
        raise ValueError(f"workers: must be >= 1, got {workers}")
    truths_ = truths(scenario, seed=seed)
    example = run_trial(scenario, seed, 0, keep=True) if keep_example else None
    results: list = [] if example is None else [{"k": 0, "values": example["values"]}]
    if tol is None and trials is None:
        trials = val.trials
    target = trials if tol is None else None
    cap = val.max_trials
    batch = val.batch_trials
    bar = None
    if progress:
        from tqdm import tqdm

        import sys

        bar = tqdm(total=target if target else cap, desc="trials", unit="trial", leave=False,
                   disable=not sys.stderr.isatty())  # quiet when not on a terminal
        bar.update(len(results))
    # "spawn": numba's OpenMP/TBB thread pools must not be forked
    pool = (ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                                initializer=worker_initializer("budget.validate:worker_init")) if workers > 1 else None)
    stopped_by = "trials"
    try:
        while True:
            done = len(results)
            want = (target - done) if target else min(batch, cap - done)
            if want <= 0:
                break
            ks = list(range(done, done + want))
            if pool is None:
                for k in ks:
                    results.append(run_trial(scenario, seed, k))
                    if bar:
                        bar.update(1)
            else:
                # small chunks (a few seconds of work each) keep both the workers and the
                # progress bar busy to the end; the order of completion does not matter
                size = max(1, min(_CHUNK_TRIALS, len(ks) // (2 * workers)))
                chunks = [ks[i:i + size] for i in range(0, len(ks), size)]
                for res in pool.map(_run_chunk, [(scenario, seed, c) for c in chunks]):
                    results.extend(res)
                    if bar:
                        bar.update(len(res))
            if tol is not None:
                if _converged(scenario, results, tol):
                    stopped_by = "tolerance"
                    break
                if len(results) >= cap:
                    stopped_by = "max_trials"
                    break
    except BaseException as exc:
        if pool is not None and not isinstance(exc, Exception):  # interrupted: stop the workers now
            from simcam.lifecycle import stop_pool

            stop_pool(pool)
            pool = None
        raise
    finally:
        if pool is not None:
            pool.shutdown()
        if bar:
            bar.close()
    results.sort(key=lambda r: r["k"])
    samples = {key: np.array([r["values"][key] for r in results]) for key in results[0]["values"]}
    return ValidationResult(scenario, seed, truths_, samples, len(results), stopped_by,
                            example=example.get("kept", {}) if example else {})


def _converged(scenario, results, tol) -> bool:
    if len(results) < 10:
        return False
    f = 3.0 * scenario.camera.scale_arcsec_per_px
    n = len(results)
    for key in results[0]["values"]:
        v = np.array([r["values"][key] for r in results]) * f
        s = v.std(ddof=1)
        if s / math.sqrt(n) > tol or s / math.sqrt(2 * (n - 1)) > tol:
            return False
    return True


def default_workers() -> int:
    """All cores of this machine."""
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))


# --------------------------------------------------------------------------- CLI
import click  # noqa: E402

#: a lower bound of the memory one trial's results hold (one float64 per class, axis, variant)
_BYTES_PER_TRIAL = 8 * len(CLASSES) * len(AXES) * len(VARIANTS)


def _check_trials_fit(scn, *, trials, tolerance, source: str) -> None:
    """Refuse a trial count whose results alone cannot fit in memory (before any work)."""
    from simcam.lifecycle import check_memory

    if trials is not None:
        n, what = trials, f"--trials {trials}"
    elif tolerance is None:
        n, what = scn.validation.trials, f"{source}: validation.trials = {scn.validation.trials}"
    else:
        n, what = scn.validation.max_trials, f"{source}: validation.max_trials = {scn.validation.max_trials}"
    check_memory(float(n) * _BYTES_PER_TRIAL, what=f"{what} (at least {_BYTES_PER_TRIAL} bytes per trial)")


@click.command("validate")
@click.argument("scenario", required=False, type=click.Path(dir_okay=False))
@click.option("--trials", type=click.IntRange(min=2), default=None,
              help="Number of Monte Carlo trials (default: the scenario's validation.trials).")
@click.option("--tolerance", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Stop when every Monte Carlo standard error is below this (arcsec, 3 sigma).")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True)
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Worker processes (default: all cores). Results do not depend on it.")
@click.option("--json", "json_out", type=click.Path(dir_okay=False), help="Write the results as JSON.")
@click.option("--report", "report_dir", type=click.Path(file_okay=False), help="Write a Markdown report with plots.")
@click.option("--progress/--no-progress", default=True, show_default=True, help="Progress bar on stderr.")
def validate_command(scenario, trials, tolerance, seed, workers, json_out, report_dir, progress) -> None:
    """Monte Carlo validation of the seed-000 lab methods on SCENARIO (default: embedded seed-000)."""
    import time

    from budget.report import format_table, write_report
    from simcam.cli_common import UserInputError, write_json_atomic
    from simcam.scenario import load_scenario

    if trials is not None and tolerance is not None:
        raise UserInputError("--trials and --tolerance: give one of them")
    scn = load_scenario(scenario)
    _check_trials_fit(scn, trials=trials, tolerance=tolerance, source=str(scenario or "<embedded scenario>"))
    t0 = time.perf_counter()
    res = validate(scn, trials=trials, tolerance_3sigma_arcsec=tolerance, seed=seed,
                   workers=workers or default_workers(), progress=progress)
    dt = time.perf_counter() - t0
    click.echo(f"{scn.name} (hash {scn.hash}), seed {seed}: {res.trials} trials "
               f"(stopped by {res.stopped_by}) in {dt:.1f} s")
    click.echo(format_table(res.summary()))
    te = res.truths["te"]
    f = 3.0 * scn.camera.scale_arcsec_per_px
    click.echo(f"TE truth vs Cramer-Rao bound: x {te.x_px * f:.3f} vs {te.details['cramer_rao_x_px'] * f:.3f}, "
               f"y {te.y_px * f:.3f} vs {te.details['cramer_rao_y_px'] * f:.3f} arcsec (3 sigma)")
    if json_out:
        write_json_atomic(json_out, res.to_json())
    if report_dir:
        path = write_report(res, report_dir)
        click.echo(f"report: {path}")
