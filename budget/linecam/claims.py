"""Seed 004's claims (the Wuhan patent, star-observation calibration of a line camera; docs/linecam.md),
for the claims ledger (:mod:`budget.runner.claims`).

The patent reports no experiment and no figure: what it claims is a method, that steps 5-7
(the collinearity model with the exterior misalignment ``R_u`` and the interior Brown
parameters, solved by alternating linear fits over repeated shifted passes) recover the camera's
injected errors and its line of sight. So every testable claim is a ``method`` claim on the
``published`` variant, judged on ``embedded:default`` in its two worlds:

* each parameter the stars determine against its injected value: yaw, the principal distance,
  k1 k2 p1 p2, and, on a line at ``x' = 0``, the combinations ``pitch + dx0/F`` and
  ``roll - dy0/F`` in place of the four parameters the patent's own model cannot separate
  (seed 004 section a; their class is ``gauge_combination``). **Tolerance: a tenth of the
  injected error's sigma** (the bias left is at most a tenth of a typical error: the
  calibration removes the error, not its average);
* the calibrated line of sight at the two ends of the line (``los``, ``along_100`` and
  ``across_100``, where the distortion is largest) against the injected camera's. **Tolerance:
  0.1 px** of the camera's angular pixel (``pitch / f``), the sub-pixel accuracy a geometric
  calibration is for.

The rest is untestable here, each with its reason: step 2's signal formula (a factor the text
leaves undefined), the aberration step (judged by a run with the lab's aberration off, not by
the ledger's two worlds) and the group's published positioning figures (other cameras).
"""

from __future__ import annotations

import math

from budget.runner.claims import Claim, ToleranceRule

from .parameters import GAUGE_COMBINATIONS, PARAM_UNITS

__all__ = ["LEDGER_SCENARIO", "ledger_claims", "PARAMETER_TOLERANCE_FRACTION", "LOS_TOLERANCE_PX"]

#: the scenario whose two worlds judge the testable claims
LEDGER_SCENARIO = "embedded:default"
#: a parameter's bias may be this fraction of its injected sigma
PARAMETER_TOLERANCE_FRACTION = 0.1
#: the line of sight's bias may be this many angular pixels
LOS_TOLERANCE_PX = 0.1

_STEPS = "steps 5-7 (formulas lost; reconstructed, docs/linecam.md)"
#: (class, parameter, what it is, the scenario's errors field)
_PARAMETERS = (("exterior", "yaw", "the exterior misalignment about the boresight", "yaw_arcsec"),
               ("focal", "df", "the principal-distance error", "df_mm"),
               ("distortion", "k1", "the radial distortion k1", "k1"),
               ("distortion", "k2", "the radial distortion k2", "k2"),
               ("distortion", "p1", "the decentring distortion p1", "p1"),
               ("distortion", "p2", "the decentring distortion p2", "p2"))


def _sigma_report(scenario, field: str, parameter: str) -> float:
    """The injected sigma of ``field`` in the parameter's report unit (the scenario gives
    angles in arcsec, offsets in px, df in mm, distortion dimensionless)."""
    sigma = float(getattr(scenario.errors, field).sigma)
    return sigma * (PARAM_UNITS[parameter][1] if parameter in ("k1", "k2", "p1", "p2") else 1.0)


def _method(cid, words, unit, axis, cls, section, tol, condition) -> Claim:
    return Claim(id=cid, words=words, figures=(), unit=unit, axis=axis, condition=condition, section=section,
                 kind="method", scenario=LEDGER_SCENARIO, class_name=cls, variant="published", tolerance=tol)


def ledger_claims(scenario) -> tuple[Claim, ...]:
    """Seed 004's claims for the ledger (module docstring), tolerances from ``scenario``'s
    injected errors and camera."""
    cam, obs = scenario.camera, scenario.observation
    where = f"{LEDGER_SCENARIO}: {obs.passes} shifted passes, stars to V {scenario.stars.mag_limit:g}"
    out = []
    for cls, p, what, field in _PARAMETERS:
        unit = PARAM_UNITS[p][0]
        half = PARAMETER_TOLERANCE_FRACTION * _sigma_report(scenario, field, p)
        tol = ToleranceRule(reason=f"a tenth of the injected sigma ({half:.3g} {unit})", absolute=half)
        out.append(_method(f"{p}.method", f"the star calibration recovers {what}", unit, p, cls, _STEPS, tol, where))
    f_px = cam.focal_length_mm / cam.pitch_mm
    if cam.x_line_mm == 0.0:
        for axis, angle, px, _sign in GAUGE_COMBINATIONS:
            s_angle = float(getattr(scenario.errors, f"{angle}_arcsec").sigma)
            s_px = float(getattr(scenario.errors, f"{px}_px").sigma) / f_px * 180.0 / math.pi * 3600.0
            half = PARAMETER_TOLERANCE_FRACTION * math.hypot(s_angle, s_px)
            tol = ToleranceRule(reason=f"a tenth of the injected sigma ({half:.3g} arcsec)", absolute=half)
            out.append(_method(f"{axis}.method", f"the star calibration recovers {angle} and {px} as far as the "
                               f"stars determine them ({axis})", "arcsec", axis, "gauge_combination",
                               f"{_STEPS}; seed 004 section a", tol, where))
    pix_arcsec = cam.pitch_mm / cam.focal_length_mm * 180.0 / math.pi * 3600.0
    los_tol = ToleranceRule(reason=f"{LOS_TOLERANCE_PX:g} px ({LOS_TOLERANCE_PX * pix_arcsec:.3g} arcsec), the "
                                   "sub-pixel accuracy a geometric calibration is for",
                            absolute=LOS_TOLERANCE_PX * pix_arcsec)
    for axis, label in (("along_100", "along track"), ("across_100", "along the line")):
        out.append(_method(f"los.{axis}.method", f"the calibrated camera gives the line of sight {label} at "
                           "the line's end", "arcsec", axis, "los", _STEPS, los_tol, where))
    out += [
        Claim(id="step2.signal", words="the centre-pixel signal of a star is P = N M I0 2.512^-Mag", figures=(),
              unit="e-", axis="signal", condition="", section="step 2", kind="method",
              untestable="M is left undefined in the text; the world renders each star's electrons from its "
                         "colour and the QE instead"),
        Claim(id="step1.aberration", words="the star directions need the aberration correction R_Aber(t_i)",
              figures=(), unit="arcsec", axis="along, across", condition="", section="step 1.2", kind="method",
              untestable="judged by a run with lab.aberration = false, not by the ledger's two worlds"),
        Claim(id="luojia.positioning", words="star calibration of the camera installation positions Luojia 1-01 "
              "images within 800 m", figures=(800.0,), unit="m", axis="ground", condition="Guan et al. 2019",
              section="references (Remote Sens. 11 2081)", kind="performance",
              untestable="another camera (a frame camera) and a ground-positioning figure, not this line camera"),
    ]
    return tuple(out)
