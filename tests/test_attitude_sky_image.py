"""``budget attitude solve`` on a real sky image: the centre of one of tetra3's test frames
(tests/data/sky_frames, Apache 2.0), against tetra3's own solution of the full frame."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from astropy import units as u
from astropy.coordinates import GCRS, SkyCoord
from astropy.time import Time
from scipy.spatial.transform import Rotation

from budget.attitude.frame_solve import attitude_angles, tetra3_attitude
from budget.attitude.solve import attitude_error
from budget.cli import cli
from simcam.infra.cli import run_cli

DATA = Path(__file__).parent / "data" / "sky_frames"
EPOCH = "2019-07-29T20:47:26"
#: tetra3's solution of the full frame (README.md there): catalogue places, its roll convention
TETRA3 = {"RA": 355.2046229225577, "Dec": 58.151826005066575, "Roll": 53.304244895010925}
TETRA3_MATCHES, TETRA3_RMSE_ARCSEC = 51, 7.129
#: the rms angular distance of tetra3's matched stars from the centre of the 11.4 x 8.6 deg field
#: (stars spread uniformly over it: sqrt((5.7^2 + 4.3^2) / 3) deg), the lever arm of its roll
TETRA3_RHO_RAD = math.radians(math.sqrt((5.7**2 + 4.3**2) / 3.0))


def _unit(ra_deg: float, dec_deg: float) -> np.ndarray:
    ra, dec = math.radians(ra_deg), math.radians(dec_deg)
    return np.array([math.cos(dec) * math.cos(ra), math.cos(dec) * math.sin(ra), math.sin(dec)])


def test_a_public_sky_frame_is_solved_to_tetra3s_solution(tmp_path, capsys):
    # tetra3's attitude carried to the apparent places of the epoch: the rotation that takes its
    # boresight to its apparent (aberrated) place, about 17" here, applied to the whole frame
    ref_cat = tetra3_attitude(TETRA3)
    app = SkyCoord(TETRA3["RA"] * u.deg, TETRA3["Dec"] * u.deg, frame="icrs").transform_to(
        GCRS(obstime=Time(EPOCH, scale="utc")))
    turn, _ = Rotation.align_vectors([_unit(app.ra.deg, app.dec.deg)], [_unit(TETRA3["RA"], TETRA3["Dec"])])
    ref = turn * ref_cat
    ra, dec, roll = attitude_angles(ref)
    prior = (ra + 0.1, dec - 0.05, roll + 0.2)  # about 5 arcmin and 0.2 deg off
    out = tmp_path / "sol.json"
    run_cli(cli, ["attitude", "solve", str(DATA / "tetra3_alt40_azi45_centre.fits"), "--camera",
                  str(DATA / "tetra3_camera.toml"), "--prior", ",".join(f"{v:.6f}" for v in prior),
                  "--epoch", EPOCH, "--json", str(out)])
    assert "stars identified" in capsys.readouterr().out
    sol = json.loads(out.read_text())
    # every star found is a catalogue star (V <= 7.5), its residual a fraction of a 40" pixel
    assert sol["stars_identified"] == sol["stars_detected"] >= 10
    res = np.hypot([s["residual_u_arcsec"] for s in sol["stars"]], [s["residual_v_arcsec"] for s in sol["stars"]])
    assert sol["centroid_sigma_px"] < 0.5 and res.max() < 40.305
    e = attitude_error(Rotation.from_quat(sol["attitude"]["quaternion_xyzw"]), ref)
    # within 4 combined 1-sigma of the two solutions (1 in 16,000 by chance for normal errors): ours
    # from its covariance, tetra3's from its per-star rms over its 51 stars (across the boresight
    # RMSE / sqrt(N), in roll over the lever arm of its field)
    s = sol["sigma_arcsec"]
    t3 = TETRA3_RMSE_ARCSEC / math.sqrt(TETRA3_MATCHES)
    assert abs(e.x_arcsec) < 4 * math.hypot(s["x"], t3)
    assert abs(e.y_arcsec) < 4 * math.hypot(s["y"], t3)
    assert abs(e.roll_arcsec) < 4 * math.hypot(s["roll"], t3 / TETRA3_RHO_RAD)
