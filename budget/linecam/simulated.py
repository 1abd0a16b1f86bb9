"""``budget linecam simulate`` without the command line: one simulated calibration
(:func:`simulate_trial`), the JSON the command writes (:func:`simulation_payload`) and the
lines it prints (:func:`simulation_lines`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from budget.runner.numbers import fmt
from budget.runner.study import instrument_seed_sequence, trial_seed_sequence
from simcam.infra.errors import UserInputError
from simcam.linecam.scenario import PARAMETERS, LineCamScenario

from .calibrate import CalibrationError
from .parameters import PARAM_UNITS, determined_combinations, gauge_combination_vector, to_report_units
from .study import trial_extra
from .trial import Simulation, simulate

__all__ = ["SimulatedCalibration", "simulate_trial", "simulation_payload", "simulation_lines"]


@dataclass(frozen=True)
class SimulatedCalibration:
    """One simulated calibration (:func:`simulate_trial`).

    Attributes
    ----------
    scenario : simcam.linecam.scenario.LineCamScenario
        The scenario simulated.
    seed, trial : int
        The run's seed and trial number (``trial_seed_sequence(seed, trial)``).
    simulation : budget.linecam.trial.Simulation
        Everything of the trial.
    example : dict
        What the report plots of it (:func:`budget.linecam.study.trial_extra`).
    """

    scenario: LineCamScenario
    seed: int
    trial: int
    simulation: Simulation
    example: dict

    def to_json(self) -> dict:
        """What ``budget linecam simulate --json`` writes (:func:`simulation_payload`)."""
        return simulation_payload(self)

    def summary_lines(self) -> list[str]:
        """What ``budget linecam simulate`` prints (:func:`simulation_lines`)."""
        return simulation_lines(self)


def simulate_trial(scenario: LineCamScenario, *, seed: int = 0, trial: int = 0) -> SimulatedCalibration:
    """Trial ``trial`` of ``seed`` of the scenario (draws from ``SeedSequence(seed,
    spawn_key=(trial,))``); a strip with too few stars is a
    :class:`simcam.infra.errors.UserInputError` naming the scenario and its fields."""
    try:
        sim = simulate(scenario, trial_seed_sequence(seed, trial),
                       instrument_seed_sequence(scenario.validation.instrument_seed, seed, trial))
    except CalibrationError as exc:
        raise UserInputError(f"{scenario.source}: stars.mag_limit / observation.passes: {exc}") from None
    return SimulatedCalibration(scenario=scenario, seed=seed, trial=trial, simulation=sim,
                                example=trial_extra(scenario, sim))


def _combinations(result: SimulatedCalibration) -> list[tuple[str, np.ndarray, dict]]:
    """The combinations the plan determines (:func:`budget.linecam.parameters.determined_combinations`):
    name, coefficient vector and each variant's value and stated sigma (arcsec)."""
    scn, sim = result.scenario, result.simulation
    f_px = scn.camera.focal_length_mm / scn.camera.pitch_mm
    out = []
    for name, ang, px, sign in determined_combinations(result.example["separability"]["null_space"], f_px):
        g = gauge_combination_vector(f_px, ang, px, sign)
        vals = {v: {"value": float(g @ c.theta), "sigma": float(np.sqrt(max(g @ c.cov @ g, 0.0)))}
                for v, c in sim.calibrations.items()}
        out.append((name, g, vals))
    return out


def _los_statistics(result: SimulatedCalibration) -> dict[str, dict[str, float]]:
    """Each variant's LOS error over the line (arcsec): rms and largest actual error, and the
    rms of the stated 1-sigma, along and across track."""
    out = {}
    for v, (ea, ec, sa, sc) in result.example["los_error_arcsec"].items():
        out[v] = {"rms_error_along_arcsec": float(np.sqrt(np.mean(ea**2))),
                  "rms_error_across_arcsec": float(np.sqrt(np.mean(ec**2))),
                  "max_error_along_arcsec": float(np.max(np.abs(ea))),
                  "max_error_across_arcsec": float(np.max(np.abs(ec))),
                  "stated_rms_along_arcsec": float(np.sqrt(np.mean(sa**2))),
                  "stated_rms_across_arcsec": float(np.sqrt(np.mean(sc**2)))}
    return out


def simulation_payload(result: SimulatedCalibration) -> dict:
    """The JSON of one simulated calibration: what was imaged and identified, the plan's
    separability, each variant's parameters (report units), covariance and LOS errors, the
    determined combinations against their truth, and the injected parameters."""
    scn, sim, ex = result.scenario, result.simulation, result.example
    out = {"scenario_hash": scn.hash, "seed": result.seed, "trial": result.trial, "identified": ex["identified"],
           "windows": ex["windows"], "separability": ex["separability"], "variants": {}}
    out["determined_combinations"] = {name: {"unit": "arcsec", "truth": float(g @ sim.theta_true), **vals}
                                      for name, g, vals in _combinations(result)}
    for v, stats in _los_statistics(result).items():
        c = sim.calibrations.get(v)
        out["variants"][v] = stats if c is None else {
            "theta": dict(zip(PARAMETERS, to_report_units(c.theta).tolist())),
            "covariance_model_units": c.cov.tolist(), "sigma0_px": c.sigma0_px, "condition": c.condition, **stats}
    out["truth"] = dict(zip(PARAMETERS, to_report_units(sim.theta_true).tolist()))
    return out


def simulation_lines(result: SimulatedCalibration) -> list[str]:
    """What ``budget linecam simulate`` prints: the stars imaged and identified, each
    parameter's truth and estimates (with their sigma, or "not determined"), the determined
    combinations, each variant's LOS error and the error before calibration."""
    sim, ex = result.simulation, result.example
    truth = to_report_units(sim.theta_true)
    lines = [f"trial {result.trial} of seed {result.seed}: {ex['windows']} star windows, "
             f"{ex['identified']} stars identified",
             f"{'parameter':10s} {'unit':7s} {'truth':>10s} " + " ".join(f"{v:>21s}" for v in sim.calibrations)]
    undet = set(ex["separability"]["inseparable"])  # no sigma for what the plan cannot separate
    for j, p in enumerate(PARAMETERS):
        cols = []
        for c in sim.calibrations.values():
            est = to_report_units(c.theta)[j]
            sd = np.sqrt(max(c.cov[j, j], 0.0)) * abs(PARAM_UNITS[p][1])
            cols.append(f"{fmt(est):>10} {'not determined':>10s}" if p in undet
                        else f"{fmt(est):>10} +-{fmt(sd, 3):>9}")
        lines.append(f"{p:10s} {PARAM_UNITS[p][0]:7s} {fmt(truth[j]):>10} " + " ".join(cols))
    for name, g, vals in _combinations(result):
        lines.append(f"{name:10s} {'arcsec':7s} {fmt(g @ sim.theta_true):>10} "
                     + " ".join(f"{fmt(d['value']):>10} +-{fmt(d['sigma'], 3):>9}" for d in vals.values()))
    for v, stats in _los_statistics(result).items():
        lines.append(f"{v}: LOS error over the line rms {stats['rms_error_along_arcsec']:.3f}\" along, "
                     f"{stats['rms_error_across_arcsec']:.3f}\" across "
                     f"(stated {stats['stated_rms_along_arcsec']:.3f}\", {stats['stated_rms_across_arcsec']:.3f}\"); "
                     f"max {stats['max_error_along_arcsec']:.3f}\", {stats['max_error_across_arcsec']:.3f}\"")
    eb = ex["los_error_before_arcsec"]
    lines.append(f"before calibration: rms {np.sqrt(np.mean(eb[0] ** 2)):.2f}\" along, "
                 f"{np.sqrt(np.mean(eb[1] ** 2)):.2f}\" across")
    return lines
