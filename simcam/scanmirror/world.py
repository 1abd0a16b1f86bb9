"""The scan-mirror world: the scenario turned into pointing, orbit, attitude, deviation and the
ground point of the line of sight (seed 003, eqs. 1-12 and 19-21 [R]).

:func:`ground_point_r0` is the one forward model: the exact line of sight (reflection on the
deviated mirror), the exact 3-1-2 attitude, the orbit-error matrix ``A_r0r`` and the orbit
radius, intersected with the sphere by the law of cosines (eqs. 3-5) or with the ellipsoid.
The world calls it with the injected truth; the lab's compensation calls it with what a lab
knows (its own estimates), never with the truth.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from simcam.scanmirror.attitude import PDAttitude, pd_system_matrix, profile_attitude
from simcam.scanmirror.geometry import (attitude_matrix_br, latlon_geocentric, line_of_sight_body,
                                        nominal_orbit_matrix_sr0, ray_ellipsoid_range, slant_range_sphere)
from simcam.scanmirror.orbit import (EarthModel, elements_to_state, orbit_angles, orbit_error_matrix_r0r,
                                     orbit_error_parameters, orbit_frame_matrix_Ir, propagate)
from simcam.scanmirror.scanplan import evaluate_plan, plan_duration_s

__all__ = ["ground_point_r0", "World", "deviation_components"]

E_Z = np.array([0.0, 0.0, 1.0])


def ground_point_r0(alpha_rad, beta_rad, dtau_x_rad, dtau_y_rad, att_rad, A_r0r, R_km, *,
                    earth_radius_km: float, omega0_rad: float, shape: str = "sphere",
                    polar_radius_km: float | None = None, A_br=None):
    """Geocentric ground point ``r_e`` in the nominal orbit frame ``r0`` (km), eqs. (2)-(7) [R].

    ``s^r = A_br^T s^b``; sphere: ``R_s`` from the law of cosines and
    ``r_e^{r0} = A_r0r (R_s s^r - R e_z)`` (eq. 23); ellipsoid: the ray from the satellite
    intersected with ``(x^2+y^2)/a^2 + z^2/b^2 = 1`` in ``s``. NaN rows where the line of
    sight misses the Earth. Shapes: angles (N,), ``att_rad`` (N, 3), ``A_r0r`` (N, 3, 3),
    ``R_km`` (N,).
    """
    sb = line_of_sight_body(alpha_rad, beta_rad, dtau_x_rad, dtau_y_rad)
    if A_br is None:
        att = np.asarray(att_rad, float)
        A_br = attitude_matrix_br(att[..., 0], att[..., 1], att[..., 2])
    sr = np.einsum("...ji,...j->...i", A_br, sb)
    R = np.asarray(R_km, float)
    if shape == "sphere":
        Rs = slant_range_sphere(sr[..., 2], R, earth_radius_km)
        v = Rs[..., None] * sr - R[..., None] * E_Z
        return np.einsum("...ij,...j->...i", A_r0r, v)
    A_sr0 = nominal_orbit_matrix_sr0(omega0_rad)
    M = A_sr0 @ A_r0r
    origin = np.einsum("...ij,...j->...i", M, -R[..., None] * E_Z)
    direction = np.einsum("...ij,...j->...i", M, sr)
    t = ray_ellipsoid_range(origin, direction, earth_radius_km, polar_radius_km)
    r_s = origin + t[..., None] * direction
    return np.einsum("ji,...j->...i", A_sr0, r_s)


def deviation_components(t_s, constant_rad, variable_rad, period_s, phase_rad, axis_rad):
    """``(dtau_x, dtau_y)`` (rad) of ``dtau(t) = dtau_c + dtau_v sin(2 pi t / P + phase)`` about
    the mirror-plane axis ``(cos a, sin a, 0)`` (eq. 19 [R]; f(t) chosen, the paper's is lost)."""
    tau = constant_rad + variable_rad * np.sin(2 * np.pi * np.asarray(t_s, float) / period_s + phase_rad)
    return tau * np.cos(axis_rad), tau * np.sin(axis_rad)


@dataclass
class World:
    """The scenario's fixed physics: plan, true orbit, attitude dynamics, Earth model."""

    scenario: object

    def __post_init__(self):
        sc = self.scenario
        o = sc.orbit
        self.earth = EarthModel(zonal_degree=o.zonal_degree)
        self.omega0_rad = np.deg2rad(o.nominal_longitude_deg)
        self.g0_rad = np.deg2rad(o.greenwich_angle_deg)
        self.R0_km = o.nominal_radius_km
        self.orbit_rate_rad_s = np.sqrt(self.earth.mu_km3_s2 / o.nominal_radius_km**3)
        self.duration_s = plan_duration_s(sc.effective_plan)
        self.r0_km, self.v0_km_s = elements_to_state(
            self.earth.mu_km3_s2, o.semi_major_axis_km, o.eccentricity, np.deg2rad(o.inclination_deg),
            np.deg2rad(o.raan_deg), np.deg2rad(o.arg_perigee_deg), np.deg2rad(o.true_anomaly_deg))
        self.orbit = propagate(self.r0_km, self.v0_km_s, self.duration_s + 1.0, self.earth)
        self.polar_radius_km = self.earth.radius_km * (1 - self.earth.flattening)

    # ------------------------------------------------------------------ parts
    def plan(self, t_s):
        return evaluate_plan(self.scenario.effective_plan, t_s)

    def orbit_geometry(self, t_s, *, position_offset_rtn_km=None):
        """Exact ``A_r0r`` (N,3,3), radius R (N,), position and velocity in ``I`` at ``t_s``;
        ``position_offset_rtn_km`` (3,) shifts the position (radial, along-track, cross-track):
        what a lab with an orbit-determination error believes."""
        r, v = self.orbit.state(t_s)
        if position_offset_rtn_km is not None:
            A_Ir = orbit_frame_matrix_Ir(r, v)
            d = np.asarray(position_offset_rtn_km, float)
            # radial = -z_r, along-track = x_r, cross-track (orbit normal, north) = -y_r
            r = r + (-d[0] * A_Ir[..., :, 2] + d[1] * A_Ir[..., :, 0] - d[2] * A_Ir[..., :, 1])
        A, R = orbit_error_matrix_r0r(r, v, t_s, self.earth, self.g0_rad, self.omega0_rad)
        return A, R, r, v

    def orbit_parameters(self, r_km, v_km_s, t_s):
        """The paper's small orbit angles (N, 3) (:func:`orbit_error_parameters`) and dR (N,)."""
        i, u, dom = orbit_angles(r_km, v_km_s, t_s, self.earth, self.g0_rad, self.omega0_rad)
        return orbit_error_parameters(i, u, dom), np.linalg.norm(r_km, axis=-1) - self.R0_km

    def pd_attitude(self, t_s) -> PDAttitude:
        a = self.scenario.attitude
        A, b = pd_system_matrix(a.inertia_kg_m2, a.kp_n_m_rad, a.kd_n_m_s_rad, self.orbit_rate_rad_s,
                                a.disturbance_torque_n_m)
        return PDAttitude(A, b, t_s)

    def attitude(self, t_s, initial_deg=None, *, pd: PDAttitude | None = None) -> np.ndarray:
        """True roll, pitch, yaw (N, 3) rad: PD response from ``initial_deg`` (rates 0) or the profile."""
        a = self.scenario.attitude
        if a.mode == "profile":
            return profile_attitude(t_s, np.deg2rad(a.profile_constant_deg), np.deg2rad(a.profile_amplitude_deg),
                                    a.profile_period_s, 0.0)
        pd = pd or self.pd_attitude(t_s)
        x0 = np.zeros(6)
        x0[:3] = np.deg2rad(a.initial_deg if initial_deg is None else initial_deg)
        return pd.angles(x0)

    def ground(self, alpha, beta, dtx, dty, att, A_r0r, R, *, A_br=None):
        """Ground point in ``r0`` (km) by :func:`ground_point_r0` with this scenario's Earth."""
        return ground_point_r0(alpha, beta, dtx, dty, att, A_r0r, R, earth_radius_km=self.earth.radius_km,
                               omega0_rad=self.omega0_rad, shape=self.scenario.orbit.earth_shape,
                               polar_radius_km=self.polar_radius_km, A_br=A_br)

    def nominal_ground(self, alpha, beta):
        """Nominal ground point (no deviation, zero attitude, nominal GEO orbit) in ``r0``."""
        alpha = np.asarray(alpha, float)
        n = alpha.shape
        return self.ground(alpha, beta, 0.0, 0.0, np.zeros(n + (3,)), np.broadcast_to(np.eye(3), n + (3, 3)),
                           np.full(n, self.R0_km))

    def latlon(self, r_e_r0):
        """Geocentric latitude and longitude (rad) of ground points given in ``r0``."""
        return latlon_geocentric(np.einsum("ij,...j->...i", nominal_orbit_matrix_sr0(self.omega0_rad), r_e_r0))

    def timeline(self, step_s: float) -> dict:
        """The whole plan every ``step_s``: commanded angles, the scenario's deviation (its
        axis and phase), the PD or profile attitude, the propagated orbit, and the nominal
        and true ground points (geocentric lat/lon, deg; NaN where the line of sight misses
        the Earth, e.g. in the star excursion). What ``benchmarks/bench_scanmirror.py`` times."""
        m = self.scenario.mirror
        t = np.arange(0.0, self.duration_s, step_s)
        plan = self.plan(t)
        dtx, dty = deviation_components(t, np.deg2rad(m.deviation_constant_deg), np.deg2rad(m.deviation_variable_deg),
                                        m.deviation_period_s, np.deg2rad(m.deviation_phase_deg),
                                        np.deg2rad(m.deviation_axis_deg))
        att = self.attitude(t)
        A, R, _, _ = self.orbit_geometry(t)
        g0 = self.nominal_ground(plan.alpha_rad, plan.beta_rad)
        g = self.ground(plan.alpha_rad, plan.beta_rad, dtx, dty, att, A, R)
        lat0, lon0 = self.latlon(g0)
        lat, lon = self.latlon(g)
        return {"t_s": t, "alpha_rad": plan.alpha_rad, "beta_rad": plan.beta_rad, "scan": plan.scan,
                "dtau_x_rad": dtx, "dtau_y_rad": dty, "attitude_rad": att, "lat0_deg": np.rad2deg(lat0),
                "lon0_deg": np.rad2deg(lon0), "lat_deg": np.rad2deg(lat), "lon_deg": np.rad2deg(lon)}

    @cached_property
    def nominal_orbit_matrix_sr0(self):
        return nominal_orbit_matrix_sr0(self.omega0_rad)
