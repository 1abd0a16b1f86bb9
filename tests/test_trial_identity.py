"""A trial's numbers do not change when its code gets faster.

``_BEFORE`` holds the estimates of trial 1 (run seed 0) of the embedded realistic default
and of the ideal world, as float.hex, recorded from the code before the trial-speed work
(commit c33ea06, before the windows and drifting-condition kernels); the trial must give
them to the rounding of its floating-point operations (``tests/golden.py``), and a full
frame its recorded ADC codes to a flipped code or two. The two kernels are also checked
against the Python loops they replace (the per-window ``StarCamera._add_stamps`` and one
``expose_centroid_chain`` per frame), bit for bit: the same operations in the same order.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from golden import assert_close_to_recorded

#: the estimates are differences of centroids on a mosaic up to 4096 px wide: four last
#: bits of such a position (3.6e-12 px) is the absolute floor of their comparison
ATOL_PX = 4 * math.ulp(4096.0)

_BEFORE = {
    "realistic": {
        "hsfe/improved/x": "0x1.12d231facdda2p-9",
        "hsfe/improved/y": "0x1.dcb09ce98130fp-10",
        "hsfe/published/x": "0x1.b90b8ffffdb09p-9",
        "hsfe/published/y": "0x1.d3abbaa9062d1p-9",
        "lsfe_c1/improved/x": "0x1.59e777d18361ep-6",
        "lsfe_c1/improved/y": "0x1.8c44d7f39775ep-6",
        "lsfe_c1/published/x": "0x1.47baa5392413bp-6",
        "lsfe_c1/published/y": "0x1.985b9739b1bc1p-6",
        "lsfe_s/improved/x": "0x1.e81a35a208340p-6",
        "lsfe_s/improved/y": "0x1.140e9b02fdc3dp-9",
        "lsfe_s/published/x": "0x1.447d38f27fbe5p-6",
        "lsfe_s/published/y": "0x1.c76c993413d70p-10",
        "te/improved/x": "0x1.a86cda75282aap-7",
        "te/improved/y": "0x1.a06d69fbaa452p-7",
        "te/published/x": "0x1.a64aac447aa8cp-7",
        "te/published/y": "0x1.9cf386817da0dp-7",
    },
    "ideal": {
        "hsfe/improved/x": "0x1.e15b25bd96905p-10",
        "hsfe/improved/y": "0x1.a840793daed45p-10",
        "hsfe/published/x": "0x1.ae20f3956b03dp-9",
        "hsfe/published/y": "0x1.ce9cefbf75861p-9",
        "lsfe_c1/improved/x": "0x1.09412e9cfa965p-6",
        "lsfe_c1/improved/y": "0x1.6e8f073461fc5p-6",
        "lsfe_c1/published/x": "0x1.4e6dc0bf289d4p-6",
        "lsfe_c1/published/y": "0x1.8fe88f4ced95ap-6",
        "lsfe_s/improved/x": "0x1.d414209905351p-6",
        "lsfe_s/improved/y": "0x1.be57355dac486p-10",
        "lsfe_s/published/x": "0x1.43c71d60ceb33p-6",
        "lsfe_s/published/y": "0x1.638ade765a4b1p-10",
        "te/improved/x": "0x1.a5f587efa291bp-7",
        "te/improved/y": "0x1.aea647bf489d9p-7",
        "te/published/x": "0x1.a217be7315385p-7",
        "te/published/y": "0x1.ab39b738daaafp-7",
    },
}


@pytest.mark.parametrize("world", ["realistic", "ideal"])
def test_trial_bit_identical_to_pre_change_values(world):
    from budget.starcam.setup import CameraSetup
    from budget.starcam.validate import run_trial
    from simcam.starcam.scenario import default, load, with_updates

    scn = default() if world == "realistic" else load("embedded:seed000_ideal")
    # the recorded values are those of the exact stamp route (the profile route, the default,
    # changes the stamps at the 1e-15 level and more: tests/test_stamp_route.py)
    scn = with_updates(scn, {"render.stamp_route": "exact"})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # on the scenario seed's camera (maps and calibration), every trial's when these were recorded
        got = run_trial(scn, 0, 1, camera=CameraSetup(scn).camera())["values"]
    assert_close_to_recorded({key: float(got[tuple(key.split("/"))]) for key in _BEFORE[world]},
                             {key: float.fromhex(hx) for key, hx in _BEFORE[world].items()}, abs_floor=ATOL_PX)


def _realistic_scene():
    from dataclasses import replace

    from budget.starcam.protocols import _star_grid, make_plan
    from budget.starcam.study import STUDY
    from simcam.starcam.render import Placement
    from simcam.starcam.scenario import default

    scn = default()
    cam = STUDY.prepared(scn).camera()
    c = make_plan("chromatic", scn).conditions[4]
    p = Placement(layout=_star_grid(cam, c.field_center_px), platform_dx_px=c.platform_dx_px + 0.137,
                  platform_dy_px=c.platform_dy_px - 0.211, filter_nm=c.filter_nm, condition=3004,
                  platform_roll_rad=2e-5)
    return cam, cam._scene(p), replace(p, platform_dx_px=c.platform_dx_px, platform_dy_px=c.platform_dy_px,
                                       platform_roll_rad=0.0)


def test_windows_kernel_equals_per_window_loop():
    from simcam.starcam.render import _expected_windows_at

    cam, scene, _ = _realistic_scene()
    col0, row0 = cam.window_origins(scene)
    w = cam.scenario.render.window_px
    ref = np.full((scene.n_stars, w, w), scene.background_e)
    cc = cam.mosaic.chip_cols
    for j in range(scene.n_stars):
        k = int(scene.chip[j])
        cam._add_stamps(ref[j], scene, chip=k, row0=int(row0[j]), col0=int(col0[j] - k * cc))
    # shifted origins too: windows that hold parts of their neighbours' stamps (exact on
    # purpose: the kernel sums the same stamps in the same order as the loop)
    for dc, dr in ((0, 0), (3, -2), (-40, 17)):
        got = _expected_windows_at(cam, scene, col0 + dc, row0 + dr)
        if dc == dr == 0:
            assert np.array_equal(got, ref)
        ref2 = np.full_like(ref, scene.background_e)
        for j in range(scene.n_stars):
            k = int(scene.chip[j])
            cam._add_stamps(ref2[j], scene, chip=k, row0=int(row0[j] + dr), col0=int(col0[j] + dc - k * cc))
        assert np.array_equal(got, ref2)


@pytest.mark.parametrize("dark", [False, True])
def test_drift_kernel_equals_one_call_per_frame(dark):
    from budget.starcam.kernels_trial import expose_centroid_chain, expose_centroid_drift_chain
    from budget.starcam.protocols import _drifted_chains

    cam, scene, nominal = _realistic_scene()
    rng = np.random.default_rng(5)  # fixed seed: any drift of the size the world gives
    drift = rng.normal(0.0, 2e-3, (7, 2))
    chain, gx, gy = cam.drift_chain(scene, nominal)
    keys = cam.frame_keys(seed=11, condition=scene.placement.condition, frames=7)
    thr = np.full(scene.n_stars, 5.0)
    dm = rng.normal(0.0, 1.0, chain.mean_e.shape) if dark else None
    got = expose_centroid_drift_chain(chain, gx, gy, drift, keys, dark_mean=dm, threshold_dn=thr)
    ref = [np.empty((7, scene.n_stars)) for _ in range(3)] + [np.empty((7, scene.n_stars), dtype=np.int64)]
    for f, ch in _drifted_chains(cam, scene, (drift, nominal)):
        r = expose_centroid_chain(ch, keys[f:f + 1], dark_mean=dm, threshold_dn=thr, parallel=False)
        for o, v in zip(ref, r):
            o[f] = v[0]
    for a, b in zip(got, ref):  # exact on purpose: one kernel pass or one call per frame, the same operations
        assert np.array_equal(a, b, equal_nan=True)


#: a full frame (frame 2, run seed 7, the star grid 0.3 px off centre) of each world, recorded
#: from the code before the trial-speed work (commit c33ea06) as the sha256 of its ADC codes;
#: here, from the same frames, each 128 x 128 tile's sum of codes and digest
_FRAME_TILES = Path(__file__).parent / "data" / "starcam_frames_c33ea06_tiles.json"
#: the codes are integers: a last-bit change of the floating-point computation moves a code
#: only when its value lies within a last bit (about 1e-13 of a code) of a rounding or
#: sampling boundary, about once in 1e6 frames of 8.4e6 pixels. Two tiles off by at most two
#: codes each absorb such flips; any change of the computation (a random stream, a stamp,
#: the detector chain) changes the digests of hundreds of tiles.
_FLIPPED_TILES, _FLIPPED_CODES = 2, 2


@pytest.mark.parametrize("world", ["realistic", "ideal"])
def test_full_frame_equals_the_pre_change_frame(world):
    import hashlib

    from simcam.starcam.render import Placement, StarCamera
    from simcam.starcam.scenario import default, load, with_updates
    from simcam.starcam.targets import star_grid

    scn = with_updates(default() if world == "realistic" else load("embedded:seed000_ideal"),
                       {"render.stamp_route": "exact"})
    cam = StarCamera(scn)
    frame = cam.render_frame(cam.scene(Placement(layout=star_grid(scn), platform_dx_px=0.3)), frame=2, seed=7)
    rec = json.loads(_FRAME_TILES.read_text())
    want, t = rec[world], rec["tile_px"]
    assert list(frame.shape) == want["shape"]
    tiles = [frame[r:r + t, c:c + t] for r in range(0, frame.shape[0], t) for c in range(0, frame.shape[1], t)]
    digests = [hashlib.sha256(np.ascontiguousarray(x).tobytes()).hexdigest()[:16] for x in tiles]
    moved = [k for k, d in enumerate(digests) if d != want["tile_sha256_16"][k]]
    assert len(moved) <= _FLIPPED_TILES, f"{len(moved)} of {len(tiles)} tiles differ from the recorded frame"
    for k in moved:
        assert abs(int(tiles[k].sum(dtype=np.int64)) - want["tile_sums"][k]) <= _FLIPPED_CODES, k
    if not moved:  # every tile as recorded: the frame is the recorded one, digest and all
        assert hashlib.sha256(frame.tobytes()).hexdigest() == want["frame_sha256"]


def test_nonlinearity_kernel_equals_its_formula():
    # s (1 - beta min(s, FW) / FW), FW per column's chip, evaluated in numpy as the reference
    from simcam.detector import DetectorParams, apply_nonlinearity

    p = DetectorParams(gain_e_per_dn=(1.0, 1.0), offset_dn=(0.0, 0.0), read_noise_e=(1.0, 1.0),
                       full_well_e=(4e4, 5e4), adc_bits=12, prnu_rms=0.01, dark_e=1.0, dsnu_rms_e=0.5,
                       nonlinearity_beta=0.008)
    m = np.random.default_rng(1).uniform(0.0, 6e4, (3, 7, 9))  # fixed seed; above and below FW
    c0 = np.array([0, 5, 11])  # windows astride the chip boundary at column 10
    fw = np.array([4e4, 5e4])[(c0[:, None] + np.arange(9)[None, :]) // 10][:, None, :]
    ref = m * (1.0 - 0.008 * np.minimum(m, fw) / fw)
    # exact on purpose: the same correctly rounded operations in the same order
    assert np.array_equal(apply_nonlinearity(m, col0=c0, chip_cols=10, params=p), ref)
    assert np.array_equal(apply_nonlinearity(m[0], col0=0, chip_cols=10, params=p), ref[0])
