"""Scenario loading: the embedded default, round trips, and each kind of bad input."""

from __future__ import annotations

import tomllib

import pytest

from simcam.infra.errors import ScenarioError
from simcam.starcam.scenario import (
    Scenario,
    default,
    load,
    from_dict,
    scenario_to_toml,
    with_updates,
)
from simcam.units import ARCSEC_PER_RAD


def test_default_is_seed000_camera_and_lab():
    scn = default()
    assert scn == Scenario()
    assert scn.camera.scale_arcsec_per_px == 5.5
    assert scn.detector.n_chips == 2 and scn.detector.mosaic_shape == (2048, 4096)
    assert (scn.lab.target.rows, scn.lab.target.cols) == (5, 5)
    assert scn.lab.calibration_target.rows * scn.lab.calibration_target.cols == 32
    assert [f.center_nm for f in scn.lab.filters] == [500.0, 600.0, 800.0]
    assert all(f.width_nm == 100.0 for f in scn.lab.filters)
    assert scn.lab.source.match_v_mag == 7.5
    assert scn.protocols.hsfe.conditions == 12 and scn.protocols.te.frames >= 30


def test_toml_round_trip_is_identity(tmp_path):
    scn = default()
    text = scenario_to_toml(scn)
    path = tmp_path / "s.toml"
    path.write_text(text)
    back = load(path)
    assert back == scn
    assert back.hash == scn.hash


def test_hash_changes_with_content():
    scn = default()
    other = with_updates(scn, {"detector.prnu_rms": 0.02})
    assert other.hash != scn.hash


def test_focal_length_and_plate_scale_agree():
    # plate scale = pitch / f: 5.5 um / 206.2648 mm = 5.5 arcsec exactly when f = pitch * ARCSEC_PER_RAD / s
    f_mm = 5.5e-3 * ARCSEC_PER_RAD / 5.5
    scn = from_dict({"camera": {"focal_length_mm": f_mm}})
    assert scn.camera.scale_arcsec_per_px == pytest.approx(5.5, rel=1e-12)
    with pytest.raises(ScenarioError, match="camera: .*contradicts"):
        from_dict({"camera": {"plate_scale_arcsec": 5.0, "focal_length_mm": f_mm}})


@pytest.mark.parametrize(
    ("data", "pattern"),
    [
        ({"camera": {"exposure": 0.1}}, r"camera\.exposure: unknown key"),
        ({"camra": {}}, r"camra: unknown key"),
        ({"camera": {"exposure_s": "0.1"}}, r"camera\.exposure_s: Input should be a valid number"),
        ({"camera": {"exposure_s": -1.0}}, r"camera\.exposure_s: Input should be greater than 0"),
        ({"detector": {"chips": [{"read_noise_e": -1.0}, {}]}}, r"detector\.chips\.0\.read_noise_e: .*greater than or equal to 0"),
        ({"detector": {"prnu_rms": -0.01}}, r"detector\.prnu_rms"),
        ({"detector": {"dsnu_rms_e": -1}}, r"detector\.dsnu_rms_e"),
        ({"detector": {"n_chips": 3}}, r"detector: .*chips lists 2 chip\(s\) but n_chips = 3"),
        ({"detector": {"bits": 12.5}}, r"detector\.bits"),
        ({"render": {"window_px": 10}}, r"render: .*window_px must be odd"),
        ({"optics": {"distortion": {"cubic_x_px": [0.0, 1.0]}}}, r"optics\.distortion: .*10 coefficients"),
        ({"optics": {"psf": {"kind": "moffat"}}}, r"optics\.psf\.kind"),
        ({"lab": {"filters": [{"center_nm": 500.0}]}}, r"lab\.filters\.0\.width_nm: Field required"),
        ({"protocols": {"chromatic": {"reference_filter_nm": 700.0}}}, r"reference_filter_nm = 700.0 is not one of"),
        ({"protocols": {"te": {"frames": 1}}}, r"protocols\.te\.frames"),
        ({"lab": {"source": {"match_spectral_type": "Q3V"}}}, r"lab\.source: .*match_spectral_type"),
        ({"validation": {"lsfe_spectral_types": ["G2V", "XX"]}}, r"validation: .*spectral type 'XX'"),
    ],
)
def test_bad_scenarios_name_the_field(data, pattern):
    with pytest.raises(ScenarioError, match=pattern):
        from_dict(data, source="bad.toml")


def test_error_names_the_file(tmp_path):
    p = tmp_path / "broken.toml"
    p.write_text("[camera]\nexposure_s = -2.0\n")
    with pytest.raises(ScenarioError, match=r"broken\.toml: camera\.exposure_s"):
        load(p)
    p.write_text("[camera\n")
    with pytest.raises(ScenarioError, match=r"broken\.toml: not valid TOML"):
        load(p)
    with pytest.raises(ScenarioError, match="not found"):
        load(tmp_path / "missing.toml")


def test_with_updates_rejects_unknown_dotted_key():
    with pytest.raises(ScenarioError, match="unknown key 'read_noise'"):
        with_updates(default(), {"detector.read_noise": 1.0})


def test_printed_toml_parses():
    data = tomllib.loads(scenario_to_toml(default()))
    assert data["camera"]["plate_scale_arcsec"] == 5.5
