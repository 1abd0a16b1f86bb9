"""Allocation estimates from a scenario: what a request's largest arrays need, refused
before any work when it cannot fit.

A field within its declared range can still ask for an array no machine holds: a Gaussian
PSF of ``sigma0_px = 1e-3`` needs its spectrum out to ``1183`` cycles/px (tables of 1.4e9
entries for a 32 px stamp), ``validation.dense_step_deg = 1e-9`` a truth grid of 3.6e11
angles, ``budget starcam measure --window 100001`` a window of 1e10 pixels per star. Each
estimate here is a lower bound of the bytes the array takes (nothing feasible is refused),
computed from the scenario alone; :func:`check_allocations` refuses, naming the field, its
value, the estimate and the memory available (:func:`simcam.infra.lifecycle.check_memory`:
:class:`~simcam.infra.errors.ResourceLimitError`, one line, exit status 2).

* :func:`psf_support_bytes`: the folded-spectrum PSF stamps
  (:mod:`simcam.starcam.psf_stamps`) drop frequencies where the Gaussian OTF
  ``exp(-2 pi^2 sigma^2 rho^2)`` is below ``eps = 1e-12``, i.e. beyond
  ``rho_g = sqrt(-ln eps / (2 pi^2 sigma^2))`` cycles/px; the stamp of side ``L`` then
  holds ``K = floor(L rho_g)`` lattice frequencies a side and its radial tables
  ``min(floor((L rho_g)^2), 2 K^2) + 1`` entries (float64, at least three arrays: the
  radii, the disc OTF and its temporary); the profile route holds ``(K + 1)(2 K + 1)``
  complex128 per star besides.
* :func:`dense_grid_bytes`: the inductosyn truth on ``round(360 / dense_step_deg)``
  angles, at least four float64 arrays (angles, reading, error and the reading's
  temporary).
* :func:`window_bytes`: ``budget starcam measure``'s windows, ``window_px^2`` float64 per
  star and frame (at least one of each).

Only the standard library is imported (the checks run at every command's start).
"""

from __future__ import annotations

import math

from simcam.infra.errors import ResourceLimitError
from simcam.infra.lifecycle import check_memory

__all__ = ["SPECTRUM_EPS", "check_allocations", "check_window", "dense_grid_bytes", "psf_support_bytes",
           "scenario_allocations", "window_bytes"]

#: the PSF spectrum's truncation (the same value as :data:`simcam.starcam.psf_stamps.SPECTRUM_EPS`,
#: which imports numba: a test checks they agree)
SPECTRUM_EPS = 1e-12
#: float64 arrays of the dense truth grid held at once (a lower bound)
DENSE_ARRAYS = 4
#: float64 arrays of the PSF radial tables held at once (a lower bound)
PSF_TABLE_ARRAYS = 3


def psf_frequency_extent_cyc_per_px(sigma_px: float) -> float:
    """``rho_g = sqrt(-ln eps / (2 pi^2 sigma^2))``: where the Gaussian OTF falls below
    :data:`SPECTRUM_EPS` (cycles/px); ``inf`` for ``sigma <= 0``."""
    if not sigma_px > 0:
        return math.inf
    return math.sqrt(-math.log(SPECTRUM_EPS) / (2.0 * math.pi ** 2)) / sigma_px


def psf_support_bytes(*, sigma_px: float, stamp_px: int, profile_route: bool = False) -> float:
    """Bytes of a Gaussian PSF's spectrum tables for one star (a lower bound; module docstring).

    Parameters
    ----------
    sigma_px : the smallest Gaussian sigma in the field, px
    stamp_px : the stamp side ``L``, px
    profile_route : add the profile route's ``(K + 1)(2 K + 1)`` complex128 spectrum
    """
    q = stamp_px * psf_frequency_extent_cyc_per_px(sigma_px)
    if not math.isfinite(q) or q > 1e150:  # beyond any memory: no overflow in the figure
        return math.inf
    k = math.floor(q)
    entries = min(math.floor(q * q), 2 * k * k) + 1
    out = 8.0 * PSF_TABLE_ARRAYS * entries
    if profile_route:
        out += 16.0 * (k + 1) * (2 * k + 1)
    return out


def dense_grid_bytes(dense_step_deg: float) -> float:
    """Bytes of the inductosyn's dense truth grid: ``round(360 / step)`` angles x
    :data:`DENSE_ARRAYS` float64 (a lower bound)."""
    if not dense_step_deg > 0:
        return math.inf
    return 8.0 * DENSE_ARRAYS * round(360.0 / dense_step_deg)


def window_bytes(window_px: int, *, stars: int = 1, frames: int = 1) -> float:
    """Bytes of square centroid windows: ``window_px^2`` float64 per star and frame."""
    return 8.0 * float(window_px) ** 2 * max(1, stars) * max(1, frames)


def _starcam(scenario) -> list[tuple[str, float, str]]:
    psf = getattr(getattr(scenario, "optics", None), "psf", None)
    render = getattr(scenario, "render", None)
    if psf is None or render is None or getattr(psf, "kind", None) != "gaussian":
        return []  # an Airy PSF's extent is its cutoff (a few cycles/px), whatever the blur
    # sigma = sigma0 + sigma_r2 (r / r_norm)^2 over the field, r^2 <= 2 r_norm^2 (as the
    # scenario's own check): its smallest value sizes the spectrum
    sigma = min(psf.sigma0_px, psf.sigma0_px + 2.0 * psf.sigma_r2_px)
    need = psf_support_bytes(sigma_px=sigma, stamp_px=render.stamp_px,
                             profile_route=getattr(render, "stamp_route", "") == "profile")
    field = "optics.psf.sigma0_px" if sigma == psf.sigma0_px else "optics.psf.sigma_r2_px"
    value = psf.sigma0_px if field.endswith("sigma0_px") else psf.sigma_r2_px
    return [(f"{field} = {value:g}", need,
             f"a Gaussian PSF of sigma {sigma:.3g} px spans {psf_frequency_extent_cyc_per_px(sigma):.3g} cycles/px: "
             f"spectrum tables of a render.stamp_px = {render.stamp_px} stamp")]


def _dense(scenario) -> list[tuple[str, float, str]]:
    step = getattr(getattr(scenario, "validation", None), "dense_step_deg", None)
    if step is None:
        return []
    return [(f"validation.dense_step_deg = {step:g}", dense_grid_bytes(step),
             f"a truth grid of {360.0 / step:.3g} angles")]


def scenario_allocations(scenario) -> list[tuple[str, float, str]]:
    """The estimated allocations of ``scenario`` (any study's: the fields it has decide):
    ``(field = value, bytes, what)`` for each."""
    return _starcam(scenario) + _dense(scenario)


def check_allocations(scenario, *, source: str = "scenario") -> None:
    """Refuse (:class:`~simcam.infra.errors.ResourceLimitError`, one line naming ``source``,
    the field and the estimate) a scenario whose largest arrays cannot fit in memory."""
    for field, need, what in scenario_allocations(scenario):
        if not math.isfinite(need):
            raise ResourceLimitError(f"{source}: {field}: {what}: needs more memory than any machine has")
        check_memory(need, what=f"{source}: {field}: {what}")


def check_window(window_px: int, *, option: str = "--window") -> None:
    """Refuse a centroid window whose one star in one frame cannot fit in memory."""
    check_memory(window_bytes(window_px), what=f"{option} {window_px}: one window of {window_px} x {window_px} "
                                               f"float64 px per star and frame")
