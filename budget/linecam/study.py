"""Seed 004 as a study of the runner: star-based on-orbit calibration of a TDI line camera.

Each trial draws the camera's interior errors (principal point, principal distance,
Brown k1 k2 p1 p2) and its misalignment ``R_u``, images the stars of the strip in every
pass, and calibrates with both variants (:mod:`budget.linecam.trial`). Classes, all with
per-trial truths:

* ``los_rms`` / ``los_max`` (arcsec): the calibrated line-of-sight field's error over the
  whole line (every ``grid_step_px`` detectors, those never crossed by a star included).
  The *estimate* is what the calibration states (rms of its propagated 1-sigma, and its
  largest 3-sigma), the *truth* is the actual rms (largest absolute) error against the
  injected camera's field: the truth column is the accuracy reached. An rms over a smooth,
  correlated field has few degrees of freedom, so its mean sits below the rms of the
  stated sigma (Jensen); ``los_ms`` (arcsec^2) compares the mean squares, equal in
  expectation when the stated covariance is right.
* ``los`` (arcsec): the calibrated look angles (minus nominal) at five detectors along the
  line (0, 25, 50, 75, 100 %), along and across track, with the stated 1-sigma: their
  bias, spread and coverage.
* ``exterior`` (arcsec), ``principal_point`` (px), ``focal`` (mm), ``distortion`` (1e-4):
  each parameter against its injected value, with the stated 1-sigma. On a line at
  ``x' = 0`` pitch and dx0, and roll and dy0, are not separable (seed 004 section a): their
  errors are the gauge, not a failure of the method; ``docs/linecam.md`` explains.

Variants: ``published`` (the patent's steps: exterior first, then interior, alternated;
coverage weights; block-diagonal stated covariance), ``improved`` (one joint fit,
gauge directions removed, the look-angle field as the calibrated quantity) and
``lookangle`` (the Wuhan group's look-angle polynomials of the line, LOS classes only:
it has no camera parameters).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from budget.runner.capabilities import CheckedScenario, Claims, Plannable, Presented, WorldEffects
from budget.runner.study import (ClassSpec, Knob, ReportSection, Study, TrialResult, Truth, instrument_seed_sequence,
                                 trial_seed_sequence)
from simcam.distortion import OpticsError
from simcam.infra.errors import ScenarioError
from simcam.linecam.scenario import PARAMETERS
from simcam.units import ARCSEC_PER_RAD

from .claims import ledger_claims
from .parameters import GAUGE_COMBINATIONS, gauge_combination_vector, to_report_units
from .report import report_sections

__all__ = ["STUDY", "LineCamStudy", "LOS_POINTS"]

#: detectors (fraction of the line) at which the ``los`` class samples the field
LOS_POINTS = (0.0, 0.25, 0.5, 0.75, 1.0)

_PARAM_CLASSES = (
    ("exterior", "exterior misalignment R_u", "arcsec", ("roll", "pitch", "yaw")),
    ("principal_point", "principal point", "px", ("dx0", "dy0")),
    ("focal", "principal distance", "mm", ("df",)),
    ("distortion", "Brown distortion (normalised by half the line)", "1e-4", ("k1", "k2", "p1", "p2")),
)


def _gauge_axes(scenario) -> tuple[str, ...]:
    """Parameters the data cannot determine: the gauge pairs on a line at x' = 0."""
    if scenario.camera.x_line_mm != 0.0:
        return ()
    return tuple(p for c in GAUGE_COMBINATIONS for p in c[1:3])


class LineCamStudy(Study, CheckedScenario, WorldEffects, Plannable, Presented, Claims):
    """Seed 004: star-observation calibration of a TDI line camera."""

    name = "linecam"
    title = "Line camera star-observation calibration (seed 004)"
    seed_document = "004"
    variants = ("published", "improved", "lookangle")
    scenario_module = "simcam.linecam.scenario"
    trials_per_task = 20

    # ------------------------------------------------------------ scenario

    def check(self, scenario, *, where: str) -> None:
        if scenario.lab.grid_step_px >= scenario.camera.n_pixels:
            raise ScenarioError(f"{where}: lab.grid_step_px must be below camera.n_pixels")

    # ------------------------------------------------------------ method
    def classes(self, scenario) -> tuple[ClassSpec, ...]:
        axes_los = tuple(f"{direction}_{int(round(100 * fraction))}"
                         for direction in ("along", "across") for fraction in LOS_POINTS)
        out = [
            ClassSpec("los_rms", "rms LOS error over the line: stated (estimate) vs actual (truth)", "arcsec",
                      ("along", "across"), "estimate: rms of the stated 1-sigma over the line; truth: rms of "
                      "the calibrated minus the injected look angles", per_trial_truth=True, role="stated"),
            ClassSpec("los_ms", "mean-square LOS error over the line: stated (estimate) vs actual (truth)",
                      "arcsec^2", ("along", "across"), "estimate: mean of the stated variance over the line; "
                      "truth: mean square of the calibrated minus the injected look angles (equal in "
                      "expectation when the stated covariance is right)", per_trial_truth=True,
                      role="stated"),
            ClassSpec("los_max", "largest LOS error over the line: stated 3 sigma (estimate) vs actual (truth)",
                      "arcsec", ("along", "across"), "estimate: largest stated 3-sigma; truth: largest "
                      "absolute error of the calibrated look angles", per_trial_truth=True, role="stated",
                      at_most=True),  # a stated bound: the claim holds when the actual is at or below it
            ClassSpec("los", "calibrated look angle minus nominal at 0-100 % of the line", "arcsec", axes_los,
                      "estimate: calibrated look angle minus nominal; truth: the injected camera's",
                      per_trial_truth=True),
        ]
        gauge = _gauge_axes(scenario)
        for name, label, unit, axes in _PARAM_CLASSES:
            out.append(ClassSpec(name, label, unit, axes, f"estimate of each parameter against the injected "
                                 f"value ({unit})", per_trial_truth=True,
                                 undetermined=tuple(a for a in axes if a in gauge)))
        if gauge:
            out.append(ClassSpec("gauge_combination", "determined combinations of the inseparable parameters",
                                 "arcsec", tuple(c[0] for c in GAUGE_COMBINATIONS),
                                 "on a line at x' = 0 pitch and dx0, roll and dy0 are not separable (seed 004 "
                                 "section a): what the stars determine is pitch + dx0/F and roll - dy0/F (F the "
                                 "focal length in px), estimate against the injected camera's, stated 1-sigma "
                                 "from the fit's covariance", per_trial_truth=True))
        return tuple(out)

    def trial(self, scenario, seed: int, k: int) -> TrialResult:
        from .calibrate import CalibrationError
        from .trial import simulate

        try:
            simulation = simulate(scenario, trial_seed_sequence(seed, k),
                                  instrument_seed_sequence(scenario.validation.instrument_seed, seed, k))
        except CalibrationError as exc:
            raise ScenarioError(f"{scenario.source}: stars.mag_limit / observation.passes: {exc}") from None
        except OpticsError as exc:
            # the camera drawn for this trial has a distortion the optics cannot invert (a
            # scenario at the edge of its ranges): name the file and the fields that drew it
            raise ScenarioError(f"{scenario.source}: errors.k1 / k2 / p1 / p2 (trial {k} of seed {seed} drew a "
                                f"distortion that folds the focal plane; give smaller sigmas): {exc}") from None
        return trial_result(scenario, simulation, keep_extra=(k == 0))

    def truths(self, scenario, seed: int) -> dict[tuple[str, str], Truth]:
        return {}

    def claims(self, scenario) -> tuple:
        """Seed 004's claims (:func:`budget.linecam.claims.ledger_claims`): the testable ones
        name ``embedded:default``, judged in its two worlds."""
        return ledger_claims(scenario)

    def truth_depends_on_effects(self, scenario) -> set[str] | None:
        """World effects whose magnitude changes the truths: the distortion outside
        the Brown family changes the true line-of-sight field; the others (jitter, time-tag
        bias, Gaia world, star colour against the solar reference, line-rate mismatch) change
        what the lab measures, not the camera."""
        return {"distortion_k3_edge_px", "thin_prism_edge_px"}

    def likely_cause(self, result, key, stats):
        cls, var, ax = key
        if cls == "los_max":
            # a stated bound (ClassSpec.at_most): asked only when the actual exceeds it
            return ("the largest actual error exceeds the largest stated 3-sigma: the stated covariance is "
                    "smaller than the actual scatter of the calibrated field, or an error the fit does not "
                    "model (a bias) adds to it." if stats["bias"] < 0 else None)
        if cls in ("los_rms", "los_ms") and stats["bias"] > 0:
            return "the stated covariance is larger than the actual scatter of the calibrated field."
        if cls in ("los_rms", "los_ms") and stats["bias"] < 0:
            return "the stated covariance is smaller than the actual scatter of the calibrated field."
        return None

    # ------------------------------------------------------------ report
    def report_sections(self, result, out_dir: Path) -> list[ReportSection]:
        return report_sections(result, Path(out_dir))

    # ------------------------------------------------------------ protocol planning
    def protocol_knobs(self, scenario) -> tuple:
        """Passes over the strip (``observation.passes``, 1 to 16: one pass calibrates every
        variant) and the lab's magnitude limit (``stars.mag_limit``, V 6.0 up to the faintest
        star the world images, ``stars.world_mag_limit``). The bright end: one pass must
        identify at least 6 stars for the published fit's 10 parameters (2 equations a star)
        and 7 for the degree-5 look-angle polynomial; at V 5.0 the densest strip has 11 stars
        and one pass identified 5, at V 6.0 it has 25. The limit costs no lab time (the
        stars are imaged anyway); it trades the fainter stars' centroid noise against their
        number."""
        return (Knob("observation.passes", "int", 1, 16, "passes",
                     "passes over the strip, each shifted across track by observation.shift_px"),
                Knob("stars.mag_limit", "real", 6.0, scenario.stars.world_mag_limit, "mag",
                     "faintest V magnitude the lab selects from its catalogue"))

    def lab_time_s(self, scenario) -> dict[str, float]:
        """The passes' time on the sky, by item: each pass scans the strip
        (``stars.strip_length_deg`` at the rate matched to the TDI line,
        ``camera.matched_rate_rad_s``), and between the starts of two passes
        ``observation.pass_interval_s`` elapse (the return and re-acquisition take what the
        scan leaves of it)."""
        obs = scenario.observation
        scan_s = math.radians(scenario.stars.strip_length_deg) / scenario.camera.matched_rate_rad_s
        return {"scans": obs.passes * scan_s,
                "returns between passes": (obs.passes - 1) * max(obs.pass_interval_s - scan_s, 0.0)}


def trial_result(scenario, sim, *, keep_extra: bool = False) -> TrialResult:
    """The estimates, per-trial truths and stated sigmas of one simulation."""
    estimates, truths, sigmas = {}, {}, {}
    true_along, true_across = sim.los_true
    nominal_along, nominal_across = sim.los_before       # the lab's design camera (estimates)
    design_along, design_across = sim.los_design         # the same by the world's camera (truths)
    n_pixels = scenario.camera.n_pixels
    # the grid detectors nearest to LOS_POINTS of the line
    picked = [int(np.argmin(np.abs(sim.grid - fraction * (n_pixels - 1)))) for fraction in LOS_POINTS]
    theta_true = to_report_units(sim.theta_true)
    for variant, los in sim.los.items():
        error_along = (los.along_rad - true_along) * ARCSEC_PER_RAD
        error_across = (los.across_rad - true_across) * ARCSEC_PER_RAD
        sigma_along = los.sigma_along_rad * ARCSEC_PER_RAD
        sigma_across = los.sigma_across_rad * ARCSEC_PER_RAD
        for axis, error, sigma in (("along", error_along, sigma_along), ("across", error_across, sigma_across)):
            estimates[("los_rms", variant, axis)] = float(np.sqrt(np.mean(sigma * sigma)))
            truths[("los_rms", variant, axis)] = float(np.sqrt(np.mean(error * error)))
            estimates[("los_ms", variant, axis)] = float(np.mean(sigma * sigma))
            truths[("los_ms", variant, axis)] = float(np.mean(error * error))
            estimates[("los_max", variant, axis)] = float(3.0 * np.max(sigma))
            truths[("los_max", variant, axis)] = float(np.max(np.abs(error)))
        for axis, calibrated, true, nominal, design, sigma in (
                ("along", los.along_rad, true_along, nominal_along, design_along, sigma_along),
                ("across", los.across_rad, true_across, nominal_across, design_across, sigma_across)):
            for fraction, index in zip(LOS_POINTS, picked):
                key = ("los", variant, f"{axis}_{int(round(100 * fraction))}")
                estimates[key] = float((calibrated[index] - nominal[index]) * ARCSEC_PER_RAD)
                truths[key] = float((true[index] - design[index]) * ARCSEC_PER_RAD)
                sigmas[key] = float(sigma[index])
        if variant not in sim.calibrations:  # the look-angle model has no camera parameters
            continue
        calibration = sim.calibrations[variant]
        theta = to_report_units(calibration.theta)
        theta_sd = (np.sqrt(np.maximum(np.diag(calibration.cov), 0.0))
                    * np.abs(to_report_units(np.ones(len(PARAMETERS)))))
        gauge = _gauge_axes(scenario)
        for name, _, _, axes in _PARAM_CLASSES:
            for parameter in axes:
                index = PARAMETERS.index(parameter)
                estimates[(name, variant, parameter)] = float(theta[index])
                truths[(name, variant, parameter)] = float(theta_true[index])
                if parameter not in gauge:  # a parameter the data cannot determine states no sigma
                    sigmas[(name, variant, parameter)] = float(theta_sd[index])
        if gauge:
            f_px = scenario.camera.focal_length_mm / scenario.camera.pitch_mm
            for axis, angle, px, sign in GAUGE_COMBINATIONS:
                g = gauge_combination_vector(f_px, angle, px, sign)
                estimates[("gauge_combination", variant, axis)] = float(g @ calibration.theta)
                truths[("gauge_combination", variant, axis)] = float(g @ sim.theta_true)
                sigmas[("gauge_combination", variant, axis)] = float(np.sqrt(max(g @ calibration.cov @ g, 0.0)))
    extra = trial_extra(scenario, sim) if keep_extra else {}
    return TrialResult(estimates=estimates, truths=truths, sigmas=sigmas, extra=extra)


def trial_extra(scenario, sim) -> dict:
    """What the report plots from trial 0 (small, picklable)."""
    from .calibrate import separability
    from .model import NominalCamera, residuals

    camera = NominalCamera.from_model(scenario.camera)
    observations = sim.identified.obs
    separable = separability(camera, observations, rcond=scenario.lab.rcond)
    before = residuals(camera, np.zeros(10), observations)
    after = {variant: calibration.residuals_px for variant, calibration in sim.calibrations.items()}
    true_along, true_across = sim.los_true
    return {
        "sample": observations.sample, "t_s": sim.identified.t_s, "pass": observations.pass_index,
        "line": sim.centroids.line[sim.identified.centroid_index],
        "residual_before_px": before, "residual_after_px": after,
        "grid": sim.grid,
        "los_error_arcsec": {variant: ((los.along_rad - true_along) * ARCSEC_PER_RAD,
                                       (los.across_rad - true_across) * ARCSEC_PER_RAD,
                                       los.sigma_along_rad * ARCSEC_PER_RAD, los.sigma_across_rad * ARCSEC_PER_RAD)
                             for variant, los in sim.los.items()},
        "los_error_before_arcsec": ((sim.los_before[0] - true_along) * ARCSEC_PER_RAD,
                                    (sim.los_before[1] - true_across) * ARCSEC_PER_RAD),
        "condition": {variant: calibration.condition for variant, calibration in sim.calibrations.items()},
        "sigma0_px": {variant: calibration.sigma0_px for variant, calibration in sim.calibrations.items()},
        "iterations": {variant: calibration.iterations for variant, calibration in sim.calibrations.items()},
        "separability": {"condition": separable.condition, "null_space": separable.null_space,
                         "inseparable": list(separable.inseparable)},
        "windows": int(sim.images.windows_dn.shape[0]), "centroids": int(sim.centroids.sample.size),
        "identified": len(observations), "unmatched": sim.identified.unmatched,
        "ambiguous": sim.identified.ambiguous,
        "n_pixels": scenario.camera.n_pixels, "coverage_bins": scenario.lab.coverage_bins,
    }


STUDY = LineCamStudy()
