"""One simulated run of the scan-mirror method: the world injects the errors, the lab estimates
the normal deviation from the star dwells and compensates the area scans (seed 003).

:class:`Setup` holds everything that does not change from one trial to the next (the plan on
its grid, the true orbit, the attitude transition matrices, the stars of each dwell, the
first-order compensation coefficients), computed once per scenario and process;
:func:`run` draws one trial's errors from a numpy Generator and returns a
:class:`ScanOutcome`: the deviation estimates, the injected deviation, the stated sigma and
the ground errors (:class:`GroundErrors`) of every area scan under each compensation. It runs
in named steps: the draws, the star measurements of the dwells, the lab's orbit and attitude
knowledge, and per area scan the estimates and the compensations.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from budget.scanmirror.compensation import FirstOrderCompensator, exact_compensation
from budget.scanmirror.estimation import DwellMeasurement, batch_estimate, published_estimate
from simcam.infra.errors import ScenarioError
from simcam.infra.lifecycle import check_memory
from simcam.scanmirror.effects import TrialEffects, WorldEffects
from simcam.scanmirror.geometry import rotvec_matrix
from simcam.scanmirror.stars import body_to_inertial, find_dwell_stars, true_centroids
from simcam.scanmirror.truth import ground_errors_truth_deg, ground_latlon_truth, ground_point_s_truth
from simcam.scanmirror.world import World, deviation_components
from simcam.units import RAD_PER_ARCSEC

__all__ = ["Setup", "run", "VARIANTS", "ScanOutcome", "GroundErrors", "TimelineSeries"]

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
        self.lat0, self.lon0 = w.latlon(self.g0)  # the lab's nominal grid (its targets)
        if np.isnan(self.g0).any():
            j = int(np.flatnonzero(np.isnan(self.g0[:, 0]))[0])
            raise ScenarioError(
                f"{self.source}: scan_plan.segments: area scan {int(self.scan[j])} leaves the Earth disc at "
                f"t = {self.t_s[j]:.1f} s (alpha {np.rad2deg(self.alpha0[j]):.3f} deg, beta "
                f"{np.rad2deg(self.beta0[j]):.3f} deg) where ground points are asked for")
        self.A_true, self.R_true, self.r, self.v = w.orbit_geometry(self.t_s)
        # the truth's nominal ground points, by the truth's own route (simcam.scanmirror.truth)
        n = self.t_s.size
        self.truth_latlon0 = ground_latlon_truth(self.truth_ground(
            self.alpha0, self.beta0, 0.0, 0.0, np.zeros((n, 3)), np.broadcast_to(np.eye(3), (n, 3, 3)),
            np.full(n, w.R0_km)))
        self.dwells = find_dwell_stars(w, source=self.source)
        self.scan_start = {int(s): float(self.t_s[self.scan == s][0]) for s in np.unique(self.scan)}
        frame_t = np.concatenate([d.frame_t_s for d in self.dwells]) if self.dwells else np.zeros(0)
        self._att_t = np.concatenate([self.t_s, frame_t])
        self.pd = w.pd_attitude(self._att_t) if self.scenario.attitude.mode == "pd" else None
        self.comp = FirstOrderCompensator(w, self.alpha0, self.beta0)
        self.dwell_A0 = [body_to_inertial(d.r_km, d.v_km_s, np.zeros((d.frame_t_s.size, 3))) for d in self.dwells]
        # the world's unmodelled effects (simulator side; the estimators never see them)
        self.effects = WorldEffects(self.scenario, w, self.dwells)

    def truth_ground(self, alpha, beta, dtx, dty, att, A_r0r, R_km):
        """The world's ground points in ``s`` (km) by the truth's route
        (:func:`simcam.scanmirror.truth.ground_point_s_truth`), with this scenario's Earth."""
        w = self.world
        polar = w.polar_radius_km if self.scenario.orbit.earth_shape == "ellipsoid" else w.earth.radius_km
        return ground_point_s_truth(alpha, beta, dtx, dty, att, A_r0r, R_km, omega0_rad=w.omega0_rad,
                                    equatorial_radius_km=w.earth.radius_km, polar_radius_km=polar)

    def attitude(self, initial_deg):
        att = self.world.attitude(self._att_t, initial_deg, pd=self.pd)
        n = self.t_s.size
        out, k = [], n
        for d in self.dwells:
            out.append(att[k:k + d.frame_t_s.size])
            k += d.frame_t_s.size
        return att[:n], out


# --------------------------------------------------------------------------- what a run returns
@dataclass(frozen=True)
class GroundErrors:
    """Ground errors of one area scan under one compensation: geocentric latitude and
    longitude of each sample's ground point minus its nominal one (deg, arrays over the
    scan's samples)."""

    lat_deg: np.ndarray
    lon_deg: np.ndarray


@dataclass(frozen=True)
class TimelineSeries:
    """The timeline of one run (:func:`run` with ``keep_series``): the area-scan samples of
    the setup (``t_s``, ``scan``, their nominal ground points ``g0``), the injected deviation
    and the true attitude angles there, and the injected deviation over the whole plan
    every ``step_s`` (``t_all_s``)."""

    t_s: np.ndarray
    scan: np.ndarray
    g0: np.ndarray
    dtau_x_rad: np.ndarray
    dtau_y_rad: np.ndarray
    attitude_rad: np.ndarray
    t_all_s: np.ndarray
    dtau_x_all_rad: np.ndarray
    dtau_y_all_rad: np.ndarray


@dataclass(frozen=True)
class ScanOutcome:
    """One trial of the scan-mirror method.

    Attributes
    ----------
    dtau_rad : mapping of str to numpy.ndarray (2,)
        The deviation estimate (dtau_x, dtau_y) of each variant (:data:`VARIANTS`) from the
        last star dwell before the last area scan (zero where no dwell precedes it, and
        always for ``without_estimate``).
    dtau_true_rad : numpy.ndarray (2,)
        The injected deviation at the middle of that dwell (NaN without a dwell).
    dtau_sigma_rad : numpy.ndarray (2,)
        The improved estimator's stated 1-sigma (NaN without a dwell).
    errors : mapping of int to mapping of str to GroundErrors
        Per area-scan number, the ground errors under each compensation (:data:`VARIANTS`)
        and ``uncompensated`` (the world's, by the truth route).
    lab_errors : mapping of int to GroundErrors
        Per area-scan number, the ground errors of the ``improved`` compensation as the lab's
        own model has them (its deviation estimate, orbit and attitude knowledge): what the
        lab believes it left (0 to the Newton tolerance).
    effects : simcam.scanmirror.effects.TrialEffects or None
        The world's unmodelled effects drawn for this trial (None when they are off).
    series : TimelineSeries or None
        The timeline, when :func:`run` is asked to keep it.
    """

    dtau_rad: Mapping[str, np.ndarray]
    dtau_true_rad: np.ndarray
    dtau_sigma_rad: np.ndarray
    errors: Mapping[int, Mapping[str, GroundErrors]]
    lab_errors: Mapping[int, GroundErrors] = field(default_factory=dict)
    effects: TrialEffects | None = None
    series: TimelineSeries | None = None

    @property
    def last_scan(self) -> int:
        """The number of the last area scan."""
        return max(self.errors)


# --------------------------------------------------------------------------- the steps of a run
@dataclass(frozen=True)
class _Draws:
    """One trial's draws, in the order the trial's stream gives them."""

    axis_rad: float
    phase_rad: float
    constant_rad: float
    initial_deg: np.ndarray
    orbit_offset_km: np.ndarray
    knowledge_rad: np.ndarray
    tracker_rad: np.ndarray
    centroid_noise_rad: list
    effects: TrialEffects | None


@dataclass(frozen=True)
class _Deviation:
    """The injected normal deviation (dtau_x, dtau_y) in rad at any time: the seed's sinusoid
    and, where the world's effects are on, their extra terms."""

    constant_rad: float
    variable_rad: float
    period_s: float
    phase_rad: float
    axis_rad: float
    effects: TrialEffects | None

    def __call__(self, t):
        base = deviation_components(t, self.constant_rad, self.variable_rad, self.period_s, self.phase_rad,
                                    self.axis_rad)
        if self.effects is None:
            return base
        return self.effects.deviation(t, base, variable_rad=self.variable_rad, period_s=self.period_s,
                                      phase_rad=self.phase_rad, axis_rad=self.axis_rad)


@dataclass(frozen=True)
class _LabKnowledge:
    """What the lab knows during the area scans: its orbit (geometry and the compensation's
    orbit parameters) and its attitude angles (rad)."""

    A: np.ndarray
    R_km: np.ndarray
    orbit: np.ndarray
    dR_km: np.ndarray
    attitude_rad: np.ndarray


@dataclass(frozen=True)
class _Estimate:
    """The deviation estimates for one area scan (rad), the improved one's covariance and the
    injected deviation at the dwell they come from."""

    published: np.ndarray
    improved: np.ndarray
    cov: np.ndarray
    truth: np.ndarray

    def by_variant(self) -> dict[str, np.ndarray]:
        return {"published": self.published, "improved": self.improved, "without_estimate": np.zeros(2)}


def _draw(setup: Setup, rng: np.random.Generator, instrument: np.random.SeedSequence | None) -> _Draws:
    """The trial's draws in a fixed order (the stream is the trial's); the world's effects
    draw from a child spawned after the lab's draws, and the instrument's properties from
    ``instrument`` (None: from a second child): off, nothing changes."""
    sc = setup.scenario
    m, a, ss = sc.mirror, sc.attitude, sc.star_sensing
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
    noise = [ss.centroid_sigma_arcsec * RAD_PER_ARCSEC * rng.standard_normal(d.visible.shape + (2,))
             for d in setup.dwells]
    fx = None
    if setup.effects.on:
        child = rng.spawn(1)[0]
        if instrument is None:
            instrument = np.random.SeedSequence(int(child.integers(2**63)))
        fx = setup.effects.draw(child, setup.t_s, instrument)
    return _Draws(axis_rad=axis, phase_rad=phase, constant_rad=const, initial_deg=init, orbit_offset_km=orbit_offset,
                  knowledge_rad=att_know, tracker_rad=tracker_err, centroid_noise_rad=noise, effects=fx)


def _deviation(setup: Setup, draws: _Draws) -> _Deviation:
    m = setup.scenario.mirror
    return _Deviation(constant_rad=draws.constant_rad, variable_rad=np.deg2rad(m.deviation_variable_deg),
                      period_s=m.deviation_period_s, phase_rad=draws.phase_rad, axis_rad=draws.axis_rad,
                      effects=draws.effects)


def _dwell_measurements(setup: Setup, draws: _Draws, dev: _Deviation,
                        att_frames: list) -> tuple[list[DwellMeasurement], list[DwellMeasurement]]:
    """The star measurements of every dwell: with the stars' apparent directions (improved)
    and with the catalogue's unless the published method uses aberration."""
    ss = setup.scenario.star_sensing
    fx = draws.effects
    meas_app, meas_cat = [], []
    for j, (d, af, te, nz) in enumerate(zip(setup.dwells, att_frames, draws.tracker_rad, draws.centroid_noise_rad)):
        dtx_f, dty_f = dev(d.frame_t_s)
        cen = true_centroids(d if fx is None else fx.world_dwell(j), dtx_f, dty_f, af) + nz
        cen = np.where(d.visible[..., None], cen, np.nan)
        A_true = body_to_inertial(d.r_km, d.v_km_s, af)
        # the tracker's A_Ib = A_true R(error): the lab's white per-dwell error, plus the world's
        tracker = A_true @ rotvec_matrix(-te if fx is None else fx.tracker_dwell[j] - te)
        meas_app.append(DwellMeasurement(d.apparent_I, tracker, cen, d.alpha_rad, d.beta_rad))
        meas_cat.append(DwellMeasurement(d.apparent_I if ss.published_uses_aberration else d.catalogue_I,
                                         tracker, cen, d.alpha_rad, d.beta_rad))
    return meas_app, meas_cat


def _lab_knowledge(setup: Setup, draws: _Draws, att_scan: np.ndarray) -> _LabKnowledge:
    """The lab's orbit (the drawn orbit-determination error) and attitude (the drawn
    knowledge error, and the world's tracker process continued through the scan) during the
    scans."""
    w = setup.world
    A_lab, R_lab, r_lab, v_lab = w.orbit_geometry(setup.t_s, position_offset_rtn_km=draws.orbit_offset_km)
    orb_lab, dR_lab = w.orbit_parameters(r_lab, v_lab, setup.t_s)
    att_lab = att_scan + draws.knowledge_rad
    if draws.effects is not None:  # small angles: 3-1-2 = rotation vector
        att_lab = att_lab + draws.effects.tracker_scan
    return _LabKnowledge(A=A_lab, R_km=R_lab, orbit=orb_lab, dR_km=dR_lab, attitude_rad=att_lab)


def _estimate(setup: Setup, scan: int, meas_app: list, meas_cat: list, dev: _Deviation) -> _Estimate:
    """The deviation estimates for area scan ``scan``: published from the last dwell before
    it (one star, its middle frame), improved from every dwell before it; zero (and no
    covariance or truth) when no dwell precedes the scan."""
    ss = setup.scenario.star_sensing
    before = [j for j, d in enumerate(setup.dwells) if d.frame_t_s[-1] < setup.scan_start[scan]]
    if not before:
        zero = np.zeros(2)
        return _Estimate(published=zero, improved=zero, cov=np.full((2, 2), np.nan), truth=np.full(2, np.nan))
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
    return _Estimate(published=est_pub, improved=est_imp, cov=cov, truth=np.array(dev(t_mid)))


def _compensate(setup: Setup, sel: np.ndarray, est: _Estimate, lab: _LabKnowledge, dtx: np.ndarray,
                dty: np.ndarray, att: np.ndarray, fx: TrialEffects | None
                ) -> tuple[dict[str, GroundErrors], GroundErrors]:
    """The ground errors of the samples ``sel`` of one area scan (true deviation ``dtx, dty``
    and attitude ``att`` there): uncompensated; published (first-order corrections from the
    nine parameters the lab knows); improved and without_estimate (exact compensation with
    the improved estimate and with dtau = 0); and the improved compensation's errors as the
    lab's model has them."""
    w = setup.world
    alpha0, beta0 = setup.alpha0[sel], setup.beta0[sel]
    n = sel.sum()
    errs = {"uncompensated": _ground_errors(setup, sel, alpha0, beta0, dtx, dty, att, fx)}
    p = np.column_stack([np.full(n, est.published[0]), np.full(n, est.published[1]), lab.attitude_rad[sel],
                         lab.orbit[sel], lab.dR_km[sel]])
    d = np.einsum("nij,nj->ni", setup.comp.K[sel], p)
    errs["published"] = _ground_errors(setup, sel, alpha0 + d[:, 0], beta0 + d[:, 1], dtx, dty, att, fx)
    for name, e in (("improved", est.improved), ("without_estimate", np.zeros(2))):
        ac, bc = exact_compensation(w, alpha0, beta0, np.full(n, e[0]), np.full(n, e[1]), lab.attitude_rad[sel],
                                    lab.A[sel], lab.R_km[sel], target=setup.g0[sel, :2])
        errs[name] = _ground_errors(setup, sel, ac, bc, dtx, dty, att, fx)
        if name == "improved":
            g = w.ground(ac, bc, e[0], e[1], lab.attitude_rad[sel], lab.A[sel], lab.R_km[sel])
            lat, lon = w.latlon(g)
            lab_errs = GroundErrors(lat_deg=np.rad2deg(lat - setup.lat0[sel]),
                                    lon_deg=np.rad2deg(np.mod(lon - setup.lon0[sel] + np.pi, 2 * np.pi) - np.pi))
    return errs, lab_errs


def _ground_errors(setup: Setup, sel, alpha, beta, dtx, dty, att, fx: TrialEffects | None) -> GroundErrors:
    # commanded angles -> the mirror's true ones (the trial instrument's encoders; identity when off)
    # and the ground point by the truth's own route (nothing shared with the lab's chain)
    if fx is not None:
        alpha, beta = fx.true_angles(alpha, beta)
    g = setup.truth_ground(alpha, beta, dtx, dty, att, setup.A_true[sel], setup.R_true[sel])
    lat, lon = ground_errors_truth_deg(g, (setup.truth_latlon0[0][sel], setup.truth_latlon0[1][sel]))
    return GroundErrors(lat_deg=lat, lon_deg=lon)


def _series(setup: Setup, dev: _Deviation, dtx_t: np.ndarray, dty_t: np.ndarray,
            att_scan: np.ndarray) -> TimelineSeries:
    t_all = np.arange(0.0, setup.world.duration_s, setup.step_s)
    dx_all, dy_all = dev(t_all)
    return TimelineSeries(t_s=setup.t_s, scan=setup.scan, g0=setup.g0, dtau_x_rad=dtx_t, dtau_y_rad=dty_t,
                          attitude_rad=att_scan, t_all_s=t_all, dtau_x_all_rad=dx_all, dtau_y_all_rad=dy_all)


def run(setup: Setup, rng: np.random.Generator, *, instrument: np.random.SeedSequence | None = None,
        keep_series: bool = False) -> ScanOutcome:
    """One trial: draws, star measurements, estimates, compensation, ground errors (and the
    timeline with ``keep_series``). ``instrument``: the seed sequence of the trial's
    instrument (:func:`budget.runner.study.instrument_seed_sequence`; None: drawn from
    ``rng``)."""
    draws = _draw(setup, rng, instrument)
    dev = _deviation(setup, draws)
    att_scan, att_frames = setup.attitude(draws.initial_deg)
    meas_app, meas_cat = _dwell_measurements(setup, draws, dev, att_frames)
    lab = _lab_knowledge(setup, draws, att_scan)
    dtx_t, dty_t = dev(setup.t_s)
    dtau, sigma, truth = {}, np.full(2, np.nan), np.full(2, np.nan)
    errors, lab_errors = {}, {}
    for s in sorted(setup.scan_start):  # the estimates kept are those of the last scan
        sel = setup.scan == s
        est = _estimate(setup, s, meas_app, meas_cat, dev)
        dtau, sigma, truth = est.by_variant(), np.sqrt(np.diag(est.cov)), est.truth
        errors[s], lab_errors[s] = _compensate(setup, sel, est, lab, dtx_t[sel], dty_t[sel], att_scan[sel],
                                               draws.effects)
    series = _series(setup, dev, dtx_t, dty_t, att_scan) if keep_series else None
    return ScanOutcome(dtau_rad=dtau, dtau_true_rad=truth, dtau_sigma_rad=sigma, errors=errors,
                       lab_errors=lab_errors, effects=draws.effects, series=series)
