"""The slanted-edge estimator (lab side) against the analytic smear MTF on noise-free
pixel-level TDI edge images, and against its own noise (its bias is what the study reports)."""

import math

import numpy as np
import pytest
from scipy import stats

from budget.whiskbroom.estimators import improved_mtf, published_mtf, slanted_edge_mtf, stage_limit_from_curve
from simcam.whiskbroom import tdi
from simcam.whiskbroom.synthesis import mtf_sinc

# near-continuous clocking: the 1/64-pixel sawtooth costs sinc(pi/128) = 0.9999
CONT = dict(n_stages=96, n_phase=64, n_time=1, angle_deg=5.0, lines=32, columns=128)


@pytest.mark.parametrize("n_eps", [0.0, 0.3514, 0.7, 1.0])
def test_edge_recovers_the_smear_mtf_noise_free(n_eps):
    img = tdi.edge_image(n_eps / 96, 0.0, **CONT)
    got = slanted_edge_mtf(img)
    # output lines sample the scene every (1 + eps) pixels: the edge looks a little flatter
    expect_deg = math.degrees(math.atan(math.tan(math.radians(5.0)) / (1 + n_eps / 96)))
    assert got["angle_deg"] == pytest.approx(expect_deg, abs=0.005)
    # reference: sinc(pi N eps / 2) (near-continuous clocking). The e-SFR at Nyquist of an
    # optics-free (box-pixel) edge depends on where the edge falls on the 1/4-pixel ESF
    # bins: the sampled ~1-pixel-wide LSF has 4 or 5 samples inside; moving the edge by
    # 1/64 to 1/1024 pixel moves the result between 0.967 and 0.995 at eps = 0. So the
    # method's own error is within 3.5 % here, not better (this is what the study's edge
    # variant shows as bias and spread; with motion it reads 1-2.5 % high even averaged over
    # placements). The method's model itself (binning, aperture, derivative) is pinned
    # tightly by the placement-averaged test below.
    assert got["mtf"] == pytest.approx(float(mtf_sinc(n_eps)), abs=0.035)


def test_edge_without_motion_averages_to_the_iso_binning_factor_over_placements():
    """Without motion the e-SFR of a box-pixel edge depends on where the edge falls on the
    1/4-pixel ESF bins (0.962-0.985 at single placements, see above), but averaged over
    placements (27: tilts 4-6 deg in 0.25 deg steps x three image widths) it must equal what
    the method leaves uncorrected: the ISO binning factor sinc(pi f delta) = sinc(pi/8) =
    0.97450 at f = 1/2, delta = 1/4 (ISO 12233:2017; the derivative and the pixel aperture
    are corrected). Tolerance: 4 standard errors of the placement mean (sd 0.0061 measured,
    se 0.0012), so a model off by 1 % (a missing aperture or derivative correction, or a
    reference without the binning factor, 2.6 %) fails."""
    res = []
    for ang in np.arange(4.0, 6.01, 0.25):
        for cols in (128, 136, 144):
            img = tdi.edge_image(0.0, 0.0, **{**CONT, "angle_deg": float(ang), "columns": cols})
            res.append(slanted_edge_mtf(img)["mtf"])
    res = np.array(res)
    se = res.std(ddof=1) / np.sqrt(res.size)
    assert se < 0.002                                   # the placements do average (27 of them)
    assert abs(res.mean() - np.sinc(0.125)) < 4 * se


def test_edge_with_noise_is_reproducible_and_near():
    """Shot and read noise on the same edge: the same seed gives the same number
    (equivalence), and 8 draws scatter about the noise-free result of the same geometry
    (the method's own bin-phase error is common to both and cancels) by the noise alone."""
    def one(seed):
        rng = np.random.default_rng(seed)
        img = tdi.edge_image(0.0, 0.0, **CONT, signal_e_per_stage=400.0, read_noise_e=30.0, rng=rng)
        return slanted_edge_mtf(img)["mtf"]

    assert one(3) == one(3)
    ref = slanted_edge_mtf(tdi.edge_image(0.0, 0.0, **CONT))["mtf"]
    vals = np.array([one(s) for s in range(8)])
    n = vals.size
    sd = vals.std(ddof=1)
    # shot noise on 38 400 e- edges: the Nyquist value scatters by about 0.7 % (a validation
    # run of the study); 8 draws: their sample sd is below 0.7 % x sqrt(chi2_0.9995(7) / 7)
    # = 1.2 % (99.95 %), and their mean lies within 4 of its own standard errors,
    # sd / sqrt(8) (~0.2 %), of the noise-free value: a noise bias of half a percent fails
    assert sd < 0.007 * math.sqrt(stats.chi2.ppf(0.9995, n - 1) / (n - 1))
    assert abs(vals.mean() - ref) < 4 * sd / math.sqrt(n), (vals.mean(), ref, sd)


def test_predictions_and_stage_limit():
    n = np.arange(1, 201)
    pub = published_mtf(0.3513 / 96 * 97.0, 97.0, n)      # N Delta V / V = 0.3513 at N = 96
    assert stage_limit_from_curve(pub, 0.95) == 96
    along, cross = improved_mtf(0.0, 0.0, n, 4)
    np.testing.assert_allclose(along, math.sin(math.pi / 8) / (math.pi / 8), rtol=1e-15)
    np.testing.assert_allclose(cross, 1.0, rtol=0)
