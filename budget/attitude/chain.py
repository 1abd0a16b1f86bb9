"""The simulated star camera on the real sky, observed and solved as a flight camera would be.

One pointing (:func:`observe`): the Hipparcos stars in view at their apparent places
(:func:`simcam.starcam.sky_view.stars_in_view`), their windows rendered by the
:class:`~simcam.starcam.render.StarCamera` (its PSF, detector maps, non-linearity, noise;
:func:`simcam.starcam.sky_view.sky_scene`), exposed and centroided in one pass as the lab's
Monte Carlo trial does (thresholded centre of gravity with the border background, the
threshold ``threshold_sigma`` times the windows' noise:
:func:`budget.starcam.kernels_trial.expose_centroid_chain` with
:func:`budget.starcam.protocols.centroid_options`), then reported through the camera's own
onboard distortion correction (:meth:`StarCamera.report_positions`, the correction
:func:`simcam.starcam.correction.fit_onboard_correction` fits from the camera's earlier
calibration, as :func:`budget.starcam.protocols.simulate` applies it in every trial).

The stars are identified by construction (the simulation knows them; identification errors
are not this question), and the solve (:func:`solve_frame`) is :func:`budget.attitude.solve.solve_attitude`
given only what a real camera gives: the reported centroids, a stated centroid error, the
camera model of :func:`camera_model` and the stars' apparent directions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from budget.attitude.solve import AttitudeSolution, CameraModel, solve_attitude
from budget.centroid import CentroidFlag
from budget.starcam.kernels_trial import expose_centroid_chain
from budget.starcam.protocols import centroid_options
from simcam.starcam.render import StarCamera
from simcam.starcam.sky_view import (
    DetectionLimit,
    SkyStars,
    StarsInView,
    image_motion_px,
    sky_scene,
    stars_in_view,
)

__all__ = ["FrameView", "PointingObservation", "camera_model", "frame_attitudes", "good_stars", "observe",
           "observe_pointing", "random_attitudes", "smooth_field_positions", "solve_frame"]

#: window batches above this many pixels expose on numba threads (as the lab's trial decides)
_PARALLEL_MIN_PIXELS = 20_000


def camera_model(scenario) -> CameraModel:
    """The geometry a user of the scenario's camera knows (:class:`CameraModel`): its plate
    scale and chip layout, and the distortion still in its centroids: none for a camera that
    reports them through its onboard correction (``optics.distortion_correction.kind =
    "fitted"``), the design's Brown-Conrady coefficients for an uncalibrated one."""
    det = scenario.detector
    dist = scenario.optics.distortion
    corrected = scenario.optics.distortion_correction.kind != "none"
    return CameraModel(
        plate_scale_arcsec=scenario.camera.scale_arcsec_per_px, n_chips=det.n_chips, chip_cols=det.chip_cols,
        chip_rows=det.chip_rows, gap_px=det.gap_px, chip_offset_u_px=tuple(c.offset_x_px for c in det.chips),
        chip_offset_v_px=tuple(c.offset_y_px for c in det.chips),
        chip_rotation_deg=tuple(c.rotation_deg for c in det.chips),
        k1=0.0 if corrected else dist.k1, k2=0.0 if corrected else dist.k2,
        p1=0.0 if corrected else dist.p1, p2=0.0 if corrected else dist.p2, r_norm_px=scenario.optics.r_norm_px)


def random_attitudes(n: int, *, seed: int) -> Rotation:
    """``n`` attitudes uniform over the rotation group (boresight uniform on the sphere, roll
    uniform), drawn from ``SeedSequence(seed)``."""
    return Rotation.random(int(n), random_state=np.random.default_rng(np.random.SeedSequence(seed)))


@dataclass(frozen=True)
class PointingObservation:
    """The frames of one pointing (:func:`observe`).

    ``view`` is the truth (the stars in view, their true image positions and apparent
    directions); ``x_px``, ``y_px`` (frames, W) the centroids the camera reports (mosaic px,
    its onboard correction applied; NaN where the star was lost); ``flux_dn`` and ``flag``
    (:class:`budget.centroid.CentroidFlag` bits) the centroider's.
    """

    pointing: int
    attitude: Rotation
    view: StarsInView
    x_px: np.ndarray
    y_px: np.ndarray
    flux_dn: np.ndarray
    flag: np.ndarray

    @property
    def n_frames(self) -> int:
        """Frames observed."""
        return int(self.x_px.shape[0])


def frame_attitudes(attitude: Rotation, *, frames: int, rate_rad_s, interval_s: float) -> Rotation:
    """The mid-exposure attitudes of ``frames`` frames about ``attitude`` while the camera
    turns at ``rate_rad_s`` (rad/s about camera x, y, z): frame ``f`` at
    ``attitude * exp([w] t_f)``, ``t_f = (f - (frames - 1) / 2) interval_s`` (the rotation
    vector ``w t_f`` in the camera frame), so that ``attitude`` is the middle of the slew."""
    w = np.asarray(rate_rad_s, dtype=np.float64).reshape(3)
    t = (np.arange(int(frames)) - (frames - 1) / 2.0) * float(interval_s)
    return attitude * Rotation.from_rotvec(t[:, None] * w[None, :])


def observe(camera: StarCamera, sky: SkyStars, attitude: Rotation, *, detection: DetectionLimit, pointing: int,
            seed: int, frames: int, threshold_sigma: float, angular_rate_rad_s=None) -> PointingObservation:
    """``frames`` frames of the camera at ``attitude``: windows exposed, centroided and reported
    (module docstring). Frame ``f`` draws the temporal noise of (``seed``, ``pointing``, ``f``).
    ``angular_rate_rad_s`` (about camera x, y, z): the camera turns during each exposure, which
    smears every image about its mid-exposure position (:func:`simcam.starcam.sky_view.image_motion_px`);
    ``attitude`` is then the mid-exposure attitude. None or zero: no smear."""
    view = stars_in_view(camera, sky, attitude, detection=detection)
    w = view.n_stars
    if w == 0:
        empty = np.empty((frames, 0))
        return PointingObservation(pointing, attitude, view, empty, empty.copy(), empty.copy(),
                                   np.zeros((frames, 0), dtype=np.int64))
    motion = None
    if angular_rate_rad_s is not None and np.any(np.asarray(angular_rate_rad_s, dtype=np.float64) != 0.0):
        motion = image_motion_px(camera, view, angular_rate_rad_s, camera.scenario.camera.exposure_s)
    scene = sky_scene(camera, view, pointing=pointing, motion_px=motion)
    chain = camera.window_chain(scene)
    keys = camera.frame_keys(seed=seed, condition=int(pointing), frames=frames)
    noise_dn = centroid_options(camera, chain.col0, threshold_sigma)["noise_dn"]
    _, h, ww = chain.mean_e.shape
    parallel = camera.parallel if camera.parallel is not None else frames * w * h * ww > _PARALLEL_MIN_PIXELS
    x, y, flux, flag = expose_centroid_chain(chain, keys, dark_mean=None, threshold_dn=threshold_sigma * noise_dn,
                                             parallel=parallel)
    xr, yr = camera.report_positions(x.ravel(), y.ravel())
    return PointingObservation(pointing, attitude, view, xr.reshape(x.shape), yr.reshape(y.shape), flux, flag)


def smooth_field_positions(camera: StarCamera, view: StarsInView) -> tuple[np.ndarray, np.ndarray]:
    """Where the camera would report each star of ``view`` with its smooth fields only (mosaic
    px): the true image position (gnomonic, distorted and shifted by its own lateral colour,
    ``x_true, y_true``: the centroid of the noise-free image) through the onboard correction,
    with no pixel sampling, detector map or noise. Its error against the ideal gnomonic
    position is the star's FOV spatial error (ECSS-E-ST-60-20C): the correction's residual and
    the lateral colour."""
    return camera.report_positions(view.x_true, view.y_true)


def good_stars(obs: PointingObservation, frame: int) -> np.ndarray:
    """Which stars of frame ``frame`` of ``obs`` have a centroid (finite, not flagged lost)."""
    x, y = obs.x_px[frame], obs.y_px[frame]
    return np.isfinite(x) & np.isfinite(y) & ((obs.flag[frame] & int(CentroidFlag.LOST)) == 0)


def solve_frame(obs: PointingObservation, model: CameraModel, *, frame: int,
                sigma_px) -> AttitudeSolution | None:
    """The attitude of frame ``frame`` of ``obs`` from its good centroids (lost ones left out,
    :func:`good_stars`), each weighted by the stated error ``sigma_px`` (one for every star,
    or one per star of the view); None with fewer than 2 good stars."""
    good = good_stars(obs, frame)
    if np.count_nonzero(good) < 2:
        return None
    sig = sigma_px if np.ndim(sigma_px) == 0 else np.asarray(sigma_px, dtype=np.float64)[good]
    return solve_attitude(obs.x_px[frame][good], obs.y_px[frame][good], sig, obs.view.direction[good], model)


@dataclass(frozen=True)
class FrameView:
    """One frame of a pointing (:func:`observe_pointing`): its true mid-exposure ``attitude``
    and where it is, frame ``index`` of ``observation``."""

    attitude: Rotation
    observation: PointingObservation
    index: int


def observe_pointing(camera: StarCamera, sky: SkyStars, attitude: Rotation, *, detection: DetectionLimit, seed: int,
                     frames: int, threshold_sigma: float, rate_rad_s, interval_s: float) -> tuple[FrameView, ...]:
    """The ``frames`` frames of one pointing (:func:`observe`). A staring camera (``rate_rad_s``
    zero) takes them all at ``attitude`` (one observation, noise condition 0); a turning
    one takes frame ``f`` at its own attitude along the slew (:func:`frame_attitudes`), smeared,
    with its own stars in view (noise condition ``f``)."""
    w = np.asarray(rate_rad_s, dtype=np.float64).reshape(3)
    if not w.any():
        obs = observe(camera, sky, attitude, detection=detection, pointing=0, seed=seed, frames=frames,
                      threshold_sigma=threshold_sigma)
        return tuple(FrameView(attitude, obs, f) for f in range(frames))
    out = []
    for f, att in enumerate(frame_attitudes(attitude, frames=frames, rate_rad_s=w, interval_s=interval_s)):
        obs = observe(camera, sky, att, detection=detection, pointing=f, seed=seed, frames=1,
                      threshold_sigma=threshold_sigma, angular_rate_rad_s=w)
        out.append(FrameView(att, obs, 0))
    return tuple(out)
