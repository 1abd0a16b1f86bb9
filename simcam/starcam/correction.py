"""The distortion correction a star camera applies to its own centroids.

A flight star camera reports star positions already corrected by the distortion model of
an earlier calibration; that model carries the errors of its own calibration. The seed-000
LSFE-C1 test (eqs 17-30) is run on such a camera, so the quantity it can measure is the
displacement the *calibrated* camera still makes, not the raw lens distortion.

Model (``optics.distortion_correction``, :class:`simcam.starcam.instrument.DistortionCorrectionModel`):
at the points ``p_i`` of an earlier calibration grid, the camera's measured position
(mosaic px) of the lamp's image is ``m_i = M(D(p_i) + s_lamp(D(p_i)))`` (``D`` the
distortion, ``s_lamp`` the lamp-weighted lateral colour, ``M`` focal plane to mosaic),
measured with centroid noise ``n_i``; the reference is ``M(p_i)`` plus a marker error
``e_i``. The displacement ``d_i = m_i + n_i - M(p_i) - e_i`` is fitted by least squares
with a full bivariate polynomial of total degree ``order`` in the normalised measured
coordinates (``c(x, y) = sum_{a+b<=order} c_ab x^a y^b``; ordinary least squares, e.g.
Draper & Smith, Applied Regression Analysis, ch. 2). The camera reports
``(x, y) - c(x, y)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simcam.starcam import optics

#: SeedSequence spawn-key root of the earlier calibration's errors (of the camera's
#: ``calibration_seed``: the scenario seed, or the instrument's drawn per trial)
STREAM_ONBOARD_CALIBRATION = 103


def poly_design(x, y, order: int) -> np.ndarray:
    """Full bivariate polynomial basis of total degree ``order``: ``x^a y^b``, ``a + b <= order``."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    cols = [x**a * y ** (d - a) for d in range(order + 1) for a in range(d, -1, -1)]
    return np.column_stack(cols)


@dataclass(frozen=True)
class OnboardCorrection:
    """A fitted distortion correction ``c(x, y)`` (mosaic px), applied as ``(x, y) - c``.

    Attributes
    ----------
    order : total degree of the polynomial.
    center_x, center_y, half_x, half_y : normalisation of the mosaic coordinates.
    coef_x, coef_y : coefficients (px) of :func:`poly_design`.
    points_x, points_y : the calibration points' measured mosaic coordinates (px).
    """

    order: int
    center_x: float
    center_y: float
    half_x: float
    half_y: float
    coef_x: np.ndarray
    coef_y: np.ndarray
    points_x: np.ndarray
    points_y: np.ndarray

    def correction_px(self, x, y):
        """``c_x(x, y), c_y(x, y)`` at mosaic px (the displacement the camera removes)."""
        b = poly_design((np.asarray(x, float) - self.center_x) / self.half_x,
                        (np.asarray(y, float) - self.center_y) / self.half_y, self.order)
        return b @ self.coef_x, b @ self.coef_y

    def apply(self, x, y):
        """The positions the camera reports for measured mosaic positions ``x, y``."""
        cx, cy = self.correction_px(x, y)
        return np.asarray(x, float) - cx, np.asarray(y, float) - cy


def lamp_image_focal_px(camera, u_px, v_px):
    """Where the lab lamp (no filter) images the ideal focal point ``(u, v)``: distortion
    then the lamp-weighted lateral colour (focal px), as :meth:`simcam.starcam.render.StarCamera.scene`
    places an image."""
    scn = camera.scenario
    lc = scn.optics.lateral_colour
    ud, vd = camera.distortion.forward(u_px=np.asarray(u_px, float), v_px=np.asarray(v_px, float))
    wl, rate = camera.spectra.electron_rate_per_nm(filter_nm=None)
    w = camera.spectra.weights(rate)
    su, sv = optics.lateral_colour_shift_px(
        wavelength_nm=wl, u_px=ud, v_px=vd, ref_wavelength_nm=lc.ref_wavelength_nm,
        radial_coeffs=tuple(lc.radial_px_per_nm), uniform_x_coeffs=tuple(lc.uniform_x_px_per_nm),
        uniform_y_coeffs=tuple(lc.uniform_y_px_per_nm), r_norm_px=scn.optics.r_norm_px)
    return ud + su @ w, vd + sv @ w


def fit_onboard_correction(camera) -> OnboardCorrection | None:
    """The camera's correction from its earlier calibration (None for ``kind = "none"``): the
    scenario's calibration design, its errors drawn from the camera's ``calibration_seed``."""
    scn = camera.scenario
    cfg = scn.optics.distortion_correction
    if cfg.kind == "none":
        return None
    det = scn.detector
    width = det.n_chips * det.chip_cols + (det.n_chips - 1) * det.gap_px
    du = width * cfg.extent_fraction / cfg.cols
    dv = det.chip_rows * cfg.extent_fraction / cfg.rows
    col, row = np.meshgrid(np.arange(cfg.cols), np.arange(cfg.rows))
    u = (col.ravel() - (cfg.cols - 1) / 2.0) * du
    v = (row.ravel() - (cfg.rows - 1) / 2.0) * dv
    mu, mv = lamp_image_focal_px(camera, u, v)
    _, mx, my = camera.mosaic.focal_to_mosaic(mu, mv)
    _, rx, ry = camera.mosaic.focal_to_mosaic(u, v)
    ok = np.isfinite(mx) & np.isfinite(rx)
    ss = np.random.SeedSequence(camera.calibration_seed, spawn_key=(STREAM_ONBOARD_CALIBRATION,))
    rng = np.random.default_rng(ss)
    marker = cfg.marker_error_3sigma_arcsec / 3.0 / scn.camera.scale_arcsec_per_px
    z = rng.standard_normal((4, u.size))
    mx_meas = mx + cfg.centroid_noise_px * z[0]
    my_meas = my + cfg.centroid_noise_px * z[1]
    rx_ref = rx + marker * z[2]
    ry_ref = ry + marker * z[3]
    mx_meas, my_meas, rx_ref, ry_ref = mx_meas[ok], my_meas[ok], rx_ref[ok], ry_ref[ok]
    cx0, cy0 = float(mx_meas.mean()), float(my_meas.mean())
    hx = float(max(np.abs(mx_meas - cx0).max(), 1e-300))
    hy = float(max(np.abs(my_meas - cy0).max(), 1e-300))
    a = poly_design((mx_meas - cx0) / hx, (my_meas - cy0) / hy, cfg.order)
    coef_x, *_ = np.linalg.lstsq(a, mx_meas - rx_ref, rcond=None)
    coef_y, *_ = np.linalg.lstsq(a, my_meas - ry_ref, rcond=None)
    return OnboardCorrection(order=cfg.order, center_x=cx0, center_y=cy0, half_x=hx, half_y=hy,
                             coef_x=coef_x, coef_y=coef_y, points_x=mx_meas, points_y=my_meas)
