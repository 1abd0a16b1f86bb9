"""Centroiding shared by every instrument that images stars: windows, thresholds, centre of
gravity, IWCoG, Gaussian fit, full-frame detection and matching (numba kernels in ``kernels``)."""

from budget.centroid.core import *  # noqa: F401,F403
from budget.centroid.core import __all__  # noqa: F401
