"""Lab targets seen through the collimator: the pinhole star grid and the calibration grid.

A pinhole at ``(X, Y)`` mm in the collimator focal plane (focal length ``F``) is seen at
field angle ``tan(theta) = X / F``; the camera (gnomonic projection, focal length ``f``,
pitch ``p``) images it at ``u = (f/p) tan(theta)`` px, i.e. ``u = X/F * rad2arcsec / s`` with
``s`` the plate scale in arcsec/px (exact for a distortion-free camera: the tangents cancel).
The pinhole's finite size is a uniform disc of angular radius ``d / (2F)`` (radians),
``d/(2F) * rad2arcsec / s`` px on the detector.

Marker errors: the pinhole grid's manufacturing error (um, 3 sigma) moves the pinholes
themselves; the calibration grid's calibration error (arcsec, 3 sigma: seed 000's C2)
is an error of the *reference coordinates* the lab believes, not of the pinholes. Both
are drawn once from the scenario seed (a target is a physical object).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simcam.starcam.scenario import Scenario
from simcam.units import ARCSEC_PER_RAD

#: SeedSequence spawn-key roots of the scenario-seed streams (fixed objects)
STREAM_TARGET_MARKERS = 101
STREAM_CALIBRATION_MARKERS = 102


@dataclass(frozen=True)
class TargetLayout:
    """Pinholes of one target placement, in focal-plane px (ideal camera, no distortion).

    Attributes
    ----------
    u_px, v_px : ndarray (W,)
        Where each pinhole images in an ideal (distortion-free, achromatic) camera.
    pinhole_radius_px : float
        Angular radius of a pinhole on the detector, px.
    reference_u_px, reference_v_px : ndarray (W,)
        The coordinates the lab believes (calibrated target); equal to ``u_px, v_px`` for
        the star grid, offset by the marker calibration error for the calibration grid.
    """

    u_px: np.ndarray
    v_px: np.ndarray
    pinhole_radius_px: float
    reference_u_px: np.ndarray
    reference_v_px: np.ndarray

    @property
    def n_stars(self) -> int:
        """Number of pinholes W."""
        return len(self.u_px)


def collimator_px_per_mm(scn: Scenario) -> float:
    """Image scale of the collimator's focal plane on the detector, px per mm."""
    return ARCSEC_PER_RAD / (scn.lab.collimator.focal_length_mm * scn.camera.scale_arcsec_per_px)


def pinhole_radius_px(scn: Scenario, diameter_um: float) -> float:
    """Angular radius of a pinhole of ``diameter_um`` behind the collimator, in px."""
    return 0.5 * diameter_um * 1e-3 * collimator_px_per_mm(scn)


def star_grid(scn: Scenario, *, center_px: tuple[float, float] | None = None) -> TargetLayout:
    """The pinhole star target (seed 000: 5 x 5) centred at ``center_px`` (focal px).

    Pinholes are numbered row by row (``j = row * cols + col``), rows along +v.
    """
    tgt = scn.lab.target
    cu, cv = scn.lab.target_center_px if center_px is None else center_px
    k = collimator_px_per_mm(scn)
    col, row = np.meshgrid(np.arange(tgt.cols), np.arange(tgt.rows))
    x_mm = (col.ravel() - (tgt.cols - 1) / 2.0) * tgt.spacing_mm
    y_mm = (row.ravel() - (tgt.rows - 1) / 2.0) * tgt.spacing_mm
    if tgt.marker_error_3sigma_um > 0:
        rng = np.random.default_rng(np.random.SeedSequence(scn.seed, spawn_key=(STREAM_TARGET_MARKERS,)))
        sig_mm = tgt.marker_error_3sigma_um / 3.0 * 1e-3
        x_mm = x_mm + rng.normal(0.0, sig_mm, x_mm.shape)
        y_mm = y_mm + rng.normal(0.0, sig_mm, y_mm.shape)
    u = cu + x_mm * k
    v = cv + y_mm * k
    return TargetLayout(u, v, pinhole_radius_px(scn, tgt.pinhole_diameter_um), u.copy(), v.copy())


def calibration_grid(scn: Scenario, *, marker_seed: int | None = None) -> TargetLayout:
    """The pre-calibrated grid target (seed 000: 32 points) spanning the mosaic.

    Points sit at the centres of a ``rows x cols`` tiling of ``extent_fraction`` of the
    mosaic's focal-plane extent (so none falls on the optical axis or, for an even number
    of columns, in the gap between two chips). The lab's reference coordinates carry the
    marker calibration error (Gaussian, sigma = 3-sigma value / 3, drawn from the scenario
    seed, or from ``marker_seed`` when a Monte Carlo trial wants a new target), converted
    from arcsec to px with the plate scale.
    """
    cal = scn.lab.calibration_target
    det = scn.detector
    width = det.n_chips * det.chip_cols + (det.n_chips - 1) * det.gap_px
    height = det.chip_rows
    du = width * cal.extent_fraction / cal.cols
    dv = height * cal.extent_fraction / cal.rows
    col, row = np.meshgrid(np.arange(cal.cols), np.arange(cal.rows))
    u = (col.ravel() - (cal.cols - 1) / 2.0) * du
    v = (row.ravel() - (cal.rows - 1) / 2.0) * dv
    sig_px = cal.marker_error_3sigma_arcsec / 3.0 / scn.camera.scale_arcsec_per_px
    root = scn.seed if marker_seed is None else marker_seed
    rng = np.random.default_rng(np.random.SeedSequence(root, spawn_key=(STREAM_CALIBRATION_MARKERS,)))
    eu = rng.normal(0.0, 1.0, u.shape) * sig_px
    ev = rng.normal(0.0, 1.0, v.shape) * sig_px
    return TargetLayout(u, v, pinhole_radius_px(scn, cal.pinhole_diameter_um), u + eu, v + ev)


def platform_offsets_px(
    *, steps: int, step_px: float, direction_deg: float, noise_px: float, seed: int, stream: int
) -> tuple[np.ndarray, np.ndarray]:
    """Image displacements of the hexapod poses of a micro-step sequence (seed 000 fig. 2).

    Pose ``k`` (0-based) displaces the image by ``k * step_px`` along ``direction_deg``
    (from +x toward +y), plus a Gaussian positioning error of rms ``noise_px`` per axis
    drawn from ``SeedSequence(seed, spawn_key=(stream, k))`` (identical for a given pose
    whatever else is rendered).
    """
    k = np.arange(steps, dtype=float)
    ang = np.deg2rad(direction_deg)
    dx = k * step_px * np.cos(ang)
    dy = k * step_px * np.sin(ang)
    if noise_px > 0:
        for i in range(steps):
            rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(stream, i)))
            ex, ey = rng.normal(0.0, noise_px, 2)
            dx[i] += ex
            dy[i] += ey
    return dx, dy
