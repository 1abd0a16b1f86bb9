"""The Python API (budget.validate, StudyResult's repr, _repr_html_, to_dataframe), from a
plain script without a __main__ guard in a subprocess, and the notebook of docs/api.md."""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import budget
from budget.runner.run import run_study
from toy_study import STUDY as TOY, Toy

ROOT = Path(__file__).resolve().parents[1]


def _env():
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    return env


@pytest.fixture(scope="module")
def toy():
    return budget.validate(TOY, Toy(trials=60), trials=60, seed=2, workers=1)


def test_validate_equals_the_runner(toy):
    ref = run_study(TOY, Toy(trials=60), trials=60, seed=2, workers=1)
    # as JSON text: a NaN (no percentage of a truth near zero) equals itself there
    assert json.dumps(toy.to_json()["classes"]) == json.dumps(ref.to_json()["classes"])


def test_scenario_as_dict_path_or_default(tmp_path):
    # a dict is validated by the study's from_dict, a path read as a file, None the default
    assert budget.validate(TOY, {"m": 4, "trials": 5}, seed=1, workers=1).trials == 5
    p = tmp_path / "toy.toml"
    p.write_text("m = 4\ntrials = 6\n")
    assert budget.validate(TOY, p, seed=1, workers=1).trials == 6
    with pytest.raises(TypeError):
        budget.validate(3)


def test_repr_is_short_and_html_shows_findings(toy):
    r = repr(toy)
    assert r.startswith("<StudyResult toy") and "\n" not in r and len(r) < 400
    h = toy._repr_html_()
    assert "Findings" in h and "<pre>" in h and "array(" not in h


def test_to_dataframe_is_tidy(toy):
    df = toy.to_dataframe()
    assert list(df.columns) == ["class", "axis", "variant", "statistic", "value", "unit"]
    assert not df.duplicated(["class", "axis", "variant", "statistic"]).any()
    st = toy.statistics(("variance", "published", "a"))
    row = df[(df["class"] == "variance") & (df.variant == "published") & (df.statistic == "bias")]
    assert row.value.item() == st["bias"]
    assert set(df.unit) == {""}  # the toy's unit "1": dimensionless, never printed as "1"


def test_plain_script_without_main_guard_runs_on_worker_processes(tmp_path):
    """Spawned workers used to re-run the script (BrokenProcessPool and a long traceback);
    the API starts them without the main module. A registered study (whiskbroom, the
    quickest), 2 workers, 4 trials."""
    script = tmp_path / "plain.py"
    script.write_text(textwrap.dedent("""
        import json, budget
        res = budget.validate("whiskbroom", trials=4, workers=2)
        print("RESULT", json.dumps({"trials": res.trials, "executor": res.executor}))
    """))
    p = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path,
                       env=_env(), timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    line = [x for x in p.stdout.splitlines() if x.startswith("RESULT ")]
    assert len(line) == 1, p.stdout  # printed once: the workers did not re-run the script
    out = json.loads(line[0][7:])
    assert out == {"trials": 4, "executor": "2 local processes"}
    assert "Traceback" not in p.stderr


def test_notebook_example_runs(tmp_path):
    """docs/examples/api.ipynb: its code cells, in order, as one script in a subprocess (a
    notebook kernel is not a test dependency); the last expression of each cell evaluated."""
    nb = json.loads((ROOT / "docs" / "examples" / "api.ipynb").read_text())
    code = ["import ast as _ast"]
    for c in nb["cells"]:
        if c["cell_type"] == "code":
            src = "".join(c["source"])
            code.append(f"exec(compile({src!r}, 'cell', 'exec'))")
    script = tmp_path / "nb.py"
    script.write_text("\n".join(code) + "\nprint('NOTEBOOK OK')\n")
    p = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path,
                       env=_env(), timeout=600)
    assert p.returncode == 0 and "NOTEBOOK OK" in p.stdout, p.stderr[-3000:]


@pytest.mark.parametrize("start", ["spawn", "fork"])
def test_a_study_defined_in_an_unguarded_script(tmp_path, start):
    """Workers must import a script that defines the study. Spawned workers (forced here by
    a second thread, :func:`budget.runner.executors.start_method`) re-run a script without
    the guard and cannot start: the call ends with one line saying to add the guard or use
    workers=1. Forked workers (a fresh process on Linux) have the script's classes already
    and the call works."""
    if start == "fork" and not sys.platform.startswith("linux"):
        pytest.skip("workers fork on Linux only")
    src = (Path(__file__).parent / "toys" / "toy_study.py").read_text().replace("STUDY = ToyStudy()", "")
    script = tmp_path / "own_study.py"
    thread = ("import threading\nthreading.Thread(target=threading.Event().wait, daemon=True).start()\n"
              if start == "spawn" else "")
    script.write_text(src + "\nimport budget\n" + thread + textwrap.dedent("""
        res = budget.validate(ToyStudy(), Toy(), trials=20, workers=2)
        print("RESULT", res.trials)
    """))
    p = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path,
                       env=_env(), timeout=300)
    if start == "fork":
        assert p.returncode == 0 and "RESULT 20" in p.stdout, p.stderr[-3000:]
        return
    assert p.returncode != 0 and "RESULT" not in p.stdout
    last = p.stderr.strip().splitlines()[-1]
    assert last.startswith("RuntimeError: budget:") and 'if __name__ == "__main__":' in last and "workers=1" in last


def test_robustness_through_the_api_equals_the_runner_and_writes_html(tmp_path):
    from toy_world_study import ToyWorldStudy

    from budget.runner.robustness import run_robustness

    study = ToyWorldStudy()
    got = budget.robustness(study, trials=30, seed=5, workers=1)
    ref = run_robustness(study, study.load_scenario(), trials=30, seed=5, workers=1)
    a, b = got.to_json(), ref.to_json()
    a.pop("elapsed_s", None), b.pop("elapsed_s", None)
    assert json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)
    got.write_report(tmp_path / "rep")
    page = (tmp_path / "rep" / "report.html").read_text()
    assert page.startswith("<!DOCTYPE html>") and "<h1>" in page and "http" not in page


def test_the_cli_json_the_report_summary_and_the_api_payload_are_one(tmp_path, monkeypatch):
    """``validate --json``, the report's summary.json and ``to_json()`` of the result (what
    ``budget.validate`` returns) are the one payload of the result, built once; a caller's
    copy can be changed without changing it."""
    import contextlib
    import io

    from budget.runner.validate_cmd import run_and_write
    from budget.runner.result import StudyResult

    built = []
    summary = StudyResult.summary
    monkeypatch.setattr(StudyResult, "summary", lambda self: built.append(1) or summary(self))
    with contextlib.redirect_stdout(io.StringIO()):
        res = run_and_write(TOY, Toy(trials=20), trials=20, seed=4, workers=1, json_out=tmp_path / "out.json",
                            report_dir=tmp_path / "rep", progress=False)
    assert len(built) == 1  # the JSON file and the report's summary.json: one payload
    payload = json.dumps(res.to_json(), sort_keys=True)
    # the files as written (strict JSON: a NaN is null there)
    assert (tmp_path / "out.json").read_text() == (tmp_path / "rep" / "summary.json").read_text()
    from simcam.infra.cli import write_json_atomic

    write_json_atomic(tmp_path / "again.json", res.to_json())
    assert (tmp_path / "again.json").read_text() == (tmp_path / "out.json").read_text()
    assert len(built) == 1
    mine = res.to_json()
    mine["classes"].clear()
    assert json.dumps(res.to_json(), sort_keys=True) == payload
    api = budget.validate(TOY, Toy(trials=20), trials=20, seed=4, workers=1).to_json()
    cli = json.loads(payload)
    for p in (api, cli):
        p.pop("elapsed_s"), p.pop("executor")  # how long it took and where: not results
    assert json.dumps(api, sort_keys=True) == json.dumps(cli, sort_keys=True)
