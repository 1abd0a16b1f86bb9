"""Sign conventions: which way each thing moves a star (in the spirit of poppy's test file).

* a field angle toward +u (the target's image centre moved to +u) moves the star to +x;
* a hexapod step of +dx px moves the star by +dx in mosaic x;
* a positive Brown-Conrady k1 (pincushion) moves an off-axis star outward;
* a positive cubic coefficient on the constant monomial moves every star to +x;
* a positive uniform lateral-colour coefficient puts the 800 nm image at larger x than 600 nm;
* a positive radial lateral-colour coefficient moves long wavelengths away from the axis;
* a hotter star's chromatic shift differs from a cooler one's by c1 (mean-wavelength difference).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import constants, integrate

from simcam.starcam.render import Placement, StarCamera
from simcam.starcam.scenario import default, with_updates
from simcam.starcam.targets import star_grid

NO_COLOUR = {
    "optics.lateral_colour.radial_px_per_nm": [],
    "optics.lateral_colour.uniform_x_px_per_nm": [],
    "optics.lateral_colour.uniform_y_px_per_nm": [],
    # the ideal world: no higher-order distortion or non-linearity beside the
    # convention under test
    "world.effects": default().world.effects.ideal().model_dump(),
}
NO_DISTORTION = {"optics.distortion.k1": 0.0, "optics.distortion.k2": 0.0}


def _truth(scn, **placement):
    cam = StarCamera(scn)
    return cam.scene(Placement(layout=star_grid(scn), **placement)).truth


def test_field_angle_toward_plus_u_moves_star_to_plus_x():
    base = with_updates(default(), NO_COLOUR | NO_DISTORTION)
    a = _truth(base)
    moved = with_updates(base, {"lab.target_center_px": [-1000.0, 10.0]})  # +24 px in u, +10 in v
    b = _truth(moved)
    np.testing.assert_allclose(b.x_true - a.x_true, 24.0, atol=1e-9)
    np.testing.assert_allclose(b.y_true - a.y_true, 10.0, atol=1e-9)


def test_hexapod_step_moves_star_by_the_step():
    base = with_updates(default(), NO_COLOUR | NO_DISTORTION)
    a = _truth(base)
    b = _truth(base, platform_dx_px=0.2 / np.sqrt(2), platform_dy_px=0.2 / np.sqrt(2))
    np.testing.assert_allclose(b.x_true - a.x_true, 0.2 / np.sqrt(2), atol=1e-12)
    np.testing.assert_allclose(b.y_true - a.y_true, 0.2 / np.sqrt(2), atol=1e-12)


def test_positive_k1_moves_off_axis_star_outward():
    base = with_updates(default(), NO_COLOUR | {"optics.distortion.k1": 0.0, "optics.distortion.k2": 0.0})
    k1 = with_updates(base, {"optics.distortion.k1": 1e-3})
    t0, t1 = _truth(base), _truth(k1)
    r0 = np.hypot(t0.u_ideal_px + t0.distortion_dx_px, t0.v_ideal_px + t0.distortion_dy_px)
    r1 = np.hypot(t1.u_ideal_px + t1.distortion_dx_px, t1.v_ideal_px + t1.distortion_dy_px)
    assert np.all(r1 > r0)
    # size: x' = x (1 + k1 r^2) in units of r_norm -> radial displacement k1 r^3 / r_norm^2 (px)
    rn = base.optics.r_norm_px
    np.testing.assert_allclose(r1 - r0, 1e-3 * r0**3 / rn**2, rtol=1e-9)


def test_constant_cubic_term_moves_every_star_to_plus_x():
    base = with_updates(default(), NO_COLOUR | NO_DISTORTION)
    c = [0.5] + [0.0] * 9
    t = _truth(with_updates(base, {"optics.distortion.cubic_x_px": c}))
    np.testing.assert_allclose(t.distortion_dx_px, 0.5, atol=1e-12)
    np.testing.assert_allclose(t.distortion_dy_px, 0.0, atol=1e-12)


def test_uniform_lateral_colour_puts_red_image_at_larger_x():
    base = with_updates(default(), NO_COLOUR | {"optics.lateral_colour.uniform_x_px_per_nm": [6e-4]})
    t6 = _truth(base, filter_nm=600.0)
    t8 = _truth(base, filter_nm=800.0)
    d = (t8.x_true - t6.x_true).to_numpy()
    assert np.all(d > 0)
    # about 6e-4 px/nm x 200 nm, minus the filters' spectral weighting (a few %)
    np.testing.assert_allclose(d, 0.12, rtol=0.1)
    np.testing.assert_allclose(t8.y_true - t6.y_true, 0.0, atol=1e-12)


def test_radial_lateral_colour_moves_red_away_from_axis():
    base = with_updates(default(), NO_COLOUR | {"optics.lateral_colour.radial_px_per_nm": [1e-3]})
    t6 = _truth(base, filter_nm=600.0)
    t8 = _truth(base, filter_nm=800.0)
    r6 = np.hypot(t6.u_ideal_px + t6.distortion_dx_px + t6.chromatic_dx_px,
                  t6.v_ideal_px + t6.distortion_dy_px + t6.chromatic_dy_px)
    r8 = np.hypot(t8.u_ideal_px + t8.distortion_dx_px + t8.chromatic_dx_px,
                  t8.v_ideal_px + t8.distortion_dy_px + t8.chromatic_dy_px)
    assert np.all(r8 > r6)


def _mean_wavelength_nm(teff_k, scn):
    """Electron-weighted mean wavelength of a blackbody star through optics and QE, by quadrature.

    Independent of simcam.spectra: Planck's law from scipy.constants, the QE as the scenario's
    split Gaussian written out here, integrated with scipy.integrate.quad.
    """
    h, c, k = constants.h, constants.c, constants.k
    q = scn.detector.qe

    def qe(lam):
        w = (q.peak_nm - q.blue_cutoff_nm) if lam <= q.peak_nm else (q.red_cutoff_nm - q.peak_nm)
        val = q.peak_qe * np.exp(-np.log(2) * ((lam - q.peak_nm) / w) ** 2)
        return val if lam * 1e-9 < h * c / (1.12 * constants.e) else 0.0

    def photons(lam):  # photon radiance up to a constant
        x = lam * 1e-9
        return 1.0 / x**4 / np.expm1(h * c / (x * k * teff_k))

    lo, hi = scn.render.wavelength_min_nm, scn.render.wavelength_max_nm
    num = integrate.quad(lambda l: l * photons(l) * qe(l), lo, hi, limit=200)[0]
    den = integrate.quad(lambda l: photons(l) * qe(l), lo, hi, limit=200)[0]
    return num / den


@pytest.mark.parametrize(("hot", "cool"), [("B0V", "M0V"), ("A0V", "K5V")])
def test_hotter_star_shift_has_sign_and_size_of_the_coefficient(hot, cool):
    from simcam.spectra import star_teff_k

    c1 = 6e-4  # px per nm, uniform x
    base = with_updates(default(), NO_COLOUR | {
        "optics.lateral_colour.uniform_x_px_per_nm": [c1], "lab.source.kind": "star",
        "render.wavelength_step_nm": 2.0,
    })
    th = _truth(with_updates(base, {"lab.source.match_spectral_type": hot}))
    tc = _truth(with_updates(base, {"lab.source.match_spectral_type": cool}))
    d = (th.chromatic_dx_px - tc.chromatic_dx_px).to_numpy()
    lam_hot = _mean_wavelength_nm(star_teff_k(spectral_type=hot), base)
    lam_cool = _mean_wavelength_nm(star_teff_k(spectral_type=cool), base)
    assert lam_hot < lam_cool
    assert np.all(d < 0)  # bluer star: image toward -x for a positive coefficient
    # trapezoid on a 2 nm grid against quad: agreement to ~1e-4 relative of the shift
    np.testing.assert_allclose(d, c1 * (lam_hot - lam_cool), rtol=2e-3)
