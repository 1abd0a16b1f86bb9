"""Estimators of the star-observation calibration of a line camera (seed 004, steps 5-7).

* :func:`calibrate_published` -- the patent's steps as written (reconstructed): the
  exterior compensation ``R_u`` first with the interior at its current value (closed-form
  Wahba solution, :meth:`scipy.spatial.transform.Rotation.align_vectors`), then the seven
  interior parameters by the linear least squares of step 6 with ``R_u`` fixed, repeated
  until nothing changes; observations weighted for coverage of the line (step 7:
  ``w_i = 1 / n(bin(s_i))``). The covariance it states is that of each step
  (block-diagonal: exterior | interior), each step's sandwich covariance with the
  residual variance, as a lab following the steps would state it.
* :func:`calibrate_joint` -- improved: one Gauss-Newton fit of all ten parameters with
  equal weights, solved through the SVD of the column-scaled Jacobian: singular values
  below ``rcond`` times the largest are gauge freedoms (combinations the observations
  cannot see) and get no step (minimum-norm solution); the covariance is the
  pseudo-inverse one. Its calibrated quantity is the look-angle field, which the gauge
  freedoms leave unchanged; parameters are reported with :func:`separability`.
* :func:`calibrate_lookangle` -- the Wuhan group's look-angle polynomials of the line
  (``tan psi(s)`` per axis, gauge-free, linear): the field without any camera parameters.
* :func:`separability` -- condition number, singular values and the null space of a
  plan: which parameters a plan cannot separate.
* :func:`calibrate_file` -- what ``budget linecam calibrate`` computes: an observation
  table (:mod:`budget.linecam.table`) read and calibrated by the methods asked
  (:func:`calibrate_table`), a :class:`TableCalibration` whose JSON
  (:func:`calibration_payload`) and printed lines (:func:`calibration_lines`) the command
  writes.

All covariances are scaled by the a-posteriori residual variance ``s0^2 = r^T W r / (m - rank)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from budget.runner.numbers import fmt
from simcam.infra.errors import UserInputError
from simcam.linecam.scenario import LineCamScenario
from simcam.linecam.scenario import load as load_scenario
from simcam.units import ARCSEC_PER_RAD

from .model import (PARAMETERS, NominalCamera, Observations, interior_design, jacobian, los_angles, los_grid,
                    los_jacobian, parameter_scale, residuals)
from .parameters import PARAM_UNITS, determined_combinations, gauge_combination_vector, to_report_units
from .table import ObservationTable, read_observations

__all__ = ["Calibration", "Separability", "calibrate_published", "calibrate_joint", "separability",
           "coverage_weights", "los_field", "LosField", "CalibrationError", "LookAngleCalibration",
           "calibrate_lookangle", "TableCalibration", "calibrate_table", "calibrate_file", "calibration_payload",
           "calibration_lines", "check_determined", "parse_solve", "METHODS", "MAX_CONDITION"]


class CalibrationError(ValueError):
    """Too few stars or a plan that cannot separate what was asked for."""


@dataclass
class Calibration:
    """Result of one calibration.

    Attributes
    ----------
    theta : numpy.ndarray (10,)
        Parameters (order of :data:`PARAMETERS`, units of :mod:`budget.linecam.model`).
    cov : numpy.ndarray (10, 10)
        Stated covariance of ``theta``.
    sigma0_px : float
        A-posteriori rms residual (px).
    rms_px : float
        Rms of the final residuals (px).
    iterations : int
    condition : float
        Condition number of the (column-scaled) normal matrix of the fit.
    residuals_px : numpy.ndarray (2n,)
    solved : tuple of str
        Parameters estimated (the others held at 0).
    null_space : numpy.ndarray (10, k)
        Gauge directions of the joint fit (columns, in unscaled parameter units); empty
        for the published steps.
    """

    theta: np.ndarray
    cov: np.ndarray
    sigma0_px: float
    rms_px: float
    iterations: int
    condition: float
    residuals_px: np.ndarray
    solved: tuple[str, ...]
    null_space: np.ndarray = field(default_factory=lambda: np.zeros((len(PARAMETERS), 0)))
    method: str = ""


def coverage_weights(sample, *, n_pixels: int, bins: int) -> np.ndarray:
    """Step 7's weights ``w_i = 1 / n(bin(s_i))``, normalised to mean 1 (equal total weight
    per occupied bin of the line)."""
    b = np.clip((np.asarray(sample) / n_pixels * bins).astype(int), 0, bins - 1)
    counts = np.bincount(b, minlength=bins)
    w = 1.0 / counts[b]
    return w * (w.size / w.sum())


def _check_count(obs: Observations, n_params: int) -> None:
    if 2 * len(obs) <= n_params:
        raise CalibrationError(f"{len(obs)} identified stars give {2 * len(obs)} equations for "
                               f"{n_params} parameters: too few stars to solve")


def _sandwich(J: np.ndarray, w: np.ndarray, r: np.ndarray, dof: int) -> tuple[np.ndarray, float]:
    """Covariance of a weighted least-squares estimate with residual variance from the
    unweighted residuals: ``s^2 (J'WJ)^-1 J'W^2J (J'WJ)^-1`` (equal to ``s^2 (J'J)^-1``
    for equal weights)."""
    JW = J * w[:, None]
    N = J.T @ JW
    Ni = np.linalg.pinv(N)
    s2 = float(r @ r) / max(dof, 1)
    return s2 * Ni @ (JW.T @ JW) @ Ni, s2


def calibrate_published(cam: NominalCamera, obs: Observations, *, coverage_bins: int = 24,
                        max_iter: int = 30, tol_px: float = 1e-7) -> Calibration:
    """The patent's steps 5-7: exterior first (Wahba), then interior (linear least squares),
    alternated until the parameters change by less than ``tol_px`` at the line's end."""
    n = len(obs)
    _check_count(obs, len(PARAMETERS))
    w = coverage_weights(obs.sample, n_pixels=cam.n_pixels, bins=coverage_bins)
    ww = np.concatenate([w, w])
    ax, ay = interior_design(cam, obs.sample)
    A = np.vstack([ax, ay])
    scale = parameter_scale(cam)
    theta = np.zeros(len(PARAMETERS))
    it = 0
    for it in range(1, max_iter + 1):
        old = theta.copy()
        # exterior: R_u c_i ~ b_i with the interior at its current value (Wahba)
        c = np.column_stack([cam.x_line_px - ax @ theta[3:], cam.y_px(obs.sample) - ay @ theta[3:],
                             np.full(n, -cam.f_px)])
        c /= np.linalg.norm(c, axis=1, keepdims=True)
        rot, _ = Rotation.align_vectors(obs.b, c, weights=w)
        theta[:3] = rot.as_rotvec()
        # interior: residuals with zero interior are exactly A theta_int (step 6)
        r0 = residuals(cam, np.concatenate([theta[:3], np.zeros(7)]), obs)
        AW = A * ww[:, None]
        theta[3:] = np.linalg.solve(A.T @ AW, AW.T @ r0)
        if np.max(np.abs(theta - old) * scale) < tol_px:
            break
    r = residuals(cam, theta, obs)
    J = jacobian(cam, theta, obs)
    dof = 2 * n - len(PARAMETERS)
    cov_e, s2 = _sandwich(J[:, :3], ww, r, dof)
    cov_i, _ = _sandwich(J[:, 3:], ww, r, dof)
    cov = np.zeros((10, 10))
    cov[:3, :3], cov[3:, 3:] = cov_e, cov_i
    Js = J * scale
    return Calibration(theta=theta, cov=cov, sigma0_px=float(np.sqrt(s2)), rms_px=float(np.sqrt(np.mean(r * r))),
                       iterations=it, condition=_cond(Js[:, 3:]) if n else np.inf, residuals_px=r,
                       solved=PARAMETERS, method="published")


def _cond(Js: np.ndarray) -> float:
    """Condition number of the normal matrix of column-normalised ``Js``."""
    lam = np.linalg.eigvalsh((Js.T @ Js) / np.outer(*(2 * [np.linalg.norm(Js, axis=0)])))
    return float(lam[-1] / lam[0]) if lam[0] > 0 else np.inf


def calibrate_joint(cam: NominalCamera, obs: Observations, *, solve=PARAMETERS, rcond: float = 1e-6,
                    gauge_sigma_px: float = 10.0, max_iter: int = 30, tol_px: float = 1e-9,
                    strict: bool = False) -> Calibration:
    """Joint Gauss-Newton fit of the parameters ``solve`` (the others held at 0).

    Each step solves the column-scaled linearised problem (columns in px at the line's end
    per unit) through the eigen-decomposition of its normal matrix. A direction is a gauge
    freedom and gets no step when its singular value is below ``rcond * s_max`` or when the
    data would determine it worse than ``gauge_sigma_px`` (``s0 / s > gauge_sigma_px``,
    ``s0`` the rms residual of the current step): an exactly degenerate direction, and a
    nearly degenerate one that only model errors or noise would pull along (a half-exposure
    time-tag error, for instance, has a large component along pitch/dx0 and would otherwise
    be "separated" through terms of order 1e-4). ``strict``: any such direction at the
    solution is an error naming the parameters involved (the user asked for parameters the
    plan cannot separate).
    """
    idx = np.array([PARAMETERS.index(p) for p in solve])
    _check_count(obs, idx.size)
    scale = parameter_scale(cam)[idx]
    theta = np.zeros(len(PARAMETERS))
    dof = max(2 * len(obs) - idx.size, 1)
    it = 0
    for it in range(1, max_iter + 1):
        r = residuals(cam, theta, obs)
        J = jacobian(cam, theta, obs)[:, idx] / scale
        s, Vt, keep = _spectrum(J, rcond)
        keep &= np.sqrt(float(r @ r) / dof) < gauge_sigma_px * s
        step = -(Vt[keep].T @ ((Vt[keep] @ (J.T @ r)) / s[keep] ** 2)) / scale
        _apply(theta, idx, step)
        if np.max(np.abs(step) * scale) < tol_px:
            break
    r = residuals(cam, theta, obs)
    J = jacobian(cam, theta, obs)[:, idx] / scale
    s, Vt, keep = _spectrum(J, rcond)
    keep &= np.sqrt(float(r @ r) / dof) < gauge_sigma_px * s
    if strict and not keep.all():
        raise CalibrationError(_null_message(Vt[~keep], [PARAMETERS[i] for i in idx], s))
    rank = int(keep.sum())
    s2 = float(r @ r) / max(2 * len(obs) - rank, 1)
    cov_s = (Vt[keep].T / s[keep] ** 2) @ Vt[keep] * s2
    cov = np.zeros((10, 10))
    cov[np.ix_(idx, idx)] = cov_s / np.outer(scale, scale)
    null = np.zeros((10, int((~keep).sum())))
    null[idx] = (Vt[~keep] / scale).T
    return Calibration(theta=theta, cov=cov, sigma0_px=float(np.sqrt(s2)), rms_px=float(np.sqrt(np.mean(r * r))),
                       iterations=it, condition=float(s[0] / s[-1]) ** 2 if s[-1] > 0 else np.inf,
                       residuals_px=r, solved=tuple(PARAMETERS[i] for i in idx), null_space=null,
                       method="joint")


def _spectrum(J: np.ndarray, rcond: float):
    """Singular values (descending) and right singular vectors (rows) of ``J`` from the
    eigen-decomposition of ``J^T J`` (10 x 10; LAPACK's SVD of the tall matrix costs 100
    times more here), and which are kept: ``s > rcond * s_max``. ``rcond`` >= 1e-7 keeps
    the squared spectrum far above rounding (1e-16 relative)."""
    lam, V = np.linalg.eigh(J.T @ J)
    lam, V = lam[::-1], V[:, ::-1]
    s = np.sqrt(np.maximum(lam, 0.0))
    return s, V.T, s > rcond * s[0]


def _apply(theta: np.ndarray, idx: np.ndarray, step: np.ndarray) -> None:
    """Add a step; rotation components compose on the right (``R_u exp([d]x)``)."""
    full = np.zeros(len(PARAMETERS))
    full[idx] = step
    if np.any(full[:3]):
        theta[:3] = (Rotation.from_rotvec(theta[:3]) * Rotation.from_rotvec(full[:3])).as_rotvec()
    theta[3:] += full[3:]


def _pivot_basis(rows: np.ndarray) -> np.ndarray:
    """A readable basis of the span of ``rows`` (k, p): column-pivoted QR picks k pivot
    parameters, and the basis is ``inv(rows[:, piv]) @ rows`` (identity on the pivots), so
    each combination names one pivot and what it trades with."""
    if rows.shape[0] == 0:
        return rows
    from scipy.linalg import qr

    _, _, piv = qr(rows, pivoting=True, mode="economic")
    k = rows.shape[0]
    return np.linalg.solve(rows[:, piv[:k]], rows)


def _null_message(null_rows: np.ndarray, names: list[str], s: np.ndarray) -> str:
    groups = []
    for v in _pivot_basis(null_rows):
        v = v / np.max(np.abs(v))
        groups.append(" ".join(f"{c:+.2f} {n}" for c, n in zip(v, names) if abs(c) > 0.05))
    cond = s[0] / s[-1] if s[-1] > 0 else np.inf
    return ("the observation plan cannot separate these parameters (condition number "
            f"{cond:.3g}): combinations {'; '.join(groups)} are unobservable; drop one parameter "
            "of each or add passes that break the degeneracy")


@dataclass
class Separability:
    """What an observation plan can separate.

    Attributes
    ----------
    singular_values : numpy.ndarray
        Of the column-scaled (unit-norm columns) Jacobian of all ten parameters.
    condition : float
        ``s_max / s_min`` of that Jacobian (the normal matrix's is its square).
    null_space : list of dict
        Each unobservable combination ``{parameter: coefficient}`` (normalised to max 1).
    inseparable : tuple of str
        Parameters taking part in a null direction.
    """

    singular_values: np.ndarray
    condition: float
    null_space: list
    inseparable: tuple[str, ...]


def separability(cam: NominalCamera, obs: Observations, *, rcond: float = 1e-6, theta=None) -> Separability:
    """Condition number and null space of the ten-parameter problem for these observations."""
    th = np.zeros(len(PARAMETERS)) if theta is None else np.asarray(theta, float)
    J = jacobian(cam, th, obs) / parameter_scale(cam)
    norms = np.linalg.norm(J, axis=0)
    Jn = J / np.where(norms > 0, norms, 1.0)
    s, Vt, keep = _spectrum(Jn, rcond)
    null, names = [], set()
    for v in _pivot_basis(Vt[~keep] / norms):  # px-at-line-end units of each parameter
        v = v / np.max(np.abs(v))
        comb = {p: float(c) for p, c in zip(PARAMETERS, v) if abs(c) > 0.05}
        null.append(comb)
        names.update(comb)
    return Separability(singular_values=s, condition=float(s[0] / s[-1]) if s[-1] > 0 else np.inf,
                        null_space=null, inseparable=tuple(p for p in PARAMETERS if p in names))


@dataclass(frozen=True)
class LosField:
    """A calibrated look-angle field at detectors along the line: the angles along and
    across track (rad) and their stated 1-sigma (rad)."""

    along_rad: np.ndarray
    across_rad: np.ndarray
    sigma_along_rad: np.ndarray
    sigma_across_rad: np.ndarray


def los_field(cam: NominalCamera, cal: Calibration, sample) -> LosField:
    """The calibrated look-angle field at detectors ``sample``: angles (rad) and their stated
    1-sigma (rad) from the covariance, ``sigma^2 = diag(G C G^T)``."""
    along, across = los_angles(cam, cal.theta, sample)
    G = los_jacobian(cam, cal.theta, sample)
    var = np.einsum("ij,jk,ik->i", G, cal.cov, G)
    sd = np.sqrt(np.maximum(var, 0.0))
    m = np.size(sample)
    return LosField(along_rad=along, across_rad=across, sigma_along_rad=sd[:m], sigma_across_rad=sd[m:])


@dataclass
class LookAngleCalibration:
    """The Wuhan group's look-angle model of a line (ZY-3 / Yaogan calibrations):
    ``tan(along(s)) = sum_k a_k u^k``, ``tan(across(s)) = sum_k b_k u^k``,
    ``u = (s - (n-1)/2) / r_n`` in [-1, 1], body frame; gauge-free and linear.

    Attributes
    ----------
    a, b : numpy.ndarray
        Coefficients (along, across), lowest power first.
    cov_a, cov_b : numpy.ndarray
        Their covariances (residual variance of each component times ``(A^T A)^-1``).
    sigma0_px : float
        Rms residual (px at the focal plane, both components).
    condition : float
        Condition number of the across-track normal matrix (the larger system).
    """

    a: np.ndarray
    b: np.ndarray
    cov_a: np.ndarray
    cov_b: np.ndarray
    sigma0_px: float
    condition: float
    r_norm_px: float
    centre_px: float
    method: str = "lookangle"

    def field(self, sample) -> LosField:
        """Look angles (rad) and stated 1-sigma (rad) at detectors ``sample``."""
        u = (np.asarray(sample, float) - self.centre_px) / self.r_norm_px
        Va = np.vander(u, self.a.size, increasing=True)
        Vb = np.vander(u, self.b.size, increasing=True)
        ta, tb = Va @ self.a, Vb @ self.b
        sa = np.sqrt(np.einsum("ij,jk,ik->i", Va, self.cov_a, Va)) / (1 + ta * ta)
        sb = np.sqrt(np.einsum("ij,jk,ik->i", Vb, self.cov_b, Vb)) / (1 + tb * tb)
        return LosField(along_rad=np.arctan(ta), across_rad=np.arctan(tb), sigma_along_rad=sa, sigma_across_rad=sb)


def calibrate_lookangle(cam: NominalCamera, obs: Observations, *, degree_along: int = 4,
                        degree_across: int = 5) -> LookAngleCalibration:
    """Linear least squares of the look-angle polynomials on the stars' body-frame tangents
    ``b_x / -b_z`` (along) and ``b_y / -b_z`` (across) at their samples."""
    n = len(obs)
    if n <= degree_across + 1:
        raise CalibrationError(f"{n} identified stars for a degree-{degree_across} look-angle polynomial: "
                               "too few stars to solve")
    centre = 0.5 * (cam.n_pixels - 1)
    u = (obs.sample - centre) / cam.r_norm_px
    ta = obs.b[:, 0] / -obs.b[:, 2]
    tb = obs.b[:, 1] / -obs.b[:, 2]
    out, covs, res = [], [], []
    cond = 1.0
    for t, deg in ((ta, degree_along), (tb, degree_across)):
        A = np.vander(u, deg + 1, increasing=True)
        N = A.T @ A
        c = np.linalg.solve(N, A.T @ t)
        r = t - A @ c
        s2 = float(r @ r) / max(n - deg - 1, 1)
        out.append(c)
        covs.append(s2 * np.linalg.inv(N))
        res.append(r)
        lam = np.linalg.eigvalsh(N)
        cond = float(lam[-1] / lam[0])
    r_px = np.concatenate(res) * cam.f_px
    return LookAngleCalibration(a=out[0], b=out[1], cov_a=covs[0], cov_b=covs[1],
                                sigma0_px=float(np.sqrt(np.mean(r_px**2))), condition=cond,
                                r_norm_px=cam.r_norm_px, centre_px=centre)


# --------------------------------------------------------------------------- an observation table
#: the estimators ``calibrate_file`` runs for ``method = "all"``, in their order
METHODS = ("published", "improved", "lookangle")

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


@dataclass(frozen=True)
class TableCalibration:
    """The calibrations of one observation table (:func:`calibrate_table`).

    Attributes
    ----------
    table : budget.linecam.table.ObservationTable
        The table calibrated (its name, observations and time tags).
    scenario : simcam.linecam.scenario.LineCamScenario
        The camera's nominal model and the lab's settings.
    camera : NominalCamera
        The nominal camera of ``scenario``.
    separability : Separability or None
        What the table can separate of the ten parameters (None with too few stars for ten).
    calibrations : dict of str to Calibration or LookAngleCalibration
        Each method run (:data:`METHODS`), in the order asked.
    grid_px : numpy.ndarray
        Detectors at which the fields are given (:func:`budget.linecam.model.los_grid`).
    los : dict of str to LosField
        Each method's calibrated look-angle field on ``grid_px``.
    """

    table: ObservationTable
    scenario: LineCamScenario
    camera: NominalCamera
    separability: Separability | None
    calibrations: dict[str, Calibration | LookAngleCalibration]
    grid_px: np.ndarray
    los: dict[str, LosField]

    def residuals_before_px(self) -> np.ndarray:
        """The stars' image residuals (px, along then across track) with the nominal camera."""
        return residuals(self.camera, np.zeros(len(PARAMETERS)), self.table.observations)

    def to_json(self) -> dict:
        """What ``budget linecam calibrate --json`` writes (:func:`calibration_payload`)."""
        return calibration_payload(self)

    def summary_lines(self) -> list[str]:
        """What ``budget linecam calibrate`` prints (:func:`calibration_lines`)."""
        return calibration_lines(self)


def parse_solve(solve, *, field: str) -> tuple[str, ...] | None:
    """The parameters an improved fit is asked to solve: None (all ten, gauge removed), a
    comma-separated string or a sequence of names of :data:`PARAMETERS`; an unknown name
    (or none at all) is a :class:`simcam.infra.errors.UserInputError` naming ``field``."""
    if solve is None:
        return None
    names = tuple(x.strip() for x in solve.split(",") if x.strip()) if isinstance(solve, str) else tuple(solve)
    bad = [x for x in names if x not in PARAMETERS]
    if bad or not names:
        raise UserInputError(f"{field}: unknown parameter {bad[0] if bad else solve!r} "
                             f"(known: {', '.join(PARAMETERS)})")
    return names


def calibrate_table(table: ObservationTable, scenario: LineCamScenario, *, solve=None,
                    methods=METHODS) -> TableCalibration:
    """The estimators ``methods`` on the observations of ``table`` with the nominal camera and
    the lab's settings of ``scenario``; ``solve``: the improved fit's parameters (None: all
    ten, gauge removed; else only those, an inseparable set being an error). Errors name the
    table and the field."""
    source, obs = table.source, table.observations
    cam = NominalCamera.from_model(scenario.camera)
    lab = scenario.lab
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
    grid = los_grid(scenario)
    los = {m: (c.field(grid) if m == "lookangle" else los_field(cam, c, grid)) for m, c in out.items()}
    return TableCalibration(table=table, scenario=scenario, camera=cam, separability=sep, calibrations=out,
                            grid_px=grid, los=los)


def calibrate_file(observations, scenario=None, *, epoch=None, method: str = "all",
                   solve=None) -> TableCalibration:
    """Calibrate a line camera from an observation table: what ``budget linecam calibrate``
    computes.

    Parameters
    ----------
    observations : str or path-like
        The observation table (CSV, :mod:`budget.linecam.table`).
    scenario : str, path-like, LineCamScenario or None
        The camera's nominal model and the lab's settings: a scenario file, a loaded
        scenario, or None for the embedded default.
    epoch : str, astropy.time.Time or None
        UTC epoch of the table's ``time_s`` (ISO); None: the scenario's ``orbit.epoch_utc``.
    method : {"all", "published", "improved", "lookangle"}
        The estimator(s): the patent's steps, the joint fit, the look-angle polynomials.
    solve : str, sequence of str or None
        Parameters the improved fit solves (comma-separated or a sequence; the others held
        at nominal; an inseparable set is an error); with ``method="all"`` only the improved
        fit runs. None: all ten, gauge removed.

    Returns
    -------
    TableCalibration
        With :meth:`TableCalibration.to_json` the JSON the command writes.

    Raises
    ------
    simcam.infra.errors.UserInputError
        One line naming the file (or the argument) and the field.
    """
    scn = scenario if isinstance(scenario, LineCamScenario) else load_scenario(scenario)
    names = parse_solve(solve, field="solve")
    if method not in ("all", *METHODS):
        raise UserInputError(f"method: {method!r} is none of all, {', '.join(METHODS)}")
    table = read_observations(observations, scn, epoch=epoch)
    methods = METHODS if method == "all" else (method,)
    if names is not None and method == "all":
        methods = ("improved",)
    return calibrate_table(table, scn, solve=names, methods=methods)


@dataclass(frozen=True)
class _StatedParameters:
    """One camera-parameter fit as the outputs state it: values and 1-sigma in report units
    (:data:`budget.linecam.parameters.PARAM_UNITS`), the parameters the plan cannot separate
    and what it determines of them (JSON-ready)."""

    theta: np.ndarray
    sigma: np.ndarray
    not_determined: frozenset
    combinations: dict


def _stated_parameters(result: TableCalibration, c: Calibration) -> _StatedParameters:
    sep, cam = result.separability, result.camera
    th = to_report_units(c.theta)
    sd = np.sqrt(np.maximum(np.diag(c.cov), 0)) * np.abs(to_report_units(np.ones(len(PARAMETERS))))
    # parameters the plan cannot separate are "not determined" (no sigma); what it does
    # determine of them is stated as the combinations
    undet = frozenset(sep.inseparable) if sep is not None else frozenset()
    combos = {}
    for name, ang, px, sign in (determined_combinations(sep.null_space, cam.f_px) if sep is not None else []):
        if ang in c.solved and px in c.solved:
            g = gauge_combination_vector(cam.f_px, ang, px, sign)
            combos[name] = {"value": float(g @ c.theta), "sigma": float(np.sqrt(max(g @ c.cov @ g, 0.0))),
                            "unit": "arcsec"}
    return _StatedParameters(theta=th, sigma=sd, not_determined=undet, combinations=combos)


def calibration_payload(result: TableCalibration) -> dict:
    """The JSON of a table's calibration (``budget linecam calibrate --json``): the table, the
    plan's separability and, per method, its parameters (report units) with their 1-sigma or
    "not determined", the determined combinations, the covariance (model units) and the
    look-angle field minus nominal with its stated 1-sigma (arcsec)."""
    sep, cam, grid = result.separability, result.camera, result.grid_px
    payload = {"observations": result.table.source, "n": len(result.table.observations),
               "scenario_hash": result.scenario.hash,
               "separability": None if sep is None else {"condition": sep.condition, "null_space": sep.null_space,
                                                          "inseparable": list(sep.inseparable)},
               "methods": {}}
    nominal = los_angles(cam, np.zeros(len(PARAMETERS)), grid)
    for m, c in result.calibrations.items():
        L = result.los[m]
        field = {"sample_px": grid.tolist(),
                 "along_minus_nominal_arcsec": ((L.along_rad - nominal[0]) * ARCSEC_PER_RAD).tolist(),
                 "across_minus_nominal_arcsec": ((L.across_rad - nominal[1]) * ARCSEC_PER_RAD).tolist(),
                 "sigma_along_arcsec": (L.sigma_along_rad * ARCSEC_PER_RAD).tolist(),
                 "sigma_across_arcsec": (L.sigma_across_rad * ARCSEC_PER_RAD).tolist()}
        if m == "lookangle":
            payload["methods"][m] = {"tan_along_coefficients": c.a.tolist(), "tan_across_coefficients": c.b.tolist(),
                                     "sigma0_px": c.sigma0_px, "condition": c.condition, "los_field": field}
            continue
        st = _stated_parameters(result, c)
        payload["methods"][m] = {
            "theta": dict(zip(PARAMETERS, st.theta.tolist())),
            "sigma": {p: (None if p in st.not_determined else v) for p, v in zip(PARAMETERS, st.sigma.tolist())},
            "not_determined": sorted(st.not_determined), "determined_combinations": st.combinations,
            "units": {p: PARAM_UNITS[p][0] for p in PARAMETERS}, "solved": list(c.solved),
            "covariance_model_units": c.cov.tolist(), "sigma0_px": c.sigma0_px, "condition": c.condition,
            "los_field": field}
    return payload


def calibration_lines(result: TableCalibration) -> list[str]:
    """What ``budget linecam calibrate`` prints: the table's size, the plan's separability and,
    per method, its residual, condition and stated LOS rms, and its parameters."""
    sep = result.separability
    lines = [f"{result.table.source}: {len(result.table.observations)} star observations"]
    if sep is not None:
        null = "; ".join(" ".join(f"{c:+.2f} {p}" for p, c in d.items()) for d in sep.null_space) or "none"
        lines.append(f"plan: condition {fmt(sep.condition, 3)}; unobservable combinations: {null}")
    for m, c in result.calibrations.items():
        L = result.los[m]
        lines.append(f"{m}: rms residual {c.sigma0_px:.3f} px, condition {fmt(c.condition, 3)}, "
                     f"stated LOS rms {np.sqrt(np.mean(L.sigma_along_rad ** 2)) * ARCSEC_PER_RAD:.3f}\" along, "
                     f"{np.sqrt(np.mean(L.sigma_across_rad ** 2)) * ARCSEC_PER_RAD:.3f}\" across")
        if m == "lookangle":
            continue
        st = _stated_parameters(result, c)
        for j, p in enumerate(PARAMETERS):
            if p in c.solved:
                lines.append(f"  {p:6s} not determined (inseparable on this plan)" if p in st.not_determined else
                             f"  {p:6s} {fmt(st.theta[j], 5):>12} +- {fmt(st.sigma[j], 3)} {PARAM_UNITS[p][0]}")
        for name, cmb in st.combinations.items():
            lines.append(f"  {name:6s} {fmt(cmb['value'], 5):>12} +- {fmt(cmb['sigma'], 3)} arcsec")
    return lines
