"""`simcam` command line and FITS round trip; reproducibility across thread counts."""

from __future__ import annotations

import numba
import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from simcam import __version__
from simcam.cli import cli, main
from simcam.io import read_frame, read_windows
from simcam.starcam.render import Placement, StarCamera
from simcam.starcam.scenario import default, load, scenario_to_toml
from simcam.starcam.targets import star_grid

SMALL = """
[detector]
chip_cols = 256
chip_rows = 256
gap_px = 10.0
[lab]
target_center_px = [-133.0, 0.0]
[lab.target]
spacing_mm = 0.5
"""


@pytest.fixture()
def small_file(tmp_path):
    p = tmp_path / "small.toml"
    p.write_text(SMALL)
    return p


def test_scenario_command_prints_toml_that_render_accepts(tmp_path):
    r = CliRunner().invoke(cli, ["scenario"])
    assert r.exit_code == 0, r.output
    p = tmp_path / "resolved.toml"
    p.write_text(r.output)
    assert load(p) == default()


def test_render_full_writes_fits_truth_and_manifest(tmp_path, small_file):
    out = tmp_path / "run"
    r = CliRunner().invoke(cli, ["render", str(small_file), "--frames", "2", "--seed", "4", "--filter", "600",
                                 "--out", str(out)])
    assert r.exit_code == 0, r.output
    data, hdr = read_frame(out / "frame_0001.fits")
    scn = load(small_file)
    assert data.shape == (256, 512)
    for key, val in {"EXPTIME": scn.camera.exposure_s, "GAIN1": 1.0, "FILTER": "600nm", "SEED": 4,
                     "SCENHASH": scn.hash, "SIMCAMV": __version__, "PLATDX": 0.0, "FRAME": 1}.items():
        assert hdr[key] == val, key
    truth = pd.read_csv(out / "truth.csv")
    assert {"star", "frame", "x_true", "y_true", "distortion_dx_px", "chromatic_dx_px", "platform_dx_px"} <= set(truth)
    assert len(truth) == 2 * 25
    # the rendered pixels are those of the API with the same seed
    cam = StarCamera(scn)
    scene = cam.scene(Placement(layout=star_grid(scn), filter_nm=600.0, label="target"))
    np.testing.assert_array_equal(data, cam.render_frame(scene, frame=1, seed=4))
    assert (out / "manifest.csv").is_file() and (out / "scenario.toml").is_file()


def test_render_windows_match_full_frames(tmp_path, small_file):
    CliRunner().invoke(cli, ["render", str(small_file), "--frames", "2", "--out", str(tmp_path / "f")])
    r = CliRunner().invoke(cli, ["render", str(small_file), "--frames", "2", "--mode", "windows",
                                 "--out", str(tmp_path / "w")])
    assert r.exit_code == 0, r.output
    pix, col0, row0, _ = read_windows(tmp_path / "w" / "windows.fits")
    full, _ = read_frame(tmp_path / "f" / "frame_0001.fits")
    h, w = pix.shape[2:]
    for j in range(pix.shape[1]):
        np.testing.assert_array_equal(pix[1, j], full[row0[j]:row0[j] + h, col0[j]:col0[j] + w])


@pytest.mark.parametrize(
    ("toml", "message"),
    [
        ("[camera]\nexposure_s = -1.0\n", "camera.exposure_s"),
        ("[detector]\nread_noise_e = 3.0\n", "detector.read_noise_e: unknown key"),
        ("[lab]\ntarget_center_px = [0.0, 0.0]\n", "off the detector"),
    ],
)
def test_bad_scenario_is_one_line_error_exit_2(tmp_path, capsys, toml, message):
    p = tmp_path / "bad.toml"
    p.write_text(toml)
    out = tmp_path / "never"
    with pytest.raises(SystemExit) as e:
        main(["render", str(p), "--out", str(out)])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not out.exists()  # no partial output left behind
    assert not list(tmp_path.glob(".never.partial*"))


def test_render_refuses_non_empty_out_and_unknown_filter(tmp_path, small_file, capsys):
    out = tmp_path / "busy"
    out.mkdir()
    (out / "keep.txt").write_text("x")
    with pytest.raises(SystemExit) as e:
        main(["render", str(small_file), "--out", str(out)])
    assert e.value.code == 2 and "not empty" in capsys.readouterr().err
    assert (out / "keep.txt").exists()
    with pytest.raises(SystemExit) as e:
        main(["render", str(small_file), "--filter", "700", "--out", str(tmp_path / "x")])
    assert e.value.code == 2 and "no lab filter centred there" in capsys.readouterr().err


def test_identical_pixels_whatever_the_thread_count():
    scn = default()
    placement = Placement(layout=star_grid(scn))
    a = StarCamera(scn, parallel=False)
    b = StarCamera(scn, parallel=True)
    wa = a.render_windows(a.scene(placement), frames=8, seed=9)
    wb = b.render_windows(b.scene(placement), frames=8, seed=9)
    np.testing.assert_array_equal(wa.pixels, wb.pixels)
    sc = a.scene(placement)
    n0 = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        f1 = a.render_frame(sc, frame=0, seed=9)
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        f2 = a.render_frame(sc, frame=0, seed=9)
    finally:
        numba.set_num_threads(n0)
    np.testing.assert_array_equal(f1, f2)


def test_scenario_toml_of_render_dir_round_trips(tmp_path, small_file):
    out = tmp_path / "r"
    CliRunner().invoke(cli, ["render", str(small_file), "--out", str(out)])
    assert load(out / "scenario.toml") == load(small_file)
    assert scenario_to_toml(load(small_file)) == (out / "scenario.toml").read_text()
