"""What a lab predicts of a star camera's attitude error from its per-star budget.

* **Published** (seed 000 eq 32): the single-star error divided by ``sqrt(N)`` with the
  budget's ``N`` (10), per cross-boresight axis, whatever the pointing; no roll.
* **Improved**: the same lab figures used for the pointing at hand (docs/attitude.md,
  "The predictions"). Per star ``i`` and axis ``a`` (1 sigma, arcsec):

  - temporal ``t_ia = TE_a sqrt(N_ref / N_i)``: the lab's TE, measured with its own source of
    ``N_ref`` photo-electrons, scaled to the star's ``N_i`` as a centre of gravity's shot
    noise (photon-limited: the read and background terms fall faster, as ``1 / N_i``);
  - static, the pixel-scale error ``p_a = HSFE_a`` (ECSS pixel spatial error), independent
    from star to star;
  - static, the smooth fields ``f_a = RSS(LSFE-C1_a, LSFE-C2_a)`` (the distortion residual and
    the calibration grid's markers; ECSS FOV spatial error, with ``c_a``): a field over the
    focal plane, which the pointing's stars sample at their own places, so that two stars
    ``d`` px apart share ``rho(d) = exp(-d^2 / (2 L^2))`` of it (a Gaussian correlogram of
    correlation length ``L``, the lab's from its residual map, ``field_correlation_px``; 0:
    independent from star to star, infinite: a bias common to the field);
  - common to the pointing's stars, ``c_a = LSFE-S_a``: the colour shift, nearly uniform
    over the field, which no number of stars averages.

  The attitude is the weighted least squares of the stars' image displacements
  ``(du, dv)_i = (e_x - rho_v,i e_roll, e_y + rho_u,i e_roll)`` (``rho = (u, v) / F`` the
  field angle, rad): ``G = (H^T W H)^-1 H^T W`` with ``W_i = 1 / w_i^2``,
  ``w_i^2 = mean_a (t_ia^2 + p_a^2 + f_a^2)`` (the weights the improved solve uses), and the
  prediction ``P = G diag(t^2) G^T`` (temporal) ``+ G diag(p^2) G^T`` (pixel spatial)
  ``+ G (R (x) diag(f^2)) G^T + diag(c_x^2, c_y^2, 0)`` (FOV spatial, ``R_ij = rho(d_ij)``):
  the stars' own count, brightness, geometry and spacing, the roll's lever arm included (the
  propagation of a covariance through a linear least squares, e.g. Bjorck, *Numerical Methods
  for Least Squares Problems*, 1996, eq. 1.1.21).

Nothing here reads a truth: the inputs are the budget's figures, the stars' catalogue
electrons and their measured focal positions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["AttitudePrediction", "LabBudget", "predict_attitude"]


def _xy(name: str, values) -> np.ndarray:
    arr = np.asarray(values, dtype=np.float64)
    if arr.shape != (2,) or not np.isfinite(arr).all() or (arr < 0.0).any():
        raise ValueError(f"{name}: expected two finite values >= 0 (x, y), got {values!r}")
    return arr


@dataclass(frozen=True)
class LabBudget:
    """A lab's per-star budget, 1 sigma, arcsec, (x, y) (module docstring).

    Attributes
    ----------
    single_star_arcsec : ndarray (2,)
        The published single-star error.
    n_stars : int
        The star count of the published attitude error (eq 32).
    te_arcsec : ndarray (2,)
        Temporal error at ``reference_electrons``.
    reference_electrons : float
        Photo-electrons per exposure of the source TE was measured with.
    pixel_arcsec : ndarray (2,)
        Pixel-scale static part per star, independent from star to star (HSFE).
    field_arcsec : ndarray (2,)
        Smooth-field static part per star, independent from star to star
        (``RSS(LSFE-C1, LSFE-C2)``).
    common_arcsec : ndarray (2,)
        Part common to a pointing's stars (LSFE-S).
    field_correlation_px : float
        Correlation length ``L`` of the smooth-field part (px; 0: independent from star to star).
    """

    single_star_arcsec: np.ndarray
    n_stars: int
    te_arcsec: np.ndarray
    reference_electrons: float
    pixel_arcsec: np.ndarray
    field_arcsec: np.ndarray
    common_arcsec: np.ndarray
    field_correlation_px: float = 0.0

    @classmethod
    def from_3sigma(cls, *, single_star, n_stars: int, te, hsfe, lsfe_s, lsfe_c1, lsfe_c2,
                    reference_electrons: float, field_correlation_px: float = 0.0) -> LabBudget:
        """The budget from its published 3-sigma figures (x, y), the TE source's electrons and
        the smooth field's correlation length (px)."""
        if not (math.isfinite(field_correlation_px) and field_correlation_px >= 0.0):
            raise ValueError(f"field_correlation_px: must be finite and >= 0, got {field_correlation_px!r}")
        ref = float(reference_electrons)
        if not (math.isfinite(ref) and ref > 0.0):
            raise ValueError(f"reference_electrons: must be finite and > 0, got {reference_electrons!r}")
        if int(n_stars) < 1:
            raise ValueError(f"n_stars: must be >= 1, got {n_stars!r}")
        field = np.sqrt(_xy("lsfe_c1", lsfe_c1) ** 2 + _xy("lsfe_c2", lsfe_c2) ** 2)
        return cls(single_star_arcsec=_xy("single_star", single_star) / 3.0, n_stars=int(n_stars),
                   te_arcsec=_xy("te", te) / 3.0, reference_electrons=ref, pixel_arcsec=_xy("hsfe", hsfe) / 3.0,
                   field_arcsec=field / 3.0, common_arcsec=_xy("lsfe_s", lsfe_s) / 3.0,
                   field_correlation_px=float(field_correlation_px))

    def field_correlation(self, u_px, v_px) -> np.ndarray:
        """``R_ij = exp(-d_ij^2 / (2 L^2))`` of stars at focal ``(u, v)`` px (the identity for
        ``L = 0``)."""
        u = np.asarray(u_px, dtype=np.float64)
        if self.field_correlation_px == 0.0:
            return np.eye(u.size)
        d2 = (u[:, None] - u[None, :]) ** 2 + (np.asarray(v_px)[:, None] - np.asarray(v_px)[None, :]) ** 2
        return np.exp(-0.5 * d2 / self.field_correlation_px**2)

    @property
    def static_arcsec(self) -> np.ndarray:
        """The static part per star independent from star to star, ``RSS(pixel, field)`` (2,)."""
        return np.sqrt(self.pixel_arcsec**2 + self.field_arcsec**2)

    @property
    def published_sigma_arcsec(self) -> np.ndarray:
        """Eq 32: the single-star error over ``sqrt(n_stars)``, 1 sigma (x, y)."""
        return self.single_star_arcsec / math.sqrt(self.n_stars)

    def temporal_arcsec(self, electrons) -> np.ndarray:
        """Each star's temporal error (N, 2): TE scaled by ``sqrt(reference_electrons / N_i)``."""
        e = np.asarray(electrons, dtype=np.float64)
        if e.ndim != 1 or not (np.isfinite(e).all() and (e > 0.0).all()):
            raise ValueError("electrons: expected a 1-D array of finite values > 0")
        return self.te_arcsec[None, :] * np.sqrt(self.reference_electrons / e)[:, None]

    def weight_sigma_arcsec(self, electrons) -> np.ndarray:
        """The error each star is weighted with in the improved solve (N,), isotropic:
        ``sqrt(mean_a (t_ia^2 + s_a^2))``."""
        t = self.temporal_arcsec(electrons)
        return np.sqrt(np.mean(t**2 + self.static_arcsec[None, :] ** 2, axis=1))


@dataclass(frozen=True)
class AttitudePrediction:
    """The predicted covariance of the attitude error components (x, y, roll), arcsec^2:
    its temporal part (the spread over frames) and the two parts of the pointing's bias,
    ECSS-E-ST-60-20C's FOV spatial error (the smooth fields) and pixel spatial error."""

    temporal_arcsec2: np.ndarray
    fov_arcsec2: np.ndarray
    pixel_arcsec2: np.ndarray

    @property
    def spatial_arcsec2(self) -> np.ndarray:
        """The pointing's bias: FOV plus pixel spatial error (independent)."""
        return self.fov_arcsec2 + self.pixel_arcsec2

    @property
    def total_arcsec2(self) -> np.ndarray:
        """Temporal plus spatial: one frame's error."""
        return self.temporal_arcsec2 + self.spatial_arcsec2

    @property
    def sigma_arcsec(self) -> np.ndarray:
        """1 sigma of one frame's error (x, y, roll)."""
        return np.sqrt(np.diag(self.total_arcsec2))


def predict_attitude(budget: LabBudget, *, u_px, v_px, focal_length_px: float, electrons) -> AttitudePrediction:
    """The improved prediction for one frame's stars (module docstring): their focal positions
    ``u_px, v_px`` (N,) as measured, the focal length in px and their catalogue electrons."""
    u = np.asarray(u_px, dtype=np.float64)
    v = np.asarray(v_px, dtype=np.float64)
    n = u.size
    if n < 2 or v.shape != u.shape:
        raise ValueError(f"u_px, v_px: expected two arrays of the same length >= 2, got {u.shape} and {v.shape}")
    t = budget.temporal_arcsec(electrons)
    if t.shape[0] != n:
        raise ValueError(f"electrons: expected {n} values, got {t.shape[0]}")
    w = 1.0 / budget.weight_sigma_arcsec(electrons) ** 2
    h = np.zeros((2 * n, 3))
    h[0::2, 0] = 1.0
    h[1::2, 1] = 1.0
    h[0::2, 2] = -v / focal_length_px
    h[1::2, 2] = u / focal_length_px
    wr = np.repeat(w, 2)
    g = np.linalg.solve(h.T @ (wr[:, None] * h), h.T * wr[None, :])
    temporal = (g * (t**2).ravel()[None, :]) @ g.T
    pixel = (g * np.tile(budget.pixel_arcsec**2, n)[None, :]) @ g.T
    c = np.zeros((2 * n, 2 * n))
    r = budget.field_correlation(u, v)
    c[0::2, 0::2] = budget.field_arcsec[0] ** 2 * r
    c[1::2, 1::2] = budget.field_arcsec[1] ** 2 * r
    fov = g @ c @ g.T + np.diag([*(budget.common_arcsec**2), 0.0])
    return AttitudePrediction(temporal_arcsec2=temporal, fov_arcsec2=fov, pixel_arcsec2=pixel)
