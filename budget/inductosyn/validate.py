"""Monte Carlo validation of the inductosyn calibration (seed 001) against the truth.

K simulated calibrations of one encoder (the scenario's), each with fresh polygon face
errors, quantisation phases, reading and autocollimator noise. Each trial runs the
published in-sequence procedure (eq 7 on 24 faces, compensate, eq 8 on 23 faces, eq 9,
verification re-measurements) and the joint fit, then compares the compensation with the
truth over the whole circle (a dense grid of true shaft angles).

Trial ``k`` draws from ``Generator(PCG64(SeedSequence(seed, spawn_key=(k,))))`` in a fixed
layout (see :func:`trial_draws`), so it is identical whatever the number of trials run
or how they are split; :func:`simulate_trial_exact` is the slow reference (exact inverse
reading map for every point), :func:`run_trials` the vectorised fast path (a second-order
expansion about each face: :class:`simcam.encoder.polygon.FaceTaylor`; batched least squares
with precomputed pseudo-inverses; residual statistics over the dense grid by Gram
identities and chunked products).

The Monte Carlo run itself, its statistics, JSON and report are the runner's
(:mod:`budget.runner`): the study :mod:`budget.inductosyn.study` calls :func:`run_trials`
for its trials; :mod:`budget.inductosyn.report` holds the seed-001 figures and plots.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from budget.inductosyn.harmonics import (
    HarmonicSpec,
    calibrate_in_sequence,
    check_design,
    design_matrix,
    fit_joint,
    sigma3_arcsec,
)
from simcam.encoder.inductosyn import Inductosyn, InductosynScenario, world_encoder_params
from simcam.encoder.polygon import (
    face_taylor,
    measure_polygon,
    nominal_face_angles_deg,
    quantise_arcsec,
    world_alpha_arcsec,
)
from simcam.units import ARCSEC_PER_DEG

__all__ = ["JOINT_ELEC", "LONG", "Prepared", "dense_stats", "prepare", "reference_coefficients",
           "run_trials", "simulate_trial_exact", "split_draws", "trial_draws", "trial_rng"]

LONG = HarmonicSpec(mech_orders=(1, 2), elec_orders=(), n_constants=1)
#: The improved variant fits electrical orders 1-4 jointly on both polygons: on 23 faces
#: electrical 3 aliases onto mechanical 1 and electrical 4 onto mechanical 9, but the
#: 24-face table pins the mechanical harmonics, so the joint design is full rank.
JOINT_ELEC = (1, 2, 3, 4)


def trial_rng(*, seed: int, trial: int) -> np.random.Generator:
    """Generator of trial ``trial``: ``SeedSequence(seed, spawn_key=(trial,))``."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(trial,))))


def trial_draws(*, rng: np.random.Generator, n_long: int, n_short: int, repeats: int = 1):
    """The draws of one trial, in their fixed order (two calls; four with ``repeats > 1``).

    ``u = rng.random(2 n_long + 2 n_short)``: quantisation phases of the four passes
    (long raw, long verify, short raw, short verify); then
    ``z = rng.standard_normal(n_long + n_short + 2 (2 n_long + 2 n_short))``: face errors
    of the long and of the short polygon, then for each pass its reading noise and its
    autocollimator noise. With ``repeats`` rounds per pass (``calibration.repeats``), the
    rounds after the first draw afterwards, ``rng.random((repeats - 1) m)`` and
    ``rng.standard_normal(2 (repeats - 1) m)`` (``m = 2 n_long + 2 n_short``), appended to
    ``u`` and ``z``: the first round's draws are those of a single round.

    Returns
    -------
    (u, z) arrays.
    """
    nm = 2 * n_long + 2 * n_short
    u, z = rng.random(nm), rng.standard_normal(n_long + n_short + 2 * nm)
    if repeats > 1:
        u = np.concatenate([u, rng.random((repeats - 1) * nm)])
        z = np.concatenate([z, rng.standard_normal(2 * (repeats - 1) * nm)])
    return u, z


def split_draws(*, u, z, n_long: int, n_short: int, repeats: int = 1):
    """Split :func:`trial_draws` arrays (last axis) into face errors and per-pass draws.

    Returns
    -------
    (face_long, face_short, passes) with ``passes`` a list of four (u, n_read, n_ac), each
    ``repeats * faces`` long on its last axis (round-major: round 0's faces, then round 1's).
    """
    sizes = (n_long, n_long, n_short, n_short)
    fl = z[..., :n_long]
    fs = z[..., n_long:n_long + n_short]
    rounds = [[] for _ in sizes]
    pos_u = 0
    pos_z = n_long + n_short
    for _ in range(repeats):
        for p, n in enumerate(sizes):
            uu = u[..., pos_u:pos_u + n]
            nr = z[..., pos_z:pos_z + n]
            na = z[..., pos_z + n:pos_z + 2 * n]
            pos_u += n
            pos_z += 2 * n
            rounds[p].append((uu, nr, na))
    if repeats == 1:
        return fl, fs, [r[0] for r in rounds]
    passes = [tuple(np.concatenate([r[j][i] for j in range(repeats)], axis=-1) for i in range(3)) for r in rounds]
    return fl, fs, passes


# ------------------------------------------------------------------ numba kernel
@numba.njit(cache=True, parallel=True)
def _residual_extrema(before, b, coef, out_max, out_min):  # pragma: no cover - compiled
    """max and min over points j of ``before[j] - b[j] . coef[k]`` for each trial k."""
    nk, p = coef.shape
    nj = before.shape[0]
    for k in numba.prange(nk):
        mx = -np.inf
        mn = np.inf
        for j in range(nj):
            r = before[j]
            for i in range(p):
                r -= b[j, i] * coef[k, i]
            if r > mx:
                mx = r
            if r < mn:
                mn = r
        out_max[k] = mx
        out_min[k] = mn


@numba.njit(cache=True)
def _rows_times(x, m):  # pragma: no cover - compiled
    """``x @ m.T`` row by row in a fixed summation order.

    A BLAS product of a batch may round a row differently depending on how many rows the
    batch has; this loop gives each trial's row the same bits whatever batch it is in, so
    results do not depend on how trials are split between workers.
    """
    nk, p = x.shape
    nj = m.shape[0]
    out = np.empty((nk, nj))
    for k in range(nk):
        for j in range(nj):
            acc = 0.0
            for i in range(p):
                acc += x[k, i] * m[j, i]
            out[k, j] = acc
    return out


@numba.njit(cache=True)
def _quad_forms(coef, g, bm, bt):  # pragma: no cover - compiled
    """Per row k: ``coef[k].bm``, ``coef[k].bt`` and ``coef[k] . g . coef[k]``, fixed order."""
    nk, p = coef.shape
    cm = np.empty(nk)
    ct = np.empty(nk)
    q = np.empty(nk)
    for k in range(nk):
        a = 0.0
        b = 0.0
        c = 0.0
        for i in range(p):
            a += coef[k, i] * bm[i]
            b += coef[k, i] * bt[i]
            gi = 0.0
            for j in range(p):
                gi += g[i, j] * coef[k, j]
            c += coef[k, i] * gi
        cm[k] = a
        ct[k] = b
        q[k] = c
    return cm, ct, q


def _mul(x, m):
    return _rows_times(np.ascontiguousarray(x, dtype=np.float64), np.ascontiguousarray(m, dtype=np.float64))


@dataclass
class Prepared:
    """Everything about one scenario that does not change between trials."""

    scenario: InductosynScenario
    encoder: Inductosyn
    taylor_long: object
    taylor_short: object
    angles_long_deg: np.ndarray
    angles_short_deg: np.ndarray
    dense_true_deg: np.ndarray
    dense_reading_deg: np.ndarray
    dense_before_arcsec: np.ndarray
    x_long: np.ndarray
    x_long_at_short: np.ndarray
    x_short: np.ndarray
    x_joint: np.ndarray
    pinv_long: np.ndarray
    pinv_short: np.ndarray
    pinv_joint: np.ndarray
    b_seq: np.ndarray
    b_joint: np.ndarray


def prepare(*, scenario: InductosynScenario, dense_step_deg: float) -> Prepared:
    """Truth on the dense grid, face expansions and the pseudo-inverses of the designs.

    The encoder is the world's (:func:`simcam.encoder.inductosyn.world_encoder_params`:
    the scenario's encoder plus the world's encoder effects), so every truth includes them.
    """
    enc = Inductosyn(params=world_encoder_params(scenario=scenario))
    cal = scenario.calibration
    pp = scenario.encoder.pole_pairs
    al = nominal_face_angles_deg(faces=cal.long_polygon.faces)
    as_ = nominal_face_angles_deg(faces=cal.short_polygon.faces)
    q = max(scenario.encoder.resolution_deg * ARCSEC_PER_DEG, 0.01)
    tl = face_taylor(encoder=enc, faces=cal.long_polygon.faces, step_arcsec=q)
    ts = face_taylor(encoder=enc, faces=cal.short_polygon.faces, step_arcsec=q)
    n_dense = int(round(360.0 / dense_step_deg))
    dense = np.arange(n_dense) * (360.0 / n_dense)
    reading = enc.quantise_deg(reading_deg=enc.continuous_reading_deg(angle_deg=dense))
    before = (reading - dense) * ARCSEC_PER_DEG
    # eq 8 with its nuisance offset (the table is relative to its first face); the offset
    # is fitted, not compensated: only the harmonic rows of the pseudo-inverse are kept
    short_fit_spec = HarmonicSpec(mech_orders=(), elec_orders=(1, 2), pole_pairs=pp, n_constants=1,
                                  nuisance_offset=True)
    short_spec = HarmonicSpec(mech_orders=(), elec_orders=(1, 2), pole_pairs=pp, n_constants=0)
    joint_spec = HarmonicSpec(mech_orders=(1, 2), elec_orders=JOINT_ELEC, pole_pairs=pp,
                              n_constants=2)
    check_design(angle_deg=al, spec=LONG, source="calibration.long_polygon")
    check_design(angle_deg=as_, spec=short_fit_spec, source="calibration.short_polygon")
    idx = np.r_[np.zeros(al.size, int), np.ones(as_.size, int)]
    check_design(angle_deg=np.r_[al, as_], spec=joint_spec, table_index=idx,
                 source="calibration (joint)")
    x_long = design_matrix(angle_deg=al, spec=LONG)
    x_long_s = design_matrix(angle_deg=as_, spec=LONG)
    x_short = design_matrix(angle_deg=as_, spec=short_spec)
    x_joint = design_matrix(angle_deg=np.r_[al, as_], spec=joint_spec, table_index=idx)
    b_seq = np.concatenate([design_matrix(angle_deg=reading, spec=LONG),
                            design_matrix(angle_deg=reading, spec=short_spec)], axis=1)
    b_joint = design_matrix(angle_deg=reading, spec=joint_spec,
                            table_index=np.zeros(reading.size, int))
    return Prepared(scenario=scenario, encoder=enc, taylor_long=tl, taylor_short=ts,
                    angles_long_deg=al, angles_short_deg=as_, dense_true_deg=dense,
                    dense_reading_deg=reading, dense_before_arcsec=before, x_long=x_long,
                    x_long_at_short=x_long_s, x_short=x_short, x_joint=x_joint,
                    pinv_long=np.linalg.pinv(x_long),
                    pinv_short=np.linalg.pinv(design_matrix(angle_deg=as_, spec=short_fit_spec))[1:],
                    pinv_joint=np.linalg.pinv(x_joint), b_seq=b_seq, b_joint=b_joint)


def _measure_fast(taylor, u, nr, nac, face, mount, q_arcsec, sr, sac, res_ac):
    d = (u - 0.5) * q_arcsec - nr * sr
    alpha = taylor.true_offset_arcsec(d_arcsec=d) + face + mount + nac * sac
    return -quantise_arcsec(value_arcsec=alpha, resolution_arcsec=res_ac)


def dense_stats(before, b, coef):
    """3 sigma, mean and max |r - mean| of ``r = before - b @ coef`` for each trial.

    The variance by the Gram identity ``<r^2> = <t^2> - 2 c.<B t> + c.<B^T B>.c``; the
    extrema by a fused numba loop (max |r - mean| = max(max r - mean, mean - min r)).
    """
    n = before.size
    g = b.T @ b / n
    bt = b.T @ before / n
    bm = b.mean(axis=0)
    cm, ct, q = _quad_forms(np.ascontiguousarray(coef, dtype=np.float64), np.ascontiguousarray(g),
                            np.ascontiguousarray(bm), np.ascontiguousarray(bt))
    mean = before.mean() - cm
    ms = np.mean(before**2) - 2 * ct + q
    var = np.maximum(ms - mean**2, 0.0) * n / (n - 1)
    mx = np.empty(coef.shape[0])
    mn = np.empty(coef.shape[0])
    _residual_extrema(np.ascontiguousarray(before, dtype=np.float64),
                      np.ascontiguousarray(b, dtype=np.float64),
                      np.ascontiguousarray(coef, dtype=np.float64), mx, mn)
    return 3 * np.sqrt(var), mean, np.maximum(mx - mean, mean - mn)


def run_trials(*, prepared: Prepared, trials: int, seed: int, first_trial: int = 0) -> dict:
    """Run trials ``first_trial .. first_trial + trials - 1`` (vectorised).

    Returns
    -------
    dict of arrays (one row per trial): raw tables ``y_long``, ``y_long_verify``,
    ``y_short``, ``y_short_verify``; coefficients ``c_long``, ``c_short``, ``c_joint``;
    3 sigma (arcsec) of each published stage and of the dense-grid residuals.
    """
    p = prepared
    sc = p.scenario
    cal = sc.calibration
    lp, sp, ac = cal.long_polygon, cal.short_polygon, cal.autocollimator
    nl, ns = lp.faces, sp.faces
    q = sc.encoder.resolution_deg * ARCSEC_PER_DEG
    sr = sc.encoder.reading_noise_arcsec
    reps = cal.repeats
    k = trials
    nm = 2 * nl + 2 * ns
    uu = np.empty((k, reps * nm))
    zz = np.empty((k, nl + ns + 2 * reps * nm))
    for i in range(k):
        uu[i], zz[i] = trial_draws(rng=trial_rng(seed=seed, trial=first_trial + i), n_long=nl, n_short=ns,
                                   repeats=reps)
    fl, fs, passes = split_draws(u=uu, z=zz, n_long=nl, n_short=ns, repeats=reps)
    # each pass reads its polygon ``reps`` times (round-major): the same face errors every round
    fl = np.tile(fl * lp.face_error_arcsec, reps)
    fs = np.tile(fs * sp.face_error_arcsec, reps)
    faces = [fl, fl, fs, fs]
    # the world's rig effects add to each face's deviation (None: all off, tables unchanged)
    world = world_alpha_arcsec(scenario=sc, seed=seed, trials=range(first_trial, first_trial + k))
    if world is not None:
        faces = [f + w for f, w in zip(faces, world)]
    ys = []
    for (u, nr, nac), (tay, face, poly) in zip(passes, ((p.taylor_long, faces[0], lp), (p.taylor_long, faces[1], lp),
                                                        (p.taylor_short, faces[2], sp), (p.taylor_short, faces[3], sp))):
        n = poly.faces
        rounds = [_measure_fast(tay, u[:, j * n:(j + 1) * n], nr[:, j * n:(j + 1) * n], nac[:, j * n:(j + 1) * n],
                                face[:, j * n:(j + 1) * n], poly.mount_offset_arcsec, q, sr,
                                ac.noise_arcsec, ac.resolution_arcsec) for j in range(reps)]
        # each face's entry: the mean of its rounds (one round: as it is)
        ys.append(rounds[0] if reps == 1 else np.mean(rounds, axis=0))
    y1, y2, y3, y4 = ys
    # every product row by row (_mul): a trial's numbers do not depend on its batch
    c_long = _mul(y1, p.pinv_long)
    long_at_short = _mul(c_long, p.x_long_at_short)
    y3c = y3 - long_at_short
    c_short = _mul(y3c, p.pinv_short)
    c_joint = _mul(np.concatenate([y1, y3], axis=1), p.pinv_joint)
    out = {
        "y_long": y1, "y_long_verify": y2, "y_short": y3, "y_short_verify": y4,
        "c_long": c_long, "c_short": c_short, "c_joint": c_joint,
        "long_sigma3_before_arcsec": sigma3_arcsec(error_arcsec=y1),
        "long_sigma3_after_arcsec": sigma3_arcsec(error_arcsec=y2 - _mul(c_long, p.x_long)),
        "short_sigma3_before_arcsec": sigma3_arcsec(error_arcsec=y3c),
        "short_sigma3_after_arcsec": sigma3_arcsec(error_arcsec=y4 - long_at_short - _mul(c_short, p.x_short)),
    }
    xj_short = p.x_joint[nl:]
    out["joint_short_sigma3_after_arcsec"] = sigma3_arcsec(error_arcsec=y4 - _mul(c_joint, xj_short))
    c_seq = np.concatenate([c_long, c_short], axis=1)
    s3, mean, mx = dense_stats(p.dense_before_arcsec, p.b_seq, c_seq)
    out.update(dense_sigma3_after_arcsec=s3, dense_mean_after_arcsec=mean, dense_maxabs_after_arcsec=mx)
    s3j, meanj, mxj = dense_stats(p.dense_before_arcsec, p.b_joint, c_joint)
    out.update(joint_dense_sigma3_after_arcsec=s3j, joint_dense_mean_after_arcsec=meanj,
               joint_dense_maxabs_after_arcsec=mxj)
    return out


def simulate_trial_exact(*, scenario: InductosynScenario, seed: int, trial: int) -> dict:
    """Slow reference of one trial: exact inverse map for every point (simcam.encoder.polygon).

    Returns the four raw tables and the in-sequence and joint fits.
    """
    enc = Inductosyn(params=world_encoder_params(scenario=scenario))
    cal = scenario.calibration
    nl, ns = cal.long_polygon.faces, cal.short_polygon.faces
    reps = cal.repeats
    u, z = trial_draws(rng=trial_rng(seed=seed, trial=trial), n_long=nl, n_short=ns, repeats=reps)
    fl, fs, passes = split_draws(u=u, z=z, n_long=nl, n_short=ns, repeats=reps)
    fl = np.tile(fl * cal.long_polygon.face_error_arcsec, reps)
    fs = np.tile(fs * cal.short_polygon.face_error_arcsec, reps)
    faces = [fl, fl, fs, fs]
    world = world_alpha_arcsec(scenario=scenario, seed=seed, trials=[trial])
    if world is not None:
        faces = [f + w[0] for f, w in zip(faces, world)]
    tables = []
    for draws, (poly, face) in zip(passes, ((cal.long_polygon, faces[0]), (cal.long_polygon, faces[1]),
                                            (cal.short_polygon, faces[2]), (cal.short_polygon, faces[3]))):
        n = poly.faces
        rounds = [measure_polygon(encoder=enc, polygon=poly, autocollimator=cal.autocollimator,
                                  face_errors_arcsec=face[j * n:(j + 1) * n],
                                  draws=tuple(d[j * n:(j + 1) * n] for d in draws)) for j in range(reps)]
        table = rounds[0]
        if reps > 1:  # each face's entry: the mean of its rounds
            table = table.assign(error_arcsec=np.mean([r.error_arcsec.to_numpy() for r in rounds], axis=0))
        tables.append(table)
    seq = calibrate_in_sequence(long_angle_deg=tables[0].angle_deg.to_numpy(),
                                long_error_arcsec=tables[0].error_arcsec.to_numpy(),
                                short_angle_deg=tables[2].angle_deg.to_numpy(),
                                short_error_arcsec=tables[2].error_arcsec.to_numpy(),
                                pole_pairs=scenario.encoder.pole_pairs)
    joint = fit_joint(tables=[(tables[0].angle_deg, tables[0].error_arcsec),
                              (tables[2].angle_deg, tables[2].error_arcsec)],
                      pole_pairs=scenario.encoder.pole_pairs, elec_orders=JOINT_ELEC)
    return {"tables": tables, "in_sequence": seq, "joint": joint}


def reference_coefficients(p: Prepared, step_deg: float = 0.01) -> np.ndarray:
    """Fourier projection of the true error as a function of the reading.

    The continuous truth ``e(r) = r - f^-1(r)`` on a uniform grid of readings (no
    quantisation), projected on constant + mechanical 1,2 + electrical 1-4: the
    coefficients the fits estimate.
    """
    n = int(round(360.0 / step_deg))
    r = np.arange(n) * (360.0 / n)
    e = p.encoder.error_at_reading_arcsec(reading_deg=r)
    b = design_matrix(angle_deg=r, spec=HarmonicSpec(mech_orders=(1, 2), elec_orders=JOINT_ELEC,
                                                     pole_pairs=p.scenario.encoder.pole_pairs))
    c, *_ = np.linalg.lstsq(b, e, rcond=None)
    return c
