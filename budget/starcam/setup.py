"""What a star-camera validation's trials and truths share: the camera and the spectral design.

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
#: cameras with their own detector maps (a detector seed) one set-up keeps, most recent last
CAMERAS_KEPT = 4


def setup_key(scenario) -> str:
    """The scenario's hash with the truth sizes set to 0 (:data:`TRUTH_SIZE_FIELDS`)."""
    fixed = {f: 0 for f in TRUTH_SIZE_FIELDS}
    return model_hash(scenario.model_copy(update={"validation": scenario.validation.model_copy(update=fixed)}))


def instrument_scenario(scenario):
    """The scenario whose seed draws the camera's fixed properties (PRNU/DSNU maps,
    :data:`simcam.starcam.render.STREAM_DETECTOR`; the onboard calibration's errors,
    :data:`simcam.starcam.correction.STREAM_ONBOARD_CALIBRATION`; its targets' fixed markers,
    :mod:`simcam.starcam.targets`): ``scenario`` itself when ``validation.instrument_seed`` is
    None, else a copy whose seed is the first word of
    :func:`budget.runner.study.instrument_seed_sequence` of the pinned seed (one camera for
    every trial and run seed). No other draw of a trial reads the scenario seed."""
    pinned = scenario.validation.instrument_seed
    if pinned is None:
        return scenario
    root = int(instrument_seed_sequence(pinned, 0, 0).generate_state(1, dtype=np.uint32)[0])
    return scenario.model_copy(update={"seed": root})


class CameraSetup:
    """The camera of a scenario (its own detector maps) and, built on first use, cameras with
    the maps of other detector seeds (new maps per trial) and the chromatic test's spectral
    design (:func:`budget.starcam.protocols.spectral_design`). Built from the first scenario of
    its :func:`setup_key`, with the instrument :func:`instrument_scenario` gives; every
    scenario of that key gives the same camera."""

    def __init__(self, scenario):
        self.scenario = instrument_scenario(scenario)
        self._cameras: dict = {}
        self._spectral = None

    def camera(self, detector_seed: int | None = None):
        """The :class:`simcam.starcam.render.StarCamera` with the scenario's detector maps
        (``detector_seed`` None) or those of ``detector_seed``; serial kernels (the runner's
        processes are the parallelism: on a 2-core machine a threaded trial was no faster,
        0.103 s against 0.102 s, and a fresh install would compile every kernel twice)."""
        from simcam.starcam.render import StarCamera

        cam = self._cameras.pop(detector_seed, None)
        if cam is None:
            cam = StarCamera(self.scenario, detector_seed=detector_seed, parallel=False)
            while len(self._cameras) >= CAMERAS_KEPT:
                self._cameras.pop(next(iter(self._cameras)))
        self._cameras[detector_seed] = cam  # most recent last
        return cam

    def spectral(self):
        """The chromatic test's spectral design of the scenario."""
        from budget.starcam.protocols import spectral_design

        if self._spectral is None:
            self._spectral = spectral_design(self.scenario)
        return self._spectral
