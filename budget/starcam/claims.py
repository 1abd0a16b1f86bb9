"""Seed 000's claims (Wang et al. 2018, docs/estimators.md), for the claims ledger
(:mod:`budget.runner.claims`).

* **Performance**: the five figures the paper prints per axis (TE, HSFE, LSFE-S, LSFE-C1 and
  the single-star total, arcsec, 3 sigma) against the truths of ``embedded:seed000_noisy``,
  the seed-000 camera and lab with the paper's noise: does the simulated camera have these
  errors? Tolerance :data:`PERFORMANCE_TOLERANCE`.
* **Method**: each published estimator recovers its class's truth on the default camera
  (``embedded:default``), within :data:`METHOD_TOLERANCE`.
* **Bound**: the attitude error of ten stars (eq 32), untestable here: the attitude study
  judges it (issue #34).

Sections are cited as docs/estimators.md cites them; where it cites none, by the equations.
The tolerances' reasons are in docs/claims.md.
"""

from __future__ import annotations

from budget.runner.claims import Claim, ToleranceRule

__all__ = ["CLAIMS", "DEFAULT_SCENARIO", "METHOD_TOLERANCE", "NOISY_SCENARIO", "PERFORMANCE_TOLERANCE", "UNIT"]

#: the unit of every figure (the study's classes')
UNIT = "arcsec, 3 sigma"
#: the camera with the paper's noise, where the paper's figures are compared
NOISY_SCENARIO = "embedded:seed000_noisy"
#: the default camera, where the methods are judged against their truths
DEFAULT_SCENARIO = "embedded:default"

#: the simulated camera is the paper's by specification and noise, not its as-built lens,
#: colour and pixel maps: 10 % of a figure, and 0.1" (0.006 px, 1 sigma) where 10 % is less
PERFORMANCE_TOLERANCE = ToleranceRule(
    reason="10 % of the paper's figure, at least 0.1 arcsec (a camera simulated to its specification and noise)",
    source="default", relative=0.10, absolute=0.1)
#: a method that measures its class to 10 % of the truth serves an error budget
METHOD_TOLERANCE = ToleranceRule(reason="10 % of the truth", source="default", relative=0.10)

#: (class, what the paper calls it, its printed x and y figures, where, what the method computes)
_FIGURES = (
    ("te", "temporal error (TE)", (1.14, 1.23), "eqs 1-2",
     "the mean over stars of each star's temporal centroid sd over a static target's frames"),
    ("hsfe", "high spatial frequency error (HSFE)", (1.08, 1.01), "eqs 3-12",
     "the scatter of the centroid means of 0.2 px steps about their common motion"),
    ("lsfe_s", "chromatic error (LSFE-S)", (0.03, 0.66), "eqs 13-16, table 1, section 2.3.1",
     "the mean colour shift over four symmetric corner fields, halved and divided by 3"),
    ("lsfe_c1", "distortion calibration residual (LSFE-C1)", (0.29, 0.41), "eqs 17-30",
     "sqrt(sigma_dX^2 - sigma_DdX^2) of a full cubic fitted at the 32-point grid"),
    ("total", "single-star error", (1.76, 1.95), "section 2.4",
     "the root-sum-square of TE, HSFE and LSFE (LSFE by eq 31)"),
)


def _performance(cls: str, label: str, figure: float, axis: str, section: str) -> Claim:
    swapped = " (as printed: its axes appear swapped, docs/estimators.md section 4)" if cls == "lsfe_s" else ""
    return Claim(
        id=f"{cls}.{axis}.performance",
        words=f"the seed's camera has a {label} of {figure:g} arcsec in {axis}, 3 sigma",
        figures=(figure,), unit=UNIT, axis=axis,
        condition=f"the paper's camera and lab; simulated by {NOISY_SCENARIO}{swapped}", section=section,
        kind="performance", scenario=NOISY_SCENARIO, class_name=cls, tolerance=PERFORMANCE_TOLERANCE)


def _method(cls: str, label: str, figure: float, axis: str, section: str, what: str) -> Claim:
    return Claim(
        id=f"{cls}.{axis}.method", words=f"{what} measures the {label} in {axis}",
        figures=(figure,), unit=UNIT, axis=axis,
        condition=f"the published estimator on the default camera ({DEFAULT_SCENARIO})", section=section,
        kind="method", scenario=DEFAULT_SCENARIO, class_name=cls, variant="published",
        tolerance=METHOD_TOLERANCE)


#: the ledger's claims, in the paper's order: per class and axis its figure, then its method
CLAIMS: tuple[Claim, ...] = (
    *(c for cls, label, figs, section, what in _FIGURES for axis, fig in zip(("x", "y"), figs)
      for c in (_performance(cls, label, fig, axis, section), _method(cls, label, fig, axis, section, what))),
    Claim(id="attitude.eq32", words="ten stars give an attitude error of 0.56 / 0.62 arcsec (x / y, 3 sigma)",
          figures=(0.56, 0.62), unit=UNIT, axis="x, y", condition="the single-star error over sqrt(10), 10 stars",
          section="section 2.4, eq 32", kind="bound",
          untestable="judged on the sky by the attitude study, whose ledger holds it (budget claims)"),
)
