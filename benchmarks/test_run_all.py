"""Tests of run_all.py's bookkeeping (not of any timing): ``python -m pytest -q benchmarks/test_run_all.py``.

They live beside the scripts (not in ``tests/``) because they test the benchmark harness;
``python -m pytest -q`` collects them too (``testpaths``). No timing is asserted, no
benchmark runs and no optional peer (galsim, pyxel, photutils, sep) is needed. Fake benchmark scripts written to a temporary folder exercise the
statuses a real run can meet: a RESULT line, none, a failure, a timeout, no ``--quick``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import pytest

from benchmarks import run_all
from benchmarks._common import RESULT_PREFIX, emit_result, figure


def _payload(figs):
    return {"bench": "x", "quick": False, "figures": figs}


def test_emit_result_round_trips_through_parse(capsys):
    emit_result("demo", [figure("t", "a time", 2.0, "ms", peer="p", peer_value=6.0, target=3.0,
                                target_source="project target")], quick=True, extra_value=1)
    out = "some table\n" + capsys.readouterr().out
    res = run_all.parse_result(out)
    assert res["bench"] == "demo" and res["quick"] is True and res["extra_value"] == 1
    assert res["figures"][0]["peer_value"] == 6.0


def test_parse_result_takes_the_last_line_and_rejects_garbage():
    a = RESULT_PREFIX + json.dumps(_payload([]) | {"bench": "first"})
    b = RESULT_PREFIX + json.dumps(_payload([]) | {"bench": "last"})
    assert run_all.parse_result(f"{a}\ntext\n{b}\n")["bench"] == "last"
    assert run_all.parse_result("no result here\n") is None
    with pytest.raises(ValueError):
        run_all.parse_result(RESULT_PREFIX + "[1, 2]")


def test_figure_rejects_bad_sense_and_drops_non_finite():
    with pytest.raises(ValueError):
        figure("k", "w", 1.0, "s", better="faster")
    assert figure("k", "w", float("nan"), "s")["ours"] is None


def _run(figs, status="ok"):
    r = run_all.BenchRun(name="b", script=run_all.HERE / "bench_b.py", args=[], status=status)
    r.result = _payload(figs) if status == "ok" else None
    return r


def test_summary_ratio_and_verdicts():
    rows = run_all.summary_rows([_run([
        # time: ratio is peer / ours; 2 ms against 6 ms is 3x; target 3 ms met
        figure("t", "time", 2.0, "ms", peer="peer", peer_value=6.0, target=3.0),
        # rate: ratio is ours / peer; 50 against 100 is 0.5x; target 80 not met
        figure("r", "rate", 50.0, "1/s", better="higher", peer="peer", peer_value=100.0,
               target=80.0),
        figure("m", "missing peer", 1.0, "s", peer="galsim", peer_status="not installed"),
    ])])
    assert rows[0][5] == "3.00x" and rows[0][7] == "yes"
    assert rows[1][5] == "0.50x" and rows[1][7] == "**no**"
    assert rows[2][4] == "not installed" and rows[2][5] == ""
    quick = run_all.summary_rows([_run([figure("t", "time", 2.0, "ms", target=3.0)])], quick=True)
    assert quick[0][7] == "yes (quick)"
    failed = run_all.summary_rows([_run([], status="failed (exit 1)")])
    assert failed[0][1] == "failed (exit 1)"


def _script(tmp_path, name, body):
    p = tmp_path / f"bench_{name}.py"
    p.write_text(textwrap.dedent(body))
    return p


def test_run_one_statuses(tmp_path):
    ok = _script(tmp_path, "ok", f"""
        import json, sys
        assert sys.argv[1:] == ["--quick"]      # the flag reaches a script that has it
        print("table")
        print({RESULT_PREFIX!r} + json.dumps({{"bench": "ok", "figures": []}}))
        # add_quick_flag(
    """)
    r = run_all.run_one("ok", ok, quick=True, timeout_s=60)
    assert r.status == "ok" and r.result["bench"] == "ok" and r.load_after is not None

    plain = _script(tmp_path, "plain", """
        import sys
        assert sys.argv[1:] == []
        print("a table but no machine-readable line")
    """)
    r = run_all.run_one("plain", plain, quick=True, timeout_s=60)
    assert r.status == "no RESULT line" and r.notes          # noted: ran with its defaults

    bad = _script(tmp_path, "bad", "raise SystemExit(3)\n")
    assert run_all.run_one("bad", bad, quick=False, timeout_s=60).status == "failed (exit 3)"

    slow = _script(tmp_path, "slow", "import time\ntime.sleep(30)\n")
    assert run_all.run_one("slow", slow, quick=False, timeout_s=1).status.startswith("timed out")


def test_page_has_every_benchmark_block_and_no_result_lines(tmp_path):
    import datetime as dt

    good = _run([figure("t", "time", 2.0, "ms", peer="peer", peer_value=6.0, target=3.0,
                        target_source="project target")])
    good.name = "render"                                      # a benchmark with template text
    good.stdout = "machine: x\n| a table |\n" + RESULT_PREFIX + json.dumps(good.result) + "\n"
    bad = run_all.BenchRun(name="extra", script=tmp_path / "bench_extra.py", args=[],
                           status="failed (exit 1)", stderr="Traceback\nValueError: boom\n")
    (tmp_path / "bench_extra.py").write_text('"""An extra benchmark.\n\nMore words."""\n')
    now = dt.datetime.now(dt.timezone.utc)
    page = run_all.render_page([good, bad], quick=True, only=None, started=now, finished=now,
                               command="python benchmarks/run_all.py --quick")
    assert not any(ln.startswith(RESULT_PREFIX) for ln in page.splitlines())
    assert "| a table |" in page and "ValueError: boom" in page
    assert "An extra benchmark." in page                      # docstring as its explanation
    assert "## Simulator: rendering" in page
    assert "Smoke run" in page and "<= 3 ms (project target)" in page
    assert page.count("```text") == 3                        # two outputs, one stderr tail


@pytest.mark.parametrize("name", ["bench_harmonics", "bench_sweep", "run_all"])
def test_scripts_run_as_a_file_and_as_a_module(tmp_path, name):
    # the two ways the README and run_all start a script; --help/--list touch only the
    # shared header and _common (these scripts import the project inside main()). As a
    # file from another folder and without PYTHONPATH: the header alone finds the package.
    flag = "--list" if name == "run_all" else "--help"
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    as_file = subprocess.run([sys.executable, str(run_all.HERE / f"{name}.py"), flag], cwd=tmp_path,
                             env=env, capture_output=True, text=True, timeout=60)
    assert as_file.returncode == 0, as_file.stderr
    as_module = subprocess.run([sys.executable, "-m", f"benchmarks.{name}", flag], cwd=run_all.ROOT,
                               env=env, capture_output=True, text=True, timeout=60)
    assert as_module.returncode == 0, as_module.stderr
    assert as_file.stdout == as_module.stdout


def test_readme_block_takes_the_main_job_time_from_the_runner():
    run = run_all.BenchRun(name="runner", script=run_all.HERE / "bench_runner.py", args=[], status="ok")
    run.result = _payload([figure("two_workers_s", "w", 27.4, "s"), figure("fixed_cost_warm_s", "w", 1.5, "s"),
                           figure("fixed_cost_cold_s", "w", 6.0, "s")]) | {"trials": 200}
    sentence = run_all.readme_main_job([run], date="2026-11-25")
    # 27.4 s warm; first run 27.4 + (6.0 - 1.5) = 31.9 s
    assert sentence.startswith("200 trials: 27 s on 2 cores, the report aside, about 32 s the first time")
    assert "docs/benchmarks.md#bench-runner" in sentence and "2026-11-25" in sentence
    assert run_all.readme_main_job([_run([])]) is None
    text = f"a {run_all.README_BEGIN}old{run_all.README_END} b"
    assert run_all.rewrite_block(text, "new") == f"a {run_all.README_BEGIN}new{run_all.README_END} b"
    with pytest.raises(ValueError):
        run_all.rewrite_block("no markers", "new")


def test_the_readme_carries_the_generated_block_once():
    text = (run_all.ROOT / "README.md").read_text(encoding="utf-8")
    run_all.rewrite_block(text, "x")  # raises when the markers are missing or doubled


@pytest.mark.parametrize("path", sorted(run_all.HERE.glob("bench_*.py")), ids=lambda p: p.stem)
def test_every_benchmark_imports(path):
    # a benchmark that cannot import fails only when run_all runs it; importing it (its
    # module-level imports of the project included, main() not run) catches a renamed or
    # removed name in the test suite instead
    import importlib

    importlib.import_module(f"benchmarks.{path.stem}")
