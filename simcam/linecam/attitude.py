"""Orbit and attitude of the spacecraft carrying the line camera.

* Orbit: circular two-body orbit (Vallado 2013, *Fundamentals of Astrodynamics*, 4th ed.,
  sec. 2.2: ``r = a (cos u P + sin u Q)``, ``v = a n (-sin u P + cos u Q)``, mean motion
  ``n = sqrt(mu / a^3)``, ``P = (cos W, sin W, 0)``, ``Q = (-cos i sin W, cos i cos W, sin i)``),
  GCRS axes. Only the observer's position and velocity matter here (parallax and
  aberration of light), so a two-body orbit is enough.
* Attitude: the body (= nominal camera) frame rotates at constant body rates
  ``w = (w_x, w_y, w_z)`` during a pass: ``R(t) = R_mid exp([w]x (t - t_mid))`` (body ->
  GCRS), the kinematics ``dR/dt = R [w]x`` integrated exactly for constant ``w``. The
  scan is about the camera ``y`` axis (along the line) at the matched rate
  ``w_y = p / (f T) (1 + rate_mismatch)``, so the image moves along ``+x`` at
  ``f w_y`` (seed 004 eq. 4.1, first term), in step with the TDI charge; the world's
  ``line_rate_mismatch_percent`` effect (:mod:`simcam.linecam.effects`) adds to
  ``rate_mismatch``.
* Pass ``k`` of ``P`` is shifted across track by a rotation about the camera ``x`` axis of
  ``(k - (P - 1)/2) shift_px p / f`` (the patent's step 7: repeated observations with
  shifts so that stars cover the whole line).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from simcam.units import MU_EARTH_KM3_S2, WGS84_A_KM

from .scenario import LineCamScenario

__all__ = ["orbit_state", "ScanPlan", "scan_plan", "strip_frame"]


def orbit_state(scenario: LineCamScenario, t_s) -> tuple[np.ndarray, np.ndarray]:
    """Geocentric position (km) and velocity (km/s), GCRS axes, at ``t_s`` after the epoch.

    Returns arrays of shape ``t.shape + (3,)``.
    """
    o = scenario.orbit
    a = WGS84_A_KM + o.altitude_km
    n = np.sqrt(MU_EARTH_KM3_S2 / a**3)
    inc, raan = np.radians(o.inclination_deg), np.radians(o.raan_deg)
    P = np.array([np.cos(raan), np.sin(raan), 0.0])
    Q = np.array([-np.cos(inc) * np.sin(raan), np.cos(inc) * np.cos(raan), np.sin(inc)])
    u = np.radians(o.arg_latitude_deg) + n * np.asarray(t_s, dtype=float)
    cu, su = np.cos(u)[..., None], np.sin(u)[..., None]
    return a * (cu * P + su * Q), a * n * (-su * P + cu * Q)


def strip_frame(ra_deg: float, dec_deg: float, pa_deg: float) -> np.ndarray:
    """Body -> GCRS rotation matrix that points the boresight (``-z``) at (ra, dec) with the
    scan direction (position angle ``pa_deg`` from north through east) along ``-x``.

    The boresight then moves along the scan direction for ``w_y > 0``.
    """
    ra, dec, pa = np.radians([ra_deg, dec_deg, pa_deg])
    c = np.array([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)])
    east = np.array([-np.sin(ra), np.cos(ra), 0.0])
    north = np.cross(c, east)
    scan = np.cos(pa) * north + np.sin(pa) * east
    z = -c
    x = -scan
    y = np.cross(z, x)
    return np.column_stack([x, y, z])


@dataclass(frozen=True)
class ScanPlan:
    """Times and attitude of the passes over one strip.

    Attributes
    ----------
    r_mid : numpy.ndarray, shape (P, 3, 3)
        Body -> GCRS at the middle of each pass.
    t_start_s, t_mid_s : numpy.ndarray, shape (P,)
        Start and middle of each pass, s after the orbit epoch.
    duration_s : float
        Duration of a pass (strip length / nominal scan rate).
    rate_rad_s : numpy.ndarray, shape (3,)
        Body rates (true), rad/s.
    """

    r_mid: np.ndarray
    t_start_s: np.ndarray
    t_mid_s: np.ndarray
    duration_s: float
    rate_rad_s: np.ndarray

    @property
    def passes(self) -> int:
        return int(self.t_mid_s.size)

    def matrices(self, t_s, pass_index) -> np.ndarray:
        """Body -> GCRS matrices (n, 3, 3) at times ``t_s`` of passes ``pass_index``:
        ``R_mid exp([w]x tau)`` by Rodrigues' formula."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        k = np.broadcast_to(np.asarray(pass_index), t.shape)
        tau = t - self.t_mid_s[k]
        return self.r_mid[k] @ rodrigues(tau[:, None] * self.rate_rad_s)

    def attitude(self, t_s, pass_index) -> Rotation:
        """Body -> GCRS at times ``t_s`` of passes ``pass_index`` (broadcast, 1-D)."""
        return Rotation.from_matrix(self.matrices(t_s, pass_index))


def rodrigues(rotvec) -> np.ndarray:
    """Rotation matrices (n, 3, 3) of rotation vectors (n, 3):
    ``I + sin(a) K + (1 - cos(a)) K^2`` with ``K = [e]x`` (Rodrigues' formula).

    Written out, not ``Rotation.from_rotvec(...).as_matrix()``: the line-camera study is pinned
    bit for bit (tests/test_linecam_effects.py, ideal world) and scipy's quaternion route
    differs in the last bit, which moves its estimates.
    """
    v = np.asarray(rotvec, dtype=float)
    a = np.linalg.norm(v, axis=-1)
    safe = np.where(a > 0, a, 1.0)
    e = v / safe[:, None]
    K = np.zeros(v.shape[:-1] + (3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -e[:, 2], e[:, 1], -e[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = e[:, 2], -e[:, 1], e[:, 0]
    s = np.sin(a)[:, None, None]
    c = (1.0 - np.cos(a))[:, None, None]
    return np.eye(3) + s * K + c * (K @ K)


def scan_plan(scenario: LineCamScenario, *, ra_deg: float, dec_deg: float) -> ScanPlan:
    """The passes of a scenario over the strip centred at (ra, dec)."""
    cam, att, obs = scenario.camera, scenario.attitude, scenario.observation
    w0 = cam.matched_rate_rad_s
    # the world's line-rate mismatch effect adds to the scenario's own mismatch
    mismatch = att.rate_mismatch + scenario.world.effects.line_rate_mismatch_percent / 100.0
    rate = np.array([np.radians(att.cross_rate_deg_s), w0 * (1.0 + mismatch),
                     np.radians(att.yaw_rate_deg_s)])
    duration = np.radians(scenario.stars.strip_length_deg) / w0
    base = strip_frame(ra_deg, dec_deg, scenario.stars.scan_pa_deg)
    k = np.arange(obs.passes)
    shifts = (k - 0.5 * (obs.passes - 1)) * obs.shift_px * cam.pitch_mm / cam.focal_length_mm
    r_mid = np.stack([base @ Rotation.from_rotvec([s, 0.0, 0.0]).as_matrix() for s in shifts])
    t_start = k * obs.pass_interval_s
    return ScanPlan(r_mid=r_mid, t_start_s=t_start.astype(float), t_mid_s=t_start + 0.5 * duration,
                    duration_s=float(duration), rate_rad_s=rate)
