"""The attitude of a sky frame (issue #34 item 3): the study's estimator on a real image.

From a full frame (FITS, as :func:`simcam.io.read_frame` reads it) and the star camera's
scenario (its plate scale, chip layout, onboard distortion correction and window size):

1. **stars detected and centroided** as the lab does on full frames: threshold and
   8-connected components (:func:`budget.centroid.detect_stars`), a window of the camera's
   size around each peak (:func:`budget.centroid.extract_windows`), thresholded centre of
   gravity with the border background (:func:`budget.centroid.centroid_cog`), then reported
   through the camera's own distortion correction (:meth:`StarCamera.report_positions`);
2. **identified** against the Hipparcos stars at their apparent places for the epoch
   (:func:`simcam.starcam.sky_view.sky_stars`) near a prior attitude: each centroid's
   direction, turned by the prior into the sky, takes the nearest catalogue star on the
   sphere within ``match_radius_arcsec`` (the prior's accuracy); a star claimed twice goes
   to the nearer centroid. The attitude solved from them, the stars are matched again at
   ``rematch_px`` times the plate scale about the solution and solved again;
3. **solved** by :func:`budget.attitude.solve.solve_attitude` with the stated centroid error
   ``sigma_px``, or, when none is given, the rms of the residuals over ``2N - 3`` degrees of
   freedom (at least 3 stars).

Attitude angles (:func:`attitude_from_angles`): the camera-to-inertial rotation
``Rz(ra) Ry(90 deg - dec) Rz(roll)`` (scipy's intrinsic ``"ZYZ"``): the boresight at
``(ra, dec)``; at roll 0 the camera's +y axis points east and +x south.

Without a prior, a lost-in-space solve (:func:`tetra3_prior`) asks cedar-solve's tetra3
(optional, not a dependency) for one, with a pattern database generated for this camera's
field (``benchmarks/bench_attitude.py`` generates and caches one).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from budget.attitude.chain import camera_model
from budget.attitude.solve import (
    AttitudeSolution,
    camera_directions,
    focal_from_mosaic,
    solve_attitude,
)
from budget.centroid import (
    CentroidFlag,
    CentroidWarning,
    centroid_cog,
    detect_stars,
    extract_windows,
)
from simcam.infra.errors import UserInputError
from simcam.starcam.render import StarCamera
from simcam.starcam.sky_view import SkyStars
from simcam.units import ARCSEC_PER_RAD

__all__ = ["FrameCentroids", "FrameSolution", "attitude_angles", "attitude_from_angles", "centroid_frame",
           "identify", "solve_sky_frame", "tetra3_attitude", "tetra3_prior"]


def attitude_from_angles(ra_deg: float, dec_deg: float, roll_deg: float) -> Rotation:
    """The attitude (camera to inertial) of boresight ``(ra, dec)`` and ``roll`` (deg): module docstring."""
    vals = [float(ra_deg), float(dec_deg), float(roll_deg)]
    if not all(math.isfinite(v) for v in vals) or not -90.0 <= vals[1] <= 90.0:
        raise UserInputError(f"prior: expected RA, Dec (-90 to 90), roll in degrees, got {vals}")
    return Rotation.from_euler("ZYZ", [vals[0], 90.0 - vals[1], vals[2]], degrees=True)


def attitude_angles(attitude: Rotation) -> tuple[float, float, float]:
    """``(ra, dec, roll)`` in degrees of an attitude (:func:`attitude_from_angles` inverted;
    RA in [0, 360), roll in (-180, 180])."""
    b = attitude.apply([0.0, 0.0, 1.0])
    ra = math.degrees(math.atan2(b[1], b[0])) % 360.0
    dec = math.degrees(math.asin(max(-1.0, min(1.0, b[2]))))
    rest = Rotation.from_euler("ZY", [ra, 90.0 - dec], degrees=True).inv() * attitude
    roll = float(rest.as_rotvec()[2])
    return ra, dec, math.degrees(roll)


@dataclass(frozen=True)
class FrameCentroids:
    """The stars found in a frame: reported (corrected) centroids in mosaic px, the flux above
    the background (DN), brightest first."""

    x_px: np.ndarray
    y_px: np.ndarray
    flux_dn: np.ndarray

    @property
    def n_stars(self) -> int:
        """Stars found."""
        return int(self.x_px.size)


def centroid_frame(frame, camera: StarCamera, *, threshold_sigma: float) -> FrameCentroids:
    """Detect, window and centroid the stars of a full frame (module docstring, step 1)."""
    img = np.asarray(frame, dtype=np.float64)
    det = detect_stars(img, threshold_sigma=threshold_sigma)
    scn = camera.scenario
    rows, cols = camera.mosaic.shape
    if img.shape != (rows, cols):
        raise UserInputError(f"frame: {img.shape[0]} x {img.shape[1]} px is not the camera's mosaic "
                             f"({rows} x {cols} px)")
    win, x0, y0, flag = extract_windows(img, x_center=det["x_peak"].to_numpy(), y_center=det["y_peak"].to_numpy(),
                                        size_px=scn.render.window_px)
    keep = (flag & int(CentroidFlag.EDGE)) == 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CentroidWarning)  # a lost window is dropped below
        x, y, flux, cflag = centroid_cog(win[keep], x0=x0[keep], y0=y0[keep], background="border", threshold_sigma=3.0)
    ok = np.isfinite(x) & np.isfinite(y) & ((cflag & int(CentroidFlag.LOST)) == 0)
    x, y, flux = x[ok], y[ok], flux[ok]
    order = np.argsort(-flux, kind="stable")
    xr, yr = camera.report_positions(x[order], y[order])
    return FrameCentroids(x_px=np.asarray(xr, float), y_px=np.asarray(yr, float), flux_dn=flux[order])


def identify(directions_camera: np.ndarray, attitude: Rotation, sky: SkyStars, *, radius_arcsec: float) -> np.ndarray:
    """For each camera-frame direction, the index of the nearest catalogue star of ``sky``
    within ``radius_arcsec`` of it turned by ``attitude`` into the sky; -1 for none. A star
    claimed twice goes to the nearer direction (module docstring, step 2)."""
    a = attitude.apply(directions_camera).reshape(-1, 3)
    chord = 2.0 * math.sin(radius_arcsec / ARCSEC_PER_RAD / 2.0)
    dist, idx = sky.tree.query(a, k=1, distance_upper_bound=chord)
    idx = np.where(np.isfinite(dist), idx, -1).astype(np.int64)
    for star in np.unique(idx[idx >= 0]):
        claim = np.flatnonzero(idx == star)
        if claim.size > 1:
            idx[claim[claim != claim[np.argmin(dist[claim])]]] = -1
    return idx


@dataclass(frozen=True)
class FrameSolution:
    """A frame's attitude (:func:`solve_sky_frame`): the solution (attitude, covariance of
    x, y, roll in arcsec^2, per-star residuals), the identified catalogue stars' HIP numbers
    and their reported centroids, the stars found and the centroid error used (with where
    it came from: ``"given"`` or ``"residuals"``)."""

    solution: AttitudeSolution
    hip: np.ndarray
    x_px: np.ndarray
    y_px: np.ndarray
    detected: int
    sigma_px: float
    sigma_source: str

    def to_json(self) -> dict:
        """JSON-ready: the attitude (angles, quaternion), covariance, sigma and per-star residuals."""
        s = self.solution
        ra, dec, roll = attitude_angles(s.attitude)
        return {
            "attitude": {"ra_deg": ra, "dec_deg": dec, "roll_deg": roll,
                         "quaternion_xyzw": s.attitude.as_quat().tolist(),
                         "convention": "camera to GCRS, Rz(ra) Ry(90 - dec) Rz(roll) (scipy 'ZYZ')"},
            "covariance_arcsec2": {"axes": ["x", "y", "roll"], "matrix": s.covariance_arcsec2.tolist()},
            "sigma_arcsec": dict(zip(("x", "y", "roll"), s.sigma_arcsec.tolist())),
            "centroid_sigma_px": self.sigma_px, "centroid_sigma_source": self.sigma_source,
            "stars_detected": self.detected, "stars_identified": int(self.hip.size), "chi2": s.chi2,
            "stars": [{"hip": int(h), "x_px": float(x), "y_px": float(y), "residual_u_arcsec": float(u),
                       "residual_v_arcsec": float(v)}
                      for h, x, y, u, v in zip(self.hip, self.x_px, self.y_px, s.residual_u_arcsec,
                                               s.residual_v_arcsec)],
        }


def _matched_solve(cents: FrameCentroids, model, sky: SkyStars, attitude: Rotation, *, radius_arcsec: float,
                   sigma_px: float):
    b = camera_directions(cents.x_px, cents.y_px, model)
    idx = identify(b, attitude, sky, radius_arcsec=radius_arcsec)
    m = idx >= 0
    if np.count_nonzero(m) < 2:
        raise UserInputError(f"identification: {np.count_nonzero(m)} of {cents.n_stars} stars found match a "
                             f"catalogue star within {radius_arcsec:g} arcsec of the prior; a better prior or a "
                             "larger --match-radius is needed")
    sol = solve_attitude(cents.x_px[m], cents.y_px[m], sigma_px, sky.direction[idx[m]], model)
    return sol, idx, m


def solve_sky_frame(frame, camera: StarCamera, sky: SkyStars, prior: Rotation, *, match_radius_arcsec: float = 600.0,
                    rematch_px: float = 5.0, sigma_px: float | None = None,
                    threshold_sigma: float = 5.0) -> FrameSolution:
    """The attitude of one frame (module docstring): ``sky`` the catalogue's stars at the
    frame's epoch through ``camera``, ``prior`` a coarse attitude."""
    if sigma_px is not None and not (math.isfinite(sigma_px) and sigma_px > 0.0):
        raise UserInputError(f"sigma_px: must be finite and > 0, got {sigma_px!r}")
    model = camera_model(camera.scenario)
    cents = centroid_frame(frame, camera, threshold_sigma=threshold_sigma)
    if cents.n_stars < 2:
        raise UserInputError(f"frame: {cents.n_stars} star(s) found above {threshold_sigma:g} sigma; an attitude "
                             "needs at least 2")
    unit = 1.0 if sigma_px is None else sigma_px
    sol, _, _ = _matched_solve(cents, model, sky, prior, radius_arcsec=match_radius_arcsec, sigma_px=unit)
    sol, idx, m = _matched_solve(cents, model, sky, sol.attitude, radius_arcsec=rematch_px * model.plate_scale_arcsec,
                                 sigma_px=unit)
    source = "given"
    if sigma_px is None:
        n = int(np.count_nonzero(m))
        if n < 3:
            raise UserInputError(f"sigma_px: {n} stars identified leave no residual to estimate the centroid error "
                                 "from; give --sigma-px")
        r2 = np.sum(sol.residual_u_arcsec**2 + sol.residual_v_arcsec**2) / (2 * n - 3)
        sigma_px = max(math.sqrt(r2) / model.plate_scale_arcsec, 1e-6)
        sol = solve_attitude(cents.x_px[m], cents.y_px[m], sigma_px, sky.direction[idx[m]], model)
        source = "residuals"
    return FrameSolution(solution=sol, hip=sky.hip[idx[m]], x_px=cents.x_px[m], y_px=cents.y_px[m],
                         detected=cents.n_stars, sigma_px=float(sigma_px), sigma_source=source)


def tetra3_prior(frame, camera: StarCamera, *, database: str, threshold_sigma: float = 5.0) -> Rotation:
    """A lost-in-space attitude from cedar-solve's tetra3 (``solve_from_centroids`` on the
    frame's centroids put into one virtual undistorted image, brightest first) with the pattern
    ``database`` generated for this camera's field. UserInputError where tetra3 is not
    installed or finds no solution."""
    try:
        import tetra3
    except ImportError:
        raise UserInputError("no --prior: a lost-in-space solve needs cedar-solve's tetra3 (optional: "
                             "pip install --no-deps cedar-solve), which is not installed; give --prior RA,DEC,ROLL") \
            from None
    if not hasattr(np, "math"):
        np.math = math  # cedar-solve 0.5.1 calls np.math.factorial, removed in numpy 2
    model = camera_model(camera.scenario)
    cents = centroid_frame(frame, camera, threshold_sigma=threshold_sigma)
    width = model.n_chips * model.chip_cols + (model.n_chips - 1) * model.gap_px
    height = model.chip_rows
    u, v = focal_from_mosaic(cents.x_px, cents.y_px, model)
    t3 = tetra3.Tetra3(load_database=None)
    t3.load_database(database)
    res = t3.solve_from_centroids(np.column_stack([v + height / 2.0, u + width / 2.0]), size=(height, width),
                                  fov_estimate=math.degrees(2.0 * math.atan(width / 2.0 / model.focal_length_px)),
                                  fov_max_error=0.05, distortion=0.0)
    if res.get("RA") is None:
        raise UserInputError(f"tetra3 found no solution for the {cents.n_stars} stars of the frame; give --prior")
    return tetra3_attitude(res)


def tetra3_attitude(solution: dict) -> Rotation:
    """Camera-to-inertial rotation of a tetra3 solution (``RA``, ``Dec``, ``Roll`` in degrees).
    tetra3's matrix ``M`` takes inertial vectors to its camera axes (boresight, -x, -y of the
    image), row 0 the boresight at (RA, Dec), rows 1-2 ``sin(roll) N + cos(roll) E`` and
    ``cos(roll) N - sin(roll) E`` (N, E the local north and east), as its RA/Dec/Roll extraction
    reads them; ours is ``(P M)^T``."""
    ra, dec, roll = np.radians([solution["RA"], solution["Dec"], solution["Roll"]])
    b = np.array([math.cos(dec) * math.cos(ra), math.cos(dec) * math.sin(ra), math.sin(dec)])
    n = np.array([-math.sin(dec) * math.cos(ra), -math.sin(dec) * math.sin(ra), math.cos(dec)])
    e = np.array([-math.sin(ra), math.cos(ra), 0.0])
    m = np.array([b, math.sin(roll) * n + math.cos(roll) * e, math.cos(roll) * n - math.sin(roll) * e])
    p = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    return Rotation.from_matrix((p @ m).T)
