"""The profile stamp route (``render.stamp_route = "profile"``) against the exact route.

:func:`simcam.starcam.psf_stamps.render_shifted_stamps` computes the same spectrum as
:func:`simcam.starcam.psf_stamps.render_stamps` with the wavelength sum taken once per target,
filter and rounded pose: the star's position and PSF width enter exactly, so at the
profile's own lateral-colour shifts the two agree to rounding. What the route
approximates is the lateral colour's spread about its mean, which keeps the rounded
pose's values; its effect on a pixel is bounded below (``_hessian_bound``) and checked on
the default's scenes.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from simcam.starcam import psf_stamps as O

# rounding: a pixel is an inverse DFT of ~L^2 terms of magnitude <= 1 (the spectrum of a
# unit-flux image), each carrying a few relative roundings of 2.2e-16 from ~n_l-term sums;
# the two routes sum in different orders, so they differ by ~1e-15 (a few 1e-15 seen),
# and 1e-13 leaves a margin of ~30 without hiding any modelling difference (those are >= 1e-9)
ROUNDING = 1e-13


def _batch(kind):
    rng = np.random.default_rng(3)  # fixed seed: arbitrary positions, widths and shifts
    n, nl = 9, 31
    wl = np.linspace(400.0, 1000.0, nl)
    w = rng.random(nl)
    w /= w.sum()
    kw = dict(stamp_px=24, psf_kind=kind, pinhole_radius_px=0.6, f_number=3.5, pixel_pitch_um=5.5,
              wavelength_nm=wl, weights=w)
    x = 300.0 + 40.0 * rng.random(n)
    y = 80.0 + 40.0 * rng.random(n)
    sig = (0.8 if kind == "gaussian" else 0.25) + 0.1 * rng.random(n)
    sx = 0.05 * rng.standard_normal((n, nl))
    sy = 0.05 * rng.standard_normal((n, nl))
    return kw, x, y, sig, sx, sy


@pytest.mark.parametrize("kind", ["gaussian", "airy"])
def test_profile_route_equals_exact_at_its_own_shifts(kind):
    kw, x, y, sig, sx, sy = _batch(kind)
    prof = O.stamp_profiles(sigma_px=sig, shift_x_px=sx, shift_y_px=sy, **kw)
    # a position, a PSF width and a common lateral-colour shift that differ from the
    # profile's: all exact in the profile route
    for dx, dy, dsig, dsx in ((0.0, 0.0, 0.0, 0.0), (0.37, -0.81, 3e-3, 2e-3), (5.5, 2.25, -1e-2, -0.1)):
        ref, ox, oy = O.render_stamps(x_px=x + dx, y_px=y + dy, sigma_px=sig + dsig, shift_x_px=sx + dsx,
                                      shift_y_px=sy, **kw)
        got, gx, gy = O.render_shifted_stamps(prof, x_px=x + dx, y_px=y + dy, sigma_px=sig + dsig,
                                              mean_shift_x_px=prof.mean_shift_x_px + dsx,
                                              mean_shift_y_px=prof.mean_shift_y_px)
        assert np.array_equal(ox, gx) and np.array_equal(oy, gy)
        assert np.abs(got - ref).max() < ROUNDING, (dx, dy, dsig)
        assert abs(got.sum(axis=(1, 2)) - 1.0).max() < ROUNDING  # flux conserved, as the exact stamps


def _hessian_bound(sigma_px, w, d, s):
    """Bound of the profile route's error per pixel (fraction of the star's flux).

    The image is ``sum_l w_l I(x - s_l)``; the route uses ``s_l + delta_l`` with
    ``delta_l = (s_l - mean s)(node) - (s_l - mean s)(actual)``, ``sum_l w_l delta_l = 0``. To first
    order the error is ``-sum_l w_l delta_l . grad I(x - s_l)``; expanding ``grad I`` about
    the mean shift, its first term vanishes with ``sum w delta = 0``, leaving
    ``sum_l w_l delta_l . H (s_l - mean s)``, ``H`` the Hessian of ``I``. For the Gaussian
    ``|H| <= 1 / (2 pi sigma^4)`` (its largest eigenvalue, at the centre); the pinhole disc and
    the pixel average ``I`` and cannot raise it. So ``|err| <= sum_l w_l |delta_l| |s_l - mean s|
    / (2 pi sigma^4)`` per star, plus second-order terms ``|delta|^2 |H|`` (delta < 1e-4 px here).
    """
    return (w[None, :] * np.hypot(*d) * np.hypot(*s)).sum(axis=1) / (2 * math.pi * sigma_px**4)


def _default_scenes():
    from budget.starcam.protocols import _star_grid, make_plan
    from simcam.starcam.render import Placement, StarCamera
    from simcam.starcam.scenario import default, with_updates
    from simcam.starcam.targets import calibration_grid

    scn = default()
    cp, ce = StarCamera(scn), StarCamera(with_updates(scn, {"render.stamp_route": "exact"}))
    for proto in ("te", "hsfe", "chromatic", "distortion"):
        plan = make_plan(proto, scn)
        for c in plan.conditions[:: max(1, len(plan.conditions) // 3)]:
            lay = calibration_grid(scn) if c.target == "calibration_grid" else _star_grid(cp, c.field_center_px)
            # poses as far from their profile's rounded pose as they come (half a step on
            # both axes), and a roll of the hexapod's size (0.5 arcsec)
            for d in ((0.499, -0.499), (0.21, 0.33)):
                yield cp, ce, Placement(layout=lay, platform_dx_px=c.platform_dx_px + d[0],
                                        platform_dy_px=c.platform_dy_px + d[1], filter_nm=c.filter_nm,
                                        platform_roll_rad=2.4e-6)


def test_profile_route_error_within_its_bound_and_far_below_the_noise():
    checked = 0
    for cp, ce, p in _default_scenes():
        a, b = cp._scene(p), ce._scene(p)
        assert np.array_equal(a.stamp_col0, b.stamp_col0) and np.array_equal(a.stamp_row0, b.stamp_row0)
        assert a.truth.equals(b.truth)  # the truth does not depend on the route
        # the lateral-colour shifts (chip px) at the actual and at the profile's pose
        lay = p.layout
        wl, rate = cp.spectra.electron_rate_per_nm(filter_nm=p.filter_nm)
        w = cp.spectra.weights(rate)
        u0 = lay.u_px + p.platform_dx_px - p.platform_roll_rad * lay.v_px
        v0 = lay.v_px + p.platform_dy_px + p.platform_roll_rad * lay.u_px
        nx, ny = cp.profile_node(p)
        sa = cp.mosaic.vector_to_chip(*cp._lateral_colour(wl, *cp.distortion.forward(u_px=u0, v_px=v0)), a.chip)
        sn = cp.mosaic.vector_to_chip(*cp._lateral_colour(wl, *cp.distortion.forward(
            u_px=lay.u_px + nx, v_px=lay.v_px + ny)), a.chip)
        dev = [v - (v @ w)[:, None] for v in (*sa, *sn)]
        delta = (dev[2] - dev[0], dev[3] - dev[1])
        bound = _hessian_bound(a.truth["psf_sigma_px"].to_numpy(), w, delta, dev[:2])
        err = np.abs(a.stamps - b.stamps).max(axis=(1, 2))
        # (the first-order bound holds with room: err / bound is 0.37-0.56 on these scenes)
        assert np.all(err <= bound + ROUNDING), (p, err.max(), bound.max())
        # against the photon noise of the brightest pixel: a small fraction of one sigma
        peak_e = a.stamps.max(axis=(1, 2)) * a.electrons
        assert np.all(err * a.electrons < 1e-3 * np.sqrt(peak_e))
        # and the noise-free centroid of the stamp: far below the HSFE truth (~1e-3 px)
        g = np.arange(a.stamps.shape[-1])

        def cx(s):
            return (s.sum(axis=1) * g).sum(axis=1) / s.sum(axis=(1, 2))

        assert np.abs(cx(a.stamps) - cx(b.stamps)).max() < 1e-9
        checked += 1
    assert checked >= 10


def test_profile_scene_does_not_depend_on_what_was_rendered_before():
    cp, _, p = next(_default_scenes())
    from dataclasses import replace

    from simcam.starcam.render import StarCamera

    first = cp._scene(p).stamps
    fresh = StarCamera(cp.scenario)
    fresh._scene(replace(p, platform_dx_px=p.platform_dx_px - 0.3))  # another pose, same profiles
    assert np.array_equal(fresh._scene(p).stamps, first)


@pytest.mark.slow
def test_default_verdicts_unchanged_by_the_profile_route():
    """Every bias-significance verdict of the default's 200-trial report (seed 0) is the same
    with the exact stamps (what changes is ~1e-15 of a pixel's flux fraction and the ~1e-5
    of its noise bounded above)."""
    from budget.runner.run import run_study
    from budget.starcam.study import STUDY
    from simcam.starcam.scenario import default, with_updates

    scn = default()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        prof = run_study(STUDY, scn, trials=200, seed=0, workers=2)
        exact = run_study(STUDY, with_updates(scn, {"render.stamp_route": "exact"}), trials=200, seed=0, workers=2)
    sp, se = prof.summary(), exact.summary()
    for c in se:
        for a in se[c]:
            for v in se[c][a]:
                assert sp[c][a][v]["bias_significant"] == se[c][a][v]["bias_significant"], (c, a, v)
