"""Centroiding shared by every instrument that images stars: windows, thresholds, centre of
gravity, IWCoG, Gaussian fit (``core``), full-frame detection and matching (``frames``),
numba kernels in ``kernels``."""

from budget.centroid.core import *  # noqa: F401,F403
from budget.centroid.core import __all__ as _core_all
from budget.centroid.frames import *  # noqa: F401,F403
from budget.centroid.frames import __all__ as _frames_all

__all__ = [*_core_all, *_frames_all]
