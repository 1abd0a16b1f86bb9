"""What a star-camera validation's trials and truths share: the cameras and the spectral design.

:class:`CameraSetup` is the study's :meth:`~budget.runner.capabilities.Prepared.setup`: the
runner keeps it per process (:func:`budget.runner.capabilities.prepared`) under
:func:`setup_key`, the scenario's hash with the truths' sampling sizes left out, so the scenario
that :func:`budget.starcam.validate.truth_size_for` resized shares the run's camera (the truths
take their sizes as arguments; the camera never reads them).
"""

from __future__ import annotations

import numpy as np

from budget.runner.study import instrument_seed_sequence
from simcam.config_base import model_hash

#: validation fields that only size the truths' sampling
#: (:func:`budget.starcam.validate.truth_size_for`): a camera built for one size serves every size
TRUTH_SIZE_FIELDS = ("te_truth_frames", "hsfe_truth_frames")
#: instruments (twins of the scenario seed's camera) one set-up keeps, most recent last: the
#: trials' running in this process, and trial 0's (the run's truths' camera)
CAMERAS_KEPT = 6


def setup_key(scenario) -> str:
    """The scenario's hash with the truth sizes set to 0 (:data:`TRUTH_SIZE_FIELDS`)."""
    fixed = {f: 0 for f in TRUTH_SIZE_FIELDS}
    return model_hash(scenario.model_copy(update={"validation": scenario.validation.model_copy(update=fixed)}))


def per_instrument(scenario) -> bool:
    """Whether every trial draws its own camera (``validation.instrument_seed`` unset, the
    default: at least its onboard calibration's errors) rather than one pinned camera serving
    every trial."""
    return scenario.validation.instrument_seed is None


def instrument_seeds(*, instrument_seed: int | None, new_maps_per_trial: bool, seed: int,
                     k: int) -> tuple[int | None, int]:
    """``(detector_seed, calibration_seed)`` of trial ``k``'s camera
    (:meth:`simcam.starcam.render.StarCamera.twin`): the calibration errors from the first word
    of :func:`budget.runner.study.instrument_seed_sequence`, the pixel maps too when they are
    drawn per trial or the camera is pinned (else None: the scenario seed's maps)."""
    root = int(instrument_seed_sequence(instrument_seed, seed, k).generate_state(1, dtype=np.uint32)[0])
    own_maps = new_maps_per_trial or instrument_seed is not None
    return (root if own_maps else None), root


class CameraSetup:
    """The cameras of a scenario's trials and the chromatic test's spectral design
    (:func:`budget.starcam.protocols.spectral_design`). The scenario seed's camera is built
    once; each trial's instrument (:meth:`instrument`) is a twin of it
    (:meth:`simcam.starcam.render.StarCamera.twin`: the same optics and optical caches, its own
    pixel maps and calibration errors); the :data:`CAMERAS_KEPT` most recently used are kept.
    Every scenario of one :func:`setup_key` gives the same cameras."""

    def __init__(self, scenario):
        self.scenario = scenario
        self._base = None
        self._cameras: dict = {}
        self._spectral = None

    def camera(self, detector_seed: int | None = None, calibration_seed: int | None = None):
        """The :class:`simcam.starcam.render.StarCamera` with the pixel maps of
        ``detector_seed`` and the calibration errors of ``calibration_seed`` (None: the
        scenario seed's); serial kernels (the runner's processes are the parallelism: on a
        2-core machine a threaded trial was no faster, 0.103 s against 0.102 s, and a fresh
        install would compile every kernel twice)."""
        from simcam.starcam.render import StarCamera

        if self._base is None:
            self._base = StarCamera(self.scenario, parallel=False)
        if detector_seed is None and calibration_seed is None:
            return self._base
        key = (detector_seed, calibration_seed)
        cam = self._cameras.pop(key, None)
        if cam is None:
            cam = self._base.twin(detector_seed=detector_seed, calibration_seed=calibration_seed)
            while len(self._cameras) >= CAMERAS_KEPT:
                self._cameras.pop(next(iter(self._cameras)))
        self._cameras[key] = cam  # most recent last
        return cam

    def instrument(self, seed: int, k: int):
        """Trial ``k``'s camera under run seed ``seed`` (:func:`instrument_seeds`): its
        calibration errors, and its maps when they are drawn per trial or pinned."""
        val = self.scenario.validation
        return self.camera(*instrument_seeds(instrument_seed=val.instrument_seed,
                                             new_maps_per_trial=val.new_maps_per_trial, seed=seed, k=k))

    def spectral(self):
        """The chromatic test's spectral design of the scenario."""
        from budget.starcam.protocols import spectral_design

        if self._spectral is None:
            self._spectral = spectral_design(self.scenario)
        return self._spectral
