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

from pathlib import Path

import numpy as np

from budget.runner.study import ClassSpec, ReportSection, Study, TrialResult, Truth, trial_seed_sequence

__all__ = ["STUDY", "LineCamStudy", "LOS_POINTS"]

#: detectors (fraction of the line) at which the ``los`` class samples the field
LOS_POINTS = (0.0, 0.25, 0.5, 0.75, 1.0)

_PARAM_CLASSES = (
    ("exterior", "exterior misalignment R_u", "arcsec", ("roll", "pitch", "yaw")),
    ("principal_point", "principal point", "px", ("dx0", "dy0")),
    ("focal", "principal distance", "mm", ("df",)),
    ("distortion", "Brown distortion (normalised by half the line)", "1e-4", ("k1", "k2", "p1", "p2")),
)


class LineCamStudy(Study):
    """Seed 004: star-observation calibration of a TDI line camera."""

    name = "linecam"
    title = "Line camera star-observation calibration (seed 004)"
    seed_document = "004"
    variants = ("published", "improved", "lookangle")
    scenario_module = "simcam.linecam.scenario"

    # ------------------------------------------------------------ scenario

    def check(self, scenario, *, where: str) -> None:
        from simcam.config_base import ScenarioError

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
                      "absolute error of the calibrated look angles", per_trial_truth=True, role="stated"),
            ClassSpec("los", "calibrated look angle minus nominal at 0-100 % of the line", "arcsec", axes_los,
                      "estimate: calibrated look angle minus nominal; truth: the injected camera's",
                      per_trial_truth=True),
        ]
        for name, label, unit, axes in _PARAM_CLASSES:
            out.append(ClassSpec(name, label, unit, axes, f"estimate of each parameter against the injected "
                                 f"value ({unit})", per_trial_truth=True))
        return tuple(out)

    def trial(self, scenario, seed: int, k: int) -> TrialResult:
        from simcam.config_base import ScenarioError

        from .calibrate import CalibrationError
        from .trial import simulate

        try:
            simulation = simulate(scenario, trial_seed_sequence(seed, k))
        except CalibrationError as exc:
            raise ScenarioError(f"{scenario.source}: stars.mag_limit / observation.passes: {exc}") from None
        return trial_result(scenario, simulation, keep_extra=(k == 0))

    def truths(self, scenario, seed: int) -> dict[tuple[str, str], Truth]:
        return {}

    def chunk_trials(self, scenario) -> int:
        return 20

    # ------------------------------------------------------------ report and commands
    def report_sections(self, result, out_dir: Path) -> list[ReportSection]:
        from .report import report_sections

        return report_sections(result, Path(out_dir))

    def commands(self) -> list:
        from .cli import commands

        return commands()


def trial_result(scenario, sim, *, keep_extra: bool = False) -> TrialResult:
    """The estimates, per-trial truths and stated sigmas of one simulation."""
    from simcam.linecam.scenario import ARCSEC_PER_RAD, PARAMETERS

    from .trial import to_report_units

    estimates, truths, sigmas = {}, {}, {}
    true_along, true_across = sim.los_true
    nominal_along, nominal_across = sim.los_before
    n_pixels = scenario.camera.n_pixels
    # the grid detectors nearest to LOS_POINTS of the line
    picked = [int(np.argmin(np.abs(sim.grid - fraction * (n_pixels - 1)))) for fraction in LOS_POINTS]
    theta_true = to_report_units(sim.theta_true)
    for variant, los in sim.los.items():
        error_along = (los["along"] - true_along) * ARCSEC_PER_RAD
        error_across = (los["across"] - true_across) * ARCSEC_PER_RAD
        sigma_along = los["sigma_along"] * ARCSEC_PER_RAD
        sigma_across = los["sigma_across"] * ARCSEC_PER_RAD
        for axis, error, sigma in (("along", error_along, sigma_along), ("across", error_across, sigma_across)):
            estimates[("los_rms", variant, axis)] = float(np.sqrt(np.mean(sigma * sigma)))
            truths[("los_rms", variant, axis)] = float(np.sqrt(np.mean(error * error)))
            estimates[("los_ms", variant, axis)] = float(np.mean(sigma * sigma))
            truths[("los_ms", variant, axis)] = float(np.mean(error * error))
            estimates[("los_max", variant, axis)] = float(3.0 * np.max(sigma))
            truths[("los_max", variant, axis)] = float(np.max(np.abs(error)))
        for axis, calibrated, true, nominal, sigma in (
                ("along", los["along"], true_along, nominal_along, sigma_along),
                ("across", los["across"], true_across, nominal_across, sigma_across)):
            for fraction, index in zip(LOS_POINTS, picked):
                key = ("los", variant, f"{axis}_{int(round(100 * fraction))}")
                estimates[key] = float((calibrated[index] - nominal[index]) * ARCSEC_PER_RAD)
                truths[key] = float((true[index] - nominal[index]) * ARCSEC_PER_RAD)
                sigmas[key] = float(sigma[index])
        if variant not in sim.calibrations:  # the look-angle model has no camera parameters
            continue
        calibration = sim.calibrations[variant]
        theta = to_report_units(calibration.theta)
        theta_sd = (np.sqrt(np.maximum(np.diag(calibration.cov), 0.0))
                    * np.abs(to_report_units(np.ones(len(PARAMETERS)))))
        for name, _, _, axes in _PARAM_CLASSES:
            for parameter in axes:
                index = PARAMETERS.index(parameter)
                estimates[(name, variant, parameter)] = float(theta[index])
                truths[(name, variant, parameter)] = float(theta_true[index])
                sigmas[(name, variant, parameter)] = float(theta_sd[index])
    extra = trial_extra(scenario, sim) if keep_extra else {}
    return TrialResult(estimates=estimates, truths=truths, sigmas=sigmas, extra=extra)


def trial_extra(scenario, sim) -> dict:
    """What the report plots from trial 0 (small, picklable)."""
    from simcam.linecam.scenario import ARCSEC_PER_RAD

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
        "los_error_arcsec": {variant: ((los["along"] - true_along) * ARCSEC_PER_RAD,
                                       (los["across"] - true_across) * ARCSEC_PER_RAD,
                                       los["sigma_along"] * ARCSEC_PER_RAD, los["sigma_across"] * ARCSEC_PER_RAD)
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
