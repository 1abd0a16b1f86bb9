"""The lab of seed 004: star-observation calibration of a TDI line camera.

* :mod:`budget.linecam.pipeline` -- steps 2-4: sky region, centroids and time tags, identification;
* :mod:`budget.linecam.model` -- the calibration model (collinearity with Brown's interior
  correction) and the look-angle field;
* :mod:`budget.linecam.calibrate` -- the published (exterior, then interior) and the joint
  estimators, separability (condition, null space);
* :mod:`budget.linecam.study` -- the study of the runner (``STUDY``);
* :mod:`budget.linecam.cli` -- ``budget linecam simulate`` and ``calibrate``.

See ``docs/linecam.md``.
"""
