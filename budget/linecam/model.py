"""The lab's calibration model of a TDI line camera (seed 004, step 5, reconstructed).

Collinearity with exterior and interior compensation::

    R_Aber(t_i) u_i = m_i R_cam(t_i) R_u [x_i - x0 - Dx, y_i - y0 - Dy, -f]^T

with Brown's (1971) interior corrections in the patent's form, in px, normalised by
``r_n`` = half the line length (px)::

    Dx = dx0 + x' df/f + r_n [k1 X r^2 + k2 X r^4 + p1 (r^2 + 2 X^2) + 2 p2 X Y]
    Dy = dy0 + y' df/f + r_n [k1 Y r^2 + k2 Y r^4 + p2 (r^2 + 2 Y^2) + 2 p1 X Y]
    x' = x - x0 (nominal), X = x'/r_n, Y = y'/r_n, r^2 = X^2 + Y^2

Eliminating ``m_i``: with ``V = R_u^T b_i``, ``b_i = R_cam(t_i)^T R_Aber u_i`` (the star in
the nominal camera = body frame), the ideal image coordinates are
``x~ = -F V1/V3``, ``y~ = -F V2/V3`` (``F = f / pitch``, px) and the two residuals
(px) are ``(x' - Dx - x~, y' - Dy - y~)``. They are linear in the seven interior
parameters once ``R_u`` is fixed (the patent's step 6: "variable substitution turns the
non-linear interior solution into a linear one").

Parameters, order of :data:`PARAMETERS`: ``roll, pitch, yaw`` (rad, a rotation vector of
``R_u``: camera -> body; updates compose on the right, ``R_u exp([d]x)``), ``dx0, dy0`` (px),
``df`` (mm), ``k1, k2, p1, p2`` (dimensionless, normalised by ``r_n``).

The line-of-sight (look-angle) field is the calibrated quantity: for detector ``s``, the
body-frame direction ``L(s) = R_u (x_line' - Dx, y'(s) - Dy, -F)`` and its angles
``along = atan2(L_x, -L_z)``, ``across = atan2(L_y, -L_z)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from simcam.linecam.scenario import PARAMETERS, LineCameraModel, LineCamScenario

__all__ = ["PARAMETERS", "NominalCamera", "Observations", "interior_design", "residuals",
           "jacobian", "los_angles", "los_jacobian", "parameter_scale", "los_grid"]


@dataclass(frozen=True)
class NominalCamera:
    """What the lab knows of its camera: the design values."""

    focal_length_mm: float
    pitch_mm: float
    n_pixels: int
    x_line_mm: float

    @classmethod
    def from_model(cls, cam: LineCameraModel) -> "NominalCamera":
        return cls(focal_length_mm=cam.focal_length_mm, pitch_mm=cam.pitch_mm, n_pixels=cam.n_pixels,
                   x_line_mm=cam.x_line_mm)

    @property
    def f_px(self) -> float:
        return self.focal_length_mm / self.pitch_mm

    @property
    def r_norm_px(self) -> float:
        return 0.5 * self.n_pixels

    @property
    def x_line_px(self) -> float:
        return self.x_line_mm / self.pitch_mm

    def y_px(self, sample) -> np.ndarray:
        """Focal-plane ``y'`` (px from the nominal principal point) of samples."""
        return np.asarray(sample, dtype=float) - 0.5 * (self.n_pixels - 1)


@dataclass(frozen=True)
class Observations:
    """Identified star observations: the star in the body frame and where it was seen.

    Attributes
    ----------
    b : numpy.ndarray (n, 3)
        Unit vectors ``R_cam(t_i)^T a_i`` (the star's apparent direction in the reported
        body frame at its time tag).
    sample : numpy.ndarray (n,)
        Centroid along the line, px (pixel centres at integers).
    pass_index, hip : numpy.ndarray (n,)
        Pass of each observation and catalogue id (for reports).
    """

    b: np.ndarray
    sample: np.ndarray
    pass_index: np.ndarray
    hip: np.ndarray

    def __len__(self) -> int:
        return int(self.sample.size)

    def subset(self, idx) -> "Observations":
        return Observations(b=self.b[idx], sample=self.sample[idx], pass_index=self.pass_index[idx],
                            hip=self.hip[idx])


def parameter_scale(cam: NominalCamera) -> np.ndarray:
    """Displacement (px) at the end of the line per unit of each parameter, used to scale the
    columns of the Jacobian: ``F`` per rad, 1 per px, ``r_n / f`` per mm, ``r_n`` per unit."""
    rn = cam.r_norm_px
    return np.array([cam.f_px] * 3 + [1.0, 1.0, rn / cam.focal_length_mm] + [rn] * 4)


def interior_design(cam: NominalCamera, sample) -> tuple[np.ndarray, np.ndarray]:
    """``d(Dx)/d(theta_int)`` and ``d(Dy)/d(theta_int)`` (n, 7), px per unit: the interior
    corrections are exactly linear, ``Dx = Ax @ theta_int``, ``Dy = Ay @ theta_int``."""
    rn = cam.r_norm_px
    xp = np.full(np.shape(sample), cam.x_line_px, dtype=float)
    yp = cam.y_px(sample)
    X, Y = xp / rn, yp / rn
    r2 = X * X + Y * Y
    one, zero = np.ones_like(X), np.zeros_like(X)
    ax = np.column_stack([one, zero, xp / cam.focal_length_mm, rn * X * r2, rn * X * r2 * r2,
                          rn * (r2 + 2 * X * X), rn * 2 * X * Y])
    ay = np.column_stack([zero, one, yp / cam.focal_length_mm, rn * Y * r2, rn * Y * r2 * r2,
                          rn * 2 * X * Y, rn * (r2 + 2 * Y * Y)])
    return ax, ay


def _ideal(cam: NominalCamera, rot_u: Rotation, b) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    V = rot_u.inv().apply(b)
    F = cam.f_px
    return -F * V[:, 0] / V[:, 2], -F * V[:, 1] / V[:, 2], V


def residuals(cam: NominalCamera, theta, obs: Observations) -> np.ndarray:
    """Residuals (2n,) in px: ``[x' - Dx - x~, y' - Dy - y~]`` (all x first, then all y)."""
    th = np.asarray(theta, dtype=float)
    ax, ay = interior_design(cam, obs.sample)
    xt, yt, _ = _ideal(cam, Rotation.from_rotvec(th[:3]), obs.b)
    rx = cam.x_line_px - ax @ th[3:] - xt
    ry = cam.y_px(obs.sample) - ay @ th[3:] - yt
    return np.concatenate([rx, ry])


def jacobian(cam: NominalCamera, theta, obs: Observations) -> np.ndarray:
    """Jacobian (2n, 10) of :func:`residuals`; the rotation columns are for a right
    perturbation ``R_u exp([d]x)`` (``dV/dd = [V]x``)."""
    th = np.asarray(theta, dtype=float)
    ax, ay = interior_design(cam, obs.sample)
    _, _, V = _ideal(cam, Rotation.from_rotvec(th[:3]), obs.b)
    F = cam.f_px
    v1, v2, v3 = V[:, 0], V[:, 1], V[:, 2]
    # d x~ / dV = -F (1/V3, 0, -V1/V3^2), times [V]x
    gx = -F * np.column_stack([1.0 / v3, np.zeros_like(v3), -v1 / v3**2])
    gy = -F * np.column_stack([np.zeros_like(v3), 1.0 / v3, -v2 / v3**2])
    Vx = np.zeros((V.shape[0], 3, 3))
    Vx[:, 0, 1], Vx[:, 0, 2], Vx[:, 1, 2] = -v3, v2, -v1
    Vx[:, 1, 0], Vx[:, 2, 0], Vx[:, 2, 1] = v3, -v2, v1
    jx = -np.einsum("ni,nij->nj", gx, Vx)
    jy = -np.einsum("ni,nij->nj", gy, Vx)
    return np.vstack([np.column_stack([jx, -ax]), np.column_stack([jy, -ay])])


def los_angles(cam: NominalCamera, theta, sample) -> tuple[np.ndarray, np.ndarray]:
    """Body-frame look angles (rad) of detectors ``sample`` under parameters ``theta``."""
    th = np.asarray(theta, dtype=float)
    ax, ay = interior_design(cam, sample)
    c = np.column_stack([cam.x_line_px - ax @ th[3:], cam.y_px(sample) - ay @ th[3:],
                         np.full(np.shape(sample), -cam.f_px)])
    L = Rotation.from_rotvec(th[:3]).apply(c)
    return np.arctan2(L[:, 0], -L[:, 2]), np.arctan2(L[:, 1], -L[:, 2])


def los_jacobian(cam: NominalCamera, theta, sample) -> np.ndarray:
    """Jacobian (2m, 10) of the look angles ``[along; across]`` with respect to the
    parameters (right perturbation of ``R_u``), by central differences (the angles are
    smooth; steps of 1e-3 px at the line's end give errors ~1e-12 rad)."""
    th = np.asarray(theta, dtype=float)
    steps = 1e-3 / parameter_scale(cam)
    base = Rotation.from_rotvec(th[:3])
    cols = []
    for j in range(th.size):
        out = []
        for sgn in (1.0, -1.0):
            t2 = th.copy()
            if j < 3:
                d = np.zeros(3)
                d[j] = sgn * steps[j]
                t2[:3] = (base * Rotation.from_rotvec(d)).as_rotvec()
            else:
                t2[j] += sgn * steps[j]
            a, c = los_angles(cam, t2, sample)
            out.append(np.concatenate([a, c]))
        cols.append((out[0] - out[1]) / (2 * steps[j]))
    return np.column_stack(cols)


def los_grid(scenario: LineCamScenario) -> np.ndarray:
    """Detectors at which LOS fields are compared: every ``lab.grid_step_px`` and the last one."""
    n = scenario.camera.n_pixels
    g = np.arange(0, n, scenario.lab.grid_step_px, dtype=float)
    return g if g[-1] == n - 1 else np.append(g, n - 1)
