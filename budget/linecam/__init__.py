"""The lab of seed 004: star-observation calibration of a TDI line camera.

* :mod:`budget.linecam.pipeline` -- steps 2-4: sky region, centroids and time tags, identification;
* :mod:`budget.linecam.model` -- the calibration model (collinearity with Brown's interior
  correction) and the look-angle field;
* :mod:`budget.linecam.calibrate` -- the published (exterior, then interior) and the joint
  estimators, separability (condition, null space), and the calibration of an observation
  table (``calibrate_file``, the Python entry of ``budget linecam calibrate``);
* :mod:`budget.linecam.table` -- the observation table (columns, reading and checks, writing);
* :mod:`budget.linecam.parameters` -- the parameters' report units and the combinations a
  line at x' = 0 determines;
* :mod:`budget.linecam.trial` -- one simulated calibration, end to end;
* :mod:`budget.linecam.simulated` -- ``budget linecam simulate`` without the command line;
* :mod:`budget.linecam.study` -- the study of the runner (``STUDY``);
* :mod:`budget.linecam.report` -- plots and report pages;
* :mod:`budget.linecam.cli` -- ``budget linecam simulate`` and ``calibrate``.

See ``docs/linecam.md``.
"""
