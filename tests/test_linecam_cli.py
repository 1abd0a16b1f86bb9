"""``budget linecam simulate`` and ``calibrate``: round trip through the observation table,
and bad input as one error line naming the file and field (exit status 2)."""

from __future__ import annotations

import json

import pandas as pd
import pytest
import tomli_w

from budget.linecam.calibrate import calibrate_file
from budget.linecam.cli import _local_group
from simcam.infra.cli import run_cli, write_json_atomic
from simcam.infra.errors import UserInputError

SMALL = {"stars": {"region": "manual", "ra_deg": 280.0, "dec_deg": -5.0},
         "observation": {"passes": 2, "shift_px": 2000.0}}


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    d = tmp_path_factory.mktemp("linecam")
    scn = d / "small.toml"
    scn.write_text(tomli_w.dumps(SMALL))
    assert _code(["simulate", str(scn), "--seed", "2", "--csv", str(d / "obs.csv"),
                  "--json", str(d / "sim.json")]) in (0, None)
    return d


def _code(argv):
    """Exit status of the command (run_cli returns normally on success)."""
    try:
        run_cli(_local_group, argv)
    except SystemExit as e:
        return e.code
    return 0


def _run(argv, capsys):
    capsys.readouterr()
    code = _code(argv)
    return code, capsys.readouterr()


def test_simulated_table_calibrates_to_the_same_result(simulated, capsys):
    d = simulated
    code, out = _run(["calibrate", str(d / "obs.csv"), "--scenario", str(d / "small.toml"),
                      "--json", str(d / "cal.json"), "--report", str(d / "rep")], capsys)
    assert code in (0, None), out.err
    sim = json.loads((d / "sim.json").read_text())
    cal = json.loads((d / "cal.json").read_text())
    for m in ("published", "improved"):
        # the table carries the attitude (quaternions) and the orbit; apparent places are
        # recomputed at the table's median time with first-order differential aberration:
        # the same calibration to far below its uncertainty
        for p, v in sim["variants"][m]["theta"].items():
            sd = cal["methods"][m]["sigma"][p]
            if sd is None:  # not determined on this plan (no sigma stated): the combination's
                assert p in cal["methods"][m]["not_determined"]
                sd = max(x["sigma"] for x in cal["methods"][m]["determined_combinations"].values())
            assert abs(cal["methods"][m]["theta"][p] - v) < 1e-3 * max(sd, 1e-9) + 1e-9, (m, p)
    assert (d / "rep" / "los_field.png").stat().st_size > 1000


def test_calibrate_file_is_the_python_entry_of_the_command(simulated, capsys, tmp_path):
    """The same table and scenario: the same printed lines and byte for byte the same JSON."""
    d = simulated
    code, out = _run(["calibrate", str(d / "obs.csv"), "--scenario", str(d / "small.toml"),
                      "--json", str(tmp_path / "cli.json")], capsys)
    assert code in (0, None), out.err
    cal = calibrate_file(str(d / "obs.csv"), str(d / "small.toml"))
    assert out.out.splitlines() == cal.summary_lines()
    write_json_atomic(tmp_path / "api.json", cal.to_json())
    assert (tmp_path / "api.json").read_bytes() == (tmp_path / "cli.json").read_bytes()
    assert list(cal.calibrations) == ["published", "improved", "lookangle"] and set(cal.los) == set(cal.calibrations)
    only = calibrate_file(str(d / "obs.csv"), str(d / "small.toml"), method="all", solve=["k1", "p1", "p2"])
    assert list(only.calibrations) == ["improved"] and only.calibrations["improved"].solved == ("k1", "p1", "p2")
    for kwargs, named in (({"method": "joint"}, "method: 'joint'"),
                          ({"solve": "k1,k9"}, "solve: unknown parameter 'k9'"),
                          ({"epoch": "yesterday"}, "epoch: not an ISO UTC time")):
        with pytest.raises(UserInputError, match=named):
            calibrate_file(str(d / "obs.csv"), str(d / "small.toml"), **kwargs)


def test_unknown_catalogue_id_is_one_error_line(simulated, capsys, tmp_path):
    df = pd.read_csv(simulated / "obs.csv")
    df.loc[3, "hip"] = 999999
    bad = tmp_path / "bad.csv"
    df.to_csv(bad, index=False)
    code, out = _run(["calibrate", str(bad), "--scenario", str(simulated / "small.toml")], capsys)
    assert code == 2
    lines = out.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {bad}: hip:") and "999999" in lines[0]
    assert out.out == ""


def test_too_few_stars_is_one_error_line(simulated, capsys, tmp_path):
    df = pd.read_csv(simulated / "obs.csv").iloc[:4]
    bad = tmp_path / "few.csv"
    df.to_csv(bad, index=False)
    code, out = _run(["calibrate", str(bad), "--scenario", str(simulated / "small.toml")], capsys)
    assert code == 2
    assert out.err.strip().splitlines() == [out.err.strip()]
    assert f"{bad}: rows:" in out.err and "too few stars" in out.err


def test_inseparable_parameters_asked_for_are_one_error_line(simulated, capsys):
    code, out = _run(["calibrate", str(simulated / "obs.csv"), "--scenario", str(simulated / "small.toml"),
                      "--method", "improved", "--solve", "roll,dy0,p2,k1"], capsys)
    assert code == 2
    line = out.err.strip()
    assert "\n" not in line and f"{simulated / 'obs.csv'}: solve:" in line and "roll" in line and "dy0" in line
    # roll and dy0 alone differ only by the y'^2/F^2 (< 1e-3) of a rotation: the stars
    # determine that difference worse than lab.gauge_sigma_px, so it is refused too
    code, out = _run(["calibrate", str(simulated / "obs.csv"), "--scenario", str(simulated / "small.toml"),
                      "--method", "improved", "--solve", "roll,dy0,k1"], capsys)
    assert code == 2 and "roll" in out.err and "dy0" in out.err
    code, out = _run(["calibrate", str(simulated / "obs.csv"), "--scenario", str(simulated / "small.toml"),
                      "--method", "improved", "--solve", "roll,pitch,yaw,df,k1,k2,p1"], capsys)
    assert code in (0, None), out.err


def test_missing_column_and_bad_values_name_the_field(simulated, capsys, tmp_path):
    df = pd.read_csv(simulated / "obs.csv")
    bad = tmp_path / "nocol.csv"
    df.drop(columns=["q_w"]).to_csv(bad, index=False)
    code, out = _run(["calibrate", str(bad)], capsys)
    assert code == 2 and f"{bad}: q_w: missing column" in out.err
    df2 = df.copy()
    df2.loc[1, "sample_px"] = 1e6
    df2.to_csv(bad, index=False)
    out_json = tmp_path / "cal.json"
    code, out = _run(["calibrate", str(bad), "--scenario", str(simulated / "small.toml"),
                      "--json", str(out_json)], capsys)
    # row 3 of the file: the header is line 1, data row index 1 is line 3
    assert code == 2 and f"{bad}: sample_px:" in out.err and "row 3" in out.err
    # one error line, no traceback, nothing on stdout and no partial output file
    lines = out.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {bad}: sample_px:"), out.err
    assert out.out == ""
    assert not out_json.exists()


def test_a_strip_with_too_few_stars_names_the_scenario(capsys, tmp_path):
    scn = tmp_path / "few.toml"
    scn.write_text(tomli_w.dumps({"stars": {"mag_limit": 3.0, "world_mag_limit": 3.0, "region": "manual",
                                            "ra_deg": 192.9, "dec_deg": 27.1},
                                  "observation": {"passes": 1}}))
    code, out = _run(["simulate", str(scn)], capsys)
    assert code == 2
    line = out.err.strip()
    assert "\n" not in line and line.startswith(f"error: {scn}: stars.mag_limit") and "too few stars" in line
