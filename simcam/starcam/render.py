"""From a scenario and a target placement to pixels and the truth they carry.

The chain for each pinhole star (stages in a fixed order, as in a detector pipeline):

1. **target**: ideal focal-plane position ``(u, v)`` (simcam.starcam.targets), plus the hexapod's
   image displacement for the pose;
2. **distortion**: ``(u, v) -> D(u, v)`` (Brown-Conrady then cubic; simcam.starcam.optics);
3. **spectrum**: electrons per nm reaching the detector from source x filter x optics
   transmission x QE (simcam.starcam.sources / simcam.spectra), giving wavelength weights and the
   electrons per exposure;
4. **lateral colour**: a displacement per wavelength ``s(lambda, u, v)``; the image is the
   weighted sum of the per-wavelength images, so its centroid moves by
   ``sum_l w_l s_l`` (the spectrum-weighted chromatic displacement);
5. **PSF**: pinhole disc x camera PSF, integrated over each pixel (simcam.starcam.optics);
6. **detector**: PRNU, dark signal + DSNU, shot noise, read noise, full well, ADC
   (simcam.detector), keyed per mosaic pixel so windows and full frames agree.

The true position reported for a star is the centroid of its noise-free image:
``D(u + platform) + sum_l w_l s_l``, mapped to mosaic pixel coordinates.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from simcam.detector import DetectorParams, detector_maps, expose, expose_windows_frames, window_chain
from simcam.infra.errors import ScenarioError
from simcam.rng import child_keys, key_from_seed
from simcam.starcam import optics, psf_stamps
from simcam.starcam.correction import fit_onboard_correction
from simcam.starcam.geometry import Mosaic
from simcam.starcam.kernels.windows import add_stamps_windows
from simcam.starcam.scenario import Scenario
from simcam.starcam.sources import SourceSpectra
from simcam.starcam.targets import TargetLayout
from simcam.starcam.world import world_motion

#: the camera's caches that depend on neither the pixel maps nor the calibration's errors, so
#: that every :meth:`StarCamera.twin` shares them: scenes (with their noise-free windows and,
#: per detector key, their chains), drift gradients (keyed by detector key), spectra, lateral
#: colour, PSF profiles, frame keys, and what the lab's protocols keep per camera (their
#: targets' layouts and centroid columns, :mod:`budget.starcam.protocols`)
_OPTICAL_CACHES = ("_scene_cache", "_drift_scenes", "_drift_grads", "_mosaic_xy", "_spectrum_cache",
                   "_lateral_colour_models", "_profile_cache", "_condition_keys", "_star_grids",
                   "_protocol_columns")
#: detector chains one scene keeps (one per instrument that rendered it, most recent last)
_CHAINS_KEPT = 8

#: SeedSequence spawn-key roots
STREAM_DETECTOR = 201  # scenario seed -> PRNU/DSNU maps
STREAM_FRAMES = 301  # run seed -> temporal noise of each frame
STREAM_DARK_FRAMES = 302  # run seed -> temporal noise of each star-free (lamp-off) frame


def mosaic_corner_radius_px(scenario: Scenario) -> float:
    """Half diagonal of the nominal mosaic in the focal plane, px (the field's corner radius)."""
    det = scenario.detector
    width = det.n_chips * det.chip_cols + (det.n_chips - 1) * det.gap_px
    return float(np.hypot(width / 2.0, det.chip_rows / 2.0))


class RenderError(ScenarioError):
    """A placement cannot be rendered (a star off the detector, in the gap, ...)."""


@dataclass(frozen=True)
class Placement:
    """One acquisition condition: a target layout, a hexapod pose and a filter.

    ``condition`` numbers the frame streams: frames of different conditions get
    independent noise; the same (seed, condition, frame) always gives the same noise.
    """

    layout: TargetLayout
    platform_dx_px: float = 0.0
    platform_dy_px: float = 0.0
    filter_nm: float | None = None
    condition: int = 0
    label: str = ""
    #: roll of the camera about its optical axis (rad, from +u toward +v), a hexapod pose
    #: error (simcam.starcam.world): the star at ideal (u, v) moves by roll (-v, u)
    platform_roll_rad: float = 0.0


@dataclass(frozen=True)
class Scene:
    """Everything deterministic about one placement: positions, spectra, stamps, truth."""

    placement: Placement
    chip: np.ndarray
    x_ref_chip: np.ndarray  # chip px, reference wavelength position (after distortion)
    y_ref_chip: np.ndarray
    electrons: np.ndarray  # photo-electrons per exposure per star (before PRNU)
    stamps: np.ndarray  # (W, L, L) flux fractions
    stamp_col0: np.ndarray  # chip px of stamps[:, 0, 0]
    stamp_row0: np.ndarray
    #: the truth table's columns (name -> (W,) array, or a scalar for a column that is the same
    #: for every star), in the table's order
    truth_columns: dict = field(repr=False, compare=False)
    background_e: float = 0.0

    @property
    def n_stars(self) -> int:
        """Number of stars W."""
        return len(self.chip)

    @property
    def truth(self) -> pd.DataFrame:
        """Per star: the injected truth (positions, the displacements that make them up, flux,
        PSF width, filter, condition). Built on first use and kept (a Monte Carlo trial never
        reads it: a table costs about a millisecond); callers must not modify it."""
        t = self.__dict__.get("_truth")
        if t is None:
            t = pd.DataFrame(self.truth_columns)
            object.__setattr__(self, "_truth", t)
        return t


@dataclass(frozen=True)
class Windows:
    """Windows cut around each star for a set of frames.

    ``pixels[f, j]`` is the window of star ``j`` in frame ``f``; its pixel ``[r, c]`` is
    mosaic pixel ``(x = col0[j] + c, y = row0[j] + r)``.
    """

    pixels: np.ndarray
    col0: np.ndarray
    row0: np.ndarray
    truth: pd.DataFrame
    frame_index: np.ndarray = field(default_factory=lambda: np.zeros(0, int))


class StarCamera:
    """The simulated star camera in its lab, built from a :class:`Scenario`.

    Parameters
    ----------
    scenario : Scenario
        The camera and lab.
    detector_seed : int, optional
        Seed of the fixed-pattern maps (PRNU, DSNU); default the scenario seed.
    calibration_seed : int, optional
        Seed of the errors of the camera's earlier distortion calibration
        (:func:`simcam.starcam.correction.fit_onboard_correction`); default the scenario seed.
        A Monte Carlo run that draws an instrument per trial gives both seeds per trial
        through :meth:`twin`, which keeps the optical caches.
    parallel : bool, optional
        Use numba threads for batches of windows (default: by batch size). Worker
        processes of a Monte Carlo run pass False. Results are identical either way.
    """

    def __init__(self, scenario: Scenario, *, detector_seed: int | None = None,
                 calibration_seed: int | None = None, parallel: bool | None = None):
        self.scenario = scenario
        #: numba threads for window batches (None: by size); results do not depend on it
        self.parallel = parallel
        self.mosaic = Mosaic.from_model(scenario.detector)
        self.spectra = SourceSpectra(scenario)
        o = scenario.optics
        self.distortion = optics.CompositeDistortion(
            brown_conrady=optics.BrownConradyDistortion(
                k1=o.distortion.k1, k2=o.distortion.k2, p1=o.distortion.p1, p2=o.distortion.p2,
                r_norm_px=o.r_norm_px,
            ),
            cubic=optics.CubicDistortion(
                coeffs_x=tuple(o.distortion.cubic_x_px), coeffs_y=tuple(o.distortion.cubic_y_px),
                r_norm_px=o.r_norm_px,
            ),
        )
        eff = scenario.world.effects
        if o.lens is None and (eff.distortion_r5_px_at_corner != 0.0 or eff.distortion_r7_px_at_corner != 0.0):
            # the world's lens distortion beyond the scenario's: fifth and seventh
            # order radial terms, sized at the mosaic's corner. A traced lens (optics.lens)
            # already carries its own higher orders (fitted up to r^5): nothing is added to it
            self.distortion = optics.HigherOrderRadialDistortion(
                base=self.distortion, a5_px=eff.distortion_r5_px_at_corner, a7_px=eff.distortion_r7_px_at_corner,
                r_corner_px=mosaic_corner_radius_px(scenario))
        det = scenario.detector
        self.detector_params = DetectorParams(
            gain_e_per_dn=tuple(c.gain_e_per_dn for c in det.chips),
            offset_dn=tuple(c.offset_dn for c in det.chips),
            read_noise_e=tuple(c.read_noise_e for c in det.chips),
            full_well_e=tuple(c.full_well_e for c in det.chips),
            adc_bits=det.bits,
            prnu_rms=det.prnu_rms,
            dark_e=det.dark_current_e_per_s * scenario.camera.exposure_s,
            dsnu_rms_e=det.dsnu_rms_e,
            nonlinearity_beta=eff.nonlinearity_beta,
        )
        #: the seeds of this instrument's drawn properties: its pixel maps, its calibration's errors
        self.detector_seed = int(scenario.seed if detector_seed is None else detector_seed)
        self.calibration_seed = int(scenario.seed if calibration_seed is None else calibration_seed)
        self.detector_key = key_from_seed(self.detector_seed, STREAM_DETECTOR)
        self.background_e = det.background_e_per_s * scenario.camera.exposure_s
        for name in _OPTICAL_CACHES:  # created here so that every twin shares them
            self.__dict__[name] = {}

    def twin(self, *, detector_seed: int | None = None, calibration_seed: int | None = None) -> StarCamera:
        """Another instrument of this design: the same scenario and optics, the pixel maps of
        ``detector_seed`` and the calibration errors of ``calibration_seed`` (None: this
        camera's). It shares this camera's optical caches (:data:`_OPTICAL_CACHES`: scenes and
        their noise-free windows, spectra, PSF profiles), which do not depend on either seed;
        what does (a scene's detector chain, the drift gradients, the correction) is kept per
        detector key or per camera."""
        other = object.__new__(StarCamera)
        # its attributes and the optical caches' dicts themselves (shared); no other cache
        other.__dict__.update({k: v for k, v in self.__dict__.items()
                               if isinstance(k, str) and (not k.startswith("_") or k in _OPTICAL_CACHES)})
        other.detector_seed = self.detector_seed if detector_seed is None else int(detector_seed)
        other.calibration_seed = self.calibration_seed if calibration_seed is None else int(calibration_seed)
        other.detector_key = key_from_seed(other.detector_seed, STREAM_DETECTOR)
        return other

    def world_motion(self, seed: int):
        """The world's hexapod pose errors and target drift for run seed ``seed``
        (:func:`simcam.starcam.world.world_motion`; None when those effects are off). The
        last seed's is kept."""
        hit = self.__dict__.get("_world_motion")
        if hit is None or hit[0] != seed:
            hit = (seed, world_motion(self.scenario, seed))
            self.__dict__["_world_motion"] = hit
        return hit[1]

    def drift_chain(self, scene: Scene, nominal: Placement | None = None, *, step_px: float = 1e-3):
        """The window chain of ``scene`` and the gradient of its mean charge with respect to a
        common image displacement (u and v, e- per px), for a drift within the condition:
        frame ``f`` of a drift ``d_f`` about the scene's own position has the mean charge
        ``mean + d_f,u G_u + d_f,v G_v`` (first order in ``d_f``; the simulation puts the
        condition's mean drift into the scene itself, so ``d_f`` stays below 1e-3 px at the
        sourced magnitudes and the neglected ``d^2`` term below 1e-6 of a pixel's charge).

        ``G`` is the central difference over ``+-step_px`` displacements of the ``nominal``
        placement (the commanded pose: default the scene's own), evaluated at the scene's window
        origins. At the commanded pose the gradients are computed once for every trial (cached):
        they differ from those at the scene's pose (a hexapod error away, ~0.2 px) by about
        that fraction of a PSF width, i.e. by ~25 % of a within-condition drift of < 1e-3 px.
        Returns ``(chain, G_u, G_v)``.
        """
        chain = self.window_chain(scene)
        p = scene.placement if nominal is None else nominal
        key = (p.layout.u_px.tobytes(), p.layout.v_px.tobytes(), p.layout.pinhole_radius_px, p.platform_dx_px,
               p.platform_dy_px, p.platform_roll_rad, p.filter_nm, chain.col0.tobytes(), chain.row0.tobytes(),
               float(step_px), int(self.detector_key))
        cache = self.__dict__.setdefault("_drift_grads", {})
        grads = cache.get(key)
        if grads is None:
            scenes = self.__dict__.setdefault("_drift_scenes", {})
            out = []
            for dx, dy in ((step_px, 0.0), (-step_px, 0.0), (0.0, step_px), (0.0, -step_px)):
                sk = key[:7] + (dx, dy)
                sc = scenes.get(sk)
                if sc is None:
                    if len(scenes) > 1024:
                        scenes.clear()
                    # the displaced scenes use the profiles of p's own pose: the gradient of
                    # one smooth stamp model, never a difference across two rounded poses
                    sc = scenes[sk] = self._scene(dataclasses.replace(
                        p, platform_dx_px=p.platform_dx_px + dx, platform_dy_px=p.platform_dy_px + dy),
                        profile_node=self.profile_node(p))
                sig = _expected_windows_at(self, sc, chain.col0, chain.row0)
                _, cols = self.mosaic.shape
                out.append(window_chain(signal_e=sig, row0=chain.row0, col0=chain.col0, mosaic_cols=cols,
                                        chip_cols=self.mosaic.chip_cols, params=self.detector_params,
                                        detector_key=self.detector_key).mean_e)
            grads = ((out[0] - out[1]) / (2 * step_px), (out[2] - out[3]) / (2 * step_px))
            if len(cache) > 1024:
                cache.clear()
            cache[key] = grads
        return chain, grads[0], grads[1]

    @property
    def onboard_correction(self):
        """The distortion correction this camera applies to its centroids
        (:class:`simcam.starcam.correction.OnboardCorrection`, from ``optics.distortion_correction``),
        or None for an uncalibrated camera. Computed once."""
        if "_onboard" not in self.__dict__:
            self.__dict__["_onboard"] = fit_onboard_correction(self)
        return self.__dict__["_onboard"]

    def report_positions(self, x_px, y_px):
        """The positions the camera reports for measured mosaic centroids (its own
        distortion correction applied; unchanged for an uncalibrated camera)."""
        corr = self.onboard_correction
        if corr is None:
            return np.asarray(x_px, float), np.asarray(y_px, float)
        return corr.apply(x_px, y_px)

    # ------------------------------------------------------------------ scene
    def scene(self, placement: Placement) -> Scene:
        """Compute positions, spectra, PSF stamps and truth of a placement (no noise).

        Scenes are deterministic, so they are cached (the last 256) per camera: Monte
        Carlo trials that repeat a placement reuse its stamps. The lab's reference
        coordinates of the targets (which carry the marker calibration error) enter only
        the truth table's ``x_reference``/``y_reference``, so a placement that differs
        from a cached one only there (a new calibrated target in each trial) reuses the
        images and gets its own truth.
        """
        lay = placement.layout
        key = (
            lay.u_px.tobytes(), lay.v_px.tobytes(), lay.pinhole_radius_px, placement.platform_dx_px,
            placement.platform_dy_px, placement.filter_nm, placement.condition, placement.label,
            placement.platform_roll_rad,
        )
        cache = self.__dict__.setdefault("_scene_cache", {})
        hit = cache.get(key)
        if hit is None:
            if len(cache) >= 256:
                cache.pop(next(iter(cache)))
            hit = cache[key] = self._scene(placement)
        old = hit.placement.layout
        if (np.array_equal(old.reference_u_px, lay.reference_u_px)
                and np.array_equal(old.reference_v_px, lay.reference_v_px)):
            return hit
        x_refm, y_refm = self._focal_to_mosaic(lay.reference_u_px, lay.reference_v_px)
        derived = dataclasses.replace(hit, placement=placement,
                                      truth_columns={**hit.truth_columns, "x_reference": x_refm, "y_reference": y_refm})
        for name in ("_windows_e", "_chains", "_true_xy"):  # do not depend on the reference
            if name in hit.__dict__:
                object.__setattr__(derived, name, hit.__dict__[name])
        return derived

    def _focal_to_mosaic(self, u_px, v_px):
        """Mosaic (x, y) of target positions (:meth:`simcam.starcam.geometry.Mosaic.focal_to_mosaic`),
        kept per position set (a target's ideal and reference positions recur in every
        condition; callers must not modify the arrays)."""
        key = (u_px.tobytes(), v_px.tobytes())
        cache = self.__dict__.setdefault("_mosaic_xy", {})
        hit = cache.get(key)
        if hit is None:
            if len(cache) >= 256:
                cache.pop(next(iter(cache)))
            hit = cache[key] = self.mosaic.focal_to_mosaic(u_px, v_px)[1:]
        return hit

    def _spectrum(self, filter_nm):
        """(wavelength_nm, per-wavelength weights, electrons per exposure) of a pinhole through
        ``filter_nm``: :class:`simcam.starcam.sources.SourceSpectra`'s, kept per filter (they do
        not depend on the placement; callers must not modify the arrays)."""
        cache = self.__dict__.setdefault("_spectrum_cache", {})
        key = None if filter_nm is None else float(filter_nm)
        hit = cache.get(key)
        if hit is None:
            wl, e_rate = self.spectra.electron_rate_per_nm(filter_nm=filter_nm)
            hit = cache[key] = (wl, self.spectra.weights(e_rate), self.spectra.electrons_per_exposure(e_rate))
        return hit

    def _lateral_colour(self, wl, ud, vd):
        """Lateral-colour shifts (focal px, (W, n_l)) of images at distorted focal positions
        ``ud``, ``vd`` (float64 (W,)): :func:`simcam.starcam.optics.lateral_colour_shift_px`, its
        model at the wavelengths ``wl`` kept per wavelength set (:func:`simcam.starcam.optics.lateral_colour`)."""
        key = wl.tobytes()
        cache = self.__dict__.setdefault("_lateral_colour_models", {})
        model = cache.get(key)
        if model is None:
            scn = self.scenario
            lc = scn.optics.lateral_colour
            if len(cache) >= 64:
                cache.clear()
            model = cache[key] = optics.lateral_colour(
                wavelength_nm=wl,
                ref_wavelength_nm=lc.ref_wavelength_nm,
                radial_coeffs=tuple(lc.radial_px_per_nm),
                uniform_x_coeffs=tuple(lc.uniform_x_px_per_nm),
                uniform_y_coeffs=tuple(lc.uniform_y_px_per_nm),
                r_norm_px=scn.optics.r_norm_px,
            )
        return model.shift_px(ud, vd)

    def profile_node(self, placement: Placement) -> tuple[float, float]:
        """The pose whose stamp profiles serve ``placement`` (``render.stamp_route = "profile"``):
        its hexapod translation rounded to the nearest multiple of ``render.stamp_profile_step_px``
        (halves up), roll 0. A function of the placement alone, so a scene does not depend on
        which scenes were rendered before it."""
        h = self.scenario.render.stamp_profile_step_px
        return (math.floor(placement.platform_dx_px / h + 0.5) * h,
                math.floor(placement.platform_dy_px / h + 0.5) * h)

    def _stamp_profiles(self, placement: Placement, chip, wl, weights_1d, node=None):
        """The stamp profiles (:func:`simcam.starcam.psf_stamps.stamp_profiles`) of the placement's
        stars at the pose ``node`` (default :meth:`profile_node`): the same chain as
        :meth:`_scene` (distortion, lateral colour, PSF width) at that pose, in the chips the
        stars land on. Cached per target, filter, pose and chips (the last 64)."""
        scn = self.scenario
        lay = placement.layout
        if node is None:
            node = self.profile_node(placement)
        key = (lay.u_px.tobytes(), lay.v_px.tobytes(), lay.pinhole_radius_px, placement.filter_nm,
               float(node[0]), float(node[1]), chip.tobytes())
        cache = self.__dict__.setdefault("_profile_cache", {})
        hit = cache.get(key)
        if hit is None:
            ud, vd = self.distortion.forward(u_px=lay.u_px + node[0], v_px=lay.v_px + node[1])
            su, sv = self._lateral_colour(wl, ud, vd)
            sx, sy = self.mosaic.vector_to_chip(su, sv, chip)
            sig = optics.psf_sigma_px(
                u_px=ud, v_px=vd, sigma0_px=scn.optics.psf.sigma0_px,
                sigma_r2_px=scn.optics.psf.sigma_r2_px, r_norm_px=scn.optics.r_norm_px,
            )
            W = lay.n_stars
            hit = psf_stamps.stamp_profiles(
                stamp_px=scn.render.stamp_px, psf_kind=scn.optics.psf.kind, sigma_px=sig,
                pinhole_radius_px=lay.pinhole_radius_px, f_number=scn.camera.f_number,
                pixel_pitch_um=scn.camera.pixel_pitch_um, wavelength_nm=wl,
                weights=np.broadcast_to(weights_1d, (W, len(wl))), shift_x_px=sx, shift_y_px=sy)
            if len(cache) >= 64:
                cache.pop(next(iter(cache)))
            cache[key] = hit
        return hit

    def _scene(self, placement: Placement, profile_node=None) -> Scene:
        scn = self.scenario
        lay = placement.layout
        u0 = lay.u_px + placement.platform_dx_px
        v0 = lay.v_px + placement.platform_dy_px
        if placement.platform_roll_rad != 0.0:
            # a small rotation about the optical axis (first order in the roll)
            u0 = u0 - placement.platform_roll_rad * lay.v_px
            v0 = v0 + placement.platform_roll_rad * lay.u_px
        ud, vd = self.distortion.forward(u_px=u0, v_px=v0)
        wl, weights_1d, electrons = self._spectrum(placement.filter_nm)
        W = lay.n_stars
        su, sv = self._lateral_colour(wl, ud, vd)
        chrom_u = su @ weights_1d
        chrom_v = sv @ weights_1d
        half = scn.render.window_px // 2
        chip, xc, yc = self.mosaic.focal_to_chip(ud + chrom_u, vd + chrom_v, margin_px=half)
        bad = np.flatnonzero(chip < 0)
        if bad.size:
            j = int(bad[0])
            raise RenderError(
                f"placement {placement.label or placement.condition}: star {j} at focal "
                f"(u, v) = ({ud[j] + chrom_u[j]:.1f}, {vd[j] + chrom_v[j]:.1f}) px is off the "
                f"detector or within {half} px of a chip edge or gap ({bad.size} of {W} stars); "
                "move lab.target_center_px or the protocol's field centres"
            )
        # reference-wavelength position in the coordinates of the chip the image lands on
        xr, yr = self.mosaic._chip_coords(ud, vd, chip)
        sx, sy = self.mosaic.vector_to_chip(su, sv, chip)
        sig = optics.psf_sigma_px(
            u_px=ud, v_px=vd, sigma0_px=scn.optics.psf.sigma0_px,
            sigma_r2_px=scn.optics.psf.sigma_r2_px, r_norm_px=scn.optics.r_norm_px,
        )
        if scn.render.stamp_route == "profile":
            prof = self._stamp_profiles(placement, chip, wl, weights_1d, profile_node)
            stamps, c0, r0 = psf_stamps.render_shifted_stamps(
                prof, x_px=xr, y_px=yr, sigma_px=sig, mean_shift_x_px=sx @ weights_1d,
                mean_shift_y_px=sy @ weights_1d)
        else:
            stamps, c0, r0 = psf_stamps.render_stamps(
                x_px=xr, y_px=yr, stamp_px=scn.render.stamp_px, psf_kind=scn.optics.psf.kind,
                sigma_px=sig, pinhole_radius_px=lay.pinhole_radius_px,
                f_number=scn.camera.f_number, pixel_pitch_um=scn.camera.pixel_pitch_um,
                wavelength_nm=wl, weights=np.broadcast_to(weights_1d, (W, len(wl))),
                shift_x_px=sx, shift_y_px=sy, parallel=self.parallel,
            )
        x_true = self.mosaic.chip_to_mosaic_x(chip, xc)
        x_ideal, y_ideal = self._focal_to_mosaic(lay.u_px, lay.v_px)
        x_refm, y_refm = self._focal_to_mosaic(lay.reference_u_px, lay.reference_v_px)
        truth = (
            {
                "star": np.arange(W),
                "chip": chip,
                "x_true": x_true,
                "y_true": yc,
                "u_ideal_px": lay.u_px,
                "v_ideal_px": lay.v_px,
                "x_ideal": x_ideal,
                "y_ideal": y_ideal,
                "x_reference": x_refm,
                "y_reference": y_refm,
                "platform_dx_px": placement.platform_dx_px,
                "platform_dy_px": placement.platform_dy_px,
                "distortion_dx_px": ud - u0,
                "distortion_dy_px": vd - v0,
                "chromatic_dx_px": chrom_u,
                "chromatic_dy_px": chrom_v,
                "electrons": electrons,
                "psf_sigma_px": sig,
                "filter_nm": np.nan if placement.filter_nm is None else placement.filter_nm,
                "condition": placement.condition,
            }
        )
        scene = Scene(
            placement=placement, chip=chip, x_ref_chip=xr, y_ref_chip=yr,
            electrons=np.full(W, electrons), stamps=stamps, stamp_col0=c0, stamp_row0=r0,
            truth_columns=truth, background_e=self.background_e,
        )
        # the true positions as arrays beside the table (a fresh DataFrame's first column
        # reads cost about a millisecond; window_origins reads them once per scene)
        object.__setattr__(scene, "_true_xy", (x_true, yc))
        return scene

    # ------------------------------------------------------------------ signal
    def _add_stamps(self, signal: np.ndarray, scene: Scene, *, chip: int, row0: int, col0: int) -> None:
        """Add the star images of ``scene`` on ``chip`` into ``signal`` (chip px block at row0, col0).

        Stamp pixels outside the chip are dropped (light lost off the sensor or in the gap).
        """
        rows, cols = signal.shape
        L = scene.stamps.shape[-1]
        cc = self.mosaic.chip_cols
        cr = self.mosaic.chip_rows
        on = np.flatnonzero(scene.chip == chip)
        # Python ints: max/min of numpy scalars cost a microsecond each, and a scene's
        # windows call this once per window
        for j, sr, sc in zip(on.tolist(), scene.stamp_row0[on].tolist(), scene.stamp_col0[on].tolist()):
            r_lo = max(sr, row0, 0)
            r_hi = min(sr + L, row0 + rows, cr)
            c_lo = max(sc, col0, 0)
            c_hi = min(sc + L, col0 + cols, cc)
            if r_lo >= r_hi or c_lo >= c_hi:
                continue
            signal[r_lo - row0 : r_hi - row0, c_lo - col0 : c_hi - col0] += scene.electrons[j] * scene.stamps[
                j, r_lo - sr : r_hi - sr, c_lo - sc : c_hi - sc,
            ]

    def expected_frame_e(self, scene: Scene) -> np.ndarray:
        """Noise-free photo-electrons per pixel of the whole mosaic (before PRNU and dark)."""
        rows, cols = self.mosaic.shape
        signal = np.full((rows, cols), scene.background_e, dtype=np.float64)
        cc = self.mosaic.chip_cols
        for k in range(self.mosaic.n_chips):
            self._add_stamps(signal[:, k * cc : (k + 1) * cc], scene, chip=k, row0=0, col0=0)
        return signal

    def window_origins(self, scene: Scene) -> tuple[np.ndarray, np.ndarray]:
        """Mosaic (col0, row0) of each star's window, centred on its true position's pixel."""
        half = self.scenario.render.window_px // 2
        xy = scene.__dict__.get("_true_xy")
        x_true, y_true = xy if xy is not None else (scene.truth["x_true"].to_numpy(), scene.truth["y_true"].to_numpy())
        xc = x_true - scene.chip * self.mosaic.chip_cols
        col0_chip = np.floor(xc + 0.5).astype(np.int64) - half
        row0 = np.floor(y_true + 0.5).astype(np.int64) - half
        return col0_chip + scene.chip * self.mosaic.chip_cols, row0

    def expected_windows_e(self, scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Noise-free photo-electrons in each star's window (all stars' light included).

        Computed once per scene (cached on it; callers must not modify the arrays).
        """
        cached = scene.__dict__.get("_windows_e")
        if cached is None:
            cached = self._expected_windows_e(scene)
            object.__setattr__(scene, "_windows_e", cached)
        return cached

    def _expected_windows_e(self, scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        col0, row0 = self.window_origins(scene)
        return _expected_windows_at(self, scene, col0, row0), col0, row0

    # ------------------------------------------------------------------ noise
    def window_chain(self, scene: Scene, *, dark: bool = False):
        """The scene's windows through the detector's fixed pattern (:func:`simcam.detector.window_chain`):
        mean charge per pixel and the chip constants, for the noise kernels. ``dark``: lamp
        off (no star, no stray light). Cached on the scene (callers must not modify it).
        """
        chains = scene.__dict__.get("_chains")
        if chains is None:
            chains = {}
            object.__setattr__(scene, "_chains", chains)
        key = (int(self.detector_key), bool(dark))  # per instrument: the maps are in the chain
        cached = chains.get(key)
        if cached is None:
            sig, col0, row0 = self.expected_windows_e(scene)
            if dark:
                sig = np.zeros_like(sig)
            _, cols = self.mosaic.shape
            cached = window_chain(signal_e=sig, row0=row0, col0=col0, mosaic_cols=cols,
                                  chip_cols=self.mosaic.chip_cols, params=self.detector_params,
                                  detector_key=self.detector_key)
            if len(chains) >= _CHAINS_KEPT:
                chains.pop(next(iter(chains)))
            chains[key] = cached
        return cached

    def frame_keys(self, *, seed: int, condition: int, frames: int, first_frame: int = 0,
                   dark: bool = False) -> np.ndarray:
        """Keys of the temporal noise of frames ``first_frame ..``: the condition's key
        ``SeedSequence(seed, spawn_key=(STREAM_FRAMES, condition))`` and, per frame ``f``,
        its SplitMix64 child ``f`` (:func:`simcam.rng.child_keys`). Star-free (lamp-off)
        frames use the stream ``STREAM_DARK_FRAMES`` instead.
        """
        ck = (seed, condition, dark)
        cache = self.__dict__.setdefault("_condition_keys", {})
        if ck not in cache:
            if len(cache) > 4096:
                cache.clear()
            cache[ck] = key_from_seed(seed, STREAM_DARK_FRAMES if dark else STREAM_FRAMES, condition)
        return child_keys(cache[ck], frames, start=first_frame)

    def frame_key(self, *, seed: int, condition: int, frame: int, dark: bool = False) -> np.uint64:
        """Key of one frame (see :meth:`frame_keys`)."""
        return self.frame_keys(seed=seed, condition=condition, frames=1, first_frame=frame, dark=dark)[0]

    def render_windows(
        self,
        scene: Scene,
        *,
        frames: int,
        seed: int,
        first_frame: int = 0,
        shot_noise: bool = True,
        read_noise: bool = True,
        quantize: bool = True,
        dark: bool = False,
    ) -> Windows:
        """Windows around every star for ``frames`` frames (the Monte Carlo fast path).

        Pixels equal those of :meth:`render_frame` at the same mosaic pixels, same seed.
        ``dark=True`` renders star-free frames (lamp off: no star, no stray light; dark
        signal, DSNU, offset and noise only) at the same windows, for dark subtraction.
        """
        chain = self.window_chain(scene, dark=dark)
        keys = self.frame_keys(seed=seed, condition=scene.placement.condition, frames=frames,
                               first_frame=first_frame, dark=dark)
        pixels = expose_windows_frames(frame_keys=keys, chain=chain, shot_noise=shot_noise,
                                       read_noise=read_noise, quantize=quantize, parallel=self.parallel)
        col0, row0 = chain.col0, chain.row0
        return Windows(pixels=pixels, col0=col0, row0=row0, truth=scene.truth,
                       frame_index=np.arange(first_frame, first_frame + frames))

    def frame_maps(self):
        """The detector's fixed pattern over the whole mosaic (:func:`simcam.detector.detector_maps`),
        computed on the first full frame and kept for the next ones (16 bytes per pixel: 134 MB
        for 2 x 2048^2); rebuilt should ``detector_params`` or ``detector_key`` change. Not
        pickled (a worker process rebuilds it)."""
        rows, cols = self.mosaic.shape
        maps = self.__dict__.get("_frame_maps")
        if maps is None or maps.shape != (rows, cols) or not maps.matches(
                params=self.detector_params, detector_key=self.detector_key, mosaic_cols=cols):
            maps = detector_maps(shape=(rows, cols), row0=0, col0=0, mosaic_cols=cols,
                                 params=self.detector_params, detector_key=self.detector_key)
            self._frame_maps = maps
        return maps

    def __getstate__(self):
        state = self.__dict__.copy()
        state.pop("_frame_maps", None)
        return state

    def render_frame(
        self,
        scene: Scene,
        *,
        frame: int,
        seed: int,
        expected_e: np.ndarray | None = None,
        shot_noise: bool = True,
        read_noise: bool = True,
        quantize: bool = True,
        dark: bool = False,
    ) -> np.ndarray:
        """One full mosaic frame (rows, cols) in DN (uint16 when quantised); ``dark``: lamp off."""
        if dark:
            expected_e = np.zeros(self.mosaic.shape)
        elif expected_e is None:
            expected_e = self.expected_frame_e(scene)
        _, cols = self.mosaic.shape
        key = self.frame_key(seed=seed, condition=scene.placement.condition, frame=frame, dark=dark)
        return expose(
            signal_e=expected_e, row0=0, col0=0, mosaic_cols=cols, chip_cols=self.mosaic.chip_cols,
            params=self.detector_params, frame_key=key, detector_key=self.detector_key,
            shot_noise=shot_noise, read_noise=read_noise, quantize=quantize, maps=self.frame_maps(),
        )


def _expected_windows_at(camera: StarCamera, scene: Scene, col0, row0) -> np.ndarray:
    """Noise-free photo-electrons of ``scene`` in windows at given mosaic origins."""
    w = camera.scenario.render.window_px
    sig = np.full((scene.n_stars, w, w), scene.background_e, dtype=np.float64)
    cc = camera.mosaic.chip_cols
    chip = np.asarray(scene.chip, dtype=np.int64)
    # one numba pass over (window, star), the same sums in the same order as
    # StarCamera._add_stamps per window (simcam.starcam.kernels.windows); arguments of one
    # type whatever the caller (numba compiles it once)
    add_stamps_windows(sig, np.ascontiguousarray(scene.stamps, dtype=np.float64),
                       np.ascontiguousarray(scene.electrons, dtype=np.float64), chip,
                       np.asarray(scene.stamp_row0, dtype=np.int64), np.asarray(scene.stamp_col0, dtype=np.int64),
                       chip, np.asarray(row0, dtype=np.int64), np.asarray(col0, dtype=np.int64) - chip * cc,
                       int(camera.mosaic.chip_rows), int(cc))
    return sig
