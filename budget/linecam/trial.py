"""One simulated star-observation calibration of the line camera (seed 004), end to end.

World (:mod:`simcam.linecam`): injected interior and exterior errors drawn per trial, the
stars of the strip imaged pass by pass through the true camera, the attitude reports.
Lab (:mod:`budget.linecam`): centroids and time tags, identification against its own
apparent places, the published and the joint calibrations, their look-angle fields.
Truth: the true look-angle field of the injected camera (:meth:`CameraTruth.los_angles`,
through the Newton-free explicit Brown correction of :mod:`simcam.distortion` and the true
principal distance and misalignment; nothing of the lab's model).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from simcam.linecam.camera import CameraTruth, camera_truth, draw_errors
from simcam.linecam.effects import effects_generator
from simcam.linecam.scenario import PARAMETERS, LineCamScenario
from simcam.linecam.world import (PassImages, SkyStrip, attitude_reports, image_passes, sky_strip, world_jitter,
                                  world_sky_strip)
from simcam.sky.catalogue import hipparcos

from .calibrate import (Calibration, LosField, calibrate_joint, calibrate_lookangle, calibrate_published,
                        los_field)
from .model import NominalCamera, Observations, los_angles, los_grid
from .pipeline import Centroids, Identified, Region, choose_region, extract_centroids, identify

__all__ = ["INSTRUMENT_CHILD", "region", "world_strip", "lab_strip", "simulate", "Simulation", "VARIANTS",
           "run_calibrations"]

VARIANTS = ("published", "improved", "lookangle")
#: spawn-key suffix of the instrument stream of a trial simulated without one (:func:`simulate`)
INSTRUMENT_CHILD = 0x1A57


@lru_cache(maxsize=16)
def region(scenario: LineCamScenario) -> Region:
    """The strip centre: step 2 ("auto", the densest strip for the lab's magnitude limit) or
    the scenario's (ra, dec)."""
    st, cam = scenario.stars, scenario.camera
    if st.region == "manual":
        return Region(ra_deg=st.ra_deg, dec_deg=st.dec_deg, stars=-1, candidates=0)
    return choose_region(hipparcos(), mag_limit=st.mag_limit,
                         across_rad=cam.n_pixels * cam.pitch_mm / cam.focal_length_mm,
                         along_rad=math.radians(st.strip_length_deg), pa_deg=st.scan_pa_deg)


def world_strip(scenario: LineCamScenario, rng: np.random.Generator | None = None) -> SkyStrip:
    """The stars the world images (all apparent-place terms, down to ``world_mag_limit``, from the
    world's catalogue: :func:`simcam.linecam.world.world_sky_strip`; ``rng`` draws the Gaia world's
    proper-motion errors, needed when that effect is on)."""
    r = region(scenario)
    return world_sky_strip(scenario, ra_deg=r.ra_deg, dec_deg=r.dec_deg, rng=rng)


def lab_strip(scenario: LineCamScenario) -> SkyStrip:
    """The lab's catalogue selection (``mag_limit``) and apparent places (its switches)."""
    r = region(scenario)
    lab = scenario.lab
    return sky_strip(scenario, ra_deg=r.ra_deg, dec_deg=r.dec_deg, mag_limit=scenario.stars.mag_limit,
                     aberration=lab.aberration, parallax=lab.parallax, proper_motion=lab.proper_motion)


@dataclass(frozen=True)
class Simulation:
    """Everything of one trial (the report and the commands use the parts).

    Attributes
    ----------
    theta_true : numpy.ndarray (10,)
        The injected parameters (model units, order of :data:`PARAMETERS`).
    truth : simcam.linecam.camera.CameraTruth
        The injected camera.
    images, centroids, identified
        The star windows imaged, their centroids, the identified stars and their observations.
    calibrations : dict of str to Calibration
        The published and improved calibrations.
    grid : numpy.ndarray
        Detectors at which the fields are compared (:func:`budget.linecam.model.los_grid`).
    los_true : tuple of numpy.ndarray
        The injected camera's look angles (along, across; rad) on the grid.
    los : dict of str to LosField
        Each variant's calibrated field on the grid (``lookangle`` included).
    los_before : tuple of numpy.ndarray
        The nominal camera's look angles (along, across; rad) on the grid, by the lab's model
        (what the estimates are reported against).
    los_design : tuple of numpy.ndarray
        The same design camera's look angles by the world's camera (no errors, no effects):
        what the truths are reported against, so no truth passes through the lab's model.
    """

    theta_true: np.ndarray
    truth: CameraTruth
    images: PassImages
    centroids: Centroids
    identified: Identified
    calibrations: dict[str, Calibration]
    grid: np.ndarray
    los_true: tuple
    los: dict[str, LosField]
    los_before: tuple
    los_design: tuple


def simulate(scenario: LineCamScenario, seed_sequence: np.random.SeedSequence,
             instrument: np.random.SeedSequence | None = None, *, noise: bool = True) -> Simulation:
    """One trial: draw the errors, image, centroid, identify, calibrate (both variants).

    ``instrument``: the seed sequence of the trial's instrument
    (:func:`budget.runner.study.instrument_seed_sequence` of ``validation.instrument_seed``); it
    draws the world's Gaia proper-motion errors (child 1) and, when the scenario pins an
    instrument (an integer ``instrument_seed``), the camera's errors (child 0). None: a child of
    ``seed_sequence`` (a per-trial instrument). The camera's errors are otherwise drawn first
    from the trial's own stream, which draws them in both cases so its later draws do not move.
    """
    rng = np.random.default_rng(seed_sequence)
    if instrument is None:
        instrument = np.random.SeedSequence(seed_sequence.entropy,
                                            spawn_key=tuple(seed_sequence.spawn_key) + (INSTRUMENT_CHILD,))
    camera_ss, sky_ss = instrument.spawn(2)
    theta = draw_errors(scenario, rng)
    if scenario.validation.instrument_seed is not None:
        theta = draw_errors(scenario, np.random.default_rng(camera_ss))
    truth = camera_truth(scenario, theta)
    wstrip = world_strip(scenario, np.random.default_rng(sky_ss))
    keys = rng.integers(1, 2**63, size=wstrip.plan.passes + 1, dtype=np.uint64)
    # the world's unmodelled effects draw from their own stream (common random numbers)
    jitter = world_jitter(scenario, wstrip.plan, effects_generator(seed_sequence))
    images = image_passes(scenario, truth, wstrip, frame_keys=keys[1:], detector_key=keys[0], noise=noise,
                          jitter=jitter)
    cents = extract_centroids(images, scenario)
    reports = attitude_reports(scenario, wstrip.plan, rng)
    att = reports.report(cents.t_s, cents.pass_index).as_matrix()
    cam = NominalCamera.from_model(scenario.camera)
    ident = identify(cam, lab_strip(scenario), sample=cents.sample, t_s=cents.t_s, pass_index=cents.pass_index,
                     attitude=att, match_radius_arcsec=scenario.lab.match_radius_arcsec)
    cals = run_calibrations(scenario, cam, ident.obs)
    grid = los_grid(scenario)
    los_true = truth.los_angles(grid)
    los = {v: los_field(cam, c, grid) for v, c in cals.items()}
    look = calibrate_lookangle(cam, ident.obs, degree_along=scenario.lab.lookangle_degree_along,
                               degree_across=scenario.lab.lookangle_degree_across)
    los["lookangle"] = look.field(grid)
    before = los_angles(cam, np.zeros(len(PARAMETERS)), grid)
    design = replace(truth, params=np.zeros(len(PARAMETERS)), k3_edge_px=0.0, prism_edge_px=0.0).los_angles(grid)
    return Simulation(theta_true=theta, truth=truth, images=images, centroids=cents, identified=ident,
                      calibrations=cals, grid=grid, los_true=los_true, los=los, los_before=before,
                      los_design=design)


def run_calibrations(scenario: LineCamScenario, cam: NominalCamera, obs: Observations) -> dict[str, Calibration]:
    """Both variants on the same observations."""
    lab = scenario.lab
    return {"published": calibrate_published(cam, obs, coverage_bins=lab.coverage_bins, max_iter=lab.max_iter),
            "improved": calibrate_joint(cam, obs, rcond=lab.rcond, gauge_sigma_px=lab.gauge_sigma_px)}
