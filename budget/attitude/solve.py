"""The attitude of a star camera from its centroids: weighted least squares on the sphere.

What a real camera gives is what this takes: star centroids in mosaic pixels (as the camera
reports them, its onboard distortion correction applied or not), their 1-sigma errors, the
camera model (:class:`CameraModel`: plate scale, chip layout, Brown-Conrady distortion left
to remove) and the inertial directions of the identified stars (their apparent places).
Nothing here knows a simulator.

Equations (docs/attitude.md):

* **Pixels to directions.** Mosaic ``(x, y)`` to chip ``k = floor((x + 1/2) / cols)`` and focal
  ``(u, v) = c_k + R(theta_k) (x_k - x_0, y_k - y_0)`` (docs/conventions.md); the distortion
  removed, ``(u, v) <- D^-1(u, v)`` (Newton, :class:`simcam.distortion.BrownConradyDistortion`);
  the camera-frame unit vector ``b = (u, v, F) / |(u, v, F)|``, ``F = 206264.8 / s`` px
  (gnomonic projection; frames as in :mod:`simcam.starcam.sky_view`: ``+z`` the boresight,
  ``+x`` toward ``+u``, ``+y`` toward ``+v``).
* **Wahba's problem** (Wahba 1965, SIAM Rev. 7, 409): the rotation ``C`` (camera to inertial)
  minimising ``1/2 sum_i w_i |a_i - C b_i|^2`` with ``a_i`` the catalogue directions and
  ``w_i = 1 / sigma_i^2`` (``sigma_i`` the star's angular error per axis, ``s`` times its
  centroid error in px), solved by :meth:`scipy.spatial.transform.Rotation.align_vectors`
  (SVD, Markley 1988, J. Astronaut. Sci. 36, 245).
* **Covariance.** scipy's sensitivity matrix ``S`` (of the small rotation vector of the
  inertial frame) times the harmonic mean of the per-star variances,
  ``P = S N / sum_i sigma_i^-2`` (scipy's documentation of ``align_vectors``; Markley 1993,
  J. Astronaut. Sci. 41, 261): for weights ``1 / sigma_i^2`` this equals the least-squares
  covariance ``[sum_i sigma_i^-2 (I - b_i b_i^T)]^-1`` (tested).
* **Attitude error** (:func:`attitude_error`): the rotation ``E = C_solved^-1 C_true`` (camera
  frame) as its rotation vector ``delta``; the solved attitude moves the field in the detector
  by ``delta x b``, so the cross-boresight error along the detector's x (u) and y (v) axes
  is ``(delta_y, -delta_x)`` and the roll about the boresight (from +u toward +v) ``delta_z``,
  in arcsec. A centroid offset of ``+d`` px in x, common to every star, is an error of about
  ``+d s`` arcsec in x.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from simcam.distortion import BrownConradyDistortion
from simcam.infra.errors import UserInputError
from simcam.units import ARCSEC_PER_RAD

__all__ = ["AttitudeError", "AttitudeSolution", "CameraModel", "attitude_error", "camera_directions",
           "component_covariance", "focal_from_mosaic", "solve_attitude"]

#: camera-frame rotation vector delta -> (x, y, roll): x = delta_y, y = -delta_x, roll = delta_z
_TO_COMPONENTS = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def _tuple(name: str, values, n: int) -> tuple[float, ...]:
    arr = np.asarray(values, dtype=np.float64).ravel()
    if arr.size != n or not np.isfinite(arr).all():
        raise UserInputError(f"{name}: expected {n} finite values (one per chip), got {list(np.ravel(values))}")
    return tuple(float(v) for v in arr)


@dataclass(frozen=True)
class CameraModel:
    """A star camera's geometry as its user knows it (all lengths in px unless named).

    Attributes
    ----------
    plate_scale_arcsec : float
        Arcsec per px at the centre (``206264.8 p / f``; :meth:`from_focal_length`).
    n_chips, chip_cols, chip_rows : int
        The mosaic: chips side by side along ``u``, each ``chip_cols x chip_rows``.
    gap_px : float
        Gap between neighbouring chips.
    chip_offset_u_px, chip_offset_v_px, chip_rotation_deg : tuple of float
        Each chip's offset from its nominal centre ``((k - (n-1)/2)(cols + gap), 0)`` and its
        rotation (from +u toward +v).
    k1, k2, p1, p2 : float
        Brown-Conrady distortion still in the centroids, normalised by ``r_norm_px`` (all 0
        for a camera that reports distortion-corrected centroids).
    r_norm_px : float
        Normalising radius of the distortion coefficients.
    """

    plate_scale_arcsec: float
    n_chips: int
    chip_cols: int
    chip_rows: int
    gap_px: float
    chip_offset_u_px: tuple[float, ...]
    chip_offset_v_px: tuple[float, ...]
    chip_rotation_deg: tuple[float, ...]
    k1: float
    k2: float
    p1: float
    p2: float
    r_norm_px: float

    def __post_init__(self):
        s = float(self.plate_scale_arcsec)
        if not math.isfinite(s) or s <= 0.0:
            raise UserInputError(f"plate_scale_arcsec: must be finite and > 0, got {self.plate_scale_arcsec!r}")
        for name in ("n_chips", "chip_cols", "chip_rows"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise UserInputError(f"{name}: must be an integer >= 1, got {v!r}")
        g = float(self.gap_px)
        if not math.isfinite(g) or g < 0.0:
            raise UserInputError(f"gap_px: must be finite and >= 0, got {self.gap_px!r}")
        for name in ("chip_offset_u_px", "chip_offset_v_px", "chip_rotation_deg"):
            object.__setattr__(self, name, _tuple(name, getattr(self, name), self.n_chips))
        for name in ("k1", "k2", "p1", "p2"):
            if not math.isfinite(float(getattr(self, name))):
                raise UserInputError(f"{name}: must be finite, got {getattr(self, name)!r}")
        if not math.isfinite(float(self.r_norm_px)) or float(self.r_norm_px) <= 0.0:
            raise UserInputError(f"r_norm_px: must be finite and > 0, got {self.r_norm_px!r}")

    @classmethod
    def from_focal_length(cls, *, focal_length_mm: float, pixel_pitch_um: float, **geometry) -> CameraModel:
        """The model with the plate scale ``206264.8 p / f`` of a focal length and pixel pitch
        (``geometry``: the other fields)."""
        f, p = float(focal_length_mm), float(pixel_pitch_um)
        if not (math.isfinite(f) and f > 0.0):
            raise UserInputError(f"focal_length_mm: must be finite and > 0, got {focal_length_mm!r}")
        if not (math.isfinite(p) and p > 0.0):
            raise UserInputError(f"pixel_pitch_um: must be finite and > 0, got {pixel_pitch_um!r}")
        return cls(plate_scale_arcsec=ARCSEC_PER_RAD * p * 1e-3 / f, **geometry)

    @property
    def focal_length_px(self) -> float:
        """Focal length in px, ``206264.8 / plate_scale_arcsec``."""
        return ARCSEC_PER_RAD / self.plate_scale_arcsec

    @property
    def has_distortion(self) -> bool:
        """Whether any distortion coefficient is non-zero."""
        return any(getattr(self, k) != 0.0 for k in ("k1", "k2", "p1", "p2"))


def _floats(name: str, values, n: int | None = None) -> np.ndarray:
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim != 1 or (n is not None and arr.size != n):
        want = "a 1-D array" if n is None else f"{n} values"
        raise UserInputError(f"{name}: expected {want}, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise UserInputError(f"{name}: must be finite (star {int(np.flatnonzero(~np.isfinite(arr))[0])} is not)")
    return arr


def focal_from_mosaic(x_px, y_px, camera: CameraModel) -> tuple[np.ndarray, np.ndarray]:
    """Focal-plane ``(u, v)`` px of mosaic centroids ``(x, y)`` px, distortion removed."""
    x = _floats("x_px", x_px)
    y = _floats("y_px", y_px, x.size)
    cols = camera.chip_cols
    chip = np.floor((x + 0.5) / cols).astype(np.int64)
    bad = (chip < 0) | (chip >= camera.n_chips)
    if bad.any():
        j = int(np.flatnonzero(bad)[0])
        raise UserInputError(f"x_px: star {j} at x = {x[j]:.2f} px is off the mosaic "
                             f"(-0.5 <= x < {camera.n_chips * cols - 0.5})")
    n = camera.n_chips
    cu = (np.arange(n) - (n - 1) / 2.0) * (cols + camera.gap_px) + np.array(camera.chip_offset_u_px)
    cv = np.array(camera.chip_offset_v_px)
    th = np.radians(np.array(camera.chip_rotation_deg))
    dx = x - chip * cols - (cols - 1) / 2.0
    dy = y - (camera.chip_rows - 1) / 2.0
    c, s = np.cos(th[chip]), np.sin(th[chip])
    u = cu[chip] + c * dx - s * dy
    v = cv[chip] + s * dx + c * dy
    if camera.has_distortion:
        d = BrownConradyDistortion(k1=camera.k1, k2=camera.k2, p1=camera.p1, p2=camera.p2,
                                   r_norm_px=camera.r_norm_px)
        u, v = d.inverse(u_px=u, v_px=v)
    return u, v


def camera_directions(x_px, y_px, camera: CameraModel) -> np.ndarray:
    """Camera-frame unit vectors (N, 3) of mosaic centroids (gnomonic projection)."""
    u, v = focal_from_mosaic(x_px, y_px, camera)
    b = np.column_stack([u, v, np.full(u.size, camera.focal_length_px)])
    return b / np.linalg.norm(b, axis=1, keepdims=True)


def component_covariance(covariance_inertial, attitude: Rotation) -> np.ndarray:
    """A covariance of the inertial frame's small rotation vector (3x3, rad^2) as that of the
    error components (x, y, roll) of :func:`attitude_error` (3x3, arcsec^2)."""
    m = _TO_COMPONENTS @ attitude.as_matrix().T
    return m @ np.asarray(covariance_inertial, float) @ m.T * ARCSEC_PER_RAD**2


@dataclass(frozen=True)
class AttitudeSolution:
    """A solved attitude (:func:`solve_attitude`).

    Attributes
    ----------
    attitude : Rotation
        Camera frame to inertial.
    covariance_arcsec2 : ndarray (3, 3)
        Covariance of the error components (x, y, roll) of :func:`attitude_error`, arcsec^2.
    covariance_inertial_rad2 : ndarray (3, 3)
        The same as the small rotation vector of the inertial frame (scipy's convention), rad^2.
    residual_u_arcsec, residual_v_arcsec : ndarray (N,)
        Per star: measured minus solved direction in the focal plane's tangent axes (u, v).
    chi2 : float
        ``sum_i |residual_i|^2 / sigma_i^2`` (2N - 3 degrees of freedom when the errors are as stated).
    """

    attitude: Rotation
    covariance_arcsec2: np.ndarray
    covariance_inertial_rad2: np.ndarray
    residual_u_arcsec: np.ndarray
    residual_v_arcsec: np.ndarray
    chi2: float

    @property
    def n_stars(self) -> int:
        """Stars in the solution."""
        return int(self.residual_u_arcsec.size)

    @property
    def sigma_arcsec(self) -> np.ndarray:
        """1-sigma of (x, y, roll), arcsec."""
        return np.sqrt(np.diag(self.covariance_arcsec2))


def solve_attitude(x_px, y_px, sigma_px, directions, camera: CameraModel) -> AttitudeSolution:
    """The attitude that best aligns the stars' measured and catalogue directions (module docstring).

    Parameters
    ----------
    x_px, y_px : array (N,)
        Centroids in mosaic px.
    sigma_px : float or array (N,)
        1-sigma centroid error per axis, px (> 0): the weights ``1 / sigma^2``.
    directions : array (N, 3)
        Inertial directions of the identified stars (any length; normalised here).
    camera : CameraModel
        The camera's geometry.
    """
    x = _floats("x_px", x_px)
    n = x.size
    if n < 2:
        raise UserInputError(f"x_px: an attitude needs at least 2 stars, got {n}")
    sig = np.broadcast_to(np.asarray(sigma_px, dtype=np.float64), (n,)) if np.ndim(sigma_px) == 0 \
        else _floats("sigma_px", sigma_px, n)
    if not (np.isfinite(sig).all() and (sig > 0.0).all()):
        raise UserInputError(f"sigma_px: must be finite and > 0, got {np.asarray(sigma_px)!r}")
    a = np.asarray(directions, dtype=np.float64)
    if a.shape != (n, 3) or not np.isfinite(a).all():
        raise UserInputError(f"directions: expected {n} finite 3-vectors, got shape {a.shape}")
    norm = np.linalg.norm(a, axis=1, keepdims=True)
    if (norm == 0.0).any():
        raise UserInputError(f"directions: star {int(np.flatnonzero(norm[:, 0] == 0.0)[0])} is the zero vector")
    a = a / norm
    b = camera_directions(x, y_px, camera)
    var_rad2 = (sig * camera.plate_scale_arcsec / ARCSEC_PER_RAD) ** 2
    rot, _, sens = Rotation.align_vectors(a, b, weights=1.0 / var_rad2, return_sensitivity=True)
    cov_inertial = sens * (n / np.sum(1.0 / var_rad2))
    p = rot.inv().apply(a)
    du = (b[:, 0] / b[:, 2] - p[:, 0] / p[:, 2]) * ARCSEC_PER_RAD
    dv = (b[:, 1] / b[:, 2] - p[:, 1] / p[:, 2]) * ARCSEC_PER_RAD
    sig_arcsec = sig * camera.plate_scale_arcsec
    return AttitudeSolution(attitude=rot, covariance_arcsec2=component_covariance(cov_inertial, rot),
                            covariance_inertial_rad2=cov_inertial, residual_u_arcsec=du, residual_v_arcsec=dv,
                            chi2=float(np.sum((du**2 + dv**2) / sig_arcsec**2)))


@dataclass(frozen=True)
class AttitudeError:
    """A solved attitude against the true one (:func:`attitude_error`), arcsec: the
    cross-boresight error along the detector's x (u) and y (v) axes and the roll about the
    boresight (from +u toward +v); arrays for a stack of rotations."""

    x_arcsec: np.ndarray | float
    y_arcsec: np.ndarray | float
    roll_arcsec: np.ndarray | float


def attitude_error(solved: Rotation, true: Rotation) -> AttitudeError:
    """The error of ``solved`` against ``true`` (module docstring): ``delta`` the rotation
    vector of ``solved^-1 true``, returned as ``(delta_y, -delta_x, delta_z)`` in arcsec."""
    d = (solved.inv() * true).as_rotvec() * ARCSEC_PER_RAD
    comp = d @ _TO_COMPONENTS.T
    if comp.ndim == 1:
        return AttitudeError(float(comp[0]), float(comp[1]), float(comp[2]))
    return AttitudeError(comp[:, 0], comp[:, 1], comp[:, 2])
