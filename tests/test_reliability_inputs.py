"""Bad input, round three (issue #35, docs/reliability.md "Round three"): inputs are sacred,
and messages that name the thing.

Every command runs in this process (through ``budget.cli.main``); the refusals come before
any work, so the tests take seconds. Frames are small FITS files written here.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

import numpy as np
import pytest

from cli_capture import one_error, run_budget
from simcam.infra.errors import UserInputError
from simcam.infra.outputs import (CommandInputs, check_distinct_inputs, check_output_dir, check_output_file,
                                  command_inputs)




def _fits(path: Path, *, plate_scale: float | None = 11.0, seed: int = 0) -> None:
    """A 64 x 64 frame with three stars and noise (header PLTSCALE, unless None)."""
    from astropy.io import fits

    rng = np.random.default_rng(seed)
    y, x = np.mgrid[:64, :64]
    img = 100.0 + rng.normal(0.0, 2.0, (64, 64))
    for cx, cy in ((15.3, 20.1), (40.7, 35.2), (25.0, 50.4)):
        img += 3000.0 * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * 1.2**2))
    hdu = fits.PrimaryHDU(img.astype(np.float32))
    if plate_scale is not None:
        hdu.header["PLTSCALE"] = plate_scale
    hdu.writeto(path)


def _dataset(d: Path, n: int = 3, *, dark: bool = True) -> list[str]:
    """A TE dataset folder: ``n`` lit frames and a dark one, and their manifest."""
    d.mkdir()
    names = [f"c000_f{i:04d}.fits" for i in range(n)]
    rows = [f"{f},0,{i},0" for i, f in enumerate(names)]
    if dark:
        names.append("c000_dark0000.fits")
        rows.append("c000_dark0000.fits,0,0,1")
    for i, f in enumerate(names):
        _fits(d / f, seed=i)
    (d / "manifest.csv").write_text("file,condition,frame,dark\n" + "\n".join(rows) + "\n")
    return names


# ----------------------------------------------------------------------------- inputs are sacred
def test_command_inputs_compare_real_paths(tmp_path):
    a = tmp_path / "a.toml"
    a.write_text("x")
    (tmp_path / "link.toml").symlink_to(a)
    os.link(a, tmp_path / "hard.toml")
    ins = command_inputs(tmp_path / "link.toml", None, [tmp_path / "b.csv"])
    assert isinstance(ins, CommandInputs) and len(ins.given) == 2
    assert ins.same_as(a) == str(tmp_path / "link.toml")  # the link's target is the input
    assert command_inputs(a).same_as(tmp_path / "hard.toml") == str(a)  # a hard link too
    assert ins.same_as(tmp_path / "other.toml") is None
    assert ins.inside(tmp_path) == str(tmp_path / "link.toml")
    assert command_inputs(ins, a).given == ins.given + (str(a),)  # by place: the link and its target
    with pytest.raises(UserInputError, match=r"link.toml: is an input of this command"):
        check_output_file(tmp_path / "link.toml", inputs=[a])
    with pytest.raises(UserInputError, match=r"a.toml: is an input of this command \(.*link.toml\)"):
        check_output_file(a, inputs=[tmp_path / "link.toml"])
    # a folder holding an input is refused before the --overwrite rule, and with it
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "in.toml").symlink_to(a)
    with pytest.raises(UserInputError, match="holds an input"):
        check_output_dir(tmp_path / "d", inputs=[tmp_path / "d" / "in.toml"], overwrite=True)
    with pytest.raises(UserInputError, match="is an input"):
        check_output_dir(tmp_path / "d", inputs=[tmp_path / "d"], overwrite=True)
    with pytest.raises(UserInputError, match=r"hard.toml: the same table given twice \(.*hard.toml is .*a.toml\)"):
        check_distinct_inputs([a, tmp_path / "hard.toml"], what="table")


@pytest.mark.parametrize("option,name", [("--centroids", "c000_f0000.fits"), ("--centroids", "c000_dark0000.fits"),
                                         ("--json", "c000_f0001.fits"), ("--json", "manifest.csv"),
                                         ("--json", "link.fits")])
def test_measure_never_writes_over_a_frame_its_manifest_lists(tmp_path, option, name):
    lab = tmp_path / "lab"
    _dataset(lab)
    (lab / "link.fits").symlink_to(lab / "c000_f0002.fits")
    before = {p.name: p.read_bytes() for p in lab.iterdir()}
    code, _, err = run_budget(["starcam", "measure", "te", str(lab), option, str(lab / name), "--no-progress"])
    one_error(code, err, f"{option} {lab / name}: is an input of this command")
    assert {p.name: p.read_bytes() for p in lab.iterdir()} == before


def test_combine_never_writes_over_its_file(tmp_path):
    c = tmp_path / "c.toml"
    c.write_text("stars = 10\n" + "".join(f"[{k}]\nx = 0.5\ny = 0.5\n"
                                          for k in ("te", "hsfe", "lsfe_s", "lsfe_c1", "lsfe_c2")))
    (tmp_path / "l.toml").symlink_to(c)
    before = c.read_bytes()
    for given, out in ((c, c), (tmp_path / "l.toml", c), (c, tmp_path / "l.toml")):
        code, _, err = run_budget(["starcam", "combine", str(given), "--json", str(out)])
        one_error(code, err, f"--json {out}: is an input of this command")
    assert c.read_bytes() == before


def test_validate_refuses_its_scenario_through_a_link_and_a_report_folder_holding_it(tmp_path):
    from budget.runner.registry import get_study

    s = tmp_path / "s.toml"
    s.write_text(get_study("scanmirror").default_text())
    (tmp_path / "l.toml").symlink_to(s)
    before = s.read_bytes()
    code, _, err = run_budget(["scanmirror", "validate", str(tmp_path / "l.toml"), "--json", str(s), "--trials", "2"])
    one_error(code, err, f"--json {s}: is an input of this command ({tmp_path / 'l.toml'})")
    sc = tmp_path / "sc"
    sc.mkdir()
    (sc / "s.toml").write_bytes(before)
    for cmd in (["validate", "--trials", "2"], ["robustness", "--trials", "2"], ["simulate"]):
        code, _, err = run_budget(["scanmirror", cmd[0], str(sc / "s.toml"), "--report", str(sc), "--overwrite",
                                *cmd[1:]])
        one_error(code, err, f"--report {sc}: holds an input of this command ({sc / 's.toml'})")
    assert s.read_bytes() == before and (sc / "s.toml").read_bytes() == before


def test_folder_outputs_of_every_writer_refuse_a_folder_holding_their_input(tmp_path):
    from simcam.io import atomic_directory
    from tiny_camera import TINY

    d = tmp_path / "lab"
    d.mkdir()
    (d / "scenario.toml").write_text(TINY)
    (d / "manifest.csv").write_text("x")
    (d / "truth.csv").write_text("x")  # an earlier output: replaceable, but it holds the input
    with pytest.raises(UserInputError, match="holds an input"):
        with atomic_directory(d, inputs=(d / "scenario.toml",)):
            pass
    code, _, err = run_budget(["starcam", "simulate", "te", str(d / "scenario.toml"), "--out", str(d), "--overwrite"])
    one_error(code, err, f"--out {d}: holds an input")
    code, _, err = run_budget(["starcam", "simulate", "te", str(d / "scenario.toml"), "--out", str(tmp_path / "new"),
                            "--json", str(d / "scenario.toml")])
    one_error(code, err, "is an input of this command")
    assert (d / "scenario.toml").read_text() == TINY and not (tmp_path / "new").exists()


def test_the_same_calibration_table_twice_and_a_plot_format_are_refused_before_the_fit(tmp_path, monkeypatch):
    import budget.inductosyn.harmonics as harmonics

    a = np.arange(0.0, 360.0, 15.0)
    body = "angle_deg,error_arcsec\n" + "".join(f"{x},{3 * np.sin(np.radians(x)) + 0.1 * i}\n"
                                                for i, x in enumerate(a))
    p = tmp_path / "p.csv"
    p.write_text(body)
    (tmp_path / "copy.csv").write_text(body)
    (tmp_path / "link.csv").symlink_to(p)

    def fitted(*a, **k):
        raise AssertionError("the fit ran")

    for name in ("fit_joint", "fit_long_period"):
        monkeypatch.setattr(harmonics, name, fitted)
    cases = [([p, p, "--period", "both"], f"{p}: the same calibration table given twice"),
             ([p, tmp_path / "link.csv", "--period", "both"], "the same calibration table given twice"),
             ([p, tmp_path / "copy.csv", "--period", "both"], f"copy.csv: the same table as {p}"),
             ([p, "--period", "long", "--plot", tmp_path / "out.txt"], "--plot"),
             ([p, "--period", "long", "--plot", tmp_path / "out"], "no suffix names the figure format")]
    for args, named in cases:
        code, _, err = run_budget(["inductosyn", "fit", *map(str, args)])
        line = one_error(code, err, named)
        if "out.txt" in line:
            assert "the suffix .txt is no figure format; give one of" in line and ".png" in line
    assert sorted(x.name for x in tmp_path.iterdir()) == ["copy.csv", "link.csv", "p.csv"]


def test_manifest_repeats_and_two_plate_scales_name_the_manifest_and_both_values(tmp_path):
    lab = tmp_path / "lab"
    _dataset(lab, dark=False)
    m = lab / "manifest.csv"
    rows = m.read_text().splitlines()
    m.write_text("\n".join(rows + [rows[2]]) + "\n")  # row 5 repeats row 3
    code, _, err = run_budget(["starcam", "measure", "te", str(lab), "--no-progress"])
    one_error(code, err, f"{m}: row 5 repeats row 3 (c000_f0001.fits)")
    m.write_text("\n".join(rows[:3] + ["c000_f0001.fits,0,0,0"]) + "\n")  # frame 0 listed twice
    code, _, err = run_budget(["starcam", "measure", "te", str(lab), "--no-progress"])
    one_error(code, err, f"{m}: condition 0: frame 0 listed twice (rows 2, 4")
    m.write_text("\n".join(rows) + "\n")
    (lab / "c000_f0002.fits").unlink()
    _fits(lab / "c000_f0002.fits", plate_scale=5.5, seed=2)  # was measured with the first one's 11
    code, _, err = run_budget(["starcam", "measure", "te", str(lab), "--no-progress"])
    one_error(code, err, f"{lab / 'c000_f0002.fits'}: header PLTSCALE = 5.5 differs from "
                          f"{lab / 'c000_f0000.fits'}'s 11.0")


def test_observation_table_literal_nan_and_a_table_repeated_twice(tmp_path):
    from budget.linecam.table import CSV_COLUMNS, check_observation_values
    from test_reliability_outputs import _obs_arrays

    a = _obs_arrays()
    lines = [",".join(CSV_COLUMNS)] + [",".join(repr(float(a[c][i])) for c in CSV_COLUMNS) for i in range(40)]
    obs = tmp_path / "obs.csv"
    for cell, got in (("nan", "'nan'"), ("NA", "'NA'"), ("", "an empty cell")):
        rows = list(lines)
        rows[3] = cell + rows[3][rows[3].index(","):]  # time_s of row 4
        obs.write_text("\n".join(rows) + "\n")
        code, _, err = run_budget(["linecam", "calibrate", str(obs)])
        one_error(code, err, f"{obs}: time_s: not a finite number in row 4 (got {got})")
    twice = {k: np.concatenate([v, v]) for k, v in a.items()}  # said "row 3 repeats row 3"
    with pytest.raises(UserInputError, match=r"obs.csv: rows: row 42 repeats row 2 \(40 duplicated row"):
        check_observation_values("obs.csv", twice, n_pixels=6144)


def test_sweep_field_both_fixed_and_varied_and_plot_precision_nan(tmp_path):
    from budget.sweeps.models import parse_sweep
    from budget.sweeps.plot import plot_store
    from simcam.infra.errors import ScenarioError

    text = ('kind = "starcam"\nseed = 1\nevaluate = "truth"\n[fixed]\n"detector.prnu_rms" = 0.01\n'
            '[parameters]\n"detector.prnu_rms" = [0.0, 0.02]\n')
    with pytest.raises(ScenarioError, match=r"^s.toml: parameters: 'detector.prnu_rms' is also in \[fixed\]"):
        parse_sweep(text, source="s.toml")
    with pytest.raises(ScenarioError, match=r"parameters: 'detector.prnu_rms' is also in \[fixed\] \('detector'"):
        parse_sweep(text.replace('"detector.prnu_rms" = 0.01', 'detector = {prnu_rms = 0.01}'), source="s.toml")
    parse_sweep(text.replace('"detector.prnu_rms" = 0.01', '"detector.dsnu_rms_e" = 0.5'), source="s.toml")
    for bad in (float("nan"), float("inf")):
        with pytest.raises(UserInputError, match=r"--precision (nan|inf): must be a finite number > 0"):
            plot_store(tmp_path / "st", tmp_path / "pl", precision=bad)
    assert not (tmp_path / "pl").exists()


# ----------------------------------------------------------------------------- messages that name the thing
def test_a_write_that_fills_the_disk_names_the_file(tmp_path, monkeypatch):
    from simcam.infra.outputs import StagedOutputs, naming_failed_writes
    from simcam.io import atomic_directory

    def full(filename=None):
        return OSError(errno.ENOSPC, "No space left on device", *([str(filename)] if filename else []))

    with pytest.raises(UserInputError, match=rf"^{tmp_path / 'rep' / 'fig.png'}: no space left on the device$"):
        with StagedOutputs() as st:
            folder = st.folder(tmp_path / "rep")  # a figure inside the staged report, named by matplotlib
            raise full(folder / "fig.png")
    with pytest.raises(UserInputError, match=rf"^{tmp_path / 'c.csv'}: no space left on the device$"):
        with StagedOutputs() as st:
            st.file(tmp_path / "a.json")
            st.file(tmp_path / "c.csv")
            raise full()  # a write to an open file names none: the output being written
    with pytest.raises(UserInputError, match=rf"^{tmp_path / 'out' / 'frame_0000.fits'}: no space left"):
        with atomic_directory(tmp_path / "out") as tmp:
            raise full(tmp / "frame_0000.fits")
    with pytest.raises(UserInputError, match=rf"^--plot {tmp_path / 'f.png'}: no space left on the device$"):
        with naming_failed_writes(tmp_path / "f.png", option="--plot"):
            raise full()
    with pytest.raises(ValueError, match="not a write"):
        with naming_failed_writes(tmp_path / "f.png"):
            raise ValueError("not a write")
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # nothing half-written left


def test_a_json_name_too_long_for_its_temporary_name_is_refused_before_the_work(tmp_path, monkeypatch):
    import budget.runner.run

    def ran(*a, **k):
        raise AssertionError("the work started")

    monkeypatch.setattr(budget.runner.run, "run_study", ran)
    name = tmp_path / ("v" * 245 + ".json")  # 250 bytes: a valid name, its temporary sibling is not
    code, _, err = run_budget(["scanmirror", "validate", "--trials", "2", "--json", str(name)])
    one_error(code, err, f"--json {name}: the name vvvv", "it is written first under a temporary name",
               "give a name of at most")
    check_output_file(tmp_path / ("v" * 200 + ".json"))  # short enough


def test_a_reader_that_leaves_early_ends_the_printing_not_the_command(tmp_path):
    """``validate --json v.json | head -1`` exited 1 and wrote no JSON: stdout to a pipe whose
    reader has gone (closed before the command starts, so every print meets a broken pipe)."""
    import subprocess
    import sys

    c = tmp_path / "c.toml"
    c.write_text("stars = 10\n" + "".join(f"[{k}]\nx = 0.5\ny = 0.5\n"
                                          for k in ("te", "hsfe", "lsfe_s", "lsfe_c1", "lsfe_c2")))
    r, w = os.pipe()
    os.close(r)
    try:
        p = subprocess.run([sys.executable, "-m", "budget", "starcam", "combine", str(c), "--json",
                            str(tmp_path / "c.json")], stdout=w, stderr=subprocess.PIPE, text=True, timeout=300,
                           cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(Path(__file__).parents[1])})
    finally:
        os.close(w)
    assert p.returncode == 0 and p.stderr == "", p.stderr
    assert '"single_star"' in (tmp_path / "c.json").read_text()
