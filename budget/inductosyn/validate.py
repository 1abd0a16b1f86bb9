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
from budget.inductosyn.truth import (
    FourierTruth,
    basis_terms,
    drift_columns_arcsec,
    fourier_truth,
    instrument_coefficients,
)
from budget.runner.study import instrument_seed_sequence
from simcam.encoder.inductosyn import (
    Inductosyn,
    InductosynScenario,
    world_encoder_params,
    world_pitch_phases_deg,
    world_pitch_terms,
)
from simcam.encoder.polygon import (
    face_taylor,
    measure_polygon,
    nominal_face_angles_deg,
    quantise_arcsec,
    world_alpha_arcsec,
)
from simcam.units import ARCSEC_PER_DEG

__all__ = ["ENVIRONMENT_STREAM", "JOINT_ELEC", "LONG", "Prepared", "environment_draws", "instrument_draws", "prepare", "run_trials",
           "simulate_trial_exact", "split_draws", "trial_draws", "trial_rng"]

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


def _mul(x, m):
    return _rows_times(np.ascontiguousarray(x, dtype=np.float64), np.ascontiguousarray(m, dtype=np.float64))


@dataclass
class Prepared:
    """Everything about one scenario that does not change between trials.

    ``encoder`` is the scenario's encoder without the world's pitch terms; each trial's
    instrument adds those terms with its own phases (:func:`instrument_draws`): to the face
    tables through ``face_basis_long`` / ``face_basis_short`` (their error at each face, first
    order, :mod:`budget.inductosyn.truth`) and to the truths through ``truth``; its drift
    after the environment (seed 001 section 4.3) to the short polygon's re-measurement through
    ``face_drift_short`` (:func:`environment_draws`).
    """

    scenario: InductosynScenario
    encoder: Inductosyn
    taylor_long: object
    taylor_short: object
    angles_long_deg: np.ndarray
    angles_short_deg: np.ndarray
    x_long: np.ndarray
    x_long_at_short: np.ndarray
    x_short: np.ndarray
    x_joint: np.ndarray
    pinv_long: np.ndarray
    pinv_short: np.ndarray
    pinv_joint: np.ndarray
    truth: FourierTruth
    face_basis_long: np.ndarray
    face_basis_short: np.ndarray
    face_drift_short: np.ndarray

    @property
    def pinned(self) -> bool:
        """Whether ``validation.instrument_seed`` pins one instrument for every trial."""
        return self.scenario.validation.instrument_seed is not None


def _face_basis(encoder: Inductosyn, taylor, basis) -> np.ndarray:
    """The error each basis term adds at each face's reading, ``(faces, J)``:
    ``g_j(theta_0) dtheta_0/dr`` (first order, :mod:`budget.inductosyn.truth`)."""
    theta0 = taylor.angles_deg - taylor.e0_arcsec / ARCSEC_PER_DEG
    return encoder.pitch_arcsec(angle_deg=theta0, harmonics=basis, separate=True) * taylor.s1[:, None]


def instrument_draws(*, scenario: InductosynScenario, seed: int, trials) -> tuple[list, np.ndarray]:
    """Each trial's instrument: its seed sequence
    (:func:`budget.runner.study.instrument_seed_sequence` of ``validation.instrument_seed``)
    and the coefficients ``a`` of its encoder's pitch phases (rows,
    :func:`budget.inductosyn.truth.instrument_coefficients`)."""
    inst = [instrument_seed_sequence(scenario.validation.instrument_seed, seed, k) for k in trials]
    n_terms = len(world_pitch_terms(scenario=scenario))
    if n_terms == 0:
        return inst, np.zeros((len(inst), 0))
    return inst, instrument_coefficients(np.array([world_pitch_phases_deg(scenario=scenario, instrument=i)
                                                   for i in inst]))


#: spawn-key tail of a trial's environment draws: ``SeedSequence(seed, spawn_key=(k, 2))``
#: (the world's draws are ``(k, 1)``, the lab's ``(k,)``)
ENVIRONMENT_STREAM = 2


def environment_draws(*, seed: int, trial: int, n_short: int) -> tuple[np.ndarray, ...]:
    """Trial ``trial``'s environment test (seed 001 section 4.3): the drift's 7 standard
    normal draws (:func:`simcam.encoder.inductosyn.drifted_params`), then the short
    polygon's re-measurement after it, one round: quantisation phases, reading and
    autocollimator noise (``n_short`` each)."""
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(trial, ENVIRONMENT_STREAM))))
    z = rng.standard_normal(7)
    return z, rng.random(n_short), rng.standard_normal(n_short), rng.standard_normal(n_short)


def prepare(*, scenario: InductosynScenario, dense_step_deg: float) -> Prepared:
    """Face expansions, the pseudo-inverses of the designs and the Fourier truth.

    ``dense_step_deg``: the step of the truth's grid of readings
    (:func:`budget.inductosyn.truth.fourier_truth`), at most ``360 / (16 P)`` deg (a grid
    whose Nyquist order is 8 electrical periods).
    """
    enc = Inductosyn(params=scenario.encoder)
    cal = scenario.calibration
    pp = scenario.encoder.pole_pairs
    al = nominal_face_angles_deg(faces=cal.long_polygon.faces)
    as_ = nominal_face_angles_deg(faces=cal.short_polygon.faces)
    q = max(scenario.encoder.resolution_deg * ARCSEC_PER_DEG, 0.01)
    tl = face_taylor(encoder=enc, faces=cal.long_polygon.faces, step_arcsec=q)
    ts = face_taylor(encoder=enc, faces=cal.short_polygon.faces, step_arcsec=q)
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
    terms = world_pitch_terms(scenario=scenario)
    basis = basis_terms(terms)
    # the grid resolves 8 electrical periods' harmonics at least (eq 8's orders 1-4 and beyond)
    truth = fourier_truth(encoder=scenario.encoder, terms=terms, step_deg=min(dense_step_deg, 360.0 / (16 * pp)),
                          drift=scenario.drift)
    return Prepared(scenario=scenario, encoder=enc, taylor_long=tl, taylor_short=ts,
                    angles_long_deg=al, angles_short_deg=as_, x_long=x_long,
                    x_long_at_short=x_long_s, x_short=x_short, x_joint=x_joint,
                    pinv_long=np.linalg.pinv(x_long),
                    pinv_short=np.linalg.pinv(design_matrix(angle_deg=as_, spec=short_fit_spec))[1:],
                    pinv_joint=np.linalg.pinv(x_joint), truth=truth,
                    face_basis_long=_face_basis(enc, tl, basis), face_basis_short=_face_basis(enc, ts, basis),
                    face_drift_short=drift_columns_arcsec(encoder=scenario.encoder, drift=scenario.drift,
                                                          theta0_deg=ts.angles_deg - ts.e0_arcsec / ARCSEC_PER_DEG,
                                                          slope=ts.s1))


def _measure_fast(taylor, u, nr, nac, face, mount, q_arcsec, sr, sac, res_ac):
    d = (u - 0.5) * q_arcsec - nr * sr
    alpha = taylor.true_offset_arcsec(d_arcsec=d) + face + mount + nac * sac
    return -quantise_arcsec(value_arcsec=alpha, resolution_arcsec=res_ac)


def run_trials(*, prepared: Prepared, trials: int, seed: int, first_trial: int = 0) -> dict:
    """Run trials ``first_trial .. first_trial + trials - 1`` (vectorised).

    Returns
    -------
    dict of arrays (one row per trial): raw tables ``y_long``, ``y_long_verify``,
    ``y_short``, ``y_short_verify``; coefficients ``c_long``, ``c_short``, ``c_joint``;
    3 sigma (arcsec) of each published stage; and the truths of each trial's instrument
    (:mod:`budget.inductosyn.truth`): ``instrument_a``, ``true_sigma3_before_arcsec``,
    ``true_coefficients`` (A_L1c .. A_S4s), ``true_mean_arcsec`` (the constant), the 3 sigma
    and max |error - mean| over the turn after each compensation.
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
    # each trial's instrument: its encoder's pitch terms move each face's error by h(face) . a
    trial_ids = range(first_trial, first_trial + k)
    inst, a = instrument_draws(scenario=sc, seed=seed, trials=trial_ids)
    # each pass reads its polygon ``reps`` times (round-major): the same face errors every round;
    # the true offset is minus the error, so the instrument's terms enter with a minus sign
    fl = np.tile(fl * lp.face_error_arcsec - _mul(a, p.face_basis_long), reps)
    fs = np.tile(fs * sp.face_error_arcsec - _mul(a, p.face_basis_short), reps)
    faces = [fl, fl, fs, fs]
    # the world's rig effects add to each face's deviation (None: all off, tables unchanged)
    world = world_alpha_arcsec(scenario=sc, seed=seed, trials=trial_ids, instruments=inst)
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
    # the environment test: the drifted encoder re-measured on the short polygon (one round;
    # its rig as in the short verification's first round), compensated as calibrated
    env = [environment_draws(seed=seed, trial=t, n_short=ns) for t in trial_ids]
    zd = np.array([e[0] for e in env])
    face5 = faces[3][:, :ns] - _mul(zd, p.face_drift_short)
    y5 = _measure_fast(p.taylor_short, np.array([e[1] for e in env]), np.array([e[2] for e in env]),
                       np.array([e[3] for e in env]), face5, sp.mount_offset_arcsec, q, sr, ac.noise_arcsec,
                       ac.resolution_arcsec)
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
    out["y_environment"] = y5
    out["environment_sigma3_arcsec"] = sigma3_arcsec(error_arcsec=y5 - long_at_short - _mul(c_short, p.x_short))
    out["joint_environment_sigma3_arcsec"] = sigma3_arcsec(error_arcsec=y5 - _mul(c_joint, xj_short))
    out["drift_z"] = zd
    out.update(truths(p, a, c_long=c_long, c_short=c_short, c_joint=c_joint, drift_z=zd))
    return out


def truths(p: Prepared, a: np.ndarray, *, c_long, c_short, c_joint, drift_z=None) -> dict:
    """The truths of instruments ``a`` (rows, :func:`instrument_draws`) and of their
    compensations by each variant's coefficients (:mod:`budget.inductosyn.truth`; the fits'
    coefficients are only read, as a lab would apply them)."""
    t = p.truth
    fit_seq = np.concatenate([c_long[:, 1:], c_short, np.zeros((c_long.shape[0], 4))], axis=1)
    fit_joint = c_joint[:, 2:]
    mx, mxj = t.maxabs_after_arcsec(a, fit_seq, fit_joint)
    return {"instrument_a": a, "true_sigma3_before_arcsec": t.sigma3_before_arcsec(a),
            "true_coefficients": t.coefficients(a), "true_mean_arcsec": t.mean(a),
            "dense_sigma3_after_arcsec": t.sigma3_after_arcsec(a, fit_seq),
            "joint_dense_sigma3_after_arcsec": t.sigma3_after_arcsec(a, fit_joint),
            "dense_maxabs_after_arcsec": mx, "joint_dense_maxabs_after_arcsec": mxj,
            **({} if drift_z is None else {
                "true_environment_sigma3_arcsec": t.sigma3_after_arcsec(np.concatenate([a, drift_z], axis=1), fit_seq),
                "true_joint_environment_sigma3_arcsec": t.sigma3_after_arcsec(np.concatenate([a, drift_z], axis=1),
                                                                              fit_joint)})}


def simulate_trial_exact(*, scenario: InductosynScenario, seed: int, trial: int) -> dict:
    """Slow reference of one trial: exact inverse map for every point (simcam.encoder.polygon).

    Returns the four raw tables and the in-sequence and joint fits.
    """
    inst, _ = instrument_draws(scenario=scenario, seed=seed, trials=[trial])
    enc = Inductosyn(params=world_encoder_params(scenario=scenario, instrument=inst[0]))
    cal = scenario.calibration
    nl, ns = cal.long_polygon.faces, cal.short_polygon.faces
    reps = cal.repeats
    u, z = trial_draws(rng=trial_rng(seed=seed, trial=trial), n_long=nl, n_short=ns, repeats=reps)
    fl, fs, passes = split_draws(u=u, z=z, n_long=nl, n_short=ns, repeats=reps)
    fl = np.tile(fl * cal.long_polygon.face_error_arcsec, reps)
    fs = np.tile(fs * cal.short_polygon.face_error_arcsec, reps)
    faces = [fl, fl, fs, fs]
    world = world_alpha_arcsec(scenario=scenario, seed=seed, trials=[trial], instruments=inst)
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
