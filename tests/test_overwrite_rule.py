"""One ``--overwrite`` rule for every command that writes a folder (simcam.infra.outputs.check_output_dir):
a missing or empty folder, or an earlier output of the same kind, is written; anything else is
refused before the work, naming ``--overwrite``; with ``--overwrite`` it is replaced; an input of
the command is refused always."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from simcam.infra.errors import UserInputError
from simcam.infra.outputs import (check_output_dir, check_run_outputs, is_earlier_output, is_earlier_plots,
                            is_earlier_report)


def test_rule_on_a_folder(tmp_path):
    new = tmp_path / "new"
    check_output_dir(new)                                     # missing: fine
    (tmp_path / "empty").mkdir()
    check_output_dir(tmp_path / "empty")                      # empty: fine
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "thesis.tex").write_text("mine")
    with pytest.raises(UserInputError, match="--overwrite"):
        check_output_dir(foreign, option="--report", replaceable=is_earlier_report)
    check_output_dir(foreign, option="--report", replaceable=is_earlier_report, overwrite=True)
    with pytest.raises(UserInputError, match="input of this command"):   # never over an input
        check_output_dir(foreign, inputs=[foreign / "thesis.tex"], overwrite=True)


def test_what_counts_as_an_earlier_output(tmp_path):
    rep = tmp_path / "rep"
    rep.mkdir()
    (rep / "report.md").write_text("# r")
    assert is_earlier_report(rep) and not is_earlier_output(rep)
    frames = tmp_path / "frames"
    frames.mkdir()
    (frames / "manifest.csv").write_text("file\n")
    assert not is_earlier_output(frames)                      # a manifest alone is not ours
    (frames / "truth.csv").write_text("x\n")
    assert is_earlier_output(frames)
    plots = tmp_path / "plots"
    plots.mkdir()
    (plots / "a.png").write_bytes(b"")
    assert is_earlier_plots(plots)
    (plots / "notes.txt").write_text("mine")
    assert not is_earlier_plots(plots)


def test_run_outputs_pass_overwrite(tmp_path):
    d = tmp_path / "d"
    d.mkdir()
    (d / "x.txt").write_text("mine")
    with pytest.raises(UserInputError, match="--overwrite"):
        check_run_outputs(report_dir=d)
    check_run_outputs(report_dir=d, overwrite=True)


COMMANDS = [("simcam", ["render"]), ("simcam", ["optics"]), ("budget", ["validate"]),
            ("budget", ["starcam", "validate"]), ("budget", ["starcam", "simulate"]),
            ("budget", ["inductosyn", "validate"]), ("budget", ["whiskbroom", "validate"]),
            ("budget", ["whiskbroom", "synthesize"]), ("budget", ["scanmirror", "validate"]),
            ("budget", ["scanmirror", "simulate"]), ("budget", ["linecam", "validate"]),
            ("budget", ["linecam", "simulate"]), ("budget", ["linecam", "calibrate"]), ("budget", ["plot"]),
            ("budget", ["scanmirror", "robustness"]), ("budget", ["starcam", "robustness"]), ("budget", ["claims"])]


@pytest.mark.parametrize("prog,args", COMMANDS, ids=[" ".join([p, *a]) for p, a in COMMANDS])
def test_every_folder_writing_command_has_the_flag(prog, args):
    if prog == "simcam":
        from simcam.cli import cli
    else:
        from budget.cli import cli
    res = CliRunner().invoke(cli, [*args, "--help"])
    assert res.exit_code == 0, res.output
    assert "--overwrite" in res.output and "earlier output" in " ".join(res.output.split())


def _budget(argv) -> int:
    """`budget ARGV` as the console script runs it (run_cli: a user error is exit 2)."""
    from budget.cli import cli
    from simcam.infra.cli import run_cli

    try:
        run_cli(cli, argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    return 0


def _report_folder_rule(tmp_path, capsys, command):
    rep = tmp_path / "rep"
    args = [*command, "--report", str(rep)]
    assert _budget(args) == 0
    assert _budget(args) == 0                                  # its own earlier report: replaced
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "keep.txt").write_text("mine")
    capsys.readouterr()
    assert _budget([*command, "--report", str(foreign)]) == 2
    err = capsys.readouterr().err
    assert err.count("error:") == 1 and "--overwrite" in err
    assert (foreign / "keep.txt").read_text() == "mine"
    assert _budget([*command, "--report", str(foreign), "--overwrite"]) == 0
    assert not (foreign / "keep.txt").exists() and (foreign / "report.md").is_file()


def test_validate_report_folder_rule(tmp_path, capsys):
    """The rule end to end on the fastest command that writes a report (a whisk-broom
    validation of two trials in this process, about 1 s a run): an earlier report is
    replaced, a foreign folder is refused before the work (exit 2, one error line naming
    --overwrite, untouched), and replaced with --overwrite."""
    _report_folder_rule(tmp_path, capsys, ["whiskbroom", "validate", "--trials", "2", "--workers", "1"])


@pytest.mark.slow
def test_synthesize_report_folder_rule(tmp_path, capsys):
    """The same on the synthesis (about 2.5 s a run; the fast twin is
    test_validate_report_folder_rule)."""
    _report_folder_rule(tmp_path, capsys, ["whiskbroom", "synthesize", "--trials", "20"])
