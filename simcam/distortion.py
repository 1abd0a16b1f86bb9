"""Geometric distortion shared by the star camera and the line camera: the Brown-Conrady
model with its analytic Jacobian and Newton inverse, and the optics' argument errors.

:mod:`simcam.starcam.optics` adds the full cubic and the composite model on the same
machinery (and re-exports what is here); :mod:`simcam.linecam.camera` uses the
Brown-Conrady model. Coordinates follow ``docs/conventions.md``: focal-plane coordinates
``(u, v)`` in nominal px from the optical axis.
"""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass

import numpy as np

__all__ = ["OpticsError", "NonInvertibleDistortionError", "BrownConradyDistortion"]


class OpticsError(ValueError):
    """An optics parameter is invalid; the message names the parameter."""


class NonInvertibleDistortionError(OpticsError):
    """The Newton inverse of a distortion did not converge (map folds or is too strong)."""


# ----------------------------------------------------------------------------------------
# validation helpers


def _finite_array(name: str, value, *, min_ndim: int = 0) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise OpticsError(f"{name}: expected numbers, got {value!r}") from None
    if arr.ndim < min_ndim:
        raise OpticsError(f"{name}: expected at least {min_ndim} dimension(s), got a scalar")
    if not np.isfinite(arr).all():
        raise OpticsError(f"{name}: must be finite (got NaN or infinity)")
    return arr


def _finite_float(name: str, value) -> float:
    if isinstance(value, bool):
        raise OpticsError(f"{name}: expected a number, got {value!r}")
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise OpticsError(f"{name}: expected a number, got {value!r}") from None
    if not math.isfinite(out):
        raise OpticsError(f"{name}: must be finite, got {value!r}")
    return out


def _positive_float(name: str, value) -> float:
    out = _finite_float(name, value)
    if out <= 0.0:
        raise OpticsError(f"{name}: must be > 0, got {value!r}")
    return out


def _coords(u_px, v_px):
    """Finite float64 coordinates of one shape (the distortions only read them: arrays of
    one shape are returned as they are, others broadcast into new arrays)."""
    u = _finite_array("u_px", u_px)
    v = _finite_array("v_px", v_px)
    if u.shape == v.shape:
        return u, v
    try:
        u, v = np.broadcast_arrays(u, v)
    except ValueError:
        raise OpticsError(f"v_px: shape {v.shape} does not broadcast with u_px {u.shape}") from None
    return u.copy(), v.copy()


class _Distortion(abc.ABC):
    """Shared forward/inverse machinery; subclasses define ``_map(u, v, jacobian)``."""

    @abc.abstractmethod
    def _map(self, u, v, jacobian=True):
        """Distorted (u', v') px and the Jacobian (..., 2, 2) at focal-plane points (u, v) px
        (None with ``jacobian=False``: the positions alone, the same values, for about a
        third of the work)."""

    def forward(self, *, u_px, v_px):
        """Distorted focal-plane coordinates ``(u', v')`` in px of ideal ``(u, v)`` px."""
        u, v = _coords(u_px, v_px)
        fu, fv, _ = self._map(u, v, jacobian=False)
        return fu, fv

    def displacement(self, *, u_px, v_px):
        """Distortion displacement ``(u' - u, v' - v)`` in px at ideal ``(u, v)`` px."""
        u, v = _coords(u_px, v_px)
        fu, fv, _ = self._map(u, v, jacobian=False)
        return fu - u, fv - v

    def jacobian(self, *, u_px, v_px):
        """Analytic Jacobian ``d(u', v') / d(u, v)``, shape ``u.shape + (2, 2)``.

        ``J[..., 0, 1] = du'/dv`` (row: output component, column: input component).
        """
        u, v = _coords(u_px, v_px)
        return self._map(u, v)[2]

    def inverse(self, *, u_px, v_px, tol_px: float = 1e-10, max_iter: int = 50):
        """Ideal coordinates ``(u, v)`` whose distorted image is the given ``(u', v')``.

        Newton's method with the analytic Jacobian, vectorised over points:
        ``p_{k+1} = p_k - J(p_k)^{-1} (F(p_k) - p')``, started from
        ``p_0 = p' - d(p')`` (first-order inverse), until every residual
        ``|F(p) - p'|`` is below ``tol_px`` in both components.

        Parameters
        ----------
        u_px, v_px : array_like
            Distorted focal-plane coordinates in px.
        tol_px : float
            Convergence tolerance on the forward residual, px (> 0). Default 1e-10.
        max_iter : int
            Maximum number of Newton steps (>= 1). Default 50.

        Returns
        -------
        u_px, v_px : ndarray
            Ideal coordinates in px.

        Raises
        ------
        NonInvertibleDistortionError
            If the Jacobian becomes singular or orientation-reversing (the map folds)
            or the iteration does not converge; the message gives the worst point.
        """
        tol = _positive_float("tol_px", tol_px)
        if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
            raise OpticsError(f"max_iter: expected an integer >= 1, got {max_iter!r}")
        tu, tv = _coords(u_px, v_px)
        du, dv = self.displacement(u_px=tu, v_px=tv)
        u = tu - du
        v = tv - dv
        for _ in range(int(max_iter)):
            fu, fv, jac = self._map(u, v)
            ru = fu - tu
            rv = fv - tv
            err = np.maximum(np.abs(ru), np.abs(rv))
            det = jac[..., 0, 0] * jac[..., 1, 1] - jac[..., 0, 1] * jac[..., 1, 0]
            # a singular or orientation-reversing Jacobian (also at a converged point):
            # the map folds, so the preimage is not unique or does not exist
            if np.any(~(det > 0)):
                k = np.unravel_index(int(np.argmin(np.where(np.isfinite(det), det, -np.inf))), det.shape)
                raise NonInvertibleDistortionError(
                    f"{type(self).__name__}.inverse: the distortion folds (Jacobian determinant "
                    f"{det[k]:.3g} <= 0) near u_px={u[k]:.6g}, v_px={v[k]:.6g}; "
                    "the coefficients are too strong for this field"
                )
            if err.size == 0 or float(err.max()) < tol:
                return u, v
            step_u = (jac[..., 1, 1] * ru - jac[..., 0, 1] * rv) / det
            step_v = (-jac[..., 1, 0] * ru + jac[..., 0, 0] * rv) / det
            u = u - step_u
            v = v - step_v
        fu, fv, jac = self._map(u, v)
        err = np.maximum(np.abs(fu - tu), np.abs(fv - tv))
        det = jac[..., 0, 0] * jac[..., 1, 1] - jac[..., 0, 1] * jac[..., 1, 0]
        if not np.all((err < tol) & (det > 0)):
            bad = np.where(np.isfinite(err), err, np.inf)
            k = np.unravel_index(int(np.argmax(bad)), err.shape)
            raise NonInvertibleDistortionError(
                f"{type(self).__name__}.inverse: no convergence in {max_iter} Newton steps at "
                f"u_px={tu[k]:.6g}, v_px={tv[k]:.6g} (residual {err[k]:.3g} px > tol_px={tol:g}); "
                "the distortion is too strong to invert in this field"
            )
        return u, v


@dataclass(frozen=True, kw_only=True)
class BrownConradyDistortion(_Distortion):
    """Brown (1966) / Conrady (1919) radial + decentring distortion.

    In normalised coordinates ``x = u / r_norm``, ``y = v / r_norm``, ``r^2 = x^2 + y^2``
    (Brown, D. C., "Decentering distortion of lenses", Photogramm. Eng. 32, 444-462,
    1966, radial terms to ``r^4`` and decentring terms to first order)::

        x' = x (1 + k1 r^2 + k2 r^4) + 2 p1 x y + p2 (r^2 + 2 x^2)
        y' = y (1 + k1 r^2 + k2 r^4) + p1 (r^2 + 2 y^2) + 2 p2 x y

    and ``(u', v') = r_norm (x', y')`` px. ``k1 > 0`` is pincushion (points move
    outward, by ``k1 r^3 r_norm`` px at normalised radius ``r``), ``k1 < 0`` barrel.

    Parameters
    ----------
    k1, k2 : float
        Radial coefficients (dimensionless, per normalised ``r^2`` and ``r^4``).
    p1, p2 : float
        Decentring (tangential) coefficients (dimensionless).
    r_norm_px : float
        Normalising radius in px (> 0).
    """

    k1: float = 0.0
    k2: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    r_norm_px: float = 2048.0

    def __post_init__(self):
        for name in ("k1", "k2", "p1", "p2"):
            object.__setattr__(self, name, _finite_float(name, getattr(self, name)))
        object.__setattr__(self, "r_norm_px", _positive_float("r_norm_px", self.r_norm_px))

    @classmethod
    def identity(cls, *, r_norm_px: float = 2048.0) -> "BrownConradyDistortion":
        """The zero distortion."""
        return cls(r_norm_px=r_norm_px)

    def _map(self, u, v, jacobian=True):
        rn = self.r_norm_px
        k1, k2, p1, p2 = self.k1, self.k2, self.p1, self.p2
        x = u / rn
        y = v / rn
        r2 = x * x + y * y
        radial = 1.0 + k1 * r2 + k2 * r2 * r2
        xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        if not jacobian:
            return xd * rn, yd * rn, None
        dradial = 2.0 * k1 + 4.0 * k2 * r2  # d(radial)/dx = x * dradial
        jac = np.empty(u.shape + (2, 2))
        jac[..., 0, 0] = radial + x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x
        jac[..., 0, 1] = x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y
        jac[..., 1, 0] = x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y
        jac[..., 1, 1] = radial + y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x
        return xd * rn, yd * rn, jac
