"""Tests of the distortion models in simcam.starcam.optics: analytic formulas written out by
hand, finite-difference Jacobians, Newton inverses and sign conventions."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from simcam.starcam.optics import (
    CUBIC_MONOMIALS,
    BrownConradyDistortion,
    CompositeDistortion,
    CubicDistortion,
    HigherOrderRadialDistortion,
    NonInvertibleDistortionError,
    OpticsError,
)

R_NORM = 2048.0
# a 4096 x 2048 px focal plane centred on the optical axis
U_FIELD = st.floats(min_value=-2048.0, max_value=2048.0, allow_nan=False)
V_FIELD = st.floats(min_value=-1024.0, max_value=1024.0, allow_nan=False)


def realistic_composite(k1=0.02, k2=-0.004, p1=3e-4, p2=-2e-4, scale=1.0):
    cx = np.array([0.3, 0.8, -0.2, 0.5, -0.4, 0.25, 1.2, -0.6, 0.35, 0.15]) * scale
    cy = np.array([-0.1, 0.15, 0.6, -0.3, 0.45, 0.2, -0.25, 0.9, -0.5, 1.1]) * scale
    return CompositeDistortion(
        brown_conrady=BrownConradyDistortion(k1=k1, k2=k2, p1=p1, p2=p2, r_norm_px=R_NORM),
        cubic=CubicDistortion(coeffs_x=cx, coeffs_y=cy, r_norm_px=R_NORM),
    )


# ---------------------------------------------------------------------- analytic formulas


def test_brown_conrady_matches_written_out_formula():
    d = BrownConradyDistortion(k1=0.05, k2=-0.01, p1=2e-3, p2=-1e-3, r_norm_px=1000.0)
    u, v = 600.0, -250.0
    x, y = 0.6, -0.25
    r2 = x * x + y * y
    xd = x * (1 + 0.05 * r2 - 0.01 * r2**2) + 2 * 2e-3 * x * y + (-1e-3) * (r2 + 2 * x * x)
    yd = y * (1 + 0.05 * r2 - 0.01 * r2**2) + 2e-3 * (r2 + 2 * y * y) + 2 * (-1e-3) * x * y
    fu, fv = d.forward(u_px=u, v_px=v)
    assert fu == pytest.approx(1000.0 * xd, abs=1e-10)
    assert fv == pytest.approx(1000.0 * yd, abs=1e-10)


def test_pure_k1_is_the_analytic_radial_formula():
    k1 = 0.03
    d = BrownConradyDistortion(k1=k1, r_norm_px=R_NORM)
    theta = np.linspace(0, 2 * np.pi, 13)
    r = np.linspace(0, 2300.0, 13)
    u, v = r * np.cos(theta), r * np.sin(theta)
    fu, fv = d.forward(u_px=u, v_px=v)
    r_d = r * (1 + k1 * (r / R_NORM) ** 2)  # r' = r (1 + k1 (r/r_norm)^2): purely radial
    np.testing.assert_allclose(np.hypot(fu, fv), r_d, rtol=0, atol=1e-9)
    # direction preserved: the displacement is parallel to the position vector
    np.testing.assert_allclose(fu * v - fv * u, 0.0, atol=1e-6)
    # at the normalising radius the point moves out by exactly k1 * r_norm px
    du, dv = d.displacement(u_px=R_NORM, v_px=0.0)
    assert du == pytest.approx(k1 * R_NORM, abs=1e-10) and dv == 0.0


def test_cubic_monomial_order_and_values():
    assert CUBIC_MONOMIALS == ("1", "x", "y", "x^2", "xy", "y^2", "x^3", "x^2y", "xy^2", "y^3")
    u, v = 1024.0, -512.0
    x, y = 0.5, -0.25
    values = [1, x, y, x * x, x * y, y * y, x**3, x * x * y, x * y * y, y**3]
    for k in range(10):
        cx = [0.0] * 10
        cy = [0.0] * 10
        cx[k] = 2.0
        cy[k] = -3.0
        d = CubicDistortion(coeffs_x=cx, coeffs_y=cy, r_norm_px=R_NORM)
        du, dv = d.displacement(u_px=u, v_px=v)
        assert du == pytest.approx(2.0 * values[k], abs=1e-12), CUBIC_MONOMIALS[k]
        assert dv == pytest.approx(-3.0 * values[k], abs=1e-12), CUBIC_MONOMIALS[k]


def test_composite_is_cubic_after_brown_conrady():
    d = realistic_composite()
    u = np.array([-1500.0, 0.0, 1900.0])
    v = np.array([800.0, -1000.0, 30.0])
    bu, bv = d.brown_conrady.forward(u_px=u, v_px=v)
    ref = d.cubic.forward(u_px=bu, v_px=bv)
    got = d.forward(u_px=u, v_px=v)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)
    du, dv = d.displacement(u_px=u, v_px=v)
    np.testing.assert_allclose(du, ref[0] - u, atol=1e-12)
    np.testing.assert_allclose(dv, ref[1] - v, atol=1e-12)


# --------------------------------------------------------------------------- sign conventions


@pytest.mark.parametrize("u, v", [(1500.0, 0.0), (-1200.0, 700.0), (0.0, -1000.0), (2000.0, 1000.0)])
def test_positive_k1_is_pincushion_negative_is_barrel(u, v):
    r0 = math.hypot(u, v)
    fu, fv = BrownConradyDistortion(k1=0.02, r_norm_px=R_NORM).forward(u_px=u, v_px=v)
    assert math.hypot(fu, fv) > r0  # outward
    fu, fv = BrownConradyDistortion(k1=-0.02, r_norm_px=R_NORM).forward(u_px=u, v_px=v)
    assert math.hypot(fu, fv) < r0  # inward


def test_decentring_signs():
    # on the +v axis: p1 moves the point along +v by p1 * 3 y^2; p2 along +u by p2 y^2
    y = 0.5
    fu, fv = BrownConradyDistortion(p1=1e-3, r_norm_px=R_NORM).displacement(u_px=0.0, v_px=y * R_NORM)
    assert fu == 0.0 and fv == pytest.approx(1e-3 * 3 * y * y * R_NORM, abs=1e-12)
    fu, fv = BrownConradyDistortion(p2=1e-3, r_norm_px=R_NORM).displacement(u_px=0.0, v_px=y * R_NORM)
    assert fu == pytest.approx(1e-3 * y * y * R_NORM, abs=1e-12) and fv == 0.0


def test_identity_maps_every_point_to_itself():
    u = np.array([-2048.0, 0.0, 1234.5])
    v = np.array([1024.0, 0.0, -77.25])
    for cls in (BrownConradyDistortion, CubicDistortion, CompositeDistortion):
        d = cls.identity(r_norm_px=R_NORM)
        fu, fv = d.forward(u_px=u, v_px=v)
        np.testing.assert_array_equal(fu, u)  # identity coefficients: u * 1 + 0, exact by construction
        np.testing.assert_array_equal(fv, v)
        iu, iv = d.inverse(u_px=u, v_px=v)
        np.testing.assert_array_equal(iu, u)
        np.testing.assert_array_equal(iv, v)


def test_positions_without_the_jacobian_are_those_with_it():
    # forward and displacement skip the Jacobian (and a cubic its zero coefficients' terms):
    # the same positions bit for bit as the full map, signed zeros included
    u = np.concatenate([np.linspace(-2048.0, 2048.0, 41), [0.0, -0.0, 1e-300]])
    v = np.concatenate([np.linspace(1024.0, -1024.0, 41), [-0.0, 0.0, -1e-300]])
    sparse = (0.0, 0.4, 0.0, 0.0, -0.3, 0.0, 0.0, 0.0, 0.2, 0.0)
    models = [realistic_composite(), realistic_composite(scale=0.0), CubicDistortion.identity(r_norm_px=R_NORM),
              CubicDistortion(coeffs_x=sparse, coeffs_y=sparse[::-1], r_norm_px=R_NORM),
              HigherOrderRadialDistortion(base=realistic_composite(scale=0.0), a5_px=1.47, a7_px=0.081,
                                          r_corner_px=2290.0)]
    for d in models:
        fu, fv, jac = d._map(u, v)
        assert jac.shape == u.shape + (2, 2)
        gu, gv = d.forward(u_px=u, v_px=v)
        assert gu.tobytes() == fu.tobytes() and gv.tobytes() == fv.tobytes()
        du, dv = d.displacement(u_px=u, v_px=v)
        assert du.tobytes() == (fu - u).tobytes() and dv.tobytes() == (fv - v).tobytes()
    # a zero coefficient adds nothing: the sparse cubic equals the sum over all ten monomials
    x, y = u / R_NORM, v / R_NORM
    monomials = (np.ones_like(x), x, y, x * x, x * y, y * y, x * x * x, x * x * y, x * y * y, y * y * y)
    fu, _ = models[3].forward(u_px=u, v_px=v)
    assert fu.tobytes() == (u + sum(c * m for c, m in zip(sparse, monomials))).tobytes()


# ---------------------------------------------------------------------- Jacobian, inverse


@pytest.mark.parametrize(
    "model",
    [
        BrownConradyDistortion(k1=0.04, k2=-0.01, p1=1e-3, p2=-2e-3, r_norm_px=R_NORM),
        CubicDistortion(coeffs_x=np.arange(10) * 0.3 - 1, coeffs_y=np.arange(10)[::-1] * 0.2 - 0.5, r_norm_px=R_NORM),
        realistic_composite(),
    ],
    ids=["brown_conrady", "cubic", "composite"],
)
def test_jacobian_against_central_differences(model):
    rng = np.random.default_rng(11)
    u = rng.uniform(-2048, 2048, 20)
    v = rng.uniform(-1024, 1024, 20)
    h = 1e-3
    jac = model.jacobian(u_px=u, v_px=v)
    fu_p, fv_p = model.forward(u_px=u + h, v_px=v)
    fu_m, fv_m = model.forward(u_px=u - h, v_px=v)
    np.testing.assert_allclose(jac[:, 0, 0], (fu_p - fu_m) / (2 * h), rtol=0, atol=1e-8)
    np.testing.assert_allclose(jac[:, 1, 0], (fv_p - fv_m) / (2 * h), rtol=0, atol=1e-8)
    fu_p, fv_p = model.forward(u_px=u, v_px=v + h)
    fu_m, fv_m = model.forward(u_px=u, v_px=v - h)
    np.testing.assert_allclose(jac[:, 0, 1], (fu_p - fu_m) / (2 * h), rtol=0, atol=1e-8)
    np.testing.assert_allclose(jac[:, 1, 1], (fv_p - fv_m) / (2 * h), rtol=0, atol=1e-8)


@settings(max_examples=60, deadline=None)
@given(
    u=U_FIELD,
    v=V_FIELD,
    k1=st.floats(-0.05, 0.05),
    k2=st.floats(-0.01, 0.01),
    p1=st.floats(-2e-3, 2e-3),
    p2=st.floats(-2e-3, 2e-3),
    scale=st.floats(-3.0, 3.0),
)
def test_forward_then_inverse_round_trip(u, v, k1, k2, p1, p2, scale):
    d = realistic_composite(k1=k1, k2=k2, p1=p1, p2=p2, scale=scale)
    fu, fv = d.forward(u_px=u, v_px=v)
    iu, iv = d.inverse(u_px=fu, v_px=fv)
    assert abs(iu - u) < 1e-6 and abs(iv - v) < 1e-6
    # and the residual of the forward map at the solution meets the documented tolerance
    gu, gv = d.forward(u_px=iu, v_px=iv)
    assert abs(gu - fu) < 1e-10 and abs(gv - fv) < 1e-10


def test_inverse_vectorised_over_a_grid():
    d = realistic_composite(k1=-0.04, scale=2.0)
    u, v = np.meshgrid(np.linspace(-2048, 2048, 33), np.linspace(-1024, 1024, 17))
    fu, fv = d.forward(u_px=u, v_px=v)
    iu, iv = d.inverse(u_px=fu, v_px=fv)
    assert iu.shape == u.shape
    assert np.abs(iu - u).max() < 1e-6 and np.abs(iv - v).max() < 1e-6


def test_inverse_of_too_strong_distortion_raises():
    # r (1 - 0.5 r^2) peaks at r = 0.816 with value 0.544: r' = 0.7 has no preimage
    d = BrownConradyDistortion(k1=-0.5, r_norm_px=R_NORM)
    with pytest.raises(NonInvertibleDistortionError, match="inverse"):
        d.inverse(u_px=np.array([100.0, 0.7 * R_NORM]), v_px=np.array([0.0, 0.0]))
    # but within the monotone part the same model inverts fine
    iu, iv = d.inverse(u_px=0.4 * R_NORM, v_px=0.0)
    fu, _ = d.forward(u_px=iu, v_px=iv)
    assert fu == pytest.approx(0.4 * R_NORM, abs=1e-9)


# ------------------------------------------------------------------------------ validation


def test_models_are_frozen_and_validated():
    d = BrownConradyDistortion(k1=0.01)
    with pytest.raises(dataclasses.FrozenInstanceError):
        d.k1 = 0.2
    assert dataclasses.replace(d, k1=0.02).k1 == 0.02
    with pytest.raises(OpticsError, match="r_norm_px"):
        BrownConradyDistortion(r_norm_px=0.0)
    with pytest.raises(OpticsError, match="k2"):
        BrownConradyDistortion(k2=float("nan"))
    with pytest.raises(OpticsError, match="coeffs_x"):
        CubicDistortion(coeffs_x=[0.0] * 9)
    with pytest.raises(OpticsError, match="coeffs_y"):
        CubicDistortion(coeffs_y=[0.0] * 9 + [np.inf])
    with pytest.raises(OpticsError, match="cubic"):
        CompositeDistortion(cubic=BrownConradyDistortion())
    with pytest.raises(OpticsError, match="tol_px"):
        BrownConradyDistortion().inverse(u_px=0.0, v_px=0.0, tol_px=0.0)
    with pytest.raises(OpticsError, match="u_px"):
        BrownConradyDistortion().forward(u_px=[np.nan], v_px=[0.0])
    with pytest.raises(TypeError):
        BrownConradyDistortion(0.1)  # keyword-only
    c = CubicDistortion(coeffs_x=np.ones(10))
    assert isinstance(c.coeffs_x, tuple) and hash(c) == hash(CubicDistortion(coeffs_x=[1.0] * 10))
