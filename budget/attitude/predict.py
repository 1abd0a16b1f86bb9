"""What a lab predicts of a star camera's attitude error from its per-star budget.

* **Published** (seed 000 eq 32): the single-star error divided by ``sqrt(N)`` with the
  budget's ``N`` (10), per cross-boresight axis, whatever the pointing; no roll.
* **Improved**: the same lab figures used for the pointing at hand (docs/attitude.md,
  "The predictions"). Per star ``i`` and axis ``a`` (1 sigma, arcsec):

  - temporal ``t_ia = TE_a sqrt(N_ref / N_i)``: the lab's TE, measured with its own source of
    ``N_ref`` photo-electrons, scaled to the star's ``N_i`` as a centre of gravity's shot
    noise (photon-limited: the read and background terms fall faster, as ``1 / N_i``);
  - static and independent from star to star, ``s_a = RSS(HSFE_a, LSFE-C1_a, LSFE-C2_a)``:
    the pixel-phase error, and the distortion residual and the calibration grid's markers,
    whose smooth fields the pointing's stars sample at scattered places;
  - common to the pointing's stars, ``c_a = LSFE-S_a``: the colour shift, nearly uniform
    over the field, which no number of stars averages.

  The attitude is the weighted least squares of the stars' image displacements
  ``(du, dv)_i = (e_x - rho_v,i e_roll, e_y + rho_u,i e_roll)`` (``rho = (u, v) / F`` the
  field angle, rad): ``G = (H^T W H)^-1 H^T W`` with ``W_i = 1 / w_i^2``,
  ``w_i^2 = mean_a (t_ia^2 + s_a^2)`` (the weights the improved solve uses), and the
  prediction ``P = G diag(t^2) G^T`` (temporal) ``+ G diag(s^2) G^T + diag(c_x^2, c_y^2, 0)``
  (spatial): the stars' own count, brightness and geometry, the roll's lever arm included.

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
    static_arcsec : ndarray (2,)
        Independent static part per star, ``RSS(HSFE, LSFE-C1, LSFE-C2)``.
    common_arcsec : ndarray (2,)
        Part common to a pointing's stars (LSFE-S).
    """

    single_star_arcsec: np.ndarray
    n_stars: int
    te_arcsec: np.ndarray
    reference_electrons: float
    static_arcsec: np.ndarray
    common_arcsec: np.ndarray

    @classmethod
    def from_3sigma(cls, *, single_star, n_stars: int, te, hsfe, lsfe_s, lsfe_c1, lsfe_c2,
                    reference_electrons: float) -> LabBudget:
        """The budget from its published 3-sigma figures (x, y) and the TE source's electrons."""
        ref = float(reference_electrons)
        if not (math.isfinite(ref) and ref > 0.0):
            raise ValueError(f"reference_electrons: must be finite and > 0, got {reference_electrons!r}")
        if int(n_stars) < 1:
            raise ValueError(f"n_stars: must be >= 1, got {n_stars!r}")
        static = np.sqrt(_xy("hsfe", hsfe) ** 2 + _xy("lsfe_c1", lsfe_c1) ** 2 + _xy("lsfe_c2", lsfe_c2) ** 2)
        return cls(single_star_arcsec=_xy("single_star", single_star) / 3.0, n_stars=int(n_stars),
                   te_arcsec=_xy("te", te) / 3.0, reference_electrons=ref, static_arcsec=static / 3.0,
                   common_arcsec=_xy("lsfe_s", lsfe_s) / 3.0)

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
    its temporal part (the spread over frames) and its spatial part (the pointing's bias)."""

    temporal_arcsec2: np.ndarray
    spatial_arcsec2: np.ndarray

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
    static = np.tile(budget.static_arcsec**2, n)
    spatial = (g * static[None, :]) @ g.T + np.diag([*(budget.common_arcsec**2), 0.0])
    return AttitudePrediction(temporal_arcsec2=temporal, spatial_arcsec2=spatial)
