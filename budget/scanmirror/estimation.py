"""Estimation of the mirror's normal deviation from star sensing (seed 003, eqs. 33-38 [R]).

What the lab has for each star-sensing dwell: the commanded angles (alpha_k, beta_k), the star
tracker's attitude ``A_Ib`` at each frame, the measured star centroids on the detector, and a
star catalogue turned into directions by its own astrometry.

* :func:`published_estimate`: eqs. (33)-(38): one star, first order. The star's direction is
  taken as the line of sight (the measured centroid offset mapped back through the nominal
  mirror), ``s^I_star - A_Ib s^b(alpha, beta; 0) = A_Ib [ds/dtau_x, ds/dtau_y] (dtau_x, dtau_y)``,
  three equations in two unknowns, solved by least squares; the tracker attitude is taken as
  exact and the catalogue direction is used without aberration (the paper does not mention it).
* :func:`batch_estimate` (improved): every star in every frame of one or more dwells, the exact
  reflection model, the apparent (aberrated) directions, and the tracker's attitude error of
  each dwell as three nuisance angles with the tracker's stated prior; Gauss-Newton, and the
  covariance ``(J^T W J)^-1`` of the weighted least squares (with the prior rows), whose
  (dtau_x, dtau_y) block is the stated uncertainty.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simcam.scanmirror.geometry import line_of_sight_body, mirror_normal_body, rot_x, rot_y, rotvec_matrix
from simcam.scanmirror.stars import detector_coordinates

__all__ = ["DwellMeasurement", "published_estimate", "batch_estimate", "los_derivatives"]


@dataclass(frozen=True)
class DwellMeasurement:
    """One dwell as the lab sees it: star directions (its catalogue astrometry, n x 3, GCRS),
    tracker attitudes at the frames (f, 3, 3) ``A_Ib``, centroids (f, n, 2) rad (NaN where the
    star was not in the field), commanded angles (rad)."""

    star_I: np.ndarray
    tracker_A_Ib: np.ndarray
    centroids: np.ndarray
    alpha_rad: float
    beta_rad: float


def los_derivatives(alpha_rad: float, beta_rad: float) -> np.ndarray:
    """``[ds/dtau_x, ds/dtau_y]`` (3, 2) of the body line of sight at zero deviation, from
    ``s = d - 2 (d . w) w`` with ``dw/dtau_x = A_bm (0, -1, 0)``, ``dw/dtau_y = A_bm (1, 0, 0)``
    (eq. 19 [R], first order)."""
    A_bm = rot_x(alpha_rad) @ rot_y(beta_rad)
    w = A_bm[:, 2]
    d = np.array([1.0, 0.0, 0.0])
    cols = []
    for dw in (-A_bm[:, 1], A_bm[:, 0]):
        cols.append(-2.0 * (d @ dw) * w - 2.0 * (d @ w) * dw)
    return np.stack(cols, -1)


def published_estimate(dwell: DwellMeasurement, *, star: int, frame: int) -> np.ndarray:
    """(dtau_x, dtau_y) (rad) from one star in one frame, eqs. (33)-(38) [R]."""
    a, b = dwell.alpha_rad, dwell.beta_rad
    A_Ib = dwell.tracker_A_Ib[frame]
    m = dwell.centroids[frame, star]
    w0 = mirror_normal_body(a, b)
    # the detector offset m seen through the nominal mirror: u - s = Refl(m_y y_b + m_z z_b)
    off = np.array([0.0, m[0], m[1]])
    off_sky = off - 2.0 * (off @ w0) * w0
    s_meas_I = dwell.star_I[star] - A_Ib @ off_sky
    s0_I = A_Ib @ line_of_sight_body(a, b)
    D = A_Ib @ los_derivatives(a, b)
    est, *_ = np.linalg.lstsq(D, s_meas_I - s0_I, rcond=None)
    return est


def _predict(theta, dwells, n_dwell):
    out = []
    for k, dw in enumerate(dwells):
        R = rotvec_matrix(theta[2 + 3 * k: 5 + 3 * k])
        A = dw.tracker_A_Ib @ R  # (f, 3, 3): the lab's corrected body -> inertial
        u_b = np.einsum("fji,nj->fni", A, dw.star_I)
        w = mirror_normal_body(dw.alpha_rad, dw.beta_rad, theta[0], theta[1])
        out.append(detector_coordinates(u_b, np.broadcast_to(w, u_b.shape)))
    return out


def batch_estimate(dwells: list[DwellMeasurement], *, centroid_sigma_rad: float, tracker_sigma_rad: float,
                   iterations: int = 2):
    """Improved estimate: (dtau_x, dtau_y) (rad) and its 2x2 covariance (rad^2).

    Unknowns: the deviation and, per dwell, the small rotation ``delta`` with
    ``A_Ib(true) = A_Ib(tracker) R(delta)`` (prior N(0, tracker_sigma^2) per axis).
    """
    K = len(dwells)
    p = 2 + 3 * K
    theta = np.zeros(p)
    masks = [np.isfinite(dw.centroids[..., 0]) for dw in dwells]
    y = np.concatenate([dw.centroids[msk].ravel() for dw, msk in zip(dwells, masks)])

    def model(th):
        pr = _predict(th, dwells, K)
        return np.concatenate([q[msk].ravel() for q, msk in zip(pr, masks)])

    h = 1e-7
    J = None
    for _ in range(iterations):
        f0 = model(theta)
        if J is None:  # the Jacobian at the start serves every step (the model is nearly linear)
            J = np.empty((f0.size, p))
            for j in range(p):
                e = np.zeros(p)
                e[j] = h
                J[:, j] = (model(theta + e) - model(theta - e)) / (2 * h)
        Jw = np.vstack([J / centroid_sigma_rad, np.hstack([np.zeros((3 * K, 2)), np.eye(3 * K)]) / tracker_sigma_rad])
        rw = np.concatenate([(y - f0) / centroid_sigma_rad, -theta[2:] / tracker_sigma_rad])
        step, *_ = np.linalg.lstsq(Jw, rw, rcond=None)
        theta = theta + step
    cov = np.linalg.inv(Jw.T @ Jw)
    return theta[:2], cov[:2, :2]
