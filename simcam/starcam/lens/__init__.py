"""Lens prescriptions traced with Mitsuba 3: PSF, distortion and lateral colour for simcam.

Public API
----------
load_prescription, Prescription
    A sequential, rotationally symmetric lens from TOML (``embedded:star_camera`` or a
    file), validated; glasses from :mod:`simcam.starcam.lens.glass` (Sellmeier coefficients).
paraxial, ParaxialData
    First-order data by ABCD matrices.
LensTracer, TraceResult, field_bundle
    Real-ray trace: Mitsuba intersections (llvm variant, scalar fallback), refinement on
    the exact surface and Snell refraction in double precision.
lens_products, compute_products, LensProducts
    Focus, centroids (distortion, lateral colour), spots and PSFs over field and
    wavelength, cached on disk under the prescription's hash.
simulator_optics, SimulatorOptics
    The products fitted to the simulator's optics models (what ``optics.lens`` in a
    scenario uses).

Command line: ``simcam optics [PRESCRIPTION] [--out DIR]``. See docs/lens.md.
"""

from simcam.starcam.lens.errors import LensBackendWarning, LensError
from simcam.starcam.lens.paraxial import ParaxialData, paraxial
from simcam.starcam.lens.prescription import (
    Prescription,
    embedded_lens_names,
    load_prescription,
)
from simcam.starcam.lens.products import LensProducts, compute_products, lens_products
from simcam.starcam.lens.simulator import SimulatorOptics, simulator_optics
from simcam.starcam.lens.tracer import LensTracer, TraceResult, field_bundle

__all__ = [
    "LensBackendWarning",
    "LensError",
    "LensProducts",
    "LensTracer",
    "ParaxialData",
    "Prescription",
    "SimulatorOptics",
    "TraceResult",
    "compute_products",
    "embedded_lens_names",
    "field_bundle",
    "lens_products",
    "load_prescription",
    "paraxial",
    "simulator_optics",
]
