"""Monte Carlo synthesis (seed 002 steps 1-5) against the first-order propagation (GUM),
the linear-model Sobol indices, the sinc MTF special values, and the dense field."""

import math

import numpy as np
import pytest

from simcam.whiskbroom import scenario as wsc
from simcam.whiskbroom import synthesis as sy
from simcam.whiskbroom.scenario import ERROR_VARIABLES


@pytest.fixture(scope="module")
def sc():
    return wsc.default()


def _scaled(sc, factor, gamma_step=0.0):
    """The default with the 11 errors scaled (small-error regime) and gamma fixed."""
    errs = {n: getattr(sc.errors, n).with_scale(getattr(sc.errors, n).scale * factor) for n in ERROR_VARIABLES}
    return sc.model_copy(update={"errors": sc.errors.model_copy(update=errs),
                                 "orbit": sc.orbit.model_copy(update={"gamma_step_deg": gamma_step})})


def test_trial_draws_depend_only_on_seed_and_trial_index():
    a = sy.trial_uniforms(11, np.arange(10))
    b = sy.trial_uniforms(11, [7, 3])
    np.testing.assert_array_equal(a[[7, 3]], b)


def test_sinc_special_values():
    # sin x / x = 0.95 at x = 0.5519 (N eps = 0.3514); N eps = 1 gives 2/pi; 2 gives 0
    assert sy.mtf_sinc(sy.N_EPS_095) == pytest.approx(0.95, abs=2e-5)
    assert sy.mtf_sinc(1.0) == pytest.approx(2 / math.pi, rel=1e-15)
    assert sy.mtf_sinc(2.0) == pytest.approx(0.0, abs=1e-15)
    assert sy.stage_limit(sy.N_EPS_095 / 48.0 * 1.0001) == 47
    assert sy.stage_limit(sy.N_EPS_095 / 48.0 * 0.9999) == 48


def test_monte_carlo_spread_matches_first_order_propagation(sc):
    small = _scaled(sc, 0.1)
    K = 1000
    ks = np.arange(K)
    draws = sy.standard_draws(small, sy.trial_uniforms(5, ks))
    know, true = sy.trial_params(small, draws, ks)
    r = sy.evaluate(know, true, np.array([0.0]), np.array([0.0]))
    u_dv, u_db, jdv, jdb = sy.gum_sigma(small, math.radians(small.orbit.gamma0_deg))
    # (a) trial by trial: Delta V_P minus its linear prediction is second order in the
    # errors (and first order in the operating point's departure from nominal, +-0.03 deg)
    lin = sum(jdv[j, 0] * draws[n] for j, n in enumerate(ERROR_VARIABLES))
    assert np.max(np.abs(r.dv_mm_s - lin)) < 0.01 * u_dv[0]
    # (b) the spread: the sample std of K near-normal values has relative standard error
    # 1/sqrt(2(K-1)) = 2.2 %; fixed seed, 4 standard errors
    tol = 4.0 / math.sqrt(2 * (K - 1))
    assert np.std(r.dv_mm_s, ddof=1) == pytest.approx(u_dv[0], rel=tol)
    assert np.std(r.dbeta_deg, ddof=1) == pytest.approx(u_db[0], rel=tol)


def test_gum_mirror_sensitivity_is_the_optical_doubling(sc):
    # dV/d omega_x = 2 f, projected on the image-motion direction (optical doubling of a fold mirror)
    _, _, jdv, _ = sy.gum_sigma(sc, 0.0)
    from simcam.whiskbroom import geometry as geo
    v = geo.image_motion(sy.nominal_params(sc, 0.0), [0.0], [0.0])[0, 0]
    expect = 2 * sc.camera.focal_length_mm * math.radians(1.0) * abs(v[1]) / np.hypot(*v)
    j = ERROR_VARIABLES.index("mirror_rate_deg_s")
    assert abs(jdv[j, 0]) == pytest.approx(expect, rel=1e-3)   # Earth term tilts V3 by 1.8 %
    k = ERROR_VARIABLES.index("focal_length_rel")
    assert jdv[k, 0] == pytest.approx(np.hypot(*v), rel=1e-9)   # dV/d(df/f) = V


def test_sobol_indices_equal_the_linear_variance_shares(sc):
    # for a (locally) linear model of independent inputs S1_j = ST_j = J_j^2 u_j^2 / sum
    s = sy.sobol_indices(sc, seed=1, base_samples=512)
    _, _, jdv, _ = sy.gum_sigma(sc, math.radians(sc.orbit.gamma0_deg))
    u = np.array([getattr(sc.errors, n).std for n in ERROR_VARIABLES])
    share = (jdv[:, 0] * u) ** 2 / np.sum((jdv[:, 0] * u) ** 2)
    idx = [s["names"].index(n) for n in ERROR_VARIABLES]
    # tolerance: SALib's own 95 % bootstrap half-widths, plus 0.01 for the weak
    # nonlinearity (operating point +-0.03 deg)
    assert np.all(np.abs(s["ST"][idx] - share) <= s["ST_conf"][idx] + 0.01)
    assert s["names"][int(np.argmax(s["ST"]))] == "mirror_rate_deg_s"


def test_sampled_field_finds_the_worst_column_of_the_full_arrays(sc):
    ks = np.arange(10)
    draws = sy.standard_draws(sc, sy.trial_uniforms(0, ks))
    know, true = sy.trial_params(sc, draws, ks)
    r = sy.evaluate(know, true, *sy.field_points(sc))
    full = sy.evaluate(know, true, *sy.full_field_points(sc, col_step=1, row_step=sc.camera.tdi_stages - 1))
    # the residual field is smooth and monotone along the line: its extreme is at a chip
    # end, which the sampled field contains; agreement to rounding
    np.testing.assert_allclose(np.abs(r.eps), np.abs(full.eps), rtol=1e-9)


def test_synthesis_is_reproducible_and_reports_each_mirror_error(sc):
    small = sc.model_copy(update={"synthesis": sc.synthesis.model_copy(update={"trials": 50})})
    a = sy.synthesize(small, 3)
    b = sy.synthesize(small, 3)
    assert [t["mirror_rate_error_deg_s"] for t in a.table] == [0.001, 0.0005, 0.0004, 0.0003]
    np.testing.assert_array_equal(a.residuals[0.001].dv_mm_s, b.residuals[0.001].dv_mm_s)
    # smaller mirror-rate error, smaller residual (common random numbers)
    spreads = [t["dv_std_mm_s"] for t in a.table]
    assert spreads == sorted(spreads, reverse=True)
