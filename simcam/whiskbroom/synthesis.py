"""Monte Carlo synthesis of the image-motion residual (seed 002, steps 1-5; eqs 5-8 [R]).

Trial ``k`` draws the 17 variables (6 true-state attitude values and rates, 11
knowledge/control errors) from ``SeedSequence(seed, spawn_key=(k,))``: one vector of 17
uniform numbers, mapped through each variable's inverse CDF (so the same trial keeps the
same draws when a scale changes: common random numbers across the mirror-rate errors of
fig. 6). Its argument of latitude is ``gamma0 + k gamma_step`` (step 4).

The *knowledge* state is what the camera computes with (the drawn operating point and
the nominal orbit, mirror rate and focal length); the *true* state adds the 11 errors.
At every sampled image point of the three butted arrays, ``V_know`` and ``V_true`` are
the image-motion velocities (eq. 5) and

* ``Delta V_P = |V_true| - |V_know|`` (eq. 7), ``Delta beta = beta_true - beta_know`` (eq. 8);
* the smear per TDI stage, in pixels, of an image that moves at ``V_true`` over charge
  clocked at ``|V_know|`` along ``beta_know``: along ``eps = |V_true| cos(Delta beta)/|V_know| - 1``,
  across ``eta = |V_true| sin(Delta beta)/|V_know|``.

A trial reports the sampled point with the largest ``|eps|`` (the worst pixel column).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.special import ndtri

from simcam.units import RAD_PER_DEG
from simcam.whiskbroom import geometry as geo
from simcam.whiskbroom.scenario import ERROR_VARIABLES, VARIABLES, WhiskbroomScenario, check_sizes

__all__ = ["trial_uniforms", "standard_draws", "nominal_params", "trial_params",
           "field_points", "full_field_points", "array_angle", "evaluate", "Residuals",
           "synthesize", "SynthesisResult", "gum_jacobian", "gum_sigma", "sobol_indices",
           "mtf_sinc", "stage_limit", "N_EPS_095"]

#: sin(x)/x = 0.95 at x = 0.5519...: MTF_along >= 0.95 <=> N |eps| <= 2 x / pi
N_EPS_095 = 0.35136


def mtf_sinc(x):
    """``|sin(pi x / 2) / (pi x / 2)|``: MTF at Nyquist of a linear smear of ``x`` pixels
    (Kopeika 1998, eq. 14.3.3; ``np.sinc(y) = sin(pi y)/(pi y)``)."""
    return np.abs(np.sinc(0.5 * np.asarray(x, dtype=float)))


def trial_uniforms(seed: int, trials, *, n: int = len(VARIABLES)) -> np.ndarray:
    """(K, 17) uniform numbers in (0, 1): row ``k`` from ``SeedSequence(seed, spawn_key=(k,))``."""
    rows = []
    for k in np.atleast_1d(trials):
        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(int(k),)))
        rows.append(rng.random(n))
    u = np.array(rows)
    return np.clip(u, 1e-300, None)          # ndtri(0) = -inf; random() can return 0


def standard_draws(sc: WhiskbroomScenario, u: np.ndarray) -> dict[str, np.ndarray]:
    """Map uniforms to each variable's distribution (inverse CDF), in the variable's unit."""
    out = {}
    for j, name in enumerate(VARIABLES):
        d = getattr(sc.errors, name)
        z = 2.0 * u[:, j] - 1.0 if d.dist == "uniform" else ndtri(u[:, j])
        out[name] = d.from_standard(z)
    return out


def nominal_params(sc: WhiskbroomScenario, gamma_rad, n: int | None = None) -> np.ndarray:
    """Parameter rows of the nominal state (zero attitude) at arguments of latitude."""
    g = np.atleast_1d(np.asarray(gamma_rad, dtype=float))
    n = g.size if n is None else n
    o = sc.orbit
    return geo.make_params(
        n, altitude_km=o.altitude_km, speed_km_s=sc.orbit_speed_km_s,
        inclination_rad=sc.inclination_rad, gamma_rad=g,
        mirror_rate_rad_s=math.radians(sc.mirror.rate_deg_s),
        mirror_rest_rad=math.radians(sc.mirror.rest_angle_deg),
        focal_length_mm=sc.camera.focal_length_mm, earth_rate_rad_s=o.earth_rate_rad_s,
        earth_radius_km=o.earth_radius_km)


def trial_params(sc: WhiskbroomScenario, draws: dict[str, np.ndarray], trials) -> tuple[np.ndarray, np.ndarray]:
    """(knowledge, true) parameter rows of the trials (paper's steps 2-3).

    knowledge: attitude and rates = the drawn operating values, nominal orbit, mirror rate,
    focal length; true = knowledge + the 11 errors (attitude and rate knowledge errors,
    mirror-rate control error, orbit speed, altitude, along-orbit position from the
    sub-satellite latitude error, relative focal-length error).
    """
    k = np.atleast_1d(np.asarray(trials, dtype=float))
    gamma = np.radians(sc.orbit.gamma0_deg + k * sc.orbit.gamma_step_deg)
    know = nominal_params(sc, gamma)
    P = geo.P
    rad = np.radians
    know[:, P["roll_rad"]] = rad(draws["roll_deg"])
    know[:, P["pitch_rad"]] = rad(draws["pitch_deg"])
    know[:, P["yaw_rad"]] = rad(draws["yaw_deg"])
    know[:, P["roll_rate_rad_s"]] = rad(draws["roll_rate_deg_s"])
    know[:, P["pitch_rate_rad_s"]] = rad(draws["pitch_rate_deg_s"])
    know[:, P["yaw_rate_rad_s"]] = rad(draws["yaw_rate_deg_s"])
    true = know.copy()
    true[:, P["roll_rad"]] += rad(draws["roll_knowledge_deg"])
    true[:, P["pitch_rad"]] += rad(draws["pitch_knowledge_deg"])
    true[:, P["yaw_rad"]] += rad(draws["yaw_knowledge_deg"])
    true[:, P["roll_rate_rad_s"]] += rad(draws["roll_rate_knowledge_deg_s"])
    true[:, P["pitch_rate_rad_s"]] += rad(draws["pitch_rate_knowledge_deg_s"])
    true[:, P["yaw_rate_rad_s"]] += rad(draws["yaw_rate_knowledge_deg_s"])
    true[:, P["mirror_rate_rad_s"]] += rad(draws["mirror_rate_deg_s"])
    true[:, P["speed_km_s"]] += draws["orbit_speed_km_s"]
    true[:, P["altitude_km"]] += draws["altitude_km"]
    true[:, P["gamma_rad"]] += rad(draws["latitude_deg"])
    true[:, P["focal_length_mm"]] *= 1.0 + draws["focal_length_rel"]
    return know, true


def array_angle(sc: WhiskbroomScenario) -> float:
    """Angle (rad) by which the arrays' TDI axis is turned: the nominal centre drift angle
    at ``gamma0`` (what the drift-angle mechanism is set to)."""
    v = geo.image_motion(nominal_params(sc, math.radians(sc.orbit.gamma0_deg)), [0.0], [0.0])
    return float(geo.drift_angle(v)[0, 0])


def _layout(sc: WhiskbroomScenario, rows, cols, beta):
    """Image coordinates (mm) of (row, column-in-line) positions of the turned arrays.

    TDI axis along the image motion ``-(cos beta, sin beta)``, line axis perpendicular;
    the chips are butted along the line (column ``j`` of chip ``c`` at line position
    ``(c - (n-1)/2)(cols + gap) + j - (cols-1)/2`` pixels).
    """
    cam = sc.camera
    p = cam.pixel_pitch_um * 1e-3
    tau = -np.array([math.cos(beta), math.sin(beta)])
    lam = np.array([-math.sin(beta), math.cos(beta)])
    r = (np.asarray(rows, dtype=float) - 0.5 * (cam.tdi_stages - 1)) * p
    q = np.asarray(cols, dtype=float) * p
    x = r[:, None, None] * tau + q[None, :, None] * lam
    return x[..., 0].ravel(), x[..., 1].ravel()


class SynthesisError(ValueError):
    """The synthesis of a scenario gave no meaningful number (one ``error:`` line)."""


def check_finite_residuals(sc: WhiskbroomScenario, r, level: float, source: str = "scenario") -> None:
    """Refuse a synthesis whose residuals are NaN or infinite (was: an all-NaN table and
    "N pub 100000" at exit status 0): the scenario's values leave the model's domain
    (the line of sight misses the Earth, a rate or an error overflows)."""
    bad = ~(np.isfinite(r.dv_mm_s) & np.isfinite(r.eps) & np.isfinite(r.eta))
    if bad.any():
        trials_bad = int(np.any(bad.reshape(bad.shape[0], -1), axis=1).sum())
        raise SynthesisError(
            f"{source}: the image motion is not finite in {trials_bad} of {bad.shape[0]} "
            f"trials (mirror-rate error {level:g} deg/s): the line of sight misses the Earth or a value "
            "overflows; check orbit, mirror.rest_angle_deg and the errors' half_width/sigma")


def _line_positions(sc, cols_per_chip):
    cam = sc.camera
    j = np.linspace(0.0, cam.chip_cols - 1.0, cols_per_chip) if cols_per_chip > 1 else np.array([0.5 * (cam.chip_cols - 1)])
    chips = np.arange(cam.n_chips) - 0.5 * (cam.n_chips - 1)
    return (chips[:, None] * (cam.chip_cols + cam.chip_gap_px) + j[None, :] - 0.5 * (cam.chip_cols - 1)).ravel()


def field_points(sc: WhiskbroomScenario, beta: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The sampled field: ``field_cols_per_chip`` columns of each chip (ends included) x
    ``field_rows`` TDI rows (first and last stage when 2). Returns x1, x3 in mm."""
    beta = array_angle(sc) if beta is None else beta
    s = sc.synthesis
    rows = np.linspace(0, sc.camera.tdi_stages - 1, s.field_rows) if s.field_rows > 1 else np.array([0.5 * (sc.camera.tdi_stages - 1)])
    return _layout(sc, rows, _line_positions(sc, s.field_cols_per_chip), beta)


def full_field_points(sc: WhiskbroomScenario, beta: float | None = None, *, col_step: int = 1,
                      row_step: int = 1):
    """Every pixel centre of the three arrays (optionally every ``col_step``-th column)."""
    beta = array_angle(sc) if beta is None else beta
    cam = sc.camera
    rows = np.arange(0, cam.tdi_stages, row_step)
    j = np.arange(0, cam.chip_cols, col_step, dtype=float)
    chips = np.arange(cam.n_chips) - 0.5 * (cam.n_chips - 1)
    cols = (chips[:, None] * (cam.chip_cols + cam.chip_gap_px) + j[None, :] - 0.5 * (cam.chip_cols - 1)).ravel()
    return _layout(sc, rows, cols, beta)


def _motion(params, x1, x3, backend):
    if backend == "numpy":
        return geo.image_motion(params, x1, x3)
    from simcam.whiskbroom.kernels import image_motion_kernel

    h = geo.COMPLEX_STEP_S
    A, rs, E = geo.chain_matrices(params.astype(complex), 1j * h)
    out = np.empty((params.shape[0], np.size(x1), 2))
    image_motion_kernel(np.ascontiguousarray(A), np.ascontiguousarray(rs), np.ascontiguousarray(E),
                        np.ascontiguousarray(params[:, geo.P["focal_length_mm"]]),
                        np.ascontiguousarray(params[:, geo.P["earth_radius_km"]]),
                        np.ascontiguousarray(x1, dtype=float), np.ascontiguousarray(x3, dtype=float), h, out)
    return out


@dataclass
class Residuals:
    """Per trial (worst sampled point) and per point quantities of one synthesis."""

    v_know: np.ndarray          # (K, N, 2) mm/s
    v_true: np.ndarray          # (K, N, 2) mm/s
    worst: np.ndarray           # (K,) index of the worst point
    speed_mm_s: np.ndarray      # (K,) |V_know| at the worst point
    beta_deg: np.ndarray        # (K,) knowledge drift angle at the worst point
    dv_mm_s: np.ndarray         # (K,) Delta V_P (eq. 7)
    dbeta_deg: np.ndarray       # (K,) Delta beta (eq. 8)
    eps: np.ndarray             # (K,) along-track smear per stage, px
    eta: np.ndarray             # (K,) cross-track smear per stage, px


def _wrap(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def evaluate(know, true, x1, x3, *, backend: str = "numba") -> Residuals:
    """Image motion of the knowledge and true states at the points; residuals (eqs 5-8)."""
    vk = _motion(know, x1, x3, backend)
    vt = _motion(true, x1, x3, backend)
    sk = np.hypot(vk[..., 0], vk[..., 1])
    st = np.hypot(vt[..., 0], vt[..., 1])
    bk = geo.drift_angle(vk)
    db = _wrap(geo.drift_angle(vt) - bk)
    eps = st * np.cos(db) / sk - 1.0
    eta = st * np.sin(db) / sk
    w = np.argmax(np.abs(eps), axis=1)
    i = np.arange(vk.shape[0])
    return Residuals(vk, vt, w, sk[i, w], np.degrees(bk[i, w]), (st - sk)[i, w],
                     np.degrees(db[i, w]), eps[i, w], eta[i, w])


def gum_jacobian(sc: WhiskbroomScenario, gamma_rad: float, x1=(0.0,), x3=(0.0,), h: float = 1e-30):
    """Sensitivities of ``Delta V_P`` (mm/s) and ``Delta beta`` (rad) to the 11 errors at the
    nominal state, by a complex step in each error through the kinematic closed form
    (an analytic function of the parameters; the complex step is exact to rounding).

    Returns ``(J_dv, J_db)``, each (11, N), per unit of each variable's scenario unit.
    ``Delta beta`` is differentiated as ``atan(V3/V1)`` (analytic; equal to the atan2
    difference away from ``V1 = 0``).
    """
    jdv, jdb = [], []
    for name in ERROR_VARIABLES:
        draws = {n: np.zeros(1, dtype=complex) for n in VARIABLES}
        draws[name] = np.array([1j * h])
        know, true = _complex_trial(sc, draws, gamma_rad)
        vk = geo.image_motion_kinematic(know, x1, x3)
        vt = geo.image_motion_kinematic(true, x1, x3)
        sk = np.sqrt(vk[..., 0] ** 2 + vk[..., 1] ** 2)
        st = np.sqrt(vt[..., 0] ** 2 + vt[..., 1] ** 2)
        bt = np.arctan(vt[..., 1] / vt[..., 0])
        bk = np.arctan(vk[..., 1] / vk[..., 0])
        jdv.append(((st - sk).imag / h)[0])
        jdb.append(((bt - bk).imag / h)[0])
    return np.array(jdv), np.array(jdb)


def _complex_trial(sc, draws, gamma_rad):
    know = nominal_params(sc, gamma_rad).astype(complex)
    true = know.copy()
    P = geo.P
    rad = RAD_PER_DEG
    true[:, P["roll_rad"]] += rad * draws["roll_knowledge_deg"]
    true[:, P["pitch_rad"]] += rad * draws["pitch_knowledge_deg"]
    true[:, P["yaw_rad"]] += rad * draws["yaw_knowledge_deg"]
    true[:, P["roll_rate_rad_s"]] += rad * draws["roll_rate_knowledge_deg_s"]
    true[:, P["pitch_rate_rad_s"]] += rad * draws["pitch_rate_knowledge_deg_s"]
    true[:, P["yaw_rate_rad_s"]] += rad * draws["yaw_rate_knowledge_deg_s"]
    true[:, P["mirror_rate_rad_s"]] += rad * draws["mirror_rate_deg_s"]
    true[:, P["speed_km_s"]] += draws["orbit_speed_km_s"]
    true[:, P["altitude_km"]] += draws["altitude_km"]
    true[:, P["gamma_rad"]] += rad * draws["latitude_deg"]
    true[:, P["focal_length_mm"]] *= 1.0 + draws["focal_length_rel"]
    return know, true


def gum_sigma(sc: WhiskbroomScenario, gamma_rad: float, x1=(0.0,), x3=(0.0,)):
    """First-order (GUM, JCGM 100 eq. 10) standard uncertainties of Delta V_P (mm/s) and
    Delta beta (deg): ``u^2 = sum_j J_j^2 u_j^2`` (the 11 errors are independent), with
    ``u_j`` = sigma or half_width/sqrt(3). Returns (u_dv, u_db_deg, J_dv, J_db)."""
    jdv, jdb = gum_jacobian(sc, gamma_rad, x1, x3)
    u = np.array([getattr(sc.errors, n).std for n in ERROR_VARIABLES])[:, None]
    return (np.sqrt(np.sum((jdv * u) ** 2, 0)), np.degrees(np.sqrt(np.sum((jdb * u) ** 2, 0))), jdv, jdb)


def sobol_indices(sc: WhiskbroomScenario, seed: int = 0, base_samples: int | None = None):
    """Sobol first-order and total indices (SALib, Saltelli/Jansen estimators) of
    ``Delta V_P`` at the array centre over the 17 variables, at ``gamma0``.

    Returns a dict ``{"names", "S1", "ST", "S1_conf", "ST_conf"}``.
    """
    from SALib.analyze import sobol as sobol_analyze
    from SALib.sample import sobol as sobol_sample

    names = list(VARIABLES)
    dists, bounds = [], []
    for n in names:
        d = getattr(sc.errors, n)
        if d.dist == "uniform":
            dists.append("unif")
            bounds.append([-d.scale, d.scale] if d.scale > 0 else [-1e-300, 1e-300])
        else:
            dists.append("norm")
            bounds.append([0.0, d.scale if d.scale > 0 else 1e-300])
    problem = {"num_vars": len(names), "names": names, "bounds": bounds, "dists": dists}
    n = base_samples or sc.synthesis.sobol_base_samples
    x = sobol_sample.sample(problem, n, calc_second_order=False, seed=seed)
    draws = {name: x[:, j] for j, name in enumerate(names)}
    know, true = trial_params(sc, draws, np.zeros(x.shape[0]))
    r = evaluate(know, true, np.array([0.0]), np.array([0.0]))
    res = sobol_analyze.analyze(problem, r.dv_mm_s, calc_second_order=False, seed=seed)
    return {"names": names, "S1": np.asarray(res["S1"]), "ST": np.asarray(res["ST"]),
            "S1_conf": np.asarray(res["S1_conf"]), "ST_conf": np.asarray(res["ST_conf"])}


def stage_limit(x_per_stage_q: float, *, n_phase: int | None = None, cross_q: float = 0.0,
                threshold: float = 0.95, n_max: int = 100000) -> int:
    """Largest stage count N with predicted MTF >= threshold.

    Published: ``sinc(pi N eps/2) >= threshold``; with ``n_phase`` the charge-clocking
    factor ``sinc(pi/(2 n_phase))`` and the cross-track term ``sinc(pi N eta/2)`` multiply.
    """
    n = np.arange(1, n_max + 1)
    m = mtf_sinc(n * x_per_stage_q)
    if n_phase is not None:
        m = m * mtf_sinc(1.0 / n_phase) * mtf_sinc(n * cross_q)
    ok = np.nonzero(m < threshold)[0]
    return int(n_max if ok.size == 0 else ok[0])


@dataclass
class SynthesisResult:
    """Outputs of :func:`synthesize` (all arrays per trial)."""

    seed: int
    trials: np.ndarray
    gamma_deg: np.ndarray
    array_angle_deg: float
    nominal_speed_mm_s: float
    residuals: dict = field(default_factory=dict)        # mirror sigma -> Residuals
    quantile: float = 0.997
    table: list = field(default_factory=list)             # per mirror error: dict
    gum: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        out = {"seed": self.seed, "trials": int(self.trials.size), "array_angle_deg": self.array_angle_deg,
               "nominal_speed_mm_s": self.nominal_speed_mm_s, "quantile": self.quantile,
               "per_mirror_rate_error": self.table, "gum": self.gum}
        return out


def synthesize(sc: WhiskbroomScenario, seed: int = 0, *, trials: int | None = None,
               backend: str = "numba", mirror_rate_errors=None, points=None,
               source: str = "scenario") -> SynthesisResult:
    """The Monte Carlo synthesis of steps 1-5 for each mirror-rate error of the scenario.

    For each mirror-rate error (the scale of ``errors.mirror_rate_deg_s`` replaced, same
    draws), the residuals of every trial at the sampled field points, the quantile of
    ``|eps|`` and ``|eta|`` and the stage limits (published sinc; improved with the
    clocking factor and cross-track term), beside the first-order (GUM) spread of
    ``Delta V_P`` at the array centre.
    """
    K = sc.synthesis.trials if trials is None else int(trials)
    if trials is not None:
        check_sizes(sc, source="whiskbroom synthesize", trials=K, trials_what=f"--trials {K}")
    ks = np.arange(K)
    u = trial_uniforms(seed, ks)
    beta0 = array_angle(sc)
    x1, x3 = field_points(sc, beta0) if points is None else points
    x1 = np.concatenate([[0.0], x1])                  # point 0: the array centre
    x3 = np.concatenate([[0.0], x3])
    levels = sc.synthesis.mirror_rate_errors_deg_s if mirror_rate_errors is None else mirror_rate_errors
    v0 = geo.image_motion(nominal_params(sc, math.radians(sc.orbit.gamma0_deg)), [0.0], [0.0])[0, 0]
    res = SynthesisResult(seed=seed, trials=ks, gamma_deg=sc.orbit.gamma0_deg + ks * sc.orbit.gamma_step_deg,
                          array_angle_deg=math.degrees(beta0), nominal_speed_mm_s=float(np.hypot(*v0)),
                          quantile=sc.synthesis.quantile)
    q = sc.synthesis.quantile
    for level in levels:
        scl = sc.model_copy(update={"errors": sc.errors.model_copy(
            update={"mirror_rate_deg_s": sc.errors.mirror_rate_deg_s.with_scale(level)})})
        draws = standard_draws(scl, u)
        know, true = trial_params(scl, draws, ks)
        r = evaluate(know, true, x1, x3, backend=backend)
        check_finite_residuals(sc, r, level, source)
        res.residuals[level] = r
        eq = float(np.quantile(np.abs(r.eps), q))
        hq = float(np.quantile(np.abs(r.eta), q))
        u_dv, u_db, _, _ = gum_sigma(scl, math.radians(sc.orbit.gamma0_deg))
        dv_c = r.v_true[:, 0, :]
        dv_centre = np.hypot(dv_c[:, 0], dv_c[:, 1]) - np.hypot(r.v_know[:, 0, 0], r.v_know[:, 0, 1])
        res.table.append({
            "mirror_rate_error_deg_s": level,
            "dv_max_abs_mm_s": float(np.max(np.abs(r.dv_mm_s))),
            "dv_std_mm_s": float(np.std(r.dv_mm_s, ddof=1)),
            "dv_centre_std_mm_s": float(np.std(dv_centre, ddof=1)),
            "dv_centre_gum_mm_s": float(u_dv[0]),
            "dbeta_std_deg": float(np.std(r.dbeta_deg, ddof=1)),
            "dbeta_gum_deg": float(u_db[0]),
            "beta_mean_deg": float(np.mean(r.beta_deg)),
            "eps_quantile": eq, "eta_quantile": hq,
            "n_max_published": stage_limit(eq, threshold=sc.synthesis.mtf_threshold),
            "eps_max": float(np.max(np.abs(r.eps))),
            "n_max_published_at_max": stage_limit(float(np.max(np.abs(r.eps))), threshold=sc.synthesis.mtf_threshold),
            "n_max_improved": stage_limit(eq, n_phase=sc.camera.n_phase, cross_q=hq,
                                          threshold=sc.synthesis.mtf_threshold),
        })
    return res
