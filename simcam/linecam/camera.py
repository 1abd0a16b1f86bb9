"""The TDI line camera of the world: interior orientation, exterior misalignment, and the
forward (direction -> focal plane) and inverse (focal plane -> direction) camera models.

Frames and conventions (seed 004, reconstructed in docs/linecam.md):

* **camera frame**: ``+z`` opposite to the boresight (the camera looks along ``-z``),
  ``x`` along track (the scan direction, across the line), ``y`` along the line. A point of
  the focal plane at image coordinates ``(x, y)`` (mm, origin at the nominal principal
  point) sees the direction of the image vector ``(x - x0 - Dx, y - y0 - Dy, -f)``
  (the collinearity equations, step 1.1 / step 5 of the patent, reconstructed).
* **the line**: ``n_pixels`` detectors at ``x = x_line_mm`` and
  ``y = (s - (n_pixels - 1) / 2) * pitch`` for sample ``s`` (pixel centres at integers,
  ``docs/conventions.md``); the TDI stages extend it along ``x`` (one pitch per stage).
* **interior errors** (true values of the world): principal point ``(x0, y0)`` (mm),
  principal distance ``f_true = f + df``, Brown (1971) radial ``k1, k2`` and decentring
  ``p1, p2`` in the photogrammetric form of the patent (the correction of *measured*
  coordinates, ``x_ideal = x' - Dx(x', y')``), normalised by ``r_n`` = half the line
  length:
  ``Dx = r_n [k1 X r^2 + k2 X r^4 + p1 (r^2 + 2 X^2) + 2 p2 X Y]``,
  ``Dy = r_n [k1 Y r^2 + k2 Y r^4 + p2 (r^2 + 2 Y^2) + 2 p1 X Y]``, ``X = x'/r_n``,
  ``Y = y'/r_n``, ``x' = x - x0``.
  The world evaluates this through :class:`simcam.distortion.BrownConradyDistortion`, whose
  ``forward`` with coefficients ``(-k1, -k2, -p2, -p1)`` is exactly ``x' -> x' - Dx``
  (its ``p1``/``p2`` are the OpenCV ones, swapped against Brown's photogrammetric
  convention), and whose tested Newton ``inverse`` gives the measured coordinates of an
  ideal image point (the forward camera model).
* **exterior misalignment** ``R_u`` (camera -> body): a rotation vector
  ``(roll, pitch, yaw)`` about camera ``x, y, z`` (the Euler order of the patent is lost;
  all orders agree to first order, so a rotation vector is used).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from simcam.distortion import BrownConradyDistortion
from simcam.units import ARCSEC_PER_RAD

from .effects import extra_distortion_px
from .scenario import PARAMETERS, LineCamScenario

__all__ = ["CameraTruth", "camera_truth", "sample_y_mm"]


def sample_y_mm(sample, *, n_pixels: int, pitch_mm: float) -> np.ndarray:
    """Focal-plane ``y`` (mm) of sample ``s``: ``(s - (n - 1)/2) p``."""
    return (np.asarray(sample, dtype=float) - 0.5 * (n_pixels - 1)) * pitch_mm


@dataclass(frozen=True)
class CameraTruth:
    """The true camera: nominal geometry plus injected interior and exterior errors.

    Parameters
    ----------
    focal_length_mm, pitch_mm : float
        Nominal principal distance and pixel pitch, mm.
    n_pixels : int
        Detectors along the line.
    x_line_mm : float
        Along-track focal-plane position of the line (TDI centre), mm.
    params : numpy.ndarray, shape (10,)
        Injected errors in the order of :data:`PARAMETERS`: roll, pitch, yaw (rad),
        dx0, dy0 (px), df (mm), k1, k2, p1, p2 (normalised by ``n_pixels / 2`` px).
    """

    focal_length_mm: float
    pitch_mm: float
    n_pixels: int
    x_line_mm: float
    params: np.ndarray
    #: distortion outside the Brown family (world effects, :func:`simcam.linecam.effects.extra_distortion_px`):
    #: k3 r^6 and thin prism, displacement at the line's end, px; 0 = none
    k3_edge_px: float = 0.0
    prism_edge_px: float = 0.0

    @property
    def has_extra_distortion(self) -> bool:
        return self.k3_edge_px != 0.0 or self.prism_edge_px != 0.0

    def extra_distortion(self, u_px, v_px):
        """The correction beyond Brown ``(Ex, Ey)``, px, at measured ``(x', y')`` px."""
        return extra_distortion_px(u_px, v_px, k3_edge_px=self.k3_edge_px, prism_edge_px=self.prism_edge_px,
                                   r_norm_px=0.5 * self.n_pixels)

    @property
    def f_true_mm(self) -> float:
        return self.focal_length_mm + float(self.params[5])

    @property
    def principal_point_mm(self) -> tuple[float, float]:
        return float(self.params[3]) * self.pitch_mm, float(self.params[4]) * self.pitch_mm

    @property
    def misalignment(self) -> Rotation:
        """``R_u``: camera -> body."""
        return Rotation.from_rotvec(np.asarray(self.params[:3], dtype=float))

    @property
    def distortion(self) -> BrownConradyDistortion:
        """Brown's correction as :class:`BrownConradyDistortion` in mm-free px units:
        ``forward`` maps measured ``x'`` (px) to ideal ``x' - Dx`` (px)."""
        k1, k2, p1, p2 = (float(v) for v in self.params[6:10])
        return BrownConradyDistortion(k1=-k1, k2=-k2, p1=-p2, p2=-p1,
                                      r_norm_px=0.5 * self.n_pixels)

    # ------------------------------------------------------------------ models
    def focal_plane(self, d_cam) -> tuple[np.ndarray, np.ndarray]:
        """Forward model: measured focal-plane ``(x, y)`` (mm) of camera-frame directions.

        Pinhole (collinearity) ``x_ideal = -f_true d_x / d_z`` then the inverse of Brown's
        correction (Newton, :meth:`BrownConradyDistortion.inverse`), then the principal
        point.

        Parameters
        ----------
        d_cam : array_like, shape (..., 3)
            Directions in the true camera frame (``d_z < 0`` in front of the camera).
        """
        d = np.asarray(d_cam, dtype=float)
        xi = -self.f_true_mm * d[..., 0] / d[..., 2]
        yi = -self.f_true_mm * d[..., 1] / d[..., 2]
        p = self.pitch_mm
        um, vm = self.distortion.inverse(u_px=xi / p, v_px=yi / p, tol_px=1e-9)
        if self.has_extra_distortion:
            # x_ideal = x' - D(x') - E(x'): fixed point x' = D^-1(x_ideal + E(x')); E changes by
            # |grad E| < 1e-3 px/px, so each iteration gains 3 digits
            for _ in range(6):
                ex, ey = self.extra_distortion(um, vm)
                um, vm = self.distortion.inverse(u_px=xi / p + ex, v_px=yi / p + ey, tol_px=1e-9)
        x0, y0 = self.principal_point_mm
        return um * p + x0, vm * p + y0

    def direction(self, x_mm, y_mm) -> np.ndarray:
        """Inverse model: unit camera-frame direction seen at focal-plane ``(x, y)`` mm.

        ``d ~ (x' - Dx, y' - Dy, -f_true)`` with ``x' = x - x0`` (step 5, reconstructed).
        """
        x0, y0 = self.principal_point_mm
        p = self.pitch_mm
        ui, vi = self.distortion.forward(u_px=(np.asarray(x_mm, float) - x0) / p,
                                         v_px=(np.asarray(y_mm, float) - y0) / p)
        if self.has_extra_distortion:
            ex, ey = self.extra_distortion((np.asarray(x_mm, float) - x0) / p, (np.asarray(y_mm, float) - y0) / p)
            ui, vi = ui - ex, vi - ey
        v = np.stack([ui * p, vi * p, np.full(np.shape(ui), -self.f_true_mm)], axis=-1)
        return v / np.linalg.norm(v, axis=-1, keepdims=True)

    def body_direction(self, x_mm, y_mm) -> np.ndarray:
        """Direction in the body (nominal camera) frame: ``R_u d``."""
        d = self.direction(x_mm, y_mm)
        return self.misalignment.apply(d.reshape(-1, 3)).reshape(d.shape)

    def los_angles(self, sample) -> tuple[np.ndarray, np.ndarray]:
        """True line-of-sight field: along- and across-track look angles (rad) of the
        detectors ``sample`` in the body frame, ``atan2(L_x, -L_z)`` and ``atan2(L_y, -L_z)``."""
        y = sample_y_mm(sample, n_pixels=self.n_pixels, pitch_mm=self.pitch_mm)
        L = self.body_direction(np.full(y.shape, self.x_line_mm), y)
        return np.arctan2(L[..., 0], -L[..., 2]), np.arctan2(L[..., 1], -L[..., 2])


def camera_truth(scenario: LineCamScenario, params) -> CameraTruth:
    """The true camera of a scenario with injected ``params`` (order of :data:`PARAMETERS`)."""
    cam = scenario.camera
    p = np.asarray(params, dtype=float)
    if p.shape != (len(PARAMETERS),):
        raise ValueError(f"params: expected {len(PARAMETERS)} values")
    fx = scenario.world.effects
    return CameraTruth(focal_length_mm=cam.focal_length_mm, pitch_mm=cam.pitch_mm,
                       n_pixels=cam.n_pixels, x_line_mm=cam.x_line_mm, params=p,
                       k3_edge_px=fx.distortion_k3_edge_px, prism_edge_px=fx.thin_prism_edge_px)


def draw_errors(scenario: LineCamScenario, rng: np.random.Generator) -> np.ndarray:
    """Injected errors of one trial, order of :data:`PARAMETERS` (angles in rad)."""
    e = scenario.errors
    vals = []
    for name in e.FIELDS:
        dist = getattr(e, name)
        v = dist.value + dist.sigma * rng.standard_normal()
        if name.endswith("_arcsec"):
            v /= ARCSEC_PER_RAD
        vals.append(v)
    return np.array(vals)
