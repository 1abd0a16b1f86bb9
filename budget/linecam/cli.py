"""Commands of the linecam study: ``budget linecam simulate`` and ``budget linecam calibrate``.

``calibrate`` runs the lab's estimators on a table of observed stars, so a real camera can
be calibrated. The table (CSV, one row per identified star crossing the line, header
required, extra columns ignored):

==============  ==================================================================
column          meaning
==============  ==================================================================
time_s          time tag of the centroid (mid-exposure), s after ``--epoch``
sample_px       centroid along the line, px (pixel centres at 0 .. n_pixels - 1)
hip             Hipparcos catalogue number of the star
q_w q_x q_y q_z reported attitude, body (nominal camera) -> GCRS, unit quaternion,
                scalar first
pos_x_km ...    spacecraft geocentric position ``pos_x_km, pos_y_km, pos_z_km`` (GCRS)
vel_x_km_s ...  spacecraft geocentric velocity ``vel_x_km_s, vel_y_km_s, vel_z_km_s``
pass            optional: pass number (reports only)
==============  ==================================================================

The camera's nominal model (focal length, pitch, number of detectors, line position) and
the lab's settings come from ``--scenario`` (default: the embedded scenario). ``simulate``
writes exactly this table for a simulated calibration (``--csv``), so the two commands
round-trip.
"""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from budget.runner.html import write_html
from budget.runner.numbers import fmt
from budget.runner.study import trial_seed_sequence
from simcam.infra.cli import overwrite_option, write_json_atomic
from simcam.infra.errors import UserInputError
from simcam.infra.outputs import StagedOutputs, apply_umask, check_input_file, check_run_outputs
from simcam.linecam.scenario import PARAMETERS
from simcam.sky.apparent import aberration_first_order, apparent_directions
from simcam.sky.catalogue import CatalogueError, hipparcos
from simcam.units import ARCSEC_PER_RAD, SECONDS_PER_DAY

from .report import figure_markdown, plot_coverage, plot_los_error, plot_los_field, plot_residuals, plot_tracks
from .study import STUDY, determined_combinations, gauge_combination_vector, trial_extra

__all__ = ["commands", "read_observations", "calibrate_table", "CSV_COLUMNS"]

CSV_COLUMNS = ("time_s", "sample_px", "hip", "q_w", "q_x", "q_y", "q_z", "pos_x_km", "pos_y_km", "pos_z_km",
               "vel_x_km_s", "vel_y_km_s", "vel_z_km_s")


def _scenario(path):
    return STUDY.load_scenario(path)


# --------------------------------------------------------------------------- simulate
@click.command("simulate", help="Simulate one star-observation calibration (one trial of SCENARIO, default: "
                                "the embedded one) and compare the calibrated LOS field with the truth.")
@click.argument("scenario", required=False, type=click.Path(dir_okay=False))
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True)
@click.option("--trial", "k", type=click.IntRange(min=0), default=0, show_default=True,
              help="Trial number (draws from SeedSequence(seed, spawn_key=(trial,))).")
@click.option("--csv", "csv_out", type=click.Path(dir_okay=False),
              help="Write the identified observations as a table for 'budget linecam calibrate'.")
@click.option("--json", "json_out", type=click.Path(dir_okay=False), help="Write the results as JSON.")
@click.option("--report", "report_dir", type=click.Path(file_okay=False), help="Write plots and a Markdown page.")
@overwrite_option
def simulate_cmd(scenario, seed, k, csv_out, json_out, report_dir, overwrite):
    from .calibrate import CalibrationError
    from .trial import PARAM_UNITS, simulate, to_report_units

    check_run_outputs(json_out=json_out, report_dir=report_dir, files={"--csv": csv_out}, inputs=(scenario,),
                      overwrite=overwrite)
    scn = _scenario(scenario)
    try:
        sim = simulate(scn, trial_seed_sequence(seed, k))
    except CalibrationError as exc:
        raise UserInputError(f"{scn.source}: stars.mag_limit / observation.passes: {exc}") from None
    ex = trial_extra(scn, sim)
    truth = to_report_units(sim.theta_true)
    out = {"scenario_hash": scn.hash, "seed": seed, "trial": k, "identified": ex["identified"],
           "windows": ex["windows"], "separability": ex["separability"], "variants": {}}
    click.echo(f"trial {k} of seed {seed}: {ex['windows']} star windows, {ex['identified']} stars identified")
    click.echo(f"{'parameter':10s} {'unit':7s} {'truth':>10s} " + " ".join(f"{v:>21s}" for v in sim.calibrations))
    undet = set(ex["separability"]["inseparable"])  # no sigma for what the plan cannot separate
    for j, p in enumerate(PARAMETERS):
        cols = []
        for c in sim.calibrations.values():
            est = to_report_units(c.theta)[j]
            sd = np.sqrt(max(c.cov[j, j], 0.0)) * abs(PARAM_UNITS[p][1])
            cols.append(f"{fmt(est):>10} {'not determined':>10s}" if p in undet else f"{fmt(est):>10} +-{fmt(sd, 3):>9}")
        click.echo(f"{p:10s} {PARAM_UNITS[p][0]:7s} {fmt(truth[j]):>10} " + " ".join(cols))
    f_px = scn.camera.focal_length_mm / scn.camera.pitch_mm
    out["determined_combinations"] = {}
    for name, ang, px, sign in determined_combinations(ex["separability"]["null_space"], f_px):
        g = gauge_combination_vector(f_px, ang, px, sign)
        vals = {v: {"value": float(g @ c.theta), "sigma": float(np.sqrt(max(g @ c.cov @ g, 0.0)))}
                for v, c in sim.calibrations.items()}
        out["determined_combinations"][name] = {"unit": "arcsec", "truth": float(g @ sim.theta_true), **vals}
        click.echo(f"{name:10s} {'arcsec':7s} {fmt(g @ sim.theta_true):>10} "
                   + " ".join(f"{fmt(d['value']):>10} +-{fmt(d['sigma'], 3):>9}" for d in vals.values()))
    for v, (ea, ec, sa, sc) in ex["los_error_arcsec"].items():
        stats = {"rms_error_along_arcsec": float(np.sqrt(np.mean(ea**2))),
                 "rms_error_across_arcsec": float(np.sqrt(np.mean(ec**2))),
                 "max_error_along_arcsec": float(np.max(np.abs(ea))),
                 "max_error_across_arcsec": float(np.max(np.abs(ec))),
                 "stated_rms_along_arcsec": float(np.sqrt(np.mean(sa**2))),
                 "stated_rms_across_arcsec": float(np.sqrt(np.mean(sc**2)))}
        c = sim.calibrations.get(v)
        out["variants"][v] = stats if c is None else {
            "theta": dict(zip(PARAMETERS, to_report_units(c.theta).tolist())),
            "covariance_model_units": c.cov.tolist(), "sigma0_px": c.sigma0_px, "condition": c.condition, **stats}
        click.echo(f"{v}: LOS error over the line rms {stats['rms_error_along_arcsec']:.3f}\" along, "
                   f"{stats['rms_error_across_arcsec']:.3f}\" across (stated {stats['stated_rms_along_arcsec']:.3f}\", "
                   f"{stats['stated_rms_across_arcsec']:.3f}\"); max {stats['max_error_along_arcsec']:.3f}\", "
                   f"{stats['max_error_across_arcsec']:.3f}\"")
    eb = ex["los_error_before_arcsec"]
    click.echo(f"before calibration: rms {np.sqrt(np.mean(eb[0] ** 2)):.2f}\" along, "
               f"{np.sqrt(np.mean(eb[1] ** 2)):.2f}\" across")
    out["truth"] = dict(zip(PARAMETERS, truth.tolist()))
    with StagedOutputs() as staged:  # the table, the JSON and the report appear together or not at all
        if csv_out:
            tmp = staged.file(csv_out)
            write_observation_csv(scn, sim, tmp)
            apply_umask(tmp, is_dir=False)
        if json_out:
            write_json_atomic(staged.file(json_out), out)
        if report_dir:
            d = staged.folder(report_dir)
            d.mkdir(parents=True, exist_ok=True)
            figs = [plot_tracks(ex, d / "tracks.png"), plot_residuals(ex, d / "residuals.png"),
                    plot_los_error(ex, d / "los_error.png"), plot_coverage(ex, d / "coverage.png")]
            (d / "simulate.md").write_text("# Line camera: one simulated calibration\n\n"
                                           + figure_markdown(figs) + "\n")
            write_html(d / "simulate.md")  # its self-contained twin, simulate.html
    if csv_out:
        click.echo(f"observations: {csv_out}")
    if report_dir:
        click.echo(f"report: {Path(report_dir) / 'simulate.md'}")


def write_observation_csv(scn, sim, path) -> None:
    """The identified observations of a simulation as the table ``calibrate`` reads."""
    import pandas as pd
    from scipy.spatial.transform import Rotation

    from simcam.linecam.attitude import orbit_state

    idf = sim.identified
    q = Rotation.from_matrix(idf.attitude).as_quat()  # scalar last
    pos, vel = orbit_state(scn, idf.t_s)
    df = pd.DataFrame({"time_s": idf.t_s, "sample_px": idf.obs.sample, "hip": idf.obs.hip,
                       "q_w": q[:, 3], "q_x": q[:, 0], "q_y": q[:, 1], "q_z": q[:, 2],
                       "pos_x_km": pos[:, 0], "pos_y_km": pos[:, 1], "pos_z_km": pos[:, 2],
                       "vel_x_km_s": vel[:, 0], "vel_y_km_s": vel[:, 1], "vel_z_km_s": vel[:, 2],
                       "pass": idf.obs.pass_index})
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(path, index=False, float_format="%.17g")


# --------------------------------------------------------------------------- calibrate
def read_observations(path, scn, *, epoch_utc: str | None = None):
    """Read and check an observation table; the stars' apparent directions in the reported
    body frame (:class:`budget.linecam.model.Observations`) and the table.

    Every problem is a :class:`simcam.infra.errors.UserInputError` naming the file and field.
    """
    import pandas as pd
    from astropy.time import Time
    from scipy.spatial.transform import Rotation

    from .model import Observations

    src = str(path)
    p = check_input_file(path, what="observation table")  # a FIFO or a device is not read
    try:
        # only an empty cell is missing: a literal "nan" or "NA" is kept as written, and named so
        df = pd.read_csv(p, encoding="utf-8-sig", keep_default_na=False, na_values=[""])
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise UserInputError(f"{src}: not a readable CSV table ({str(exc).splitlines()[0]})") from None
    missing = [c for c in CSV_COLUMNS if c not in df.columns]
    if missing:
        raise UserInputError(f"{src}: {missing[0]}: missing column (needed: {', '.join(CSV_COLUMNS)})")
    if len(df) == 0:
        raise UserInputError(f"{src}: rows: the table has no observations")
    arr = {}
    for c in CSV_COLUMNS:
        v = pd.to_numeric(df[c], errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            raw = df[c].iloc[bad[0]]
            got = "an empty cell" if pd.isna(raw) else repr(str(raw))
            raise UserInputError(f"{src}: {c}: not a finite number in row {int(bad[0]) + 2} (got {got})")
        arr[c] = v
    check_observation_values(src, arr, n_pixels=scn.camera.n_pixels)
    hip = arr["hip"]
    if np.any(hip != np.round(hip)) or np.any(hip < 1):
        r = int(np.flatnonzero((hip != np.round(hip)) | (hip < 1))[0])
        raise UserInputError(f"{src}: hip: not a catalogue number in row {r + 2} (got {df['hip'].iloc[r]!r})")
    n_pix = scn.camera.n_pixels
    s = arr["sample_px"]
    out = np.flatnonzero((s < -0.5) | (s > n_pix - 0.5))
    if out.size:
        raise UserInputError(f"{src}: sample_px: {s[out[0]]:g} in row {int(out[0]) + 2} is off the line "
                             f"(0 .. {n_pix - 1} for camera.n_pixels = {n_pix})")
    q = np.column_stack([arr["q_x"], arr["q_y"], arr["q_z"], arr["q_w"]])
    qn = np.linalg.norm(q, axis=1)
    out = np.flatnonzero(np.abs(qn - 1.0) > 1e-6)
    if out.size:
        raise UserInputError(f"{src}: q_w: the quaternion in row {int(out[0]) + 2} is not a unit quaternion "
                             f"(norm {qn[out[0]]:.9g})")
    try:
        cat = hipparcos().by_hip(hip.astype(np.int64))
    except CatalogueError as exc:
        raise UserInputError(f"{src}: hip: {exc}") from None
    t = arr["time_s"]
    pos = np.column_stack([arr["pos_x_km"], arr["pos_y_km"], arr["pos_z_km"]])
    vel = np.column_stack([arr["vel_x_km_s"], arr["vel_y_km_s"], arr["vel_z_km_s"]])
    try:
        epoch = Time(epoch_utc or scn.orbit.epoch_utc, scale="utc")
    except ValueError:
        raise UserInputError(f"--epoch: not an ISO UTC time: {epoch_utc!r}") from None
    import astropy.units as u

    lab = scn.lab
    ref = int(np.argsort(t)[t.size // 2])
    a = apparent_directions(cat, epoch + t[ref] * u.s, observer_position_km=pos[ref], observer_velocity_km_s=vel[ref],
                            proper_motion=lab.proper_motion, parallax=lab.parallax, aberration=lab.aberration)
    if lab.aberration:  # first-order differential aberration for each row's velocity (|v||dv|/c^2 < 2e-9 rad)
        a = aberration_first_order(a, vel - vel[ref])
    att = Rotation.from_quat(q / qn[:, None]).as_matrix()
    b = np.einsum("nji,nj->ni", att, a)
    passes = pd.to_numeric(df["pass"], errors="coerce").fillna(0).to_numpy(dtype=int) if "pass" in df else \
        np.zeros(len(df), dtype=int)
    return Observations(b=b, sample=s, pass_index=passes, hip=hip.astype(np.int64)), t


#: a physical observation table: times within a century of the epoch, the
#: spacecraft between the Earth's surface and ten times the Moon's distance, at less than
#: the Earth's escape speed from its surface (11.2 km/s) plus margin
MAX_ABS_TIME_S = 100 * 365.25 * SECONDS_PER_DAY
MIN_RADIUS_KM, MAX_RADIUS_KM = 6356.0, 4.0e6
MAX_SPEED_KM_S = 20.0
#: at least this many distinct catalogue stars (each gives two equations; ten parameters)
MIN_DISTINCT_STARS = 6
#: the samples must spread over at least this many pixels along the line
MIN_SAMPLE_SPREAD_PX = 2.0


def check_observation_values(src: str, arr: dict, *, n_pixels: int) -> None:
    """What makes a calibration from this table meaningless, refused with the file and field:
    duplicated rows (counted twice, they overstate the stated precision by sqrt 2),
    non-physical times, positions and velocities, too few distinct stars, all samples at
    one pixel. ``arr``: the table's columns as float arrays (already finite)."""
    t = arr["time_s"]
    bad = np.flatnonzero(np.abs(t) > MAX_ABS_TIME_S)
    if bad.size:
        raise UserInputError(f"{src}: time_s: {t[bad[0]]:g} s in row {int(bad[0]) + 2} is more than a century "
                             f"from the epoch (|time_s| <= {MAX_ABS_TIME_S:.3g})")
    r = np.sqrt(arr["pos_x_km"] ** 2 + arr["pos_y_km"] ** 2 + arr["pos_z_km"] ** 2)
    bad = np.flatnonzero((r < MIN_RADIUS_KM) | (r > MAX_RADIUS_KM))
    if bad.size:
        raise UserInputError(f"{src}: pos_x_km: the position in row {int(bad[0]) + 2} is {r[bad[0]]:.6g} km from "
                             f"the Earth's centre (an orbit is between {MIN_RADIUS_KM:g} and {MAX_RADIUS_KM:g} km)")
    v = np.sqrt(arr["vel_x_km_s"] ** 2 + arr["vel_y_km_s"] ** 2 + arr["vel_z_km_s"] ** 2)
    bad = np.flatnonzero(v > MAX_SPEED_KM_S)
    if bad.size:
        raise UserInputError(f"{src}: vel_x_km_s: the speed in row {int(bad[0]) + 2} is {v[bad[0]]:.6g} km/s "
                             f"(an orbit is slower than {MAX_SPEED_KM_S:g} km/s)")
    table = np.column_stack([arr[c] for c in CSV_COLUMNS])
    _, first, inverse, counts = np.unique(table, axis=0, return_index=True, return_inverse=True,
                                          return_counts=True)
    if np.any(counts > 1):
        inverse = np.ravel(inverse)
        dup = int(np.flatnonzero(first[inverse] != np.arange(inverse.size))[0])  # the first later copy
        k = int(inverse[dup])
        raise UserInputError(f"{src}: rows: row {dup + 2} repeats row {int(first[k]) + 2} "
                             f"({int((counts - 1).clip(0).sum())} duplicated row(s)); a repeated observation "
                             "is counted twice and overstates the stated precision: remove the duplicates")
    stars = np.unique(arr["hip"]).size
    if stars < MIN_DISTINCT_STARS:
        raise UserInputError(f"{src}: rows: {stars} distinct star(s) (column hip); a calibration needs at "
                             f"least {MIN_DISTINCT_STARS}: too few stars")
    s = arr["sample_px"]
    if float(np.ptp(s)) < MIN_SAMPLE_SPREAD_PX:
        raise UserInputError(f"{src}: sample_px: every observation is at pixel {np.median(s):.6g} (spread "
                             f"{float(np.ptp(s)):.3g} px of the {n_pixels}); the field along the line is not "
                             "determined")


#: a fit whose normal matrix has a condition number above this is singular to double precision
MAX_CONDITION = 1e12


def check_determined(calibrations: dict, *, source: str) -> None:
    """A singular or near-singular fit is an error, never a result stated "+- 0".

    The published steps and the look-angle polynomials have no gauge: a normal matrix
    with a condition number above :data:`MAX_CONDITION` (or infinite) means the table does
    not determine them. The joint fit removes its gauge directions by design (their
    zero variance is the gauge, stated as such); a non-finite stated uncertainty is refused.
    """
    for m, c in calibrations.items():
        cond = float(getattr(c, "condition", np.nan))
        if m != "improved" and (not np.isfinite(cond) or cond > MAX_CONDITION):
            raise UserInputError(f"{source}: rows: the {m} fit is singular (condition {cond:.3g}); these "
                                 "observations do not determine the parameters")
        cov = getattr(c, "cov", None)
        if cov is not None and not np.all(np.isfinite(np.diag(cov))):
            raise UserInputError(f"{source}: rows: the {m} fit has no finite uncertainty; these observations "
                                 "do not determine the parameters")


def calibrate_table(obs, scn, *, source: str, solve=None, methods=("published", "improved", "lookangle")) -> dict:
    """Both estimators on the observations; errors name ``source`` and the field."""
    from .calibrate import (
        CalibrationError,
        calibrate_joint,
        calibrate_lookangle,
        calibrate_published,
        los_field,
        separability,
    )
    from .model import NominalCamera
    from .trial import los_grid

    cam = NominalCamera.from_model(scn.camera)
    lab = scn.lab
    out = {}
    try:
        sep = separability(cam, obs, rcond=lab.rcond) if 2 * len(obs) > len(PARAMETERS) else None
        for m in methods:
            if m == "lookangle":
                out[m] = calibrate_lookangle(cam, obs, degree_along=lab.lookangle_degree_along,
                                             degree_across=lab.lookangle_degree_across)
            elif m == "published":
                if solve is not None:
                    raise UserInputError(f"{source}: solve: the published method solves all ten parameters "
                                         "(exterior, then interior); use --method improved with --solve")
                out[m] = calibrate_published(cam, obs, coverage_bins=lab.coverage_bins, max_iter=lab.max_iter)
            else:
                out[m] = calibrate_joint(cam, obs, solve=solve or PARAMETERS, rcond=lab.rcond,
                                         gauge_sigma_px=lab.gauge_sigma_px,
                                         strict=solve is not None)
    except CalibrationError as exc:
        field = "solve" if "separate" in str(exc) else "rows"
        raise UserInputError(f"{source}: {field}: {exc}") from None
    except np.linalg.LinAlgError as exc:
        raise UserInputError(f"{source}: rows: the fit is singular ({exc}); these observations do not "
                             "determine the parameters") from None
    check_determined(out, source=source)
    grid = los_grid(scn)
    los = {m: (c.field(grid) if m == "lookangle" else los_field(cam, c, grid)) for m, c in out.items()}
    return {"calibrations": out, "los": los, "grid": grid,
            "separability": sep, "camera": cam}


@click.command("calibrate", help="Calibrate a line camera from OBSERVATIONS (CSV: time_s, sample_px, hip, "
                                 "q_w..q_z, pos_*_km, vel_*_km_s; see docs/linecam.md) with the nominal "
                                 "camera of --scenario.")
@click.argument("observations", type=click.Path(dir_okay=False))
@click.option("--scenario", "scenario", type=click.Path(dir_okay=False), default=None,
              help="Scenario with the camera's nominal model and the lab settings (default: embedded).")
@click.option("--epoch", default=None, help="UTC epoch of time_s (ISO; default: the scenario's orbit.epoch_utc).")
@click.option("--method", type=click.Choice(["all", "published", "improved", "lookangle"]), default="all",
              show_default=True, help="Estimator(s): the patent's steps, the joint fit, the look-angle polynomials.")
@click.option("--solve", default=None,
              help="Comma-separated parameters for the improved fit (others held at nominal), e.g. "
                   "'yaw,df,k1,k2,p1,p2'; an inseparable set is an error. Default: all ten, gauge removed.")
@click.option("--json", "json_out", type=click.Path(dir_okay=False), help="Write the results as JSON.")
@click.option("--report", "report_dir", type=click.Path(file_okay=False), help="Write plots and a Markdown page.")
@overwrite_option
def calibrate_cmd(observations, scenario, epoch, method, solve, json_out, report_dir, overwrite):
    from .model import los_angles, residuals
    from .trial import PARAM_UNITS, to_report_units

    # before any work: --json/--report are new files/folders or earlier outputs, not a
    # device and not the observation table or the scenario
    check_run_outputs(json_out=json_out, report_dir=report_dir, inputs=(observations, scenario), overwrite=overwrite)
    scn = _scenario(scenario)
    src = str(observations)
    names = None
    if solve is not None:
        names = tuple(x.strip() for x in solve.split(",") if x.strip())
        bad = [x for x in names if x not in PARAMETERS]
        if bad or not names:
            raise UserInputError(f"--solve: unknown parameter {bad[0] if bad else solve!r} "
                                 f"(known: {', '.join(PARAMETERS)})")
    obs, t = read_observations(observations, scn, epoch_utc=epoch)
    methods = ("published", "improved", "lookangle") if method == "all" else (method,)
    if names is not None and method == "all":
        methods = ("improved",)
    res = calibrate_table(obs, scn, source=src, solve=names, methods=methods)
    cam, sep = res["camera"], res["separability"]
    click.echo(f"{src}: {len(obs)} star observations")
    if sep is not None:
        null = "; ".join(" ".join(f"{c:+.2f} {p}" for p, c in d.items()) for d in sep.null_space) or "none"
        click.echo(f"plan: condition {fmt(sep.condition, 3)}; unobservable combinations: {null}")
    payload = {"observations": src, "n": len(obs), "scenario_hash": scn.hash,
               "separability": None if sep is None else {"condition": sep.condition, "null_space": sep.null_space,
                                                          "inseparable": list(sep.inseparable)},
               "methods": {}}
    nominal = los_angles(cam, np.zeros(len(PARAMETERS)), res["grid"])
    for m, c in res["calibrations"].items():
        L = res["los"][m]
        field = {"sample_px": res["grid"].tolist(),
                 "along_minus_nominal_arcsec": ((L["along"] - nominal[0]) * ARCSEC_PER_RAD).tolist(),
                 "across_minus_nominal_arcsec": ((L["across"] - nominal[1]) * ARCSEC_PER_RAD).tolist(),
                 "sigma_along_arcsec": (L["sigma_along"] * ARCSEC_PER_RAD).tolist(),
                 "sigma_across_arcsec": (L["sigma_across"] * ARCSEC_PER_RAD).tolist()}
        click.echo(f"{m}: rms residual {c.sigma0_px:.3f} px, condition {fmt(c.condition, 3)}, "
                   f"stated LOS rms {np.sqrt(np.mean(L['sigma_along'] ** 2)) * ARCSEC_PER_RAD:.3f}\" along, "
                   f"{np.sqrt(np.mean(L['sigma_across'] ** 2)) * ARCSEC_PER_RAD:.3f}\" across")
        if m == "lookangle":
            payload["methods"][m] = {"tan_along_coefficients": c.a.tolist(), "tan_across_coefficients": c.b.tolist(),
                                     "sigma0_px": c.sigma0_px, "condition": c.condition, "los_field": field}
            continue
        th = to_report_units(c.theta)
        sd = np.sqrt(np.maximum(np.diag(c.cov), 0)) * np.abs(to_report_units(np.ones(len(PARAMETERS))))
        # parameters the plan cannot separate are "not determined" (no sigma); what it does
        # determine of them is printed as the combinations
        undet = set(sep.inseparable) if sep is not None else set()
        for j, p in enumerate(PARAMETERS):
            if p in c.solved:
                click.echo(f"  {p:6s} not determined (inseparable on this plan)" if p in undet else
                           f"  {p:6s} {fmt(th[j], 5):>12} +- {fmt(sd[j], 3)} {PARAM_UNITS[p][0]}")
        combos = {}
        for name, ang, px, sign in (determined_combinations(sep.null_space, cam.f_px) if sep is not None else []):
            if ang in c.solved and px in c.solved:
                g = gauge_combination_vector(cam.f_px, ang, px, sign)
                combos[name] = {"value": float(g @ c.theta), "sigma": float(np.sqrt(max(g @ c.cov @ g, 0.0))),
                                "unit": "arcsec"}
                click.echo(f"  {name:6s} {fmt(combos[name]['value'], 5):>12} +- {fmt(combos[name]['sigma'], 3)} arcsec")
        payload["methods"][m] = {
            "theta": dict(zip(PARAMETERS, th.tolist())),
            "sigma": {p: (None if p in undet else v) for p, v in zip(PARAMETERS, sd.tolist())},
            "not_determined": sorted(undet), "determined_combinations": combos,
            "units": {p: PARAM_UNITS[p][0] for p in PARAMETERS}, "solved": list(c.solved),
            "covariance_model_units": c.cov.tolist(), "sigma0_px": c.sigma0_px, "condition": c.condition,
            "los_field": field}
    with StagedOutputs() as staged:  # the JSON and the report appear together or not at all
        if json_out:
            write_json_atomic(staged.file(json_out), payload)
        if report_dir:
            d = staged.folder(report_dir)
            d.mkdir(parents=True, exist_ok=True)
            ex = {"sample": obs.sample, "t_s": t, "pass": obs.pass_index, "n_pixels": scn.camera.n_pixels,
                  "coverage_bins": scn.lab.coverage_bins,
                  "residual_before_px": residuals(cam, np.zeros(len(PARAMETERS)), obs),
                  "residual_after_px": {m: c.residuals_px for m, c in res["calibrations"].items()
                                        if m != "lookangle"}}
            figs = [plot_tracks(ex, d / "tracks.png"), plot_residuals(ex, d / "residuals.png"),
                    plot_los_field(payload, d / "los_field.png"), plot_coverage(ex, d / "coverage.png")]
            rows = ["| method | parameter | value | 1-sigma | unit |", "|---|---|---|---|---|"]
            for m, pm in payload["methods"].items():
                for p in pm.get("solved", []):
                    rows.append(f"| {m} | {p} | not determined | - | {pm['units'][p]} |" if p in pm["not_determined"]
                                else f"| {m} | {p} | {fmt(pm['theta'][p], 5)} | {fmt(pm['sigma'][p], 3)} | {pm['units'][p]} |")
                for name, cmb in pm.get("determined_combinations", {}).items():
                    rows.append(f"| {m} | {name} | {fmt(cmb['value'], 5)} | {fmt(cmb['sigma'], 3)} | arcsec |")
            note = ("Parameters this plan cannot separate are not determined (no sigma); the combinations the "
                    "stars do determine are listed in their place." if any(
                        pm.get("not_determined") for pm in payload["methods"].values()) else "")
            (d / "calibrate.md").write_text(f"# Line camera calibration from {src}\n\n" + "\n".join(rows) + "\n\n"
                                            + (note + "\n\n" if note else "")
                                            + figure_markdown(figs) + "\n")
            write_html(d / "calibrate.md")  # its self-contained twin, calibrate.html
    if report_dir:
        click.echo(f"report: {Path(report_dir) / 'calibrate.md'}")


def commands() -> list[click.Command]:
    """The linecam study's own commands: ``simulate`` and ``calibrate``."""
    return [simulate_cmd, calibrate_cmd]


@click.group("linecam")
def _local_group():
    """Local group for manual testing: python -m budget.linecam.cli ..."""


for _c in commands():
    _local_group.add_command(_c)

if __name__ == "__main__":  # pragma: no cover
    from simcam.infra.cli import run_cli

    run_cli(_local_group)
