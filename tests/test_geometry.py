"""Mosaic geometry and target layouts against hand-computed positions."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from simcam.starcam.geometry import Mosaic
from simcam.starcam.scenario import default, with_updates
from simcam.starcam.targets import calibration_grid, collimator_px_per_mm, pinhole_radius_px, platform_offsets_px, star_grid
from simcam.units import ARCSEC_PER_RAD


def test_nominal_mosaic_centres_and_gap():
    det = default().detector  # 2 chips of 2048, gap 20 px
    m = Mosaic.from_model(det)
    np.testing.assert_allclose(m.center_u_px, [-(2048 + 20) / 2, (2048 + 20) / 2])
    # the optical axis (u = 0) is in the gap
    chip, _, _ = m.focal_to_chip(0.0, 0.0)
    assert chip[0] == -1
    # chip 0's pixel centre (0, 0) sits at u = -1034 - 1023.5, v = -1023.5
    u, v = m.chip_to_focal(np.array([0]), np.array([0.0]), np.array([0.0]))
    assert u[0] == pytest.approx(-1034 - 1023.5) and v[0] == pytest.approx(-1023.5)
    # chip 1's first column is mosaic column 2048
    chip, x, y = m.focal_to_mosaic(1034 - 1023.5, 0.0)
    assert chip[0] == 1 and x[0] == pytest.approx(2048.0) and y[0] == pytest.approx(1023.5)


@settings(max_examples=60, deadline=None)
@given(
    u=st.floats(-2000, 2000), v=st.floats(-1000, 1000),
    off=st.floats(-3, 3), rot=st.floats(-0.5, 0.5),
)
def test_focal_chip_round_trip(u, v, off, rot):
    scn = with_updates(default(), {"detector.chips": [
        {"offset_x_px": off, "offset_y_px": -off, "rotation_deg": rot}, {"rotation_deg": -rot}]})
    m = Mosaic.from_model(scn.detector)
    chip, xc, yc = m.focal_to_chip(u, v)
    if chip[0] < 0:
        return
    uu, vv = m.chip_to_focal(chip, xc, yc)
    assert uu[0] == pytest.approx(u, abs=1e-9) and vv[0] == pytest.approx(v, abs=1e-9)
    x = m.chip_to_mosaic_x(chip, xc)
    u2, v2 = m.mosaic_to_focal(x, yc)
    assert u2[0] == pytest.approx(u, abs=1e-9) and v2[0] == pytest.approx(v, abs=1e-9)


def test_chip_offset_and_rotation_directions():
    scn = with_updates(default(), {"detector.chips": [
        {"offset_x_px": 2.0, "offset_y_px": 1.0}, {"rotation_deg": 90.0}]})
    m = Mosaic.from_model(scn.detector)
    # chip 0 displaced by +2 px in u: a fixed focal point lands 2 px lower in chip x
    nominal = Mosaic.from_model(default().detector)
    _, x0, y0 = nominal.focal_to_chip(-1000.0, 10.0)
    _, x1, y1 = m.focal_to_chip(-1000.0, 10.0)
    assert x1[0] - x0[0] == pytest.approx(-2.0) and y1[0] - y0[0] == pytest.approx(-1.0)
    # chip 1 rotated +90 deg (from +u toward +v): its +x axis points along focal +v
    c = m.center_u_px[1]
    _, xa, ya = m.focal_to_chip(c, 100.0)
    assert xa[0] - 1023.5 == pytest.approx(100.0) and ya[0] - 1023.5 == pytest.approx(0.0, abs=1e-9)
    dx, dy = m.vector_to_chip(np.array([0.0]), np.array([1.0]), np.array([1]))
    assert dx[0] == pytest.approx(1.0) and dy[0] == pytest.approx(0.0, abs=1e-12)


def test_star_grid_spacing_from_collimator():
    scn = default()
    # 2 mm at a 1000 mm collimator = 2e-3 rad = 412.53" -> / 5.5"/px = 75.0 px
    k = collimator_px_per_mm(scn)
    assert k == pytest.approx(ARCSEC_PER_RAD / 1000.0 / 5.5)
    lay = star_grid(scn)
    assert lay.n_stars == 25
    du = np.diff(lay.u_px.reshape(5, 5), axis=1)
    np.testing.assert_allclose(du, 2.0 * k)
    assert lay.u_px.mean() == pytest.approx(scn.lab.target_center_px[0])
    # a 15 um pinhole subtends 15e-3/1000 rad: radius 7.5e-6 rad = 1.547" = 0.281 px
    assert pinhole_radius_px(scn, 15.0) == pytest.approx(7.5e-6 * ARCSEC_PER_RAD / 5.5)


def test_calibration_grid_32_points_with_marker_error():
    scn = default()
    lay = calibration_grid(scn)
    assert lay.n_stars == 32
    err = np.concatenate([lay.reference_u_px - lay.u_px, lay.reference_v_px - lay.v_px])
    sigma_px = 0.5 / 3 / 5.5
    # 64 draws of N(0, sigma): the sample std lies within +-4 standard errors sigma/sqrt(2*63)
    assert abs(err.std(ddof=1) - sigma_px) < 4 * sigma_px / np.sqrt(2 * 63)
    # no point in the gap or off the detector
    m = Mosaic.from_model(scn.detector)
    chip, _, _ = m.focal_to_chip(lay.u_px, lay.v_px, margin_px=16)
    assert np.all(chip >= 0)
    # the marker error is fixed by the scenario seed
    np.testing.assert_array_equal(calibration_grid(scn).reference_u_px, lay.reference_u_px)


def test_platform_steps_along_45_degrees():
    dx, dy = platform_offsets_px(steps=12, step_px=0.2, direction_deg=45.0, noise_px=0.0, seed=1, stream=5)
    np.testing.assert_allclose(np.hypot(np.diff(dx), np.diff(dy)), 0.2)
    np.testing.assert_allclose(dx, dy)
    assert dx[0] == 0.0 and dx[1] > 0  # pose 0 is 0 * step without noise: exactly zero by construction
    ex, ey = platform_offsets_px(steps=12, step_px=0.2, direction_deg=45.0, noise_px=0.01, seed=1, stream=5)
    ex2, _ = platform_offsets_px(steps=4, step_px=0.2, direction_deg=45.0, noise_px=0.01, seed=1, stream=5)
    np.testing.assert_array_equal(ex[:4], ex2)  # pose k's error does not depend on the sequence length
    assert np.all(ex != dx)
