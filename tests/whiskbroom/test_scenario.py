"""Whiskbroom scenario: the embedded default loads; bad input is one line naming file and field."""

import pytest

from simcam.infra.errors import ScenarioError
from simcam.whiskbroom import scenario as wsc


def _write(tmp_path, old, new):
    text = wsc.default_text()
    assert old in text
    p = tmp_path / "bad.toml"
    p.write_text(text.replace(old, new, 1))
    return p


def test_default_has_the_papers_values():
    sc = wsc.default()
    assert sc.orbit.altitude_km == 1200.0 and sc.mirror.rate_deg_s == 0.6
    assert sc.camera.pixel_pitch_um == 8.75 and sc.camera.tdi_stages == 96
    assert sc.synthesis.trials == 1000
    assert len(wsc.VARIABLES) == 17
    assert sum(getattr(sc.errors, n).dist == "uniform" for n in wsc.VARIABLES) == 6
    assert sc.errors.mirror_rate_deg_s.sigma == 0.001


@pytest.mark.parametrize("old,new,field", [
    ("altitude_km = 1200.0", "altitude_km = -5.0", "orbit.altitude_km"),
    ('[errors.pitch_deg]\ndist = "uniform"', '[errors.pitch_deg]\ndist = "gauss"', "errors.pitch_deg.dist"),
    ("rate_deg_s = 0.6", "rate_deg_s = 0.0", "mirror.rate_deg_s"),
    ("pixel_pitch_um = 8.75", "pixel_pitch_um = 8.75\npixel_pich_um = 1", "camera.pixel_pich_um"),
])
def test_bad_input_names_file_and_field(tmp_path, old, new, field):
    p = _write(tmp_path, old, new)
    with pytest.raises(ScenarioError) as exc:
        wsc.load(p)
    lines = str(exc.value).splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"{p}: {field}:")


def test_zero_mirror_rate_is_fine_without_a_drift_angle_request(tmp_path):
    p = _write(tmp_path, "rate_deg_s = 0.6", "rate_deg_s = 0.0")
    p.write_text(p.read_text().replace("drift_angle = true", "drift_angle = false"))
    assert wsc.load(p).mirror.rate_deg_s == 0.0
