"""One simulated run of the scan-mirror method: the world injects the errors, the lab estimates
the normal deviation from the star dwells and compensates the area scans (seed 003).

:class:`Setup` holds everything that does not change from one trial to the next (the plan on
its grid, the true orbit, the attitude transition matrices, the stars of each dwell, the
first-order compensation coefficients), computed once per scenario and process;
:func:`run` draws one trial's errors from a numpy Generator and returns estimates, truths
and ground errors.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from budget.scanmirror.compensation import FirstOrderCompensator, exact_compensation, ground_errors_deg
from budget.scanmirror.estimation import DwellMeasurement, batch_estimate, published_estimate
from simcam.infra.errors import ScenarioError
from simcam.infra.lifecycle import check_memory
from simcam.scanmirror.effects import WorldEffects
from simcam.scanmirror.geometry import rotvec_matrix
from simcam.scanmirror.stars import body_to_inertial, find_dwell_stars, true_centroids
from simcam.scanmirror.world import World, deviation_components
from simcam.units import RAD_PER_ARCSEC

__all__ = ["Setup", "run", "VARIANTS"]

VARIANTS = ("published", "improved", "without_estimate")


@dataclass
class Setup:
    """Per-scenario precomputation on the sample times ``t_s`` (only area-scan samples are kept)."""

    scenario: object
    step_s: float
    scans: tuple[int, ...] | None = None
    source: str = "scenario"
    world: World = field(init=False)

    #: bytes per ground sample held while the setup is built (plan angles, ground points,
    #: orbit geometry, attitude matrices): a lower bound, so nothing feasible is refused
    BYTES_PER_SAMPLE = 400

    def _check_size(self, duration_s: float) -> None:
        """Refuse, before allocating, a step that gives more samples than memory holds,
        naming the scenario field the step came from."""
        sc = self.scenario
        field_name = "ground_step_s"
        for sect in ("compensation", "validation"):
            if getattr(getattr(sc, sect, None), "ground_step_s", None) == self.step_s:
                field_name = f"{sect}.ground_step_s"
                break
        n = float(duration_s) / float(self.step_s)
        check_memory(n * self.BYTES_PER_SAMPLE,
                     what=f"{self.source}: {field_name} = {self.step_s:g} s over the plan's {duration_s:.4g} s "
                          f"(scan_plan): {n:.3g} ground samples")

    def __post_init__(self):
        w = self.world = World(self.scenario)
        self._check_size(w.duration_s)
        t = np.arange(0.0, w.duration_s, self.step_s)
        plan = w.plan(t)
        keep = plan.scan > 0 if self.scans is None else np.isin(plan.scan, self.scans)
        self.t_s = t[keep]
        self.scan = plan.scan[keep]
        self.alpha0, self.beta0 = plan.alpha_rad[keep], plan.beta_rad[keep]
        self.g0 = w.nominal_ground(self.alpha0, self.beta0)
        self.latlon0 = w.latlon(self.g0)
        if np.isnan(self.g0).any():
            j = int(np.flatnonzero(np.isnan(self.g0[:, 0]))[0])
            raise ScenarioError(
                f"{self.source}: scan_plan.segments: area scan {int(self.scan[j])} leaves the Earth disc at "
                f"t = {self.t_s[j]:.1f} s (alpha {np.rad2deg(self.alpha0[j]):.3f} deg, beta "
                f"{np.rad2deg(self.beta0[j]):.3f} deg) where ground points are asked for")
        self.A_true, self.R_true, self.r, self.v = w.orbit_geometry(self.t_s)
        self.dwells = find_dwell_stars(w, source=self.source)
        self.scan_start = {int(s): float(self.t_s[self.scan == s][0]) for s in np.unique(self.scan)}
        frame_t = np.concatenate([d.frame_t_s for d in self.dwells]) if self.dwells else np.zeros(0)
        self._att_t = np.concatenate([self.t_s, frame_t])
        self.pd = w.pd_attitude(self._att_t) if self.scenario.attitude.mode == "pd" else None
        self.comp = FirstOrderCompensator(w, self.alpha0, self.beta0)
        self.dwell_A0 = [body_to_inertial(d.r_km, d.v_km_s, np.zeros((d.frame_t_s.size, 3))) for d in self.dwells]
        # the world's unmodelled effects (simulator side; the estimators never see them)
        self.effects = WorldEffects(self.scenario, w, self.dwells)

    def attitude(self, initial_deg):
        att = self.world.attitude(self._att_t, initial_deg, pd=self.pd)
        n = self.t_s.size
        out, k = [], n
        for d in self.dwells:
            out.append(att[k:k + d.frame_t_s.size])
            k += d.frame_t_s.size
        return att[:n], out


def run(setup: Setup, rng: np.random.Generator, *, keep_series: bool = False) -> dict:
    """One trial: draws, star measurements, estimates, compensation, ground errors.

    Returns a dict with ``dtau_true`` (rad, (2,), at the last dwell before the last scan),
    ``dtau`` {variant: (2,)}, ``dtau_sigma`` (improved, (2,)), and per scan number
    ``errors[scan][variant] = (lat_deg, lon_deg)`` arrays (plus ``uncompensated``).
    """
    sc = setup.scenario
    w = setup.world
    m, a, ss = sc.mirror, sc.attitude, sc.star_sensing
    # --- draws (fixed order: the stream is the trial's)
    if m.random_axis:
        axis, phase = rng.uniform(0, 2 * np.pi), rng.uniform(0, 2 * np.pi)
    else:
        axis, phase = np.deg2rad(m.deviation_axis_deg), np.deg2rad(m.deviation_phase_deg)
    const = np.deg2rad(m.deviation_constant_deg) + np.deg2rad(m.constant_sigma_deg) * rng.standard_normal()
    init = np.asarray(a.initial_deg) + a.initial_sigma_deg * rng.standard_normal(3)
    orbit_offset = sc.orbit.knowledge_sigma_km * rng.standard_normal(3)
    att_know = a.knowledge_sigma_arcsec * RAD_PER_ARCSEC * rng.standard_normal(3)
    n_d = len(setup.dwells)
    tracker_err = ss.tracker_sigma_arcsec * RAD_PER_ARCSEC * rng.standard_normal((n_d, 3))
    noise = [ss.centroid_sigma_arcsec * RAD_PER_ARCSEC * rng.standard_normal(d.visible.shape + (2,)) for d in setup.dwells]
    # the world's effects draw from a child spawned after the lab's draws: off, nothing changes
    fx = setup.effects.draw(rng.spawn(1)[0], setup.t_s) if setup.effects.on else None

    def dev(t):
        base = deviation_components(t, const, np.deg2rad(m.deviation_variable_deg), m.deviation_period_s, phase, axis)
        if fx is None:
            return base
        return fx.deviation(t, base, variable_rad=np.deg2rad(m.deviation_variable_deg), period_s=m.deviation_period_s,
                            phase_rad=phase, axis_rad=axis)

    att_scan, att_frames = setup.attitude(init)
    # --- star measurements and the estimates (per dwell, for every scan that follows)
    meas_app, meas_cat = [], []
    for j, (d, af, te, nz) in enumerate(zip(setup.dwells, att_frames, tracker_err, noise)):
        dtx_f, dty_f = dev(d.frame_t_s)
        cen = true_centroids(d if fx is None else setup.effects.world_dwell(j), dtx_f, dty_f, af) + nz
        cen = np.where(d.visible[..., None], cen, np.nan)
        A_true = body_to_inertial(d.r_km, d.v_km_s, af)
        # the tracker's A_Ib = A_true R(error): the lab's white per-dwell error, plus the world's
        tracker = A_true @ rotvec_matrix(-te if fx is None else fx.tracker_dwell[j] - te)
        meas_app.append(DwellMeasurement(d.apparent_I, tracker, cen, d.alpha_rad, d.beta_rad))
        meas_cat.append(DwellMeasurement(d.apparent_I if ss.published_uses_aberration else d.catalogue_I,
                                         tracker, cen, d.alpha_rad, d.beta_rad))
    # --- lab knowledge during the scans
    A_lab, R_lab, r_lab, v_lab = w.orbit_geometry(setup.t_s, position_offset_rtn_km=orbit_offset)
    orb_lab, dR_lab = w.orbit_parameters(r_lab, v_lab, setup.t_s)
    att_lab = att_scan + att_know
    if fx is not None:  # the same tracker process continues through the scan (small angles: 3-1-2 = rotation vector)
        att_lab = att_lab + fx.tracker_scan
    dtx_t, dty_t = dev(setup.t_s)
    out = {"errors": {}, "dtau": {}, "dtau_sigma": np.full(2, np.nan), "dtau_true": np.full(2, np.nan)}
    sc_errors = {}
    for s in sorted(setup.scan_start):
        sel = setup.scan == s
        before = [j for j, d in enumerate(setup.dwells) if d.frame_t_s[-1] < setup.scan_start[s]]
        if before:
            last = setup.dwells[before[-1]]
            mid = int(last.frame_t_s.size // 2)
            star = int(np.nanargmin(np.where(last.visible[mid], np.abs(meas_cat[before[-1]].centroids[mid]).max(-1),
                                             np.inf)))
            if not last.visible[mid, star]:
                fr = np.flatnonzero(last.visible.any(1))[0]
                mid, star = int(fr), int(np.flatnonzero(last.visible[fr])[0])
            est_pub = published_estimate(meas_cat[before[-1]], star=star, frame=mid)
            est_imp, cov = batch_estimate([meas_app[j] for j in before],
                                          centroid_sigma_rad=ss.centroid_sigma_arcsec * RAD_PER_ARCSEC,
                                          tracker_sigma_rad=ss.tracker_sigma_arcsec * RAD_PER_ARCSEC)
            t_mid = float(last.frame_t_s.mean())
            truth = np.array(dev(t_mid))
        else:
            est_pub = est_imp = np.zeros(2)
            cov = np.full((2, 2), np.nan)
            truth = np.full(2, np.nan)
        est = {"published": est_pub, "improved": est_imp, "without_estimate": np.zeros(2)}
        out["dtau"], out["dtau_sigma"], out["dtau_true"] = est, np.sqrt(np.diag(cov)), truth
        errs = {"uncompensated": _errors_sel(setup, sel, setup.alpha0[sel], setup.beta0[sel], dtx_t[sel],
                                             dty_t[sel], att_scan[sel])}
        # published: first-order corrections from the nine parameters the lab knows
        p = np.column_stack([np.full(sel.sum(), est_pub[0]), np.full(sel.sum(), est_pub[1]), att_lab[sel],
                             orb_lab[sel], dR_lab[sel]])
        K = setup.comp.K[sel]
        d = np.einsum("nij,nj->ni", K, p)
        errs["published"] = _errors_sel(setup, sel, setup.alpha0[sel] + d[:, 0], setup.beta0[sel] + d[:, 1],
                                        dtx_t[sel], dty_t[sel], att_scan[sel])
        for name, e in (("improved", est_imp), ("without_estimate", np.zeros(2))):
            ac, bc = exact_compensation(w, setup.alpha0[sel], setup.beta0[sel], np.full(sel.sum(), e[0]),
                                        np.full(sel.sum(), e[1]), att_lab[sel], A_lab[sel], R_lab[sel],
                                        target=setup.g0[sel, :2])
            errs[name] = _errors_sel(setup, sel, ac, bc, dtx_t[sel], dty_t[sel], att_scan[sel])
            if keep_series:
                errs[name + "_angles"] = (ac - setup.alpha0[sel], bc - setup.beta0[sel])
        sc_errors[s] = errs
    out["errors"] = sc_errors
    if fx is not None:
        out["effects"] = fx
    if keep_series:
        t_all = np.arange(0.0, w.duration_s, setup.step_s)
        dx_all, dy_all = dev(t_all)
        out["series"] = {"t_s": setup.t_s, "scan": setup.scan, "dtau_x": dtx_t, "dtau_y": dty_t,
                         "attitude": att_scan, "g0": setup.g0, "t_all_s": t_all, "dtau_x_all": dx_all,
                         "dtau_y_all": dy_all}
    return out


def _errors_sel(setup, sel, alpha, beta, dtx, dty, att):
    # commanded angles -> the mirror's true ones (the world's encoders; identity when off)
    alpha, beta = setup.effects.true_angles(alpha, beta)
    g = setup.world.ground(alpha, beta, dtx, dty, att, setup.A_true[sel], setup.R_true[sel])
    return ground_errors_deg(setup.world, g, None, latlon0=(setup.latlon0[0][sel], setup.latlon0[1][sel]))
