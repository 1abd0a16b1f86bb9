"""Error estimators of seed 000 (as published) and improved variants beside them.

One module per quantity: :mod:`.te` (TE), :mod:`.hsfe` (HSFE), :mod:`.chromatic`
(LSFE-S), :mod:`.distortion` (LSFE-C1, LSFE-C2), :mod:`.combination` (LSFE, single star,
attitude); :mod:`.results` the result types, :mod:`.common` the shared table steps. Every
public name is re-exported here: ``from budget.starcam.estimators import X``.

All functions are pure functions of centroid tables (``docs/conventions.md``: columns
``star``, ``condition``, ``frame``, ``x``, ``y`` in mosaic px, and ``filter_nm``,
``field``, ``flag`` where they apply). The plate scale is a parameter; the counts
W (stars), N (frames), M (conditions), K (fields) come from the data.

Published (seed 000, Wang et al., Infrared and Laser Engineering 47(9) 0917002, 2018):

* :func:`temporal_error` -- TE, eqs 1-2
* :func:`high_spatial_frequency_error` -- HSFE, eqs 3-12
* :func:`chromatic_error` -- LSFE-S, eqs 13-16 (and the "/3" of section 1.4.1)
* :func:`distortion_residual_error` -- LSFE-C1, eqs 17-30
* :func:`target_marker_error` -- LSFE-C2, given (section 1.4.3)
* :func:`low_spatial_frequency_error` -- LSFE, eq 31
* :func:`single_star_error` -- RSS of TE, HSFE, LSFE (section 2.4)
* :func:`attitude_error` -- eq 32

Improved (derived in ``docs/estimators.md``):

* :func:`temporal_error_pooled` -- pooled RMS, with the c4 discussion
* :func:`high_spatial_frequency_error_debiased` -- temporal noise and common-motion
  removal accounted for
* :func:`chromatic_error_decomposed` -- uniform and radial parts kept apart
* :func:`distortion_residual_error_dof` -- fit degrees of freedom (W - 10)
* :func:`chromatic_error_population` -- a stellar population through the camera's
  spectral response instead of "/2" and "/3"
* :func:`high_spatial_frequency_error_static` -- the static error itself, not its
  consecutive differences
* :func:`distortion_calibration_residual` -- the distortion left after calibration
* :func:`distortion_remaining_displacement` -- the displacement a calibrated camera still makes

Rows with a non-zero ``flag`` or a non-finite ``x``/``y`` are excluded with an
:class:`EstimatorWarning`; stars that then lack what an estimator needs are excluded
with a warning too. Both counts are in the result. Malformed tables raise
:class:`simcam.infra.errors.UserInputError` naming the column, star or condition.
"""

from __future__ import annotations

from .chromatic import chromatic_error, chromatic_error_decomposed, chromatic_error_population
from .combination import attitude_error, low_spatial_frequency_error, single_star_error
from .distortion import (
    cubic_design_matrix,
    distortion_calibration_residual,
    distortion_remaining_displacement,
    distortion_residual_error,
    distortion_residual_error_dof,
    target_marker_error,
)
from .hsfe import (
    high_spatial_frequency_error,
    high_spatial_frequency_error_debiased,
    high_spatial_frequency_error_static,
)
from .results import ChromaticEstimate, DistortionEstimate, ErrorEstimate, EstimatorWarning, HsfeEstimate
from .te import c4, temporal_error, temporal_error_pooled


__all__ = [
    "EstimatorWarning",
    "ErrorEstimate",
    "HsfeEstimate",
    "ChromaticEstimate",
    "DistortionEstimate",
    "temporal_error",
    "temporal_error_pooled",
    "c4",
    "high_spatial_frequency_error",
    "high_spatial_frequency_error_debiased",
    "high_spatial_frequency_error_static",
    "chromatic_error",
    "chromatic_error_decomposed",
    "chromatic_error_population",
    "distortion_residual_error",
    "distortion_residual_error_dof",
    "distortion_calibration_residual",
    "distortion_remaining_displacement",
    "cubic_design_matrix",
    "target_marker_error",
    "low_spatial_frequency_error",
    "single_star_error",
    "attitude_error",
]
