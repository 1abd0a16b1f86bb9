"""The patent's steps 2-4 as the lab runs them (seed 004): choose the sky region, extract
the stars' centroids with their time tags, predict the footprint and identify the stars.

* Step 2, :func:`choose_region`: the strip centre (on a Fibonacci lattice of the sphere)
  that holds the most catalogue stars brighter than the detectable magnitude (the
  patent's "simulated traversal of the whole sky").
* Step 4, :func:`extract_centroids`: thresholded centre of gravity of each window
  (:func:`budget.centroid.core.centroid_cog`) and the time tag. During the TDI exposure of
  ``N`` line periods the star moves (eq. 4.1); the patent rotates the blurred star by the
  motion angle ``theta = atan2(B, A)`` (:func:`motion_angle`) and centroids along and across
  the smear. A centre of gravity is equivariant under that rotation, so the rotated
  centroid is the plain one; what the motion model changes is the time tag: the centroid
  of a uniformly smeared star is its position at mid-exposure, ``t_L - N T / 2`` for output
  line ``L`` read out at ``t_L`` (``time_tag = "readout"`` shows the half-exposure error).
* Step 3, :func:`identify`: the nominal camera and the reported attitude predict where each
  centroid looks on the sky; the nearest catalogue star (apparent place) within
  ``match_radius_arcsec`` is the star, unless a second star is inside the radius too or two
  centroids claim the same star (both then dropped).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from budget.centroid.core import centroid_cog
from simcam.linecam.attitude import strip_frame
from simcam.linecam.scenario import LineCamScenario
from simcam.linecam.world import PassImages, SkyStrip
from simcam.units import ARCSEC_PER_RAD

from .model import NominalCamera, Observations

__all__ = ["choose_region", "Region", "motion_angle", "rotated_blur_centroid", "Centroids", "extract_centroids",
           "identify", "Identified"]


@dataclass(frozen=True)
class Region:
    ra_deg: float
    dec_deg: float
    stars: int
    candidates: int


def choose_region(catalogue, *, mag_limit: float, across_rad: float, along_rad: float, pa_deg: float = 0.0,
                  candidates: int = 600) -> Region:
    """Step 2: the strip centre with the most stars of V <= ``mag_limit`` in a strip of
    ``along_rad`` x ``across_rad`` (scan direction at position angle ``pa_deg``), over
    ``candidates`` centres of a Fibonacci lattice (quasi-uniform on the sphere)."""
    i = np.arange(candidates) + 0.5
    dec = np.arcsin(1.0 - 2.0 * i / candidates)
    ra = np.mod(np.pi * (1.0 + 5.0**0.5) * i, 2.0 * np.pi)
    keep = catalogue.v_mag <= mag_limit
    u = catalogue.unit_vectors()[keep]
    tree = cKDTree(u)
    reach = 2.0 * math.sin(0.5 * math.hypot(along_rad, across_rad) * 0.5 * 1.01)  # chord of the half diagonal
    counts = np.zeros(candidates, dtype=int)
    for c, (a, d) in enumerate(zip(ra, dec)):
        frame = strip_frame(math.degrees(a), math.degrees(d), pa_deg)
        near = tree.query_ball_point(frame[:, 2] * -1.0, reach)
        if not near:
            continue
        body = u[near] @ frame
        al = np.abs(np.arctan2(body[:, 0], -body[:, 2]))
        ac = np.abs(np.arctan2(body[:, 1], -body[:, 2]))
        counts[c] = int(np.sum((body[:, 2] < 0) & (al <= 0.5 * along_rad) & (ac <= 0.5 * across_rad)))
    best = int(np.argmax(counts))
    return Region(ra_deg=float(np.degrees(ra[best])), dec_deg=float(np.degrees(dec[best])),
                  stars=int(counts[best]), candidates=candidates)


def motion_angle(*, f_px: float, x_px, y_px, rates_rad_s, exposure_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Step 4.2: image motion over the exposure and its angle (seed 004 eq. 4.1, first terms).

    ``A = (f w_y + Y w_z) dt``, ``B = (-f w_x - X w_z) dt`` (px), ``theta = atan2(B, A)``.
    Returns ``(hypot(A, B), theta)``.
    """
    wx, wy, wz = rates_rad_s
    A = (f_px * wy + np.asarray(y_px) * wz) * exposure_s
    B = (-f_px * wx - np.asarray(x_px) * wz) * exposure_s
    return np.hypot(A, B), np.arctan2(B, A)


def rotated_blur_centroid(window, *, theta: float, x0: float = 0.0, y0: float = 0.0,
                          background: float | None = None) -> tuple[float, float, float, float]:
    """The patent's step 4.2: centroid of the blurred star normalised by its motion angle.

    The window (background removed: the border median unless given) is read in
    coordinates rotated by ``-theta`` (``G'(x', y') = G(R(theta) (x', y'))``), so that the
    smear lies along ``x'``; the centroid is taken along (``x'``) and across (``y'``) the
    smear and rotated back to window coordinates. Returns ``(x, y, along, across)``:
    mosaic position (px) and the rotated-frame centroid. A centre of gravity is
    rotation-equivariant, so ``(x, y)`` equals the plain centre of gravity of the same
    weights (tested); the rotated frame is what the patent uses to separate smear from
    noise across it.
    """
    w = np.asarray(window, dtype=float)
    if background is None:
        border = np.concatenate([w[0], w[-1], w[1:-1, 0], w[1:-1, -1]])
        background = float(np.median(border))
    g = np.clip(w - background, 0.0, None)
    iy, ix = np.indices(w.shape, dtype=float)
    c, s_ = math.cos(theta), math.sin(theta)
    xr = c * ix + s_ * iy  # R(-theta) (x, y)
    yr = -s_ * ix + c * iy
    tot = g.sum()
    along, across = float((g * xr).sum() / tot), float((g * yr).sum() / tot)
    x = c * along - s_ * across
    y = s_ * along + c * across
    return x0 + x, y0 + y, along, across


@dataclass
class Centroids:
    """Centroids of the star windows: sample (px), output line (px), time tag (s), pass."""

    sample: np.ndarray
    line: np.ndarray
    t_s: np.ndarray
    pass_index: np.ndarray
    flux_dn: np.ndarray
    window: np.ndarray


def extract_centroids(images: PassImages, scenario: LineCamScenario) -> Centroids:
    """Step 4: centre of gravity of each window above 3 sigma of its border, with the time tag
    of ``scenario.lab.time_tag``; flagged windows (lost, saturated, edge) are dropped."""
    cam = scenario.camera
    x, y, flux, flag = centroid_cog(images.windows_dn.astype(np.float64), x0=images.col0.astype(float),
                                    y0=images.line0.astype(float), background="border",
                                    threshold_sigma=3.0, adc_max_dn=float(2**scenario.detector.adc_bits - 1))
    ok = (flag == 0) & np.isfinite(x) & np.isfinite(y)
    T, N = cam.line_period_s, cam.tdi_stages
    lag = 0.5 * N if scenario.lab.time_tag == "mid_exposure" else 0.0
    t = images.t_pass0_s[images.pass_index] + (y - lag) * T
    return Centroids(sample=x[ok], line=y[ok], t_s=t[ok], pass_index=images.pass_index[ok], flux_dn=flux[ok],
                     window=np.flatnonzero(ok))


@dataclass
class Identified:
    """Observations of identified stars and what identification did."""

    obs: Observations
    t_s: np.ndarray
    attitude: np.ndarray
    star_index: np.ndarray
    centroid_index: np.ndarray
    unmatched: int
    ambiguous: int
    predicted_sep_arcsec: np.ndarray


def identify(cam: NominalCamera, strip: SkyStrip, *, sample, t_s, pass_index, attitude,
             match_radius_arcsec: float) -> Identified:
    """Step 3: identify centroids with catalogue stars and form the calibration's observations.

    Parameters
    ----------
    strip : SkyStrip
        The lab's catalogue stars and apparent directions (its own switches of
        aberration, parallax, proper motion).
    sample, t_s, pass_index : arrays (n,)
        Centroids: sample, time tag, pass.
    attitude : numpy.ndarray (n, 3, 3)
        Reported body -> GCRS matrices at the time tags.
    """
    sample = np.asarray(sample, float)
    n = sample.size
    c = np.column_stack([np.full(n, cam.x_line_px), cam.y_px(sample), np.full(n, -cam.f_px)])
    c /= np.linalg.norm(c, axis=1, keepdims=True)
    w = np.einsum("nij,nj->ni", attitude, c)
    radius = match_radius_arcsec / ARCSEC_PER_RAD
    star = np.full(n, -1)
    sep = np.full(n, np.inf)
    ambiguous = 0
    for k in np.unique(pass_index):
        sel = np.flatnonzero(pass_index == k)
        if len(strip.cat) == 0:
            continue
        tree = cKDTree(strip.directions[k])
        d, j = tree.query(w[sel], k=[1, 2])  # (m, 2); a missing neighbour is at inf
        hit = d[:, 0] < radius
        amb = hit & (d[:, 1] < radius)  # two catalogue stars inside the radius
        ambiguous += int(amb.sum())
        hit &= ~amb
        star[sel[hit]] = j[hit, 0]
        sep[sel[hit]] = d[hit, 0]
    # two centroids of one pass claiming one star: drop both
    key = np.where(star >= 0, pass_index * (len(strip.cat) + 1) + star, -1)
    vals, counts = np.unique(key[key >= 0], return_counts=True)
    dup = np.isin(key, vals[counts > 1])
    ambiguous += int(dup.sum())
    good = (star >= 0) & ~dup
    idx = np.flatnonzero(good)
    a = strip.at(pass_index[idx], star[idx], np.asarray(t_s)[idx])
    b = np.einsum("nji,nj->ni", attitude[idx], a)
    obs = Observations(b=b, sample=sample[idx], pass_index=np.asarray(pass_index)[idx],
                       hip=strip.cat.hip[star[idx]])
    return Identified(obs=obs, t_s=np.asarray(t_s)[idx], attitude=attitude[idx], star_index=star[idx],
                      centroid_index=idx, unmatched=int(np.sum(star < 0)), ambiguous=ambiguous,
                      predicted_sep_arcsec=sep[idx] * ARCSEC_PER_RAD)
