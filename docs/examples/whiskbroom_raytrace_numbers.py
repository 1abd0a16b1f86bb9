"""Independent image motion of the whiskbroom camera (seed 002): the numbers of
docs/whiskbroom.md, "Independent image motion: ray tracing to the ellipsoid".

1. step study of the ray trace's central difference against the package's complex step;
2. the synthesis's own trial states (seed 0, 1000 trials, mirror-rate error 0.001 deg/s):
   knowledge and true V_P and the residuals by both routes;
3. WGS 84 minus sphere at the nominal state around the orbit, and in the trials with the
   truth on WGS 84 and the knowledge (the camera's model) on the sphere.

Run from the repository root: ``python docs/examples/whiskbroom_raytrace_numbers.py`` (~15 s).
"""

from __future__ import annotations

import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))

import numpy as np  # noqa: E402

from simcam.whiskbroom import geometry as geo  # noqa: E402
from simcam.whiskbroom import raytrace as rt  # noqa: E402
from simcam.whiskbroom import scenario as wsc  # noqa: E402
from simcam.whiskbroom import synthesis as sy  # noqa: E402
from simcam.units import WGS84_F  # noqa: E402

TRIALS = 1000


def trace(rows, flattening, x1, x3):
    return np.array([rt.image_motion(rt.World.from_values(dict(zip(geo.PARAMS, p)), flattening=flattening),
                                     x1, x3)[0] for p in rows])


def residuals(vk, vt):
    """Delta V_P, eps, eta at each trial's worst point (the synthesis's eqs 7-8)."""
    sk = np.hypot(vk[..., 0], vk[..., 1])
    st = np.hypot(vt[..., 0], vt[..., 1])
    db = (rt.drift_angle(vt) - rt.drift_angle(vk) + np.pi) % (2 * np.pi) - np.pi
    eps = st * np.cos(db) / sk - 1
    eta = st * np.sin(db) / sk
    w = np.argmax(np.abs(eps), 1)
    i = np.arange(vk.shape[0])
    return (st - sk)[i, w], eps[i, w], eta[i, w], np.degrees(db[i, w])


def main():
    sc = wsc.default()
    beta = sy.array_angle(sc)
    x1, x3 = sy.field_points(sc, beta)
    w = rt.World.from_scenario(sc, ellipsoid=False)

    print("1. step study, default state (gamma0 = 0), sphere, 199 field points")
    vg = geo.image_motion(sy.nominal_params(sc, math.radians(sc.orbit.gamma0_deg)), x1, x3)[0]
    for dt in (1e-5, 1e-4, 2e-4, 4e-4, 1e-3, 1e-2, 1e-1):
        err = np.abs(rt.image_motion(w, x1, x3, dt=dt)[0] - vg).max()
        print(f"   dt {dt:.0e} s: max |V_raytrace - V_complex_step| = {err:.2e} mm/s")
    print(f"   error bound at dt = {rt.DT_S:g} s: {rt.error_bound(w, x1, x3).max():.1e} mm/s;"
          f" |V| = {np.hypot(vg[:, 0], vg[:, 1]).min():.2f}-{np.hypot(vg[:, 0], vg[:, 1]).max():.2f} mm/s")

    print(f"2. the synthesis's trial states (seed 0, {TRIALS} trials, 0.001 deg/s), sphere")
    ks = np.arange(TRIALS)
    know, true = sy.trial_params(sc, sy.standard_draws(sc, sy.trial_uniforms(0, ks)), ks)
    r = sy.evaluate(know, true, x1, x3, backend="numpy")
    vk, vt = trace(know, 0.0, x1, x3), trace(true, 0.0, x1, x3)
    print(f"   max |V_raytrace - V_complex_step| = "
          f"{max(np.abs(vk - r.v_know).max(), np.abs(vt - r.v_true).max()):.1e} mm/s")
    dv, eps, eta, _ = residuals(vk, vt)
    print(f"   max |Delta V_P|: complex step {np.abs(r.dv_mm_s).max():.4f}, ray trace {np.abs(dv).max():.4f} mm/s;"
          f" q0.997 |eps| {np.quantile(np.abs(eps), 0.997):.3e}, |eta| {np.quantile(np.abs(eta), 0.997):.3e} px/stage")

    print("3. WGS 84 minus sphere, nominal state, 199 field points")
    for g in (0.0, 30.0, 60.0, 90.0):
        we = rt.World.from_scenario(sc, math.radians(g))
        vs = rt.image_motion(we.sphere(), x1, x3)[0]
        ve = rt.image_motion(we, x1, x3)[0]
        s = np.hypot(vs[:, 0], vs[:, 1])
        ds = np.abs(np.hypot(ve[:, 0], ve[:, 1]) - s)
        dc = np.abs(rt.tdi_components(ve - vs, beta))
        lat = math.degrees(math.asin(math.sin(we.inclination_rad) * math.sin(math.radians(g))))
        print(f"   gamma {g:3.0f} deg (latitude {lat:5.1f}): max d|V| {ds.max():.2e} mm/s ({ds.max() / s.min():.1e} of V);"
              f" along TDI {dc[:, 0].max():.3f}, across {dc[:, 1].max():.3f} mm/s;"
              f" d beta {np.degrees(np.abs(rt.drift_angle(ve) - rt.drift_angle(vs))).max():.3f} deg")
    vte = trace(true, WGS84_F, x1, x3)
    for name, v in (("sphere", vt), ("WGS 84", vte)):
        dv, eps, eta, db = residuals(vk, v)
        eq, hq = np.quantile(np.abs(eps), 0.997), np.quantile(np.abs(eta), 0.997)
        print(f"   truth on {name}: Delta V_P {dv.min():.3f} .. {dv.max():.3f} mm/s, max |Delta beta| {np.abs(db).max():.3f} deg,"
              f" q0.997 |eps| {eq:.2e}, |eta| {hq:.2e} px/stage; N pub {sy.stage_limit(eq)},"
              f" N impr {sy.stage_limit(eq, n_phase=sc.camera.n_phase, cross_q=hq)}")


if __name__ == "__main__":
    main()
