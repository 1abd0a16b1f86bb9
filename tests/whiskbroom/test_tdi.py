"""Pixel-level TDI simulation against the sinc smear formula where its assumptions hold
(Kopeika 1998 eq. 14.3.3) and against its plain-numpy twin."""

import math

import numpy as np
import pytest

from simcam.whiskbroom import tdi
from simcam.whiskbroom.synthesis import N_EPS_095, mtf_sinc

# Continuous clocking: many clock phases per line, one exposure sample in each (the
# sample sits at the phase's midpoint, so no intra-phase sawtooth remains).
CONT = dict(n_phase=4096, n_time=1, columns=3)


@pytest.mark.parametrize("n_eps,expect", [(N_EPS_095, 0.95), (1.0, 2 / math.pi), (2.0, 0.0)])
def test_continuous_clocking_gives_the_sinc(n_eps, expect):
    n = 96
    along, cross = tdi.pixel_mtf(n_eps / n, n_eps / n, n_stages=n, **CONT)
    # the only difference from the continuous sinc is the Riemann sum over 96 x 4096
    # samples of the linear drift: relative error ~ (pi n_eps / (2 * 96 * 4096))**2 / 6
    assert along[-1] == pytest.approx(expect, abs=3e-5)
    assert cross[-1] == pytest.approx(expect, abs=3e-5)
    # and every shorter stage count follows sinc(pi N eps / 2)
    nn = np.arange(1, n + 1)
    np.testing.assert_allclose(along, mtf_sinc(nn * n_eps / n), atol=3e-5)


@pytest.mark.parametrize("n_phase", [3, 4])
def test_charge_clocking_factor_at_perfect_match(n_phase):
    along, cross = tdi.pixel_mtf(0.0, 0.0, n_stages=8, n_phase=n_phase, n_time=256, columns=2)
    # the image moves 1/n_phase pixel while the charge waits: a uniform smear of that
    # width, sinc(pi / (2 n_phase)) at Nyquist (0.974 for 4 phases, 0.955 for 3);
    # midpoint quadrature with 256 samples: relative error (pi/(2 n 256))^2/6 < 1e-6
    assert along[-1] == pytest.approx(float(mtf_sinc(1.0 / n_phase)), abs=2e-6)
    assert cross[-1] == pytest.approx(1.0, abs=1e-12)     # clocking is along the TDI only


def test_four_phase_with_mismatch_is_drift_times_clocking():
    n, eps = 96, 0.004
    along, _ = tdi.pixel_mtf(eps, 0.0, n_stages=n, n_phase=4, n_time=256, columns=2)
    # exact decomposition of the relative motion (1 + eps) t - j/4: a clock-phase sawtooth
    # of width (1 + eps)/4 and a drift sampled once per clock phase
    expect = mtf_sinc((1 + eps) / 4) * mtf_sinc(n * eps)
    assert along[-1] == pytest.approx(float(expect), abs=2e-5)


def test_kernel_equals_plain_numpy():
    a, c = tdi.pixel_mtf(0.0021, -0.0013, n_stages=40, n_phase=4, n_time=16, columns=50)
    a2, c2 = tdi.pixel_mtf_numpy(0.0021, -0.0013, n_stages=40, n_phase=4, n_time=16, columns=50)
    np.testing.assert_allclose(a, a2, atol=1e-12)
    np.testing.assert_allclose(c, c2, atol=1e-12)


def test_smear_per_stage_decomposes_the_velocity_residual():
    vk = np.array([22.8, 94.5])
    rot = np.radians(0.01)
    vt = 1.002 * np.array([vk[0] * math.cos(rot) - vk[1] * math.sin(rot),
                           vk[0] * math.sin(rot) + vk[1] * math.cos(rot)])
    eps, eta = tdi.smear_per_stage(vt, vk)
    assert eps == pytest.approx(1.002 * math.cos(rot) - 1, rel=1e-12)
    assert eta == pytest.approx(1.002 * math.sin(rot), rel=1e-12)


def test_edge_image_is_dark_bright_with_the_aperture_ramp():
    img = tdi.edge_image(0.0, 0.0, n_stages=8, n_phase=4, n_time=4, angle_deg=5.0, lines=32,
                         columns=64)
    assert img.shape == (32, 64)
    assert np.all((img >= 0) & (img <= 1))
    assert np.all(img[:3] == 0.0) and np.all(img[-3:] == 1.0)
    # the bright area equals the half-plane's area over the image (exact aperture):
    # lines with the edge at L_edge(c) = (sin a c - offset)/cos a, offset per edge_image
    a = math.radians(5.0)
    offset = math.sin(a) * 32 - math.cos(a) * 16
    c = np.arange(64)
    l_edge = (math.sin(a) * c - offset) / math.cos(a)
    # output line L sees scene row -L - 1/8 on average (the packet waits while the image
    # advances: half a clock phase, 1/8 pixel), so the bright lines of column c number
    # 32 - (l_edge - 1/8) - 1/2 (sum of the aperture ramp over the lines)
    assert img.sum(axis=0) == pytest.approx(32 - l_edge + 0.125 - 0.5, abs=0.02)
