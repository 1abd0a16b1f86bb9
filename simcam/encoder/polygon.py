"""Polygon-and-autocollimator calibration rig for an angle encoder (seed 001 section 3-4).

Lab protocol simulated (the one under which eq 9's compensation
``theta_hat = theta - e(theta)`` is exact, ``theta`` being the *reading*): for face ``i``
of an ``N``-face polygon the servo holds the (quantised) encoder reading at the nominal
face angle ``theta_i = i * 360/N``; the true shaft angle is then the one whose continuous
reading lies within the resolution cell, ``theta_true = f^-1(theta_i + d)`` with
``d = u q - n_r`` (``u`` uniform in [-1/2, 1/2), ``q`` the resolution, ``n_r`` the reading
noise). The autocollimator reads the deviation of face ``i`` from its nominal direction,
``alpha = (theta_true - theta_i) + face_error_i + mount_offset + n_ac`` rounded to its
resolution; the lab writes down ``error_arcsec = -alpha`` (encoder reading minus true
angle) against ``angle_deg = theta_i``. A compensated re-measurement ("verify") holds the
same raw readings and writes ``-alpha - e_hat(theta_i)``.

Random draws for one measurement, in this order when a generator is given:
``u`` (``rng.random(N)``), reading noise (``rng.standard_normal(N)``), autocollimator
noise (``rng.standard_normal(N)``); or the same standardised draws passed in (the Monte
Carlo validator lays a whole trial's draws out in two calls and passes them).
A polygon's face errors are one ``rng.standard_normal(N)`` draw scaled by its uncertainty.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from simcam.encoder.inductosyn import (
    ARCSEC_PER_DEG,
    AutocollimatorParams,
    Inductosyn,
    PolygonParams,
)

__all__ = [
    "FaceTaylor",
    "draw_face_errors_arcsec",
    "face_taylor",
    "measure_polygon",
    "nominal_face_angles_deg",
    "quantise_arcsec",
]


def nominal_face_angles_deg(*, faces: int) -> np.ndarray:
    """Nominal face angles ``i * 360 / faces`` (deg), i = 0 .. faces-1."""
    if faces < 3:
        raise ValueError("a polygon has at least 3 faces")
    return np.arange(faces) * (360.0 / faces)


def draw_face_errors_arcsec(*, polygon: PolygonParams, rng: np.random.Generator) -> np.ndarray:
    """Residual face-angle errors (after the certificate correction), arcsec."""
    return rng.standard_normal(polygon.faces) * polygon.face_error_arcsec


def quantise_arcsec(*, value_arcsec, resolution_arcsec: float):
    """Round to a resolution (arcsec); identity for 0."""
    x = np.asarray(value_arcsec, dtype=float)
    return x if resolution_arcsec == 0 else np.round(x / resolution_arcsec) * resolution_arcsec


def measure_polygon(*, encoder: Inductosyn, polygon: PolygonParams,
                    autocollimator: AutocollimatorParams, face_errors_arcsec: np.ndarray,
                    rng: np.random.Generator | None = None, draws=None,
                    compensation_arcsec=None) -> pd.DataFrame:
    """One pass round the polygon: the table a lab writes down (exact inverse map).

    Parameters
    ----------
    encoder : the encoder under test (truth).
    polygon, autocollimator : the rig.
    face_errors_arcsec : this polygon's residual face errors (see
        :func:`draw_face_errors_arcsec`).
    rng : generator for this measurement's draws (order in the module docstring).
    draws : alternatively, the standardised draws ``(u, z_read, z_ac)`` (u uniform in
        [0, 1), z standard normal), each of length ``faces``.
    compensation_arcsec : optional ``e_hat`` at the nominal angles (arcsec) subtracted
        from the written error (a compensated re-measurement).

    Returns
    -------
    DataFrame with columns ``angle_deg`` (nominal face angle = held reading) and
    ``error_arcsec`` (reading minus true angle, as measured).
    """
    angles = nominal_face_angles_deg(faces=polygon.faces)
    n = polygon.faces
    q_arcsec = encoder.params.resolution_deg * ARCSEC_PER_DEG
    if draws is None:
        if rng is None:
            raise ValueError("measure_polygon needs rng or draws")
        draws = (rng.random(n), rng.standard_normal(n), rng.standard_normal(n))
    u = np.asarray(draws[0]) - 0.5
    n_read = np.asarray(draws[1]) * encoder.params.reading_noise_arcsec
    n_ac = np.asarray(draws[2]) * autocollimator.noise_arcsec
    d_arcsec = u * q_arcsec - n_read
    true_deg = encoder.true_angle_deg(reading_deg=angles + d_arcsec / ARCSEC_PER_DEG)
    alpha = ((true_deg - angles) * ARCSEC_PER_DEG + face_errors_arcsec
             + polygon.mount_offset_arcsec + n_ac)
    err = -quantise_arcsec(value_arcsec=alpha, resolution_arcsec=autocollimator.resolution_arcsec)
    if compensation_arcsec is not None:
        err = err - np.asarray(compensation_arcsec, dtype=float)
    return pd.DataFrame({"angle_deg": angles, "error_arcsec": err})


class FaceTaylor:
    """Second-order expansion of the measured error about each nominal face angle.

    The true-angle offset from the held reading ``theta_i + d`` (arcsec) is
    ``f^-1(theta_i + d) - theta_i = -e0_i + s1_i d + s2_i d^2 + O(d^3)``. The truncation error
    is ``|f^-1'''| |d|^3 / 6``, below 1e-9 arcsec for |d| < 1 arcsec with the default
    encoder (checked against the exact inverse in tests/test_inductosyn.py).

    Attributes
    ----------
    angles_deg : nominal face angles.
    e0_arcsec : ``theta_i - f^-1(theta_i)`` (arcsec), the exact error at the reading.
    s1 : first derivative of ``f^-1`` (dimensionless).
    s2_per_arcsec : half the second derivative (1/arcsec).
    """

    def __init__(self, *, angles_deg, e0_arcsec, s1, s2_per_arcsec):
        self.angles_deg = angles_deg
        self.e0_arcsec = e0_arcsec
        self.s1 = s1
        self.s2_per_arcsec = s2_per_arcsec

    def true_offset_arcsec(self, *, d_arcsec):
        """``(f^-1(theta_i + d) - theta_i)`` in arcsec, for d (arcsec) of shape (..., N)."""
        return -self.e0_arcsec + self.s1 * d_arcsec + self.s2_per_arcsec * d_arcsec**2


def face_taylor(*, encoder: Inductosyn, faces: int, step_arcsec: float = 0.36) -> FaceTaylor:
    """Exact inverse map at the face angles and its derivatives (central differences)."""
    angles = nominal_face_angles_deg(faces=faces)
    h = step_arcsec / ARCSEC_PER_DEG
    t0 = encoder.true_angle_deg(reading_deg=angles)
    tp = encoder.true_angle_deg(reading_deg=angles + h)
    tm = encoder.true_angle_deg(reading_deg=angles - h)
    s1 = (tp - tm) / (2 * h)
    s2 = (tp - 2 * t0 + tm) / (2 * h * h) / ARCSEC_PER_DEG  # per arcsec
    return FaceTaylor(angles_deg=angles, e0_arcsec=(angles - t0) * ARCSEC_PER_DEG, s1=s1,
                      s2_per_arcsec=s2)
