"""Bad input, round three (issue #35): the Python API validates like the command line.

Every argument of :func:`budget.validate`, :func:`budget.robustness`, :func:`budget.plan` and
:func:`budget.sweep` is checked at the entry (:mod:`budget.arguments`): one line naming the
argument and what it must be, before any work (the runner is never reached). The study
commands check their option values the same way.
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest

import budget
from budget.arguments import ArgumentTypeError, check_arguments
from simcam.infra.errors import UserInputError


@pytest.fixture(autouse=True)
def no_work(monkeypatch):
    """Any run reaching the runner, the robustness cases, the planner or a sweep fails the test."""
    import budget.runner.plan
    import budget.runner.robustness
    import budget.runner.run
    import budget.sweeps.run

    def reached(*a, **k):
        raise AssertionError("the work started: the argument was not checked at the entry")

    monkeypatch.setattr(budget.runner.run, "run_study", reached)
    monkeypatch.setattr(budget.runner.robustness, "run_robustness", reached)
    monkeypatch.setattr(budget.runner.plan, "plan_protocol", reached)
    monkeypatch.setattr(budget.sweeps.run, "run_sweep", reached)


def _whiskbroom_model():
    from budget.runner.registry import get_study

    return get_study("whiskbroom").load_scenario()


@pytest.mark.parametrize("call,kwargs,named,is_type", [
    ("validate", {"trials": 2.5}, "trials=2.5: the number of trials must be an int", True),
    ("validate", {"trials": "10"}, "trials='10': the number of trials must be an int", True),
    ("plan", {"trials": 20.7}, "trials=20.7: the number of trials must be an int", True),  # was truncated to 20
    ("validate", {"trials": True}, "trials=True: the number of trials must be an int", True),
    ("validate", {"workers": "2"}, "workers='2': the number of worker processes must be an int", True),
    ("validate", {"workers": 1.5}, "workers=1.5: the number of worker processes must be an int", True),
    ("robustness", {"workers": 0}, "workers=0: must be at least 1", False),
    ("plan", {"confidence": None}, "confidence=None: must be a number in [0.5, 1)", True),
    ("plan", {"sure": 1.0}, "sure=1.0: must be in [0.5, 1)", False),
    ("plan", {"require": 5}, "require=5: must be a requirement text 'CLASS.AXIS<=VALUE'", True),
    ("plan", {"fix": 3}, "fix=3: must be a mapping {field: value} or a list of 'FIELD=VALUE' texts", True),
    ("plan", {"budget_hours": float("nan")}, "budget_hours=nan: must be a finite number > 0", False),
    ("validate", {"seed": None}, "seed=None: pass an int (e.g. 0); the seed makes the run reproducible", True),
    ("plan", {"seed": -1}, "seed=-1: must be in [0, 2**63 - 1]", False),  # was: five truths, then "no protocol"
    ("validate", {"seed": 2.0}, "seed=2.0: the seed must be an int", True),
    ("plan", {"trials": 10**12}, "trials=1000000000000: needs about 272.8 TiB of memory", False),
    ("validate", {"tolerance": -1.0}, "tolerance=-1.0: must be a finite number > 0", False),
    ("validate", {"progress": "yes"}, "progress='yes': must be True or False", True),
    ("validate", {"scenario": 123}, "scenario=123: must be None (the embedded default), a path", True),
    ("validate", {"scenario": [1, 2]}, "scenario=[1, 2]: must be None", True),
    ("validate", {"scenario": b"x.toml"}, "scenario=b'x.toml': must be None", True),
    ("validate", {"scenario": "MODEL"}, "scenario: a WhiskbroomScenario is not a scenario of the scanmirror study", True),
])
def test_api_arguments_are_checked_at_the_entry_naming_the_argument(call, kwargs, named, is_type):
    if kwargs.get("scenario") == "MODEL":
        kwargs = {"scenario": _whiskbroom_model()}
    with pytest.raises(UserInputError) as ei:
        getattr(budget, call)("scanmirror", **kwargs)
    msg = str(ei.value)
    assert "\n" not in msg and named in msg, msg
    assert isinstance(ei.value, TypeError) is is_type and isinstance(ei.value, ArgumentTypeError) is is_type


def test_sweep_and_study_arguments(tmp_path):
    with pytest.raises(ArgumentTypeError, match=r"^out=5: the sweep store's folder must be a path"):
        budget.sweep(tmp_path / "s.toml", out=5)
    with pytest.raises(ArgumentTypeError, match=r"^sweep_file=None: the sweep file must be a path"):
        budget.sweep(None, tmp_path / "st")
    with pytest.raises(ArgumentTypeError, match=r"^workers=1.5"):
        budget.sweep(tmp_path / "s.toml", tmp_path / "st", workers=1.5)
    with pytest.raises(TypeError, match=r"^study=3: a registered study's name"):
        budget.validate(3)
    with pytest.raises(UserInputError, match="unknown study 'nope'"):
        budget.validate("nope")


def test_good_arguments_pass_and_command_values_use_the_option_spelling():
    check_arguments({"study": "scanmirror", "scenario": None, "trials": 20, "seed": 0, "workers": None,
                     "tolerance": None, "progress": False})
    check_arguments({"study": "scanmirror", "scenario": Path("s.toml"), "require": ("a.x<=1",), "fix": {"k": 1},
                     "confidence": 0.95, "sure": 0.5, "budget_hours": 2, "variant": None})
    check_arguments({"trials": None, "seed": 3, "progress": None, "json_out": "x"}, cli=True)  # unknown: skipped
    with pytest.raises(UserInputError, match=r"^--trials 1000000000000: needs about .* of memory"):
        check_arguments({"trials": 10**12}, cli=True)
    with pytest.raises(UserInputError, match=r"^--budget-hours inf: must be a finite number > 0"):
        check_arguments({"budget_hours": float("inf")}, cli=True)


def test_plan_with_a_trillion_trials_is_refused_before_any_truth():
    """``budget <study> plan --trials 1000000000000`` computed five truths, then said "no
    protocol could be run"; now the option is refused before the scenario is even loaded."""
    from budget.cli import main

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()), pytest.raises(SystemExit) as ei:
        main(["scanmirror", "plan", "--trials", "1000000000000", "--require", "ground_max.lat<=0.1"])
    lines = err.getvalue().splitlines()
    assert ei.value.code == 2 and len(lines) == 1, lines
    assert lines[0].startswith("error: --trials 1000000000000: needs about") and "of memory" in lines[0]
