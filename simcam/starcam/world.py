"""The star camera's world beyond the lab's model: hexapod pose errors and drift.

:class:`simcam.starcam.scenario.StarCameraEffects` gives the magnitudes (0 = off) and
:class:`simcam.starcam.scenario.StarCameraWorld` the settings of the model forms. The other
two effects live where their physics is: the distortion beyond the cubic in
:class:`simcam.starcam.optics.HigherOrderRadialDistortion`, the detector's integral
non-linearity in :mod:`simcam.detector`. Only the simulator and the truth routes
read them; the lab's plans and estimators never do.

Timeline of a lab run (:func:`timeline`). The protocols run in the order TE, HSFE,
chromatic, distortion; their conditions in plan order (condition index). A frame takes
``camera.exposure_s + world.frame_overhead_s``; a condition starts ``world.settle_s``
after the previous one ends, a protocol ``world.setup_s`` after the previous protocol.
Frame ``f`` of a condition starting at ``t0`` is dated at mid-exposure,
``t0 + f * period + exposure / 2``.

Commanded pointings (:func:`commanded_pointing_px`): the hexapod points the camera so that
the target's centre images where the plan says (TE: ``lab.target_center_px``; HSFE pose
``k``: that plus ``k * step_px`` along ``direction_deg``, or its grid offset with
``pattern = "grid"``; chromatic: the field centre of the
condition, the same for the three filters of a field; distortion: the grid target centred,
pointing ``(0, 0)``). A condition whose pointing differs from the previous condition's is
reached by a **move**.

**Hexapod** (:func:`hexapod_pose_errors`), per move, a rotation error of the camera about its
three axes: repeatability ``N(0, sigma_rep)`` per axis (arcsec), plus backlash ``b *
sign(move)`` on the two commanded axes (tip/tilt, the axes that move the image along u and
v; the sign kept from the last non-zero move on that axis; the state before the first move
of a run is unknown, drawn as +-1 per axis). No roll is commanded, so the roll (``theta_z``)
error is repeatability only. In a collimated beam a camera rotation ``(theta_u, theta_v)``
about the axes through its entrance pupil moves every star's image by ``theta / scale`` px
(common mode), and a roll ``delta`` about the optical axis moves the star at ``(u, v)`` by
``delta (-v, u)`` px: a field-dependent ``r delta`` that the HSFE method sees (it removes
only the common motion of each pose). Translations of the camera are left out: in a
collimated beam they move no image (the beam is the same everywhere in the pupil). The
draws come from ``SeedSequence(seed, spawn_key=(STREAM_HEXAPOD,))`` in acquisition order,
so each trial (seed) draws new pose errors, the same in every robustness case.

**Drift** (:func:`drift_px`) of the collimator/target, common to every star: a ramp of
``drift_rate_arcsec_per_h`` in a direction drawn uniformly per trial, plus a first-order
Gauss-Markov process per axis (stationary sigma ``drift_random_arcsec``, time constant
``drift_time_constant_s``), exact discretisation between frame times
``x_{k+1} = x_k e^{-dt/tau} + sigma sqrt(1 - e^{-2 dt/tau}) z`` (e.g. Gelb, *Applied Optimal
Estimation*, 1974, section 3.8), stationary start. Draws from
``SeedSequence(seed, spawn_key=(STREAM_DRIFT,))``. The simulation
(:func:`budget.starcam.protocols.simulate`) renders a condition's mean drift exactly and each
frame's deviation from it to first order (:meth:`simcam.starcam.render.StarCamera.drift_chain`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from simcam.starcam.scenario import Scenario
from simcam.units import ARCSEC_PER_RAD, SECONDS_PER_HOUR

#: SeedSequence roots of the world's per-trial draws (run seed)
STREAM_HEXAPOD = 402
STREAM_DRIFT = 403

#: acquisition order of the seed-000 protocols (as budget.starcam.protocols.PROTOCOLS)
RUN_ORDER = ("te", "hsfe", "chromatic", "distortion")


def _conditions(scn: Scenario):
    """(protocol, condition index, frames, commanded pointing px) in acquisition order."""
    p = scn.protocols
    out = [("te", 0, p.te.frames, tuple(map(float, scn.lab.target_center_px)))]
    h = p.hsfe
    ang = math.radians(h.direction_deg)
    cu, cv = scn.lab.target_center_px
    if h.pattern == "grid":
        for k, (gx, gy) in enumerate(h.grid_offsets_px()):
            out.append(("hsfe", k, h.frames, (cu + gx, cv + gy)))
    else:
        for k in range(h.conditions):
            out.append(("hsfe", k, h.frames, (cu + k * h.step_px * math.cos(ang),
                                              cv + k * h.step_px * math.sin(ang))))
    # the condition index is the lab's (field x number of lab filters + lab filter), whichever
    # filters the test takes (protocols.chromatic.filters_nm), as budget.starcam.protocols.make_plan
    nf = len(scn.lab.filters)
    chosen = scn.chromatic_filters_nm()
    taken = [k for k, f in enumerate(scn.lab.filters) if f.center_nm in chosen]
    for i, ctr in enumerate(p.chromatic.field_centers_px):
        for k in taken:
            out.append(("chromatic", i * nf + k, p.chromatic.frames, (float(ctr[0]), float(ctr[1]))))
    out.append(("distortion", 0, p.distortion.frames, (0.0, 0.0)))
    return out


def commanded_pointing_px(scn: Scenario) -> dict:
    """``{(protocol, condition): (u, v)}``: where the hexapod points the target centre (module docstring)."""
    return {(pr, i): pt for pr, i, _, pt in _conditions(scn)}


def timeline(scn: Scenario) -> dict:
    """``{(protocol, condition): (start_s, period_s, frames)}`` of a lab run (module docstring)."""
    w = scn.world
    period = scn.camera.exposure_s + w.frame_overhead_s
    out = {}
    t = 0.0
    prev = None
    for pr, i, n, _ in _conditions(scn):
        if prev is not None:
            t += w.setup_s if pr != prev else w.settle_s
        out[(pr, i)] = (t, period, n)
        t += n * period
        prev = pr
    return out


def frame_times_s(scn: Scenario, protocol: str, condition: int) -> np.ndarray:
    """Mid-exposure time (s from the start of the run) of each frame of a condition."""
    t0, period, n = timeline(scn)[(protocol, condition)]
    return t0 + np.arange(n) * period + 0.5 * scn.camera.exposure_s


def hexapod_pose_errors(scn: Scenario, seed: int) -> dict:
    """``{(protocol, condition): (dx_px, dy_px, roll_rad)}``: each condition's hexapod pose
    error as the common image displacement (tip/tilt, px) and the roll about the optical
    axis (rad), per move (module docstring). All zero when both hexapod magnitudes are 0."""
    eff = scn.world.effects
    sig = eff.hexapod_repeatability_arcsec
    b = eff.hexapod_backlash_arcsec
    scale = scn.camera.scale_arcsec_per_px
    conds = _conditions(scn)
    if sig == 0.0 and b == 0.0:
        return {(pr, i): (0.0, 0.0, 0.0) for pr, i, _, _ in conds}
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(STREAM_HEXAPOD,)))
    sign = rng.choice(np.array([-1.0, 1.0]), size=2)  # backlash state before the run's first move
    out = {}
    prev = None
    err = (0.0, 0.0, 0.0)
    for pr, i, _, pt in conds:
        if prev is None or pt != prev:
            if prev is not None:
                for ax in (0, 1):
                    d = pt[ax] - prev[ax]
                    if d != 0.0:
                        sign[ax] = math.copysign(1.0, d)
            rep = rng.normal(0.0, 1.0, 3) * sig
            err = ((rep[0] + b * sign[0]) / scale, (rep[1] + b * sign[1]) / scale, rep[2] / ARCSEC_PER_RAD)
        out[(pr, i)] = (float(err[0]), float(err[1]), float(err[2]))
        prev = pt
    return out


_GM_STEPS: dict = {}


def _gauss_markov_steps(t_s: np.ndarray, tau_s: float, sigma: float) -> tuple[list, list]:
    """The exact discretisation of the Gauss-Markov drift between frame times ``t_s``
    (module docstring): ``a_k = exp(-(t_k - t_{k-1}) / tau)`` and ``b_k = sigma sqrt(1 - a_k^2)``,
    k >= 1, as Python floats. They depend on the timeline only, not on the trial's draws:
    kept per timeline (the last 16)."""
    key = (t_s.tobytes(), float(tau_s), float(sigma))
    hit = _GM_STEPS.get(key)
    if hit is None:
        if len(_GM_STEPS) >= 16:
            _GM_STEPS.clear()
        tl = t_s.tolist()
        a = [math.exp(-(tl[k] - tl[k - 1]) / tau_s) for k in range(1, len(tl))]
        hit = _GM_STEPS[key] = (a, [sigma * math.sqrt(max(0.0, 1.0 - ak * ak)) for ak in a])
    return hit


def drift_px(scn: Scenario, seed: int) -> dict:
    """``{(protocol, condition): (frames, 2) array}``: the target drift (px, u and v) at each
    frame's mid-exposure time (module docstring). None when both drift magnitudes are 0."""
    eff = scn.world.effects
    rate = eff.drift_rate_arcsec_per_h
    sig = eff.drift_random_arcsec
    if rate == 0.0 and sig == 0.0:
        return None
    scale = scn.camera.scale_arcsec_per_px
    keys, times = [], []
    tl = timeline(scn)  # once (frame_times_s rebuilds it per condition)
    for pr, i, _, _ in _conditions(scn):
        keys.append((pr, i))
        t0, period, n = tl[(pr, i)]
        times.append(t0 + np.arange(n) * period + 0.5 * scn.camera.exposure_s)  # as frame_times_s
    t = np.concatenate(times)
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(STREAM_DRIFT,)))
    phi = rng.uniform(0.0, 2.0 * math.pi)
    z = rng.normal(0.0, 1.0, (t.size, 2))
    ramp = (rate / SECONDS_PER_HOUR) * t[:, None] * np.array([math.cos(phi), math.sin(phi)])[None, :]
    # the recursion on Python floats (the same IEEE operations in the same order as on
    # numpy rows, a microsecond less per frame), its coefficients kept per timeline
    zu, zv = z[:, 0].tolist(), z[:, 1].tolist()
    pu, pv = sig * zu[0], sig * zv[0]
    gu, gv = [pu], [pv]
    for a, b, u, v in zip(*_gauss_markov_steps(t, scn.world.drift_time_constant_s, sig), zu[1:], zv[1:]):
        pu = a * pu + b * u
        pv = a * pv + b * v
        gu.append(pu)
        gv.append(pv)
    gm = np.column_stack([gu, gv])
    d = (ramp + gm) / scale
    out = {}
    start = 0
    for key, tt in zip(keys, times):
        out[key] = d[start:start + tt.size]
        start += tt.size
    return out


@dataclass(frozen=True)
class WorldMotion:
    """One trial's hexapod pose errors and drift (see :func:`world_motion`)."""

    poses: dict
    drift: dict | None

    def pose(self, protocol: str, condition: int) -> tuple[float, float, float]:
        """(dx_px, dy_px, roll_rad) of a condition (zeros for an unknown one)."""
        return self.poses.get((protocol, condition), (0.0, 0.0, 0.0))

    def drift_of(self, protocol: str, condition: int, frames: int, first_frame: int = 0):
        """(frames, 2) drift (px) of frames ``first_frame ..`` of a condition, or None (no drift)."""
        if self.drift is None or (protocol, condition) not in self.drift:
            return None
        d = self.drift[(protocol, condition)]
        if first_frame + frames > d.shape[0]:
            # more frames than the scenario's protocol plans: continue the ramp's last step
            extra = first_frame + frames - d.shape[0]
            step = d[-1] - d[-2] if d.shape[0] > 1 else np.zeros(2)
            d = np.concatenate([d, d[-1] + step * np.arange(1, extra + 1)[:, None]])
        return d[first_frame:first_frame + frames]


def world_motion(scn: Scenario, seed: int) -> WorldMotion | None:
    """The hexapod and drift of a trial with run seed ``seed``; None when both are off."""
    eff = scn.world.effects
    if not any((eff.hexapod_repeatability_arcsec, eff.hexapod_backlash_arcsec, eff.drift_rate_arcsec_per_h,
                eff.drift_random_arcsec)):
        return None
    return WorldMotion(hexapod_pose_errors(scn, seed), drift_px(scn, seed))
