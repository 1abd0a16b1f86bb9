"""Seed 000: what the star-camera simulator would refuse, checked before any work.

The star-camera study's :meth:`~budget.runner.capabilities.CheckedScenario.check` (used by the sweep engine
on every point before a sweep starts): a star the render would put off the detector is one
:class:`~simcam.infra.errors.ScenarioError` naming the protocol, the condition and the star,
not a failure hours into a run.
"""

from __future__ import annotations

import numpy as np

from simcam.infra.errors import ScenarioError
from simcam.starcam import optics
from simcam.starcam.targets import calibration_grid, star_grid

__all__ = ["check_geometry"]


def check_geometry(scenario, *, where: str) -> None:
    """Seed 000: every star of every protocol condition (and of the HSFE truth's sub-pixel
    phases) lands on a chip at least half a window from its edges and the gap, the test
    :meth:`simcam.starcam.render.StarCamera.scene` applies when it renders."""
    from budget.starcam.protocols import PROTOCOLS, make_plan
    from simcam.starcam.render import StarCamera

    cam = StarCamera(scenario, parallel=False)
    scn = scenario
    half = scn.render.window_px // 2
    lc = scn.optics.lateral_colour
    # every star of every condition, grouped by filter (one vectorised test per filter)
    groups: dict = {}
    for proto in PROTOCOLS:
        for c in make_plan(proto, scn).conditions:
            lay = calibration_grid(scn) if c.target == "calibration_grid" else star_grid(scn, center_px=c.field_center_px)
            shifts = [(c.platform_dx_px, c.platform_dy_px)]
            if proto == "hsfe" and c.index == 0:  # the HSFE truth visits phases in [0, 1) px
                shifts.append((c.platform_dx_px + 1.0, c.platform_dy_px + 1.0))
            for dx, dy in shifts:
                g = groups.setdefault(c.filter_nm, ([], [], []))
                g[0].append(lay.u_px + dx)
                g[1].append(lay.v_px + dy)
                g[2].extend((proto, c.label, j) for j in range(lay.n_stars))
    for filter_nm, (us, vs, who) in groups.items():
        wl, rate = cam.spectra.electron_rate_per_nm(filter_nm=filter_nm)
        w = cam.spectra.weights(rate)
        ud, vd = cam.distortion.forward(u_px=np.concatenate(us), v_px=np.concatenate(vs))
        su, sv = optics.lateral_colour_shift_px(
            wavelength_nm=wl, u_px=ud, v_px=vd, ref_wavelength_nm=lc.ref_wavelength_nm,
            radial_coeffs=tuple(lc.radial_px_per_nm), uniform_x_coeffs=tuple(lc.uniform_x_px_per_nm),
            uniform_y_coeffs=tuple(lc.uniform_y_px_per_nm), r_norm_px=scn.optics.r_norm_px)
        chip, _, _ = cam.mosaic.focal_to_chip(ud + su @ w, vd + sv @ w, margin_px=half)
        bad = np.flatnonzero(chip < 0)
        if bad.size:
            k = int(bad[0])
            proto, label, j = who[k]
            raise ScenarioError(
                f"{where}: protocol {proto}, condition {label!r}: star {j} at focal (u, v) = "
                f"({ud[k]:.1f}, {vd[k]:.1f}) px is off the detector or within {half} px of a chip "
                f"edge or gap ({bad.size} star positions of the plans fail)")

