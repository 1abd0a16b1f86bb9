"""Bad input, round three (issue #35, docs/reliability.md "Round three"): inputs are sacred,
and messages that name the thing.

Every command runs in this process (through ``budget.cli.main``); the refusals come before
any work, so the tests take seconds. Frames are small FITS files written here.
"""

from __future__ import annotations

import contextlib
import errno
import io
import os
from pathlib import Path

import numpy as np
import pytest

from simcam.infra.errors import UserInputError
from simcam.infra.outputs import (CommandInputs, check_distinct_inputs, check_output_dir, check_output_file,
                                  command_inputs)


def _budget(argv: list[str]) -> tuple[int, str, str]:
    """``budget ARGV`` in this process: (exit status, stdout, stderr)."""
    from budget.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            main(argv)
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    return code, out.getvalue(), err.getvalue()


def _one_error(code: int, err: str, *named: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err
    for n in named:
        assert n in lines[0], err
    return lines[0]


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
    code, _, err = _budget(["starcam", "measure", "te", str(lab), option, str(lab / name), "--no-progress"])
    _one_error(code, err, f"{option} {lab / name}: is an input of this command")
    assert {p.name: p.read_bytes() for p in lab.iterdir()} == before


def test_combine_never_writes_over_its_file(tmp_path):
    c = tmp_path / "c.toml"
    c.write_text("stars = 10\n" + "".join(f"[{k}]\nx = 0.5\ny = 0.5\n"
                                          for k in ("te", "hsfe", "lsfe_s", "lsfe_c1", "lsfe_c2")))
    (tmp_path / "l.toml").symlink_to(c)
    before = c.read_bytes()
    for given, out in ((c, c), (tmp_path / "l.toml", c), (c, tmp_path / "l.toml")):
        code, _, err = _budget(["starcam", "combine", str(given), "--json", str(out)])
        _one_error(code, err, f"--json {out}: is an input of this command")
    assert c.read_bytes() == before


def test_validate_refuses_its_scenario_through_a_link_and_a_report_folder_holding_it(tmp_path):
    from budget.runner.registry import get_study

    s = tmp_path / "s.toml"
    s.write_text(get_study("scanmirror").default_text())
    (tmp_path / "l.toml").symlink_to(s)
    before = s.read_bytes()
    code, _, err = _budget(["scanmirror", "validate", str(tmp_path / "l.toml"), "--json", str(s), "--trials", "2"])
    _one_error(code, err, f"--json {s}: is an input of this command ({tmp_path / 'l.toml'})")
    sc = tmp_path / "sc"
    sc.mkdir()
    (sc / "s.toml").write_bytes(before)
    for cmd in (["validate", "--trials", "2"], ["robustness", "--trials", "2"], ["simulate"]):
        code, _, err = _budget(["scanmirror", cmd[0], str(sc / "s.toml"), "--report", str(sc), "--overwrite",
                                *cmd[1:]])
        _one_error(code, err, f"--report {sc}: holds an input of this command ({sc / 's.toml'})")
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
    code, _, err = _budget(["starcam", "simulate", "te", str(d / "scenario.toml"), "--out", str(d), "--overwrite"])
    _one_error(code, err, f"--out {d}: holds an input")
    code, _, err = _budget(["starcam", "simulate", "te", str(d / "scenario.toml"), "--out", str(tmp_path / "new"),
                            "--json", str(d / "scenario.toml")])
    _one_error(code, err, "is an input of this command")
    assert (d / "scenario.toml").read_text() == TINY and not (tmp_path / "new").exists()
