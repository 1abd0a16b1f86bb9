"""The star camera pointed at the sky: the Hipparcos stars in view of an attitude at an epoch,
projected through the camera's optics, and their scene for :class:`~simcam.starcam.render.StarCamera`.

Frames
------
* **Inertial**: the GCRS axes of :func:`simcam.sky.apparent.apparent_directions` (the
  stars' apparent directions seen by the observer).
* **Camera**: ``+z`` the boresight (optical axis); ``+x`` the direction whose field angle
  images toward focal ``+u`` (mosaic ``+x``), ``+y`` toward focal ``+v`` (mosaic ``+y``);
  right-handed (``x cross y = z``). The focal-plane axes are those of
  ``docs/conventions.md`` and ``tests/test_conventions.py`` (a field angle toward ``+u``
  moves the star to ``+x``).
* **Attitude**: a :class:`scipy.spatial.transform.Rotation` taking camera-frame vectors to
  inertial ones, ``d_inertial = attitude.apply(d_camera)``; the boresight points at
  ``attitude.apply([0, 0, 1])``.

The chain for one pointing (:func:`stars_in_view`), stage by stage as the lab's scenes
(:meth:`simcam.starcam.render.StarCamera.scene`, docs/simulator.md):

1. **apparent places** (:func:`sky_stars`, once per epoch and observer): the catalogue's
   stars at the epoch with proper motion, parallax, light deflection and annual plus
   orbital aberration (ERFA through astropy, :mod:`simcam.sky.apparent`);
2. **gnomonic projection**: ``u = F c_x / c_z``, ``v = F c_y / c_z`` with ``c`` the camera-frame
   direction and ``F = 206264.8 / s`` px the focal length in pixels (``s`` the plate scale,
   arcsec/px): the lab targets' projection ``u = (f/p) tan(theta)`` (:mod:`simcam.starcam.targets`);
3. **distortion** ``D(u, v)`` of the camera (:attr:`StarCamera.distortion`, the world's
   higher orders included);
4. **lateral colour** for the star's own spectrum: ``sum_l w_l s_l(D(u, v))`` with the
   star's wavelength weights ``w_l`` (:func:`star_spectra`);
5. **mosaic**: the chip the image lands on, at least half a window (``render.window_px // 2``)
   inside its edges (the lab's rule for a star that can be windowed); stars in the gap or
   off the chips are not in view;
6. **detection**: a star is kept when its photo-electrons reach the camera's limit
   (:func:`detection_limit`).

Star colour and flux (:func:`star_spectra`): Johnson V from Hipparcos Hp and B - V
(:attr:`simcam.sky.catalogue.Catalogue.v_mag`); effective temperature from B - V by
Ballesteros (2012, EPL 97, 34008, eq. 14, :func:`b_v_to_teff_k`); the spectrum a blackbody
at that temperature (no stellar library offline, as for the lab's stars,
:func:`simcam.spectra.star_photon_flux_per_nm`) scaled to the star's V, through the camera's
aperture, optics transmission and QE without a filter
(:func:`simcam.spectra.detected_electron_rate_per_nm`): the lab's photo-electron chain
(:class:`simcam.starcam.sources.SourceSpectra`) for a star.

The scene (:func:`sky_scene`) is a :class:`simcam.starcam.render.Scene` whose stars carry
their own spectrum (stamps of :func:`simcam.starcam.psf_stamps.render_stamps` with per-star
weights) and electrons, so that :meth:`StarCamera.render_windows`, :meth:`StarCamera.window_chain`
and :meth:`StarCamera.render_frame` expose it with the camera's PSF, detector maps,
non-linearity and noise unchanged. Docs: docs/attitude.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from simcam import spectra
from simcam.sky.apparent import apparent_directions
from simcam.sky.catalogue import DEFAULT_B_V, Catalogue, hipparcos
from simcam.starcam import optics, psf_stamps
from simcam.starcam.render import Placement, Scene, StarCamera, mosaic_corner_radius_px
from simcam.starcam.targets import TargetLayout
from simcam.units import ARCSEC_PER_RAD

__all__ = ["BV_RANGE", "SMEAR_STEP_PX", "DetectionLimit", "SkyStars", "StarsInView", "b_v_to_teff_k",
           "detection_limit", "focal_length_px", "image_motion_px", "sky_scene", "sky_stars", "star_spectra",
           "stars_in_view"]

#: B - V range of :func:`b_v_to_teff_k`: held at its ends outside (about 16,500 K and 3,170 K)
BV_RANGE = (-0.4, 2.0)
#: directions of the field's corner ring sampled for the search margin (:func:`_field_margin_px`)
_RING_SAMPLES = 72
#: extra search radius (px) beyond the corner, distortion and lateral colour
_SEARCH_SLACK_PX = 2.0
#: largest step (px) between the sub-exposure images that make up a smeared image (:func:`sky_scene`)
SMEAR_STEP_PX = 0.25


def b_v_to_teff_k(b_v) -> np.ndarray:
    """Effective temperature (K) of stars of colour ``b_v`` (Johnson B - V, mag).

    Ballesteros (2012, EPL 97, 34008, eq. 14), the blackbody relation fitted to stars::

        T = 4600 K (1 / (0.92 (B - V) + 1.7) + 1 / (0.92 (B - V) + 0.62))

    (5,780 K at the Sun's B - V = 0.65). B - V is held to :data:`BV_RANGE` (the relation has
    a pole at B - V = -0.67; hotter and redder colours than the range are rare among
    catalogue stars and a blackbody describes them poorly anyway).
    """
    bv = np.clip(np.asarray(b_v, dtype=np.float64), *BV_RANGE)
    return 4600.0 * (1.0 / (0.92 * bv + 1.7) + 1.0 / (0.92 * bv + 0.62))


def focal_length_px(camera: StarCamera) -> float:
    """The camera's focal length in pixels, ``F = 206264.8 / s`` (``s`` the plate scale, arcsec/px)."""
    return ARCSEC_PER_RAD / camera.scenario.camera.scale_arcsec_per_px


def star_spectra(camera: StarCamera, teff_k) -> tuple[np.ndarray, np.ndarray]:
    """Photo-electrons per exposure of a V = 0 star and its wavelength weights, per temperature.

    For each temperature ``T`` in ``teff_k`` (K, shape (K,)): the blackbody star of V = 0
    (:func:`simcam.spectra.star_photon_flux_per_nm`) through the camera's aperture, optics
    transmission and QE, no filter (:func:`simcam.spectra.detected_electron_rate_per_nm`),
    integrated over the exposure on the render grid. A star of magnitude V gives
    ``10**(-0.4 V)`` times as many electrons (the spectrum is proportional to ``10**(-0.4 V)``).

    Returns
    -------
    electrons_v0 : ndarray (K,)
        Photo-electrons per exposure at V = 0.
    weights : ndarray (K, n_l)
        Per-wavelength weights (rows sum to 1) on ``camera.spectra.wavelength_nm``.
    """
    src = camera.spectra
    wl = src.wavelength_nm
    temps = np.atleast_1d(np.asarray(teff_k, dtype=np.float64))
    e0 = np.empty(temps.size)
    w = np.empty((temps.size, wl.size))
    for i, t in enumerate(temps.tolist()):
        flux = spectra.star_photon_flux_per_nm(v_mag=0.0, temperature_k=t, wavelength_nm=wl)
        rate = spectra.detected_electron_rate_per_nm(
            photon_flux_per_nm=flux, aperture_area_m2=src.aperture_area_m2, transmission=src.transmission,
            filter_transmission=1.0, qe=src.qe, wavelength_nm=wl)
        e0[i] = src.electrons_per_exposure(rate)
        w[i] = src.weights(rate)
    return e0, w


@dataclass(frozen=True)
class DetectionLimit:
    """The faintest star the camera detects, per chip.

    ``noise_e[k]`` is the background noise of one pixel of chip ``k`` (e-):
    ``sqrt(r_k^2 + d t + b t + sigma_DSNU^2)`` (read noise, dark and stray-light shot noise,
    DSNU; the noise the lab's centroid threshold uses, ``budget.starcam.protocols.centroid_options``).
    ``peak_fraction`` is the smallest share of a point source's light in its brightest pixel:
    the image centred on a pixel corner, with the widest PSF of the field (at the mosaic's
    corner), at the lateral-colour reference wavelength, from the camera's own
    pixel-integrated PSF (:func:`simcam.starcam.psf_stamps.render_stamps`). A star of ``N`` photo-electrons
    is detected when its brightest pixel reaches the centroid threshold in expectation
    wherever it falls::

        N peak_fraction >= threshold_sigma noise_e[k],  i.e.  N >= min_electrons[k].
    """

    threshold_sigma: float
    noise_e: np.ndarray
    peak_fraction: float

    @property
    def min_electrons(self) -> np.ndarray:
        """Photo-electrons per exposure of the faintest detected star, per chip."""
        return self.threshold_sigma * self.noise_e / self.peak_fraction

    def v_limit_mag(self, electrons_v0: float) -> float:
        """The limiting V magnitude of a star giving ``electrons_v0`` at V = 0 (the least
        sensitive chip's limit)."""
        return float(2.5 * np.log10(electrons_v0 / self.min_electrons.max()))


def detection_limit(camera: StarCamera, *, threshold_sigma: float) -> DetectionLimit:
    """The camera's detection limit at ``threshold_sigma`` times its pixel noise (:class:`DetectionLimit`)."""
    k = float(threshold_sigma)
    if not math.isfinite(k) or k <= 0.0:
        raise ValueError(f"threshold_sigma: must be finite and > 0, got {threshold_sigma!r}")
    scn = camera.scenario
    det = scn.detector
    t = scn.camera.exposure_s
    read = np.array([c.read_noise_e for c in det.chips], dtype=np.float64)
    noise = np.sqrt(read**2 + det.dark_current_e_per_s * t + camera.background_e + det.dsnu_rms_e**2)
    r = mosaic_corner_radius_px(scn)
    sigma = optics.psf_sigma_px(u_px=np.array([r]), v_px=np.array([0.0]), sigma0_px=scn.optics.psf.sigma0_px,
                                sigma_r2_px=scn.optics.psf.sigma_r2_px, r_norm_px=scn.optics.r_norm_px)
    stamp, _, _ = psf_stamps.render_stamps(
        x_px=np.array([0.5]), y_px=np.array([0.5]), stamp_px=scn.render.stamp_px, psf_kind=scn.optics.psf.kind,
        sigma_px=sigma, pinhole_radius_px=0.0, f_number=scn.camera.f_number,
        pixel_pitch_um=scn.camera.pixel_pitch_um,
        wavelength_nm=np.array([scn.optics.lateral_colour.ref_wavelength_nm]), weights=np.ones((1, 1)),
        shift_x_px=0.0, shift_y_px=0.0)
    return DetectionLimit(threshold_sigma=k, noise_e=noise, peak_fraction=float(stamp.max()))


def _field_margin_px(camera: StarCamera, wavelength_nm: np.ndarray) -> float:
    """How far (px) the distortion and lateral colour can move an image at the field's corner
    radius: the search cone's margin beyond the corner, so that no star the optics bring
    into the field is missed."""
    scn = camera.scenario
    r = mosaic_corner_radius_px(scn)
    phi = np.linspace(0.0, 2.0 * np.pi, _RING_SAMPLES, endpoint=False)
    u, v = r * np.cos(phi), r * np.sin(phi)
    du, dv = camera.distortion.displacement(u_px=u, v_px=v)
    lc = scn.optics.lateral_colour
    su, sv = optics.lateral_colour_shift_px(
        wavelength_nm=wavelength_nm, u_px=u, v_px=v, ref_wavelength_nm=lc.ref_wavelength_nm,
        radial_coeffs=tuple(lc.radial_px_per_nm), uniform_x_coeffs=tuple(lc.uniform_x_px_per_nm),
        uniform_y_coeffs=tuple(lc.uniform_y_px_per_nm), r_norm_px=scn.optics.r_norm_px)
    return float(np.hypot(du, dv).max() + np.hypot(su, sv).max() + _SEARCH_SLACK_PX)


@dataclass(frozen=True)
class SkyStars:
    """The catalogue's stars at one epoch seen by one observer, with their colours and fluxes
    through one camera: what every pointing of a run shares (:func:`sky_stars`).

    Arrays are per star, in catalogue order. ``spectrum`` indexes the rows of ``weights``
    (one per distinct temperature). ``search_radius_rad`` is the angle from the boresight
    beyond which no star reaches the chips (the field's corner plus the optics' margin).
    """

    hip: np.ndarray
    direction: np.ndarray
    v_mag: np.ndarray
    b_v: np.ndarray
    teff_k: np.ndarray
    electrons: np.ndarray
    spectrum: np.ndarray
    weights: np.ndarray
    wavelength_nm: np.ndarray
    catalogue_v_max_mag: float
    search_radius_rad: float
    tree: object = field(repr=False, compare=False)

    def __len__(self) -> int:
        return int(self.hip.size)


def sky_stars(camera: StarCamera, time, *, catalogue_v_max_mag: float, observer_position_km=None,
              observer_velocity_km_s=None, catalogue: Catalogue | None = None) -> SkyStars:
    """The stars a camera can see at ``time`` (:class:`SkyStars`).

    Parameters
    ----------
    camera : StarCamera
        The camera (its spectral chain and optics).
    time : astropy.time.Time
        Epoch of observation (scalar).
    catalogue_v_max_mag : float
        The onboard catalogue's limit: only stars with V <= this are used (``math.inf``: every
        star of the catalogue; the camera's own detection limit applies in either case,
        :func:`stars_in_view`).
    observer_position_km, observer_velocity_km_s : array-like (3,), optional
        The observer's geocentric position and velocity (GCRS; default the geocentre at rest):
        the velocity gives the orbital aberration (:func:`simcam.sky.apparent.apparent_directions`).
    catalogue : Catalogue, optional
        The stars (default the whole Hipparcos catalogue, :func:`simcam.sky.catalogue.hipparcos`).
    """
    from scipy.spatial import cKDTree

    vmax = float(catalogue_v_max_mag)
    if math.isnan(vmax):
        raise ValueError("catalogue_v_max_mag: must be a number (math.inf for no limit), got nan")
    cat = hipparcos() if catalogue is None else catalogue
    cat = cat.select(np.flatnonzero(cat.v_mag <= vmax))
    if len(cat) == 0:
        raise ValueError(f"catalogue_v_max_mag: no star of the catalogue has V <= {vmax}")
    teff = b_v_to_teff_k(np.where(np.isfinite(cat.b_v), cat.b_v, DEFAULT_B_V))
    temps, spectrum = np.unique(teff, return_inverse=True)
    e0, weights = star_spectra(camera, temps)
    v = cat.v_mag
    d = apparent_directions(cat, time, observer_position_km=observer_position_km,
                            observer_velocity_km_s=observer_velocity_km_s)
    wl = camera.spectra.wavelength_nm
    r = (mosaic_corner_radius_px(camera.scenario) + _field_margin_px(camera, wl)) / focal_length_px(camera)
    return SkyStars(hip=cat.hip, direction=d, v_mag=v, b_v=cat.b_v, teff_k=teff,
                    electrons=e0[spectrum] * 10.0 ** (-0.4 * v), spectrum=spectrum.astype(np.int64),
                    weights=weights, wavelength_nm=wl, catalogue_v_max_mag=vmax,
                    search_radius_rad=float(math.atan(r)), tree=cKDTree(d))


@dataclass(frozen=True)
class StarsInView:
    """The stars of one pointing that land on a chip and are detected (:func:`stars_in_view`).

    Per star (arrays of length W, in catalogue order): ``index`` into the :class:`SkyStars`,
    ``hip``, the apparent inertial ``direction`` (W, 3), ``v_mag``, ``teff_k``, ``electrons``
    (per exposure), the ideal focal position ``u_px, v_px`` (gnomonic), the distortion and the
    chromatic displacement (focal px), the ``chip``, the true image position in mosaic px
    ``x_true, y_true`` (the centroid of the noise-free image, as the lab's truth) and the PSF
    width. ``weights`` (W, n_l) is each star's spectrum on ``wavelength_nm``.
    """

    attitude: object
    index: np.ndarray
    hip: np.ndarray
    direction: np.ndarray
    v_mag: np.ndarray
    teff_k: np.ndarray
    electrons: np.ndarray
    u_px: np.ndarray
    v_px: np.ndarray
    distortion_du_px: np.ndarray
    distortion_dv_px: np.ndarray
    chromatic_du_px: np.ndarray
    chromatic_dv_px: np.ndarray
    chip: np.ndarray
    x_true: np.ndarray
    y_true: np.ndarray
    psf_sigma_px: np.ndarray
    weights: np.ndarray
    wavelength_nm: np.ndarray

    @property
    def n_stars(self) -> int:
        """Number of stars W."""
        return int(self.index.size)


def _lateral_colour_model(camera: StarCamera, wavelength_nm: np.ndarray) -> optics.LateralColour:
    """The camera's lateral colour at the sky's wavelengths, kept on the camera (per grid)."""
    key = ("_sky_lateral_colour", wavelength_nm.tobytes())
    model = camera.__dict__.get(key)
    if model is None:
        scn = camera.scenario
        lc = scn.optics.lateral_colour
        model = camera.__dict__[key] = optics.lateral_colour(
            wavelength_nm=wavelength_nm, ref_wavelength_nm=lc.ref_wavelength_nm,
            radial_coeffs=tuple(lc.radial_px_per_nm), uniform_x_coeffs=tuple(lc.uniform_x_px_per_nm),
            uniform_y_coeffs=tuple(lc.uniform_y_px_per_nm), r_norm_px=scn.optics.r_norm_px)
    return model


def stars_in_view(camera: StarCamera, sky: SkyStars, attitude, *, detection: DetectionLimit) -> StarsInView:
    """The stars of ``sky`` on the camera's chips at ``attitude`` and above its ``detection`` limit.

    Parameters
    ----------
    camera : StarCamera
        The camera (optics, mosaic, window size).
    sky : SkyStars
        The stars at the epoch (:func:`sky_stars`, computed with this camera).
    attitude : scipy.spatial.transform.Rotation
        Camera frame to inertial (module docstring).
    detection : DetectionLimit
        The camera's limit (:func:`detection_limit`).
    """
    if not attitude.single:
        raise ValueError(f"attitude: expected a single rotation, got a stack of {len(attitude)}")
    scn = camera.scenario
    boresight = attitude.apply([0.0, 0.0, 1.0])
    chord = 2.0 * math.sin(sky.search_radius_rad / 2.0)
    cand = np.sort(np.asarray(sky.tree.query_ball_point(boresight, chord), dtype=np.int64))
    c = attitude.inv().apply(sky.direction[cand]).reshape(-1, 3)
    front = c[:, 2] > 0.0
    cand, c = cand[front], c[front]
    f = focal_length_px(camera)
    u0 = f * c[:, 0] / c[:, 2]
    v0 = f * c[:, 1] / c[:, 2]
    ud, vd = camera.distortion.forward(u_px=u0, v_px=v0)
    w = sky.weights[sky.spectrum[cand]]
    su, sv = _lateral_colour_model(camera, sky.wavelength_nm).shift_px(ud, vd)
    cu = np.sum(su * w, axis=1)
    cv = np.sum(sv * w, axis=1)
    chip, xc, yc = camera.mosaic.focal_to_chip(ud + cu, vd + cv, margin_px=scn.render.window_px // 2)
    on = chip >= 0
    keep = np.flatnonzero(on)
    keep = keep[sky.electrons[cand[keep]] >= detection.min_electrons[chip[keep]]]
    idx = cand[keep]
    sig = optics.psf_sigma_px(u_px=ud[keep], v_px=vd[keep], sigma0_px=scn.optics.psf.sigma0_px,
                              sigma_r2_px=scn.optics.psf.sigma_r2_px, r_norm_px=scn.optics.r_norm_px)
    return StarsInView(
        attitude=attitude, index=idx, hip=sky.hip[idx], direction=sky.direction[idx], v_mag=sky.v_mag[idx],
        teff_k=sky.teff_k[idx], electrons=sky.electrons[idx], u_px=u0[keep], v_px=v0[keep],
        distortion_du_px=ud[keep] - u0[keep], distortion_dv_px=vd[keep] - v0[keep], chromatic_du_px=cu[keep],
        chromatic_dv_px=cv[keep], chip=chip[keep], x_true=camera.mosaic.chip_to_mosaic_x(chip[keep], xc[keep]),
        y_true=yc[keep], psf_sigma_px=sig, weights=w[keep], wavelength_nm=sky.wavelength_nm)


def image_motion_px(camera: StarCamera, view: StarsInView, rate_rad_s, exposure_s: float) -> tuple[np.ndarray, np.ndarray]:
    """How far each star's image moves in the focal plane (px, u and v) during one exposure
    of ``exposure_s`` while the camera turns at ``rate_rad_s`` (rad/s about camera x, y, z).

    The attitude at time ``t`` from mid-exposure is ``A exp([w] t)`` (the rotation vector
    ``w t`` in the camera frame), so a star's camera-frame direction is ``exp(-[w] t) c``;
    its image ``D(F c_x / c_z, F c_y / c_z)`` (gnomonic, then the camera's distortion) at
    ``t = +T/2`` less that at ``-T/2``.
    """
    from scipy.spatial.transform import Rotation

    w = np.asarray(rate_rad_s, dtype=np.float64).reshape(3)
    c = view.attitude.inv().apply(view.direction).reshape(-1, 3)
    f = focal_length_px(camera)
    ends = []
    for t in (0.5 * exposure_s, -0.5 * exposure_s):
        ct = Rotation.from_rotvec(-w * t).apply(c).reshape(-1, 3)
        ends.append(camera.distortion.forward(u_px=f * ct[:, 0] / ct[:, 2], v_px=f * ct[:, 1] / ct[:, 2]))
    return ends[0][0] - ends[1][0], ends[0][1] - ends[1][1]


def sky_scene(camera: StarCamera, view: StarsInView, *, pointing: int,
              motion_px: tuple[np.ndarray, np.ndarray] | None = None) -> Scene:
    """The scene of one pointing for ``camera``'s renderer: each star's pixel-integrated image
    for its own spectrum and its electrons (no noise).

    ``motion_px`` (focal px, u and v per star, :func:`image_motion_px`): the image moves by it
    during the exposure, at a constant rate about the view's (mid-exposure) position. The
    smeared stamp is the mean of ``K`` images at equally spaced times (offsets
    ``((j + 1/2) / K - 1/2)`` of the motion, ``K`` the smallest count with steps of at most
    :data:`SMEAR_STEP_PX`): a box of the motion's length sampled much finer than the PSF
    (its Fourier transform differs from the box's beyond ``1 / SMEAR_STEP_PX`` cycles/px,
    where a 0.8 px Gaussian leaves ``exp(-2 pi^2 0.8^2 16)``, nothing). Its centroid is the
    mid-exposure position, the window's centre and the truth.

    ``pointing`` numbers the noise streams (the scene's ``condition``): frames of different
    pointings get independent temporal noise; the same (seed, pointing, frame) always the same.
    The stamps are those of the lab's ``"exact"`` stamp route
    (:func:`simcam.starcam.psf_stamps.render_stamps`), per star and wavelength, since every star
    has its own spectrum. The truth table holds, per star, ``star``, ``hip``, ``chip``,
    ``x_true``, ``y_true`` (mosaic px), the ideal and displaced focal positions, ``v_mag``,
    ``teff_k``, ``electrons``, ``psf_sigma_px`` and ``condition``.
    """
    if view.n_stars == 0:
        raise ValueError(f"view: pointing {pointing} has no star in view to render")
    scn = camera.scenario
    chip = view.chip
    ud = view.u_px + view.distortion_du_px
    vd = view.v_px + view.distortion_dv_px
    su, sv = _lateral_colour_model(camera, view.wavelength_nm).shift_px(ud, vd)
    sx, sy = camera.mosaic.vector_to_chip(su, sv, chip)
    mean_x, mean_y = camera.mosaic.vector_to_chip(view.chromatic_du_px, view.chromatic_dv_px, chip)
    xc = view.x_true - chip * camera.mosaic.chip_cols
    # the reference-wavelength position in the chip's pixels: the true image less its chromatic shift
    xr, yr = xc - mean_x, view.y_true - mean_y
    shifts = [(sx, sy)]
    if motion_px is not None:
        du, dv = (np.asarray(m, dtype=np.float64).reshape(view.n_stars) for m in motion_px)
        k = max(1, math.ceil(float(np.hypot(du, dv).max(initial=0.0)) / SMEAR_STEP_PX))
        mx, my = (m[:, None] for m in camera.mosaic.vector_to_chip(du, dv, chip))
        shifts = [(sx + t * mx, sy + t * my) for t in (np.arange(k) + 0.5) / k - 0.5]
    stamps = None
    for shift_x, shift_y in shifts:
        one, c0, r0 = psf_stamps.render_stamps(
            x_px=xr, y_px=yr, stamp_px=scn.render.stamp_px, psf_kind=scn.optics.psf.kind,
            sigma_px=view.psf_sigma_px, pinhole_radius_px=0.0, f_number=scn.camera.f_number,
            pixel_pitch_um=scn.camera.pixel_pitch_um, wavelength_nm=view.wavelength_nm, weights=view.weights,
            shift_x_px=shift_x, shift_y_px=shift_y, parallel=camera.parallel)
        stamps = one if stamps is None else stamps + one
    if len(shifts) > 1:
        stamps /= len(shifts)
    layout = TargetLayout(view.u_px, view.v_px, 0.0, view.u_px, view.v_px)
    placement = Placement(layout=layout, condition=int(pointing), label=f"pointing {pointing}")
    truth = {
        "star": np.arange(view.n_stars), "hip": view.hip, "chip": chip, "x_true": view.x_true, "y_true": view.y_true,
        "u_ideal_px": view.u_px, "v_ideal_px": view.v_px, "distortion_dx_px": view.distortion_du_px,
        "distortion_dy_px": view.distortion_dv_px, "chromatic_dx_px": view.chromatic_du_px,
        "chromatic_dy_px": view.chromatic_dv_px, "v_mag": view.v_mag, "teff_k": view.teff_k,
        "electrons": view.electrons, "psf_sigma_px": view.psf_sigma_px, "condition": int(pointing),
    }
    scene = Scene(placement=placement, chip=chip, x_ref_chip=xr, y_ref_chip=yr, electrons=view.electrons.copy(),
                  stamps=stamps, stamp_col0=c0, stamp_row0=r0, truth_columns=truth,
                  background_e=camera.background_e)
    # the true positions beside the table, as StarCamera.scene keeps them (window_origins reads them)
    object.__setattr__(scene, "_true_xy", (view.x_true, view.y_true))
    return scene
