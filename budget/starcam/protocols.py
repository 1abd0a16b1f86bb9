"""The seed-000 lab protocols as acquisition plans (data), and running them on the simulator.

An :class:`AcquisitionPlan` is a list of conditions, each saying which target, where in
the field, which hexapod pose, which filter and how many frames: exactly what a lab
technician writes in a test procedure and what a manifest of real frames records. The
plans are built from the scenario's ``[protocols]`` section (no protocol is a branch in
code), and the same centroid tables come out of :func:`simulate` (simulated windows) and
out of ``budget starcam measure`` (real FITS frames).

Plans (seed 000, section 1):

* ``te`` (1.2): the 5x5 target, static, ``N`` frames;
* ``hsfe`` (1.3): ``M`` conditions, the image moved ``step_px`` along ``direction_deg``
  between consecutive conditions by the hexapod, ``N`` frames each; or, with
  ``pattern = "grid"``, a square grid of poses spanning pixels in x and y;
* ``chromatic`` (1.4.1): the target at each corner field, behind each of the test's filters
  (``protocols.chromatic.filters_nm``, default every lab filter), ``N`` frames each
  (condition index = field index x number of lab filters + lab filter index);
* ``distortion`` (1.4.2): the calibrated grid target, ``N`` frames; its reference
  coordinates come with the plan.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
import pandas as pd

from simcam import spectra
from simcam.starcam.geometry import Mosaic
from simcam.starcam.scenario import LAB_PROTOCOLS, Scenario, with_updates
from simcam.starcam.sources import SourceSpectra
from simcam.starcam.targets import calibration_grid, platform_offsets_px, star_grid

#: the lab protocols in acquisition order (``validation.protocols`` names those a validation runs)
PROTOCOLS = LAB_PROTOCOLS
#: noise-stream id of each protocol: condition streams are ``1000 * id + condition``
PROTOCOL_STREAM = {"te": 1, "hsfe": 2, "chromatic": 3, "distortion": 4}
#: SeedSequence root of the hexapod positioning errors (run seed)
STREAM_PLATFORM = 401


@dataclass(frozen=True)
class Condition:
    """One acquisition condition of a plan."""

    index: int
    label: str
    target: Literal["star_grid", "calibration_grid"]
    frames: int
    field_center_px: tuple[float, float] | None = None
    platform_dx_px: float = 0.0
    platform_dy_px: float = 0.0
    filter_nm: float | None = None
    field: str = ""


@dataclass(frozen=True)
class AcquisitionPlan:
    """A protocol's conditions, in acquisition order."""

    protocol: str
    conditions: tuple[Condition, ...]
    dark_frames: int = 0

    def to_frame(self) -> pd.DataFrame:
        """The plan as a table (one row per condition), as a lab procedure would list it."""
        return pd.DataFrame([c.__dict__ for c in self.conditions])


def make_plan(protocol: str, scenario: Scenario, *, seed: int = 0, dark_frames: int = 0) -> AcquisitionPlan:
    """Build the acquisition plan of ``protocol`` from the scenario's ``[protocols]`` section.

    ``seed`` (the run seed) draws the hexapod positioning errors when the scenario has
    ``lab.platform.positioning_noise_px > 0``. ``dark_frames`` star-free frames per
    condition are taken for dark subtraction (0: the window-border background is used).
    """
    p = scenario.protocols
    if protocol == "te":
        conds = (Condition(0, "static", "star_grid", p.te.frames, tuple(scenario.lab.target_center_px)),)
    elif protocol == "hsfe":
        h = p.hsfe
        noise = scenario.lab.platform.positioning_noise_px
        if h.pattern == "diagonal":
            dx, dy = platform_offsets_px(steps=h.conditions, step_px=h.step_px, direction_deg=h.direction_deg,
                                         noise_px=noise, seed=seed, stream=STREAM_PLATFORM)
        else:
            dx, dy = _grid_offsets_px(h, noise_px=noise, seed=seed)
        conds = tuple(
            Condition(k, f"pose {k + 1}", "star_grid", h.frames, tuple(scenario.lab.target_center_px),
                      float(dx[k]), float(dy[k]))
            for k in range(h.conditions)
        )
    elif protocol == "chromatic":
        c = p.chromatic
        # the test's filters (protocols.chromatic.filters_nm; every lab filter by default); a
        # condition's index is the lab's, field x number of lab filters + lab filter, so a
        # filter's frames (their noise stream) are the same whichever other filters are taken
        filters = [f.center_nm for f in scenario.lab.filters]
        chosen = scenario.chromatic_filters_nm()
        conds = tuple(
            Condition(i * len(filters) + k, f"{name} {fnm:g} nm", "star_grid", c.frames,
                      (float(ctr[0]), float(ctr[1])), filter_nm=fnm, field=name)
            for i, (name, ctr) in enumerate(zip(c.field_names, c.field_centers_px))
            for k, fnm in enumerate(filters) if fnm in chosen
        )
    elif protocol == "distortion":
        conds = (Condition(0, "grid", "calibration_grid", p.distortion.frames),)
    else:
        raise ValueError(f"protocol: unknown {protocol!r} (one of {', '.join(PROTOCOLS)})")
    return AcquisitionPlan(protocol, conds, dark_frames=dark_frames)


def _grid_offsets_px(h, *, noise_px: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Image displacements of the HSFE grid pattern's poses
    (:meth:`simcam.starcam.scenario.HSFEProtocolModel.grid_offsets_px`), plus the positioning
    error of :func:`simcam.starcam.targets.platform_offsets_px` (same streams, per pose)."""
    off = np.array(h.grid_offsets_px(), dtype=float)
    dx, dy = off[:, 0].copy(), off[:, 1].copy()
    if noise_px > 0:
        for i in range(dx.size):
            rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(STREAM_PLATFORM, i)))
            ex, ey = rng.normal(0.0, noise_px, 2)
            dx[i] += ex
            dy[i] += ey
    return dx, dy


@dataclass
class ProtocolData:
    """What a protocol run yields: centroids (what the lab sees) and truth (what was injected).

    ``rows`` holds the centroid table as arrays, what the estimators compute on
    (:class:`budget.starcam.estimators.common._Rows`; the Monte Carlo validator passes them
    to :func:`estimate`), and ``centroids`` the same table as a DataFrame, built on first
    use; so do ``reference_rows`` and ``reference`` the distortion grid's reference
    coordinates (:func:`reference_table`). ``truth_parts`` holds each condition's truth
    table with its condition index and field label; the ``truth`` table (one row per star
    and condition) is assembled from them on first use (the Monte Carlo validator never
    needs it).
    """

    protocol: str
    rows: object
    truth_parts: list
    reference_rows: object = None
    plan: AcquisitionPlan | None = None
    windows: dict = field(default_factory=dict)
    camera: object = None

    @property
    def centroids(self) -> pd.DataFrame:
        """The centroid table: ``star, frame, x, y, flux_dn, flag`` and the plan's
        ``condition``, ``filter_nm`` and ``field`` (where it has filters and fields)."""
        cached = self.__dict__.get("_centroids")
        if cached is None:
            cached = self.__dict__["_centroids"] = self.rows.to_frame()
        return cached

    @property
    def reference(self) -> pd.DataFrame | None:
        """The reference coordinates ``star, x_ref, y_ref`` (distortion protocol; else None)."""
        if self.reference_rows is None:
            return None
        cached = self.__dict__.get("_reference")
        if cached is None:
            cached = self.__dict__["_reference"] = self.reference_rows.to_frame()
        return cached

    @property
    def truth(self) -> pd.DataFrame:
        """Per star and condition: the scene's truth, plus ``x_reported``/``y_reported``, the
        position the camera reports for the true image position (its own distortion
        correction applied, :meth:`simcam.starcam.render.StarCamera.report_positions`; equal to
        ``x_true``/``y_true`` for an uncalibrated camera): what a perfect centroid gives."""
        cached = self.__dict__.get("_truth")
        if cached is None:
            parts = []
            for table, index, field_label in self.truth_parts:
                # a condition's scene (simcam.starcam.render.Scene: its table is built on first use) or a table
                tr = (table if isinstance(table, pd.DataFrame) else table.truth).copy()
                tr["condition"] = index
                tr["field"] = field_label
                parts.append(tr)
            cached = pd.concat(parts, ignore_index=True)
            if self.camera is not None:
                cached["x_reported"], cached["y_reported"] = self.camera.report_positions(
                    cached["x_true"].to_numpy(), cached["y_true"].to_numpy())
            self.__dict__["_truth"] = cached
        return cached


def centroid_options(camera, col0, threshold_sigma: float, *, dark_frames: int = 0) -> dict:
    """Centroiding options for simulated windows: border background and a threshold at
    ``threshold_sigma`` times the background's noise, known from the scenario.

    The noise per pixel (DN) of a window on chip ``k``: temporal read, dark and stray-light
    shot noise, and the DSNU's spatial scatter, ``sqrt(r^2 + d + b + dsnu^2) / g``; with
    ``K`` dark frames subtracted the temporal part grows by ``sqrt(1 + 1/K)`` and the DSNU
    cancels. Passing it explicitly keeps the threshold the same in noise-free truth
    renderings as in noisy trials (a border-MAD threshold would collapse to 0 there).
    """
    scn = camera.scenario
    det = scn.detector
    chip = np.asarray(col0) // det.chip_cols
    read = np.array([c.read_noise_e for c in det.chips])[chip]
    gain = np.array([c.gain_e_per_dn for c in det.chips])[chip]
    temporal = read**2 + det.dark_current_e_per_s * scn.camera.exposure_s + camera.background_e
    if dark_frames:
        var = temporal * (1.0 + 1.0 / dark_frames)
    else:
        var = temporal + det.dsnu_rms_e**2
    return {"background": "border", "noise_dn": np.sqrt(var) / gain, "threshold_sigma": float(threshold_sigma)}


def design_psf_sigma_px(scenario: Scenario) -> float:
    """The PSF's Gaussian-equivalent sigma (px) at the field centre, from the optical design:
    the Gaussian sigma, or for an Airy PSF ``0.42 lambda N / p`` at 600 nm (the Gaussian
    that best matches the Airy core) combined in quadrature with its blur. Used as the
    IWCoG weight width, as a lab would take it from its design."""
    psf = scenario.optics.psf
    if psf.kind == "gaussian":
        return float(psf.sigma0_px)
    airy = 0.42 * 0.6 * scenario.camera.f_number / scenario.camera.pixel_pitch_um
    return float(np.hypot(airy, psf.sigma0_px))


def reference_table(scenario: Scenario, camera=None, *, marker_seed: int | None = None) -> pd.DataFrame:
    """Reference coordinates of the calibration grid as the lab has them (mosaic px).

    The ideal projection of the calibrated point positions (nominal chip layout is the
    camera's own), including the marker calibration error (seed 000 C2).
    """
    return _reference_points(scenario, camera, marker_seed=marker_seed).to_frame()


def _reference_points(scenario: Scenario, camera=None, *, marker_seed: int | None = None):
    """:func:`reference_table` as the estimators' rows (:class:`budget.starcam.estimators.common._Rows`)."""
    from budget.starcam.estimators.common import _Rows

    lay = calibration_grid(scenario, marker_seed=marker_seed)
    mosaic = camera.mosaic if camera is not None else Mosaic.from_model(scenario.detector)
    _, x, y = mosaic.focal_to_mosaic(lay.reference_u_px, lay.reference_v_px)
    return _Rows({"star": np.arange(lay.n_stars), "x_ref": x, "y_ref": y})


def simulate(
    plan: AcquisitionPlan,
    camera,
    *,
    seed: int,
    method: str = "cog",
    keep_windows: bool = False,
    threshold_sigma: float = 3.0,
    marker_seed: int | None = None,
) -> ProtocolData:
    """Run ``plan`` on a :class:`simcam.starcam.render.StarCamera` (windows mode) and centroid every frame.

    Each condition's frames get the noise stream ``1000 * PROTOCOL_STREAM + index``, so
    protocols, conditions and frames never share noise, and a condition's frames are
    the same whatever else is simulated. With ``plan.dark_frames > 0`` the mean of that
    many star-free frames is subtracted from each lit window first (seed 000's
    inter-frame differencing). ``marker_seed`` draws new marker errors of the calibration
    grid (default: the scenario's fixed target).
    """
    from budget.centroid.core import centroid_arrays, table_columns, warn_flags
    from budget.starcam.estimators.common import _Rows

    scn = camera.scenario
    # the fused kernel (exposure and centroid in one pass, same values) serves the
    # thresholded centre of gravity when the windows themselves are not wanted
    fused = method == "cog" and not keep_windows
    truths, wins = [], {}
    cols: dict[str, list] = {k: [] for k in ("pix", "x0", "y0", "noise", "star", "frame", "cond", "filt",
                                             "x", "y", "flux", "flag")}
    # the simulated world's hexapod pose errors and target drift: the camera draws
    # them from the run seed (simcam.starcam.world); the plan, like a lab's, has only the
    # commanded poses
    motion = camera.world_motion(seed)
    for c in plan.conditions:
        scene, drift = _condition_scene(camera, plan, c, motion, marker_seed=marker_seed)
        n = c.frames
        dark_mean = None
        if plan.dark_frames:
            dark = camera.render_windows(scene, frames=plan.dark_frames, seed=seed, dark=True)
            dark_mean = dark.pixels.astype(np.float64).mean(axis=0)
        chain = camera.window_chain(scene)
        cc = _condition_columns(camera, scene, chain, c, threshold_sigma, plan.dark_frames)
        if fused:
            x, y, flux, flag = _fused_centroids(camera, chain, scene, drift, frames=n, seed=seed,
                                                dark_mean=dark_mean, threshold_dn=cc["threshold_dn"])
            for name, v in (("x", x), ("y", y), ("flux", flux), ("flag", flag)):
                cols[name].append(v.reshape(-1))
        else:
            win, pix = _condition_windows(camera, scene, drift, frames=n, seed=seed, dark_mean=dark_mean)
            cols["pix"].append(pix)
            cols["noise"].append(np.tile(cc["noise_dn"], n))
            if keep_windows:
                wins[c.index] = win
        for name in ("x0", "y0", "star", "frame", "cond", "filt"):
            cols[name].append(cc[name])
        truths.append((scene, c.index, c.field))  # the scene's truth table only when asked for
    extra, field_labels = _extra_columns(plan, cols)
    if fused:
        x, y, flux, flag = (np.concatenate(cols[k]) for k in ("x", "y", "flux", "flag"))
    else:
        # one centroiding call for the whole protocol (same options as per condition)
        opts = {"background": "border", "noise_dn": np.concatenate(cols["noise"]),
                "threshold_sigma": float(threshold_sigma)}
        if method == "iwcog":
            opts["weight_sigma_px"] = design_psf_sigma_px(scn)
        x, y, flux, flag = centroid_arrays(np.concatenate(cols["pix"]), x0=np.concatenate(cols["x0"]),
                                           y0=np.concatenate(cols["y0"]), method=method, **opts)
    table = table_columns(star=np.concatenate(cols["star"]), frame=np.concatenate(cols["frame"]), x=x, y=y,
                          flux=flux, flag=flag, flux_column="flux_dn", extra_columns=extra)
    warn_flags(table["flag"], table["star"], table["frame"])
    if camera.onboard_correction is not None:
        # the camera reports its centroids through its own distortion correction
        # (optics.distortion_correction, simcam.starcam.correction), as a flight camera does
        table["x"], table["y"] = camera.report_positions(table["x"], table["y"])
    ref = _reference_points(scn, camera, marker_seed=marker_seed) if plan.protocol == "distortion" else None
    return ProtocolData(plan.protocol, _Rows(table, field_labels), truths, ref, plan, wins, camera)


def _condition_scene(camera, plan: AcquisitionPlan, c: Condition, motion, *, marker_seed: int | None):
    """The scene of condition ``c`` (its target placed at the commanded pose, plus the world's
    pose error and the condition's mean drift when the world moves) and the drift about that
    mean per frame: ``None``, or (drift (frames, 2) px, the placement at the commanded pose)."""
    from simcam.starcam.render import Placement

    scn = camera.scenario
    layout = (calibration_grid(scn, marker_seed=marker_seed) if c.target == "calibration_grid"
              else _star_grid(camera, c.field_center_px))
    stream = 1000 * PROTOCOL_STREAM[plan.protocol] + c.index
    if motion is None:
        placement = Placement(layout=layout, platform_dx_px=c.platform_dx_px, platform_dy_px=c.platform_dy_px,
                              filter_nm=c.filter_nm, condition=stream, label=c.label)
        drift = None
    else:
        pdx, pdy, roll = motion.pose(plan.protocol, c.index)
        drift = motion.drift_of(plan.protocol, c.index, c.frames)
        # the condition's mean drift is rendered exactly (in the scene's pose), the drift
        # about it per frame to first order (StarCamera.drift_chain)
        d0 = (0.0, 0.0) if drift is None else tuple(float(v) for v in drift.mean(axis=0))
        placement = Placement(layout=layout, platform_dx_px=c.platform_dx_px + pdx + d0[0],
                              platform_dy_px=c.platform_dy_px + pdy + d0[1], filter_nm=c.filter_nm,
                              condition=stream, label=c.label, platform_roll_rad=roll)
        if drift is not None:
            drift = (drift - np.array(d0)[None, :], Placement(
                layout=layout, platform_dx_px=c.platform_dx_px, platform_dy_px=c.platform_dy_px,
                filter_nm=c.filter_nm, condition=stream, label=c.label))
    return camera.scene(placement), drift


def _fused_centroids(camera, chain, scene, drift, *, frames: int, seed: int, dark_mean, threshold_dn):
    """A condition's frames exposed and centroided in one pass (:func:`_expose_centroid`, or
    :func:`_expose_centroid_drift` for a drifting image): x, y, flux, flag as (frames, W)."""
    if drift is None:
        return _expose_centroid(camera, chain, scene, frames=frames, seed=seed, dark_mean=dark_mean,
                                threshold_dn=threshold_dn)
    return _expose_centroid_drift(camera, scene, drift, seed=seed, dark_mean=dark_mean, threshold_dn=threshold_dn)


def _condition_windows(camera, scene, drift, *, frames: int, seed: int, dark_mean):
    """A condition's exposed windows (:class:`simcam.starcam.render.Windows`) and their pixels
    less the dark mean, float64 (frames x W, h, w)."""
    win = (camera.render_windows(scene, frames=frames, seed=seed) if drift is None
           else _render_windows_drift(camera, scene, drift, seed=seed))
    pix = win.pixels.astype(np.float64)
    if dark_mean is not None:
        pix = pix - dark_mean[None]
    return win, pix.reshape(scene.n_stars * frames, *pix.shape[2:])


def _extra_columns(plan: AcquisitionPlan, cols: dict[str, list]):
    """The columns a protocol's centroid table carries beside the centroids (condition; the
    filter and the field where the plan names them) and the sorted field labels the field
    column codes (``None`` without fields)."""
    extra = {"condition": np.concatenate(cols["cond"])}
    if any(c.filter_nm is not None for c in plan.conditions):
        extra["filter_nm"] = np.concatenate(cols["filt"])
    field_labels = None
    if any(c.field for c in plan.conditions):
        # the fields as codes into their sorted labels (the estimators' rows, _Rows)
        field_labels = np.array(sorted({c.field for c in plan.conditions}), dtype=object)
        extra["field"] = np.repeat(np.searchsorted(field_labels, [c.field for c in plan.conditions]),
                                   [s.size for s in cols["star"]])
    return extra, field_labels


def _condition_columns(camera, scene, chain, c: Condition, threshold_sigma: float, dark_frames: int) -> dict:
    """The per-row columns of a condition's centroid table (window origins, star, frame,
    condition, filter) and its windows' noise and threshold (DN): fixed for a
    condition and its window origins, so kept on the camera (read-only) for the next trial,
    also when a new pose error (the world's hexapod, drift) makes the scene new but leaves
    the windows where they were."""
    key = ("_columns", c.index, c.frames, c.filter_nm, c.field, float(threshold_sigma), dark_frames,
           scene.n_stars, chain.col0.tobytes(), chain.row0.tobytes())
    store = camera.__dict__.setdefault("_protocol_columns", {})
    cc = store.get(key)
    if cc is None:
        if len(store) > 512:
            store.clear()
        W, n = scene.n_stars, c.frames
        noise_dn = centroid_options(camera, chain.col0, threshold_sigma, dark_frames=dark_frames)["noise_dn"]
        cc = {"noise_dn": noise_dn, "threshold_dn": float(threshold_sigma) * noise_dn,
              "x0": np.tile(chain.col0, n), "y0": np.tile(chain.row0, n),
              "star": np.tile(np.arange(W), n), "frame": np.repeat(np.arange(n), W),
              "cond": np.full(W * n, c.index),
              "filt": np.full(W * n, np.nan if c.filter_nm is None else c.filter_nm)}
        for v in cc.values():
            v.flags.writeable = False
        store[key] = cc
    return cc


def _star_grid(camera, center_px):
    """:func:`simcam.starcam.targets.star_grid` of the camera's scenario, kept on the camera per
    centre (as :func:`_condition_columns` keeps its columns): it is deterministic and its arrays
    are not modified downstream."""
    key = None if center_px is None else tuple(center_px)
    store = camera.__dict__.setdefault("_star_grids", {})
    lay = store.get(key)
    if lay is None:
        if len(store) > 256:
            store.clear()
        lay = store[key] = star_grid(camera.scenario, center_px=center_px)
    return lay


def _expose_centroid(camera, chain, scene, *, frames: int, seed: int, dark_mean, threshold_dn):
    """Frames of a scene's windows exposed and centroided in one pass (thresholded centre of
    gravity, border background; :mod:`budget.starcam.kernels_trial`): x, y, flux, flag as (frames, W)."""
    keys = camera.frame_keys(seed=seed, condition=scene.placement.condition, frames=frames)
    W, h, _ = chain.mean_e.shape
    parallel = camera.parallel if camera.parallel is not None else frames * W * h > 20_000
    from budget.starcam.kernels_trial import expose_centroid_chain

    return expose_centroid_chain(chain, keys, dark_mean=dark_mean, threshold_dn=threshold_dn, parallel=parallel)


def _drifted_chains(camera, scene, drift):
    """One window chain per frame of a scene whose image drifts by ``drift[0]`` (frames, 2) px
    about the scene's own position, with gradients at the commanded placement ``drift[1]``
    (:meth:`simcam.starcam.render.StarCamera.drift_chain`)."""
    drift, nominal = drift
    chain, gx, gy = camera.drift_chain(scene, nominal)
    for f in range(drift.shape[0]):
        mean = np.maximum(chain.mean_e + drift[f, 0] * gx + drift[f, 1] * gy, 0.0)
        yield f, replace(chain, mean_e=mean)


def _expose_centroid_drift(camera, scene, drift, *, seed: int, dark_mean, threshold_dn):
    """:func:`_expose_centroid` for a drifting image: each frame exposed from its own chain."""
    from budget.starcam.kernels_trial import expose_centroid_drift_chain

    d, nominal = drift
    keys = camera.frame_keys(seed=seed, condition=scene.placement.condition, frames=d.shape[0])
    chain, gx, gy = camera.drift_chain(scene, nominal)
    # one kernel call for every frame, each from its own drifted mean (the same values as
    # _drifted_chains and one expose_centroid_chain call per frame, bit for bit)
    return expose_centroid_drift_chain(chain, gx, gy, d, keys, dark_mean=dark_mean, threshold_dn=threshold_dn)


def _render_windows_drift(camera, scene, drift, *, seed: int):
    """:meth:`simcam.starcam.render.StarCamera.render_windows` for a drifting image."""
    from simcam.detector import expose_windows_frames
    from simcam.starcam.render import Windows

    n = drift[0].shape[0]
    keys = camera.frame_keys(seed=seed, condition=scene.placement.condition, frames=n)
    frames = []
    for f, ch in _drifted_chains(camera, scene, drift):
        frames.append(expose_windows_frames(chain=ch, frame_keys=keys[f:f + 1], parallel=False)[0])
    chain = camera.window_chain(scene)
    return Windows(pixels=np.stack(frames), col0=chain.col0, row0=chain.row0, truth=scene.truth,
                   frame_index=np.arange(n))


def estimate(
    protocol: str,
    centroids: Any,
    *,
    plate_scale_arcsec: float,
    reference: Any = None,
    reference_filter_nm: float | None = None,
    marker_3sigma_arcsec: float = 0.0,
    spectral: dict | None = None,
    extra_variants: bool = True,
    camera_corrects_distortion: bool = False,
) -> dict:
    """Run the published estimator of ``protocol`` and its improved variant(s) on a centroid table.

    Returns ``{"published": ErrorEstimate, "improved": ErrorEstimate, ...}``: the
    improved variant is the one derived in docs/estimators.md that targets what the class
    is meant to be (TE: pooled rms; HSFE: the static error itself; LSFE-S: uniform and
    radial parts kept apart, or, given the camera's ``spectral`` design (see
    :func:`spectral_design`), the stellar population through its spectral response;
    LSFE-C1: the distortion left after calibration, which needs the marker error
    ``marker_3sigma_arcsec``, seed 000's C2; with ``camera_corrects_distortion`` (the camera
    reports positions through its own distortion correction, as a flight camera does) the
    displacement that calibrated camera still makes). Other variants are returned under their
    own names (``extra_variants=False`` skips them, as the Monte Carlo validator does).
    The same function serves simulated and real tables: a DataFrame is checked
    (:func:`budget.starcam.estimators.common._checked_rows`); the rows of a simulated protocol
    (:attr:`ProtocolData.rows` and ``reference_rows``, which the Monte Carlo validator
    passes) meet those checks by construction and go to the same estimators unchecked.
    """
    from budget.starcam import estimators as E

    ps = plate_scale_arcsec
    if protocol == "te":
        return {"published": E.temporal_error(centroids, plate_scale_arcsec=ps),
                "improved": E.temporal_error_pooled(centroids, plate_scale_arcsec=ps)}
    if protocol == "hsfe":
        out = {"published": E.high_spatial_frequency_error(centroids, plate_scale_arcsec=ps),
               "improved": E.high_spatial_frequency_error_static(centroids, plate_scale_arcsec=ps)}
        if extra_variants:
            out["debiased"] = E.high_spatial_frequency_error_debiased(centroids, plate_scale_arcsec=ps)
        return out
    if protocol == "chromatic":
        ref = None if reference_filter_nm is None else int(round(reference_filter_nm))
        out = {"published": E.chromatic_error(centroids, plate_scale_arcsec=ps, reference_filter_nm=ref)}
        if spectral is None or extra_variants:
            out["decomposed"] = E.chromatic_error_decomposed(centroids, plate_scale_arcsec=ps, reference_filter_nm=ref)
        if spectral is not None:
            out["improved"] = E.chromatic_error_population(centroids, plate_scale_arcsec=ps,
                                                           reference_filter_nm=ref, **spectral)
        else:
            out["improved"] = out["decomposed"]
        return out
    if protocol == "distortion":
        if reference is None:
            raise ValueError("distortion: the reference coordinates of the grid target are required")
        improved = E.distortion_remaining_displacement if camera_corrects_distortion else E.distortion_calibration_residual
        out = {"published": E.distortion_residual_error(centroids, reference=reference, plate_scale_arcsec=ps),
               "improved": improved(centroids, reference=reference, plate_scale_arcsec=ps,
                                    marker_3sigma_arcsec=marker_3sigma_arcsec)}
        if extra_variants:
            out["fit_dof"] = E.distortion_residual_error_dof(centroids, reference=reference, plate_scale_arcsec=ps)
        return out
    raise ValueError(f"protocol: unknown {protocol!r} (one of {', '.join(PROTOCOLS)})")


def lab_spectral_scenario(scenario: Scenario) -> Scenario:
    """The camera as the lab believes it to be: the scenario with ``lab.knowledge``'s stated
    errors applied to the QE peak, the filters' centres and widths and the lamp's colour
    temperature (the stellar Teff error is applied in :func:`spectral_design`)."""
    k = scenario.lab.knowledge
    filters = [dict(f.model_dump(mode="python"), center_nm=f.center_nm + k.filter_center_nm_error,
                    width_nm=f.width_nm + k.filter_width_nm_error) for f in scenario.lab.filters]
    return with_updates(scenario, {
        "detector.qe.peak_nm": scenario.detector.qe.peak_nm + k.qe_peak_nm_error,
        "lab.source.temperature_k": scenario.lab.source.temperature_k + k.lamp_temperature_k_error,
        "lab.filters": filters,
        # (the plan's reference filter is named by its centre, which moves with the others)
        "protocols.chromatic.reference_filter_nm": (scenario.protocols.chromatic.reference_filter_nm
                                                    + k.filter_center_nm_error),
        "protocols.chromatic.filters_nm": [f + k.filter_center_nm_error
                                           for f in scenario.protocols.chromatic.filters_nm],
        "protocols.chromatic.plan_filter_sets": [],
    })


def spectral_design(scenario: Scenario) -> dict:
    """Effective wavelengths from the lab's model of the camera (for the population LSFE-S).

    The electron-weighted mean wavelength of the lab lamp through each filter, of the
    calibration spectrum (``validation.calibration_spectrum``: the population mean, the
    unfiltered lamp, or a star type) and of each stellar type of
    ``validation.lsfe_spectral_types``, through the optics transmission and QE, all as
    the lab believes them: :func:`lab_spectral_scenario` applies ``lab.knowledge``'s stated
    errors (QE peak, filter centres and widths, lamp temperature), and each star's Teff is
    the spectral model's, ``Teff (1 + star_teff_fraction_error)``. These are design data a
    lab has (filter certificates, lamp, sensor QE, a spectral library), not measurements,
    and not the simulator's own spectra. The returned filter keys are the filters' nominal
    centres (as the centroid table labels them).
    """
    lab = lab_spectral_scenario(scenario)
    k = scenario.lab.knowledge
    sp = SourceSpectra(lab)
    wl = sp.wavelength_nm

    def mean_wl(rate):
        return float(np.dot(sp.weights(rate), wl))

    filt = {int(round(f.center_nm)): mean_wl(sp.electron_rate_per_nm(filter_nm=fl.center_nm)[1])
            for f, fl in zip(scenario.lab.filters, lab.lab.filters)}

    def star_rate(st):
        t = spectra.star_teff_k(spectral_type=st) * (1.0 + k.star_teff_fraction_error)
        flux = spectra.star_photon_flux_per_nm(v_mag=0.0, temperature_k=t, wavelength_nm=wl)
        return spectra.detected_electron_rate_per_nm(
            photon_flux_per_nm=flux, aperture_area_m2=sp.aperture_area_m2, transmission=sp.transmission,
            filter_transmission=1.0, qe=sp.qe, wavelength_nm=wl)

    cal = scenario.validation.calibration_spectrum
    stars = [mean_wl(star_rate(st)) for st in scenario.validation.lsfe_spectral_types]
    if cal == "population_mean":
        lam_cal = float(np.mean(stars))
    elif cal == "lamp":
        lam_cal = mean_wl(sp.electron_rate_per_nm(filter_nm=None)[1])
    else:
        lam_cal = mean_wl(star_rate(cal))
    return {"filter_wavelength_nm": filt, "star_wavelengths_nm": stars, "calibration_wavelength_nm": lam_cal}
