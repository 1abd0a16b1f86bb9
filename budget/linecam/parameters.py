"""The ten calibration parameters as the line camera's outputs report them: their report
units (:data:`PARAM_UNITS`, :func:`to_report_units`) and, for the pairs a line at
``x' = 0`` cannot separate, the combinations the stars do determine
(:data:`GAUGE_COMBINATIONS`, :func:`gauge_combination_vector`,
:func:`determined_combinations`; docs/linecam.md section 3)."""

from __future__ import annotations

import numpy as np

from simcam.linecam.scenario import PARAMETERS
from simcam.units import ARCSEC_PER_RAD

__all__ = ["PARAM_UNITS", "to_report_units", "GAUGE_COMBINATIONS", "gauge_combination_vector",
           "determined_combinations"]

#: report unit of each parameter and the factor from model units
PARAM_UNITS = {"roll": ("arcsec", ARCSEC_PER_RAD), "pitch": ("arcsec", ARCSEC_PER_RAD),
               "yaw": ("arcsec", ARCSEC_PER_RAD), "dx0": ("px", 1.0), "dy0": ("px", 1.0),
               "df": ("mm", 1.0), "k1": ("1e-4", 1e4), "k2": ("1e-4", 1e4), "p1": ("1e-4", 1e4),
               "p2": ("1e-4", 1e4)}


def to_report_units(theta) -> np.ndarray:
    """Parameters (order of :data:`simcam.linecam.scenario.PARAMETERS`) from model units to
    the report units of :data:`PARAM_UNITS`."""
    return np.asarray(theta, float) * np.array([PARAM_UNITS[p][1] for p in PARAMETERS])


#: what the stars determine on a line at x' = 0 (docs/linecam.md section 3): the null
#: directions are ``-pitch F + dx0`` and ``roll F + dy0`` (px at the line's end), so
#: ``pitch + dx0 / F`` and ``roll - dy0 / F`` (arcsec) are invariant along them:
#: (axis name, angle parameter, px parameter, sign of the px term)
GAUGE_COMBINATIONS = (("pitch+dx0/F", "pitch", "dx0", 1.0), ("roll-dy0/F", "roll", "dy0", -1.0))


def gauge_combination_vector(f_px: float, angle: str, px: str, sign: float):
    """Coefficients (arcsec per model unit: rad, px) of ``angle + sign px / F`` over the ten
    parameters (:data:`simcam.linecam.scenario.PARAMETERS`)."""
    g = np.zeros(len(PARAMETERS))
    g[PARAMETERS.index(angle)] = ARCSEC_PER_RAD
    g[PARAMETERS.index(px)] = sign * ARCSEC_PER_RAD / f_px
    return g


def determined_combinations(null_space: list[dict], f_px: float) -> list[tuple[str, str, str, float]]:
    """From a plan's null space (:func:`budget.linecam.calibrate.separability`, px at the line's
    end) the combinations that are determined: for each null direction of one angle and one
    px parameter, ``c_a angle F + c_p px`` unobservable makes ``angle - (c_a / c_p) px / F``
    invariant. Returns (name, angle, px, sign) like :data:`GAUGE_COMBINATIONS`."""
    out = []
    for comb in null_space:
        ang = [p for p in comb if p in ("roll", "pitch", "yaw")]
        pxs = [p for p in comb if p in ("dx0", "dy0")]
        if len(comb) == 2 and len(ang) == 1 and len(pxs) == 1 and comb[pxs[0]] != 0:
            sign = -comb[ang[0]] / comb[pxs[0]]
            out.append((f"{ang[0]}{'+' if sign > 0 else '-'}{pxs[0]}/F", ang[0], pxs[0], float(sign)))
    return out
