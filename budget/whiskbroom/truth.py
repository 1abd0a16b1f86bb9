"""The whiskbroom study's truth: the MTF the TDI detector delivers under the trial's image motion,
by a route that shares nothing with the predictions.

The predictions (:mod:`budget.whiskbroom.estimators`) take the smear per stage ``(eps, eta)``
from the paper's chain (:mod:`simcam.whiskbroom.geometry` through
:func:`simcam.whiskbroom.synthesis.evaluate`: the analytic image-motion velocity, complex-step
differentiated). The truth here takes it from the injected physics by a separate route:

* the true image velocity ``V_true`` is the ray trace of the trial's true state
  (:func:`simcam.whiskbroom.world.world_motion`: the pixel's line of sight traced back to the
  rotating Earth, the ground point re-projected at ``t -+ dt``, the central difference of the
  projected points; :mod:`simcam.whiskbroom.raytrace` imports nothing of ``geometry.py``), on the
  world's ellipsoid (flattening ``earth_flattening_scale`` x WGS 84; the paper's sphere when 0);
* the charge is clocked at the camera's knowledge: the paper's image-motion model evaluated at
  the trial's knowledge state, which here is the same ray trace on the paper's sphere (the
  camera's own model is a fact of the world; its implementation here is not the estimator's);
* ``(eps, eta)`` = :func:`simcam.whiskbroom.tdi.smear_per_stage` of the two, and the MTF is the
  pixel-level TDI simulation (:func:`simcam.whiskbroom.tdi.pixel_mtf`), or, under jitter and
  ripple, of the sampled image path (:func:`simcam.whiskbroom.world.tdi_mtf_path`).

The two routes agree to the ray trace's finite-difference error (6e-11 of ``V``,
:mod:`simcam.whiskbroom.raytrace`), far below what moves an MTF; they share no code, so an error
in the paper's chain shows as a bias instead of cancelling. Nothing here imports the
estimators, the synthesis or the paper's geometry (tests/whiskbroom/test_truth.py reads the source).
"""

from __future__ import annotations

import numpy as np

from simcam.units import WGS84_F
from simcam.whiskbroom import tdi
from simcam.whiskbroom import world as wd

__all__ = ["smear_truth", "stage_limit_truth", "trial_truth"]


def smear_truth(names, know_row, true_row, x1_mm, x3_mm, flattening: float):
    """Smear per stage ``(eps, eta)`` (pixels per stage, along and across the clocking) at the
    image points ``(x1_mm, x3_mm)`` (arrays of one point or more) of an image moving at the
    ray-traced ``V_true`` of ``true_row`` (ellipsoid of ``flattening``) over charge clocked at the
    ray-traced ``V_know`` of ``know_row`` on the sphere; also returns ``V_know`` (mm/s).

    ``names`` are the rows' column names (:data:`simcam.whiskbroom.geometry.PARAMS`)."""
    x1, x3 = np.atleast_1d(np.asarray(x1_mm, dtype=float)), np.atleast_1d(np.asarray(x3_mm, dtype=float))
    vt = wd.world_motion(true_row, names, x1, x3, flattening)
    vk = wd.world_motion(know_row, names, x1, x3, 0.0)
    eps, eta = tdi.smear_per_stage(vt, vk)
    return eps, eta, vk


def stage_limit_truth(mtf_by_stage, threshold: float) -> int:
    """The largest N such that the MTF of every stage count 1..N is at or above ``threshold``
    (``mtf_by_stage[m - 1]`` the MTF of m stages): the length of the run of passing stage counts
    from N = 1."""
    return int(np.sum(np.logical_and.accumulate(np.asarray(mtf_by_stage, dtype=float) >= threshold)))


def trial_truth(scenario, seed: int, k: int, names, know_row, true_row, x1_mm: float, x3_mm: float, cap: int):
    """The motion MTF at Nyquist of the trial's column ``(x1_mm, x3_mm)`` along and across for
    N = 1..``cap`` stages, and the world's image motion for the edge image: ``(eps, eta)``
    (uniform motion) or the image path (a function of the time in line periods -> along, across
    pixels, from the position at t = 0) when jitter or ripple is on."""
    cam, t, w = scenario.camera, scenario.tdi, scenario.world
    eff = w.effects
    flat = eff.earth_flattening_scale * WGS84_F
    px1, px3 = np.array([float(x1_mm)]), np.array([float(x3_mm)])
    e, h, vk = smear_truth(names, know_row, true_row, px1, px3, flat)
    eps, eta, vk = float(e[0]), float(h[0]), vk[0]
    roll = eff.attitude_jitter_arcsec > 0 or eff.wheel_jitter_arcsec > 0
    if not roll and eff.mirror_rate_ripple_fraction == 0:
        a, c = tdi.pixel_mtf(eps, eta, n_stages=cap, n_phase=cam.n_phase, n_time=t.time_samples_per_phase,
                             columns=t.columns, aperture_samples=t.aperture_samples)
        return a, c, (eps, eta)
    p_mm = cam.pixel_pitch_um * 1e-3
    sk = float(np.hypot(*vk))
    tau = vk / sk
    g_roll = wd.rate_sensitivity(true_row, names, px1, px3, flat, "roll_rate_rad_s")[0] if roll else None
    g_mir = (wd.rate_sensitivity(true_row, names, px1, px3, flat, "mirror_rate_rad_s")[0]
             if eff.mirror_rate_ripple_fraction > 0 else None)
    mirror_rate = float(true_row[list(names).index("mirror_rate_rad_s")])

    def path(tl):
        """Image path (along, across; pixels, from the position at t = 0) at times ``tl`` (line
        periods): the uniform residual plus the jitter and ripple displacements (each from its
        own stream, recreated per call, so the truth and the edge image see the same phases)."""
        ts = np.concatenate([[0.0], tl * p_mm / sk])                          # t = 0 first
        disp = np.zeros((ts.size, 2))                                      # mm
        if eff.attitude_jitter_arcsec > 0:
            ang = wd.jitter_angle(wd.effects_rng(seed, k, 0), ts, eff.attitude_jitter_arcsec,
                                  w.jitter_tones_hz, w.jitter_tone_weights)
            disp += ang[:, None] * g_roll[None, :]
        if eff.mirror_rate_ripple_fraction > 0:
            ang = wd.ripple_angle(wd.effects_rng(seed, k, 1), ts, eff.mirror_rate_ripple_fraction,
                                  mirror_rate, w.ripple_period_deg)
            disp += ang[:, None] * g_mir[None, :]
        if eff.wheel_jitter_arcsec > 0:
            ang = wd.jitter_angle(wd.effects_rng(seed, k, 2), ts, eff.wheel_jitter_arcsec, [w.wheel_tone_hz], [1.0])
            disp += ang[:, None] * g_roll[None, :]
        disp = disp[1:] - disp[0]              # relative to the scene at t = 0 (the edge stays centred)
        return ((1.0 + eps) * tl + (disp @ tau) / p_mm,
                eta * tl + (tau[0] * disp[:, 1] - tau[1] * disp[:, 0]) / p_mm)

    da, dc = path(wd.sample_times(cap, cam.n_phase, t.time_samples_per_phase))
    a, c = wd.tdi_mtf_path(da, dc, n_stages=cap, n_phase=cam.n_phase, n_time=t.time_samples_per_phase)
    return a, c, path
