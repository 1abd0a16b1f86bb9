"""A star-camera validation's first-run compilation, in two processes.

A trial needs three groups of numba kernels: the PSF stamps
(:mod:`simcam.starcam.kernels.psf`, and the windows summed from them,
:mod:`simcam.starcam.kernels.windows`), the detector's fixed pattern
(:func:`simcam.kernels.detector.mean_charge_windows`) and the fused
expose-and-centroid kernels (:mod:`budget.starcam.kernels_trial`: a static and a
drifting condition's, with the noise, random number and centroid kernels they call); the
truths add their own, the control-variate kernels (:mod:`budget.starcam.kernels_truth`,
where :func:`budget.starcam.truth.control_variate_applies`). On a fresh install numba
compiles them one after the other, about 12 s of one core. :func:`prewarm` splits them
over two processes (:func:`simcam.numba_warm.compiling_in_parallel`) in about equal
halves, each kernel compiled once:

* a child (:func:`compile_support`) compiles the random-number kernels first (the
  fixed pattern and the noise kernels call them), the per-window centroid kernels, the
  drifting condition's fused kernel (with its own signature of the noise kernel), then
  the truths' exposure with control variates (option ``truth``);
* this process (:func:`compile_stamps_and_exposure`) compiles meanwhile (the child is
  still importing) the truths' control-variate tables (option ``truth``: the child then
  finds them in numba's cache), the stamps, then the fixed pattern, the static
  condition's fused kernel (whose centroid callees it by then finds in numba's cache)
  and the kernel that sums a scene's windows from its stamps.

With a warm cache nothing happens. Each target calls the kernels through the functions
a trial calls them through (which hand numba arguments of one type whatever their caller
passes), or compiles them with the types the fused kernels pass, on tiny inputs: what
they compile is what a trial then loads. ``tests/test_warm.py`` checks that after both
targets a trial and the truths compile nothing.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np

from simcam import numba_warm  # numba_warm.compiling_in_parallel: looked up when called (a test replaces it)


def options(scenario) -> dict:
    """What a validation of ``scenario`` compiles besides the stamps and the fixed pattern:
    ``fused`` (the fused expose-and-centroid kernels, which serve the centre of gravity),
    ``windows`` (the window exposure: dark frames, or another centroid method, whose own
    kernels compile where they are first called) and ``truth`` (the truths' control-variate
    kernels: :func:`budget.starcam.truth.control_variate_applies`, and a TE or HSFE truth)."""
    from budget.starcam.truth import control_variate_applies
    from budget.starcam.validate import computed_classes

    val = scenario.validation
    fused = val.centroid_method == "cog"
    return {"fused": fused, "windows": int(val.dark_frames) > 0 or not fused,
            "truth": control_variate_applies(scenario) and bool({"te", "hsfe"} & set(computed_classes(scenario)))}


def prewarm(scenario) -> None:
    """Compile what a validation of ``scenario`` calls, on two cores, if numba's cache is cold."""
    from budget.starcam import kernels_trial as kt
    from budget.starcam import kernels_truth as ktr
    from simcam.kernels import detector as kd
    from simcam.starcam.kernels import psf as kp
    from simcam.starcam.kernels import windows as kw

    opts = options(scenario)
    check = [kp.folded_stamp_spectra, kp.stamp_profiles, kp.shifted_stamp_spectra, kw.add_stamps_windows]
    check += [kt.expose_centroid_frames_serial, kt.expose_centroid_drift_serial] if opts["fused"] else []
    check += [kd.expose_windows_frames_serial] if opts["windows"] else []
    check += [ktr.cv_tables, ktr.expose_centroid_cv_serial] if opts["truth"] else []
    arg = json.dumps(opts)
    with numba_warm.compiling_in_parallel([("budget.starcam.warm:compile_support", arg)], check=check) as cold:
        if cold:
            compile_stamps_and_exposure(arg)


def compile_support(arg: str) -> None:
    """Child target: the random-number kernels (first: the fixed pattern and the noise
    kernels call them), the per-window centroid kernels with the types the fused kernels
    pass them, the drifting condition's fused kernel (option ``fused``) through
    :func:`budget.starcam.kernels_trial.expose_centroid_drift_chain`, then the truths'
    exposure with control variates (option ``truth``) through
    :func:`budget.starcam.kernels_truth.expose_centroid_cv` (its tables, which
    :func:`budget.starcam.kernels_truth.cv_prepare` computes, this process loads from the
    cache: :func:`compile_stamps_and_exposure` compiles them first). ``arg``: JSON options."""
    from numba import types

    from budget.centroid.kernels import border_one, cog_one
    from simcam.rng import child_keys, std_normal
    from simcam.rng_poisson import poisson_prepared

    opts = json.loads(arg)
    poisson_prepared(1.0, 2, 16, 0.0, 0.0, 0.0, 0.0, np.uint64(1), np.uint64(2))
    std_normal(np.uint64(1), np.uint64(2))
    h = w = 5
    win = np.zeros((h, w))
    border_one(win, np.empty(16), np.bool_(False))
    cog_one(win, 0.0, 0.0, 0.0, 1.0, False, np.inf)
    chain = _tiny_chain(h, w)
    keys = child_keys(np.uint64(1), 2)
    if opts.get("fused", True):
        f8 = types.float64  # the fused kernels (border_cog_one, the truths' kernel) pass cog_one a literal False
        cog_one.compile((types.Array(f8, 2, "C"), f8, f8, f8, f8, types.literal(False), f8))
        from budget.starcam.kernels_trial import expose_centroid_drift_chain

        g = np.zeros((1, h, w))
        expose_centroid_drift_chain(chain, g, g, np.zeros((2, 2)), keys, dark_mean=None,
                                    threshold_dn=np.full(1, 3.0))
    if opts.get("truth", False):
        from budget.starcam.kernels_truth import cv_prepare, expose_centroid_cv

        expose_centroid_cv(chain, keys, cv_prepare(chain, threshold_dn=np.full(1, 3.0)))


def _tiny_chain(h: int, w: int):
    """A one-window :class:`simcam.detector.WindowChain` of the production types."""
    from simcam.detector import WindowChain

    return WindowChain(mean_e=np.full((1, h, w), 100.0), row0=np.zeros(1, dtype=np.int64),
                       col0=np.zeros(1, dtype=np.int64), mosaic_cols=w, chip_cols=w,
                       gain=np.ones(1), offset=np.zeros(1), read_noise=np.ones(1),
                       full_well=np.full(1, 1e4), max_dn=4095.0, output_dtype=np.dtype(np.uint16))


def compile_stamps_and_exposure(arg: str) -> None:
    """The truths' control-variate tables (option ``truth``) through
    :func:`budget.starcam.kernels_truth.cv_prepare`, first (:func:`compile_support` needs
    them late), the serial stamp kernel through
    :func:`simcam.starcam.psf_stamps.render_stamps` (a trial's camera renders serially), the
    fixed pattern through
    :func:`simcam.detector.window_chain`, then on one tiny window the static condition's
    fused expose-and-centroid kernel (option ``fused``), the window exposure (option
    ``windows``: dark frames, or a method other than the centre of gravity), through
    :func:`budget.starcam.kernels_trial.expose_centroid_chain` and
    :func:`simcam.detector.expose_windows_frames`, and a scene's windows summed from its
    stamps. ``arg``: JSON options."""
    from budget.starcam.kernels_trial import expose_centroid_chain
    from simcam.detector import DetectorParams, expose_windows_frames, window_chain
    from simcam.rng import child_keys
    from simcam.starcam.kernels.windows import add_stamps_windows
    from simcam.starcam.psf_stamps import (
        render_shifted_stamps,
        render_stamps,
        stamp_profiles,
    )

    opts = json.loads(arg)
    h = w = 5
    chain = _tiny_chain(h, w)
    if opts.get("truth", False):
        from budget.starcam.kernels_truth import cv_prepare

        cv_prepare(chain, threshold_dn=np.full(1, 3.0))
    n, n_l = 2, 3
    render_stamps(x_px=np.array([10.2, 20.7]), y_px=np.array([11.4, 30.1]), stamp_px=8, psf_kind="gaussian",
                  sigma_px=np.full(n, 0.8), pinhole_radius_px=0.3, wavelength_nm=np.array([500.0, 600.0, 700.0]),
                  weights=np.full((n, n_l), 1.0 / n_l), shift_x_px=np.zeros((n, n_l)),
                  shift_y_px=np.zeros((n, n_l)), parallel=False)
    # the profile stamp route (render.stamp_route = "profile")
    prof = stamp_profiles(stamp_px=8, psf_kind="gaussian", sigma_px=np.full(n, 0.8), pinhole_radius_px=0.3,
                          wavelength_nm=np.array([500.0, 600.0, 700.0]), weights=np.full((n, n_l), 1.0 / n_l),
                          shift_x_px=np.zeros((n, n_l)), shift_y_px=np.zeros((n, n_l)))
    render_shifted_stamps(prof, x_px=np.array([10.2, 20.7]), y_px=np.array([11.4, 30.1]), sigma_px=np.full(n, 0.8),
                          mean_shift_x_px=np.zeros(n), mean_shift_y_px=np.zeros(n))
    params = DetectorParams(gain_e_per_dn=(1.0,), offset_dn=(0.0,), read_noise_e=(1.0,), full_well_e=(1e4,),
                            adc_bits=12, prnu_rms=0.01, dark_e=1.0, dsnu_rms_e=0.5)
    window_chain(signal_e=np.ones((1, h, w)), row0=[0], col0=[0], mosaic_cols=w, chip_cols=w,
                 params=dataclasses.replace(params, nonlinearity_beta=0.008), detector_key=np.uint64(1))
    window_chain(signal_e=np.ones((1, h, w)), row0=[0], col0=[0], mosaic_cols=w, chip_cols=w, params=params,
                 detector_key=np.uint64(1))
    keys = child_keys(np.uint64(1), 2)
    if opts.get("fused", True):
        expose_centroid_chain(chain, keys, dark_mean=None, threshold_dn=np.full(1, 3.0), parallel=False)
    if opts.get("windows", True):
        expose_windows_frames(frame_keys=keys, chain=chain, parallel=False)
    # a scene's windows from its stamps, with the types simcam.starcam.render passes
    i1 = np.zeros(1, dtype=np.int64)
    add_stamps_windows(np.zeros((1, h, w)), np.zeros((1, 4, 4)), np.ones(1), i1, i1, i1, i1, i1, i1, 5, 5)
