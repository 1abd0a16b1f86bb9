"""The arguments of the Python API and the values of the study commands, checked at the entry.

:func:`budget.validate`, :func:`budget.robustness`, :func:`budget.plan` and
:func:`budget.sweep` call :func:`check_arguments` with their arguments before any work, and
the study commands (``validate``, ``robustness``, ``plan``) check their option values the
same way (:func:`checked_command`). One function per kind of argument; each mistake is one
line naming the argument and what it must be:

* a wrong type (``trials=2.5``, ``'10'``, ``workers='2'``, ``require=5``, ``out=5``,
  ``scenario=123``) is an :class:`ArgumentTypeError`, both a
  :class:`~simcam.infra.errors.UserInputError` and a :class:`TypeError`;
* a value out of its range (``seed=-1``, ``workers=0``) is a
  :class:`~simcam.infra.errors.UserInputError`, and so is a number of trials whose results
  cannot fit in memory (the runner's per-trial floor, checked before any truth is computed).

``seed=None`` is refused: a run is reproduced from its seed, so the API asks for an int.
Only the standard library and :mod:`simcam.infra` are imported (``import budget`` stays light).
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Callable, Mapping
from functools import wraps
from typing import Any

from budget.runner.registry import get_study, study_names
from budget.runner.study import Study
from simcam.infra.errors import UserInputError
from simcam.infra.lifecycle import SAFETY_FRACTION, available_memory_bytes, format_bytes

__all__ = [
    "ArgumentTypeError", "check_arguments", "check_confidence", "check_fix", "check_flag", "check_out",
    "check_path", "check_positive_number", "check_require", "check_scenario", "check_seed", "check_study",
    "check_trials", "check_variant", "check_workers", "checked_command",
]

#: the largest seed: numpy's SeedSequence takes any non-negative int, a 64-bit one is plenty
MAX_SEED = 2**63 - 1
#: memory each trial's results take at least (the runner's estimate,
#: :func:`budget.runner.run.run_study`: 300 bytes a trial before its values)
TRIAL_BYTES = 300


class ArgumentTypeError(UserInputError, TypeError):
    """An argument of the wrong type: a :class:`TypeError` that the command line prints as
    one ``error:`` line (a :class:`~simcam.infra.errors.UserInputError`)."""


def _shown(name: str, value: Any, cli: bool) -> str:
    """``trials=2.5`` (the API) or ``--trials 2.5`` (a command's option)."""
    return f"--{name.replace('_', '-')} {value}" if cli else f"{name}={value!r}"


def _is_int(value: Any) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def check_trials(value: Any, name: str = "trials", *, cli: bool = False) -> None:
    """None (the scenario's own), or an int of at least 2 whose results fit in memory."""
    if value is None:
        return
    if not _is_int(value):
        raise ArgumentTypeError(f"{_shown(name, value, cli)}: the number of trials must be an int (e.g. 200), "
                                f"not {type(value).__name__}")
    if value < 2:
        raise UserInputError(f"{_shown(name, value, cli)}: must be at least 2 (a spread needs two trials)")
    avail = available_memory_bytes()
    if avail is not None and float(value) * TRIAL_BYTES > SAFETY_FRACTION * avail:
        most = int(SAFETY_FRACTION * avail // TRIAL_BYTES)
        raise UserInputError(f"{_shown(name, value, cli)}: needs about {format_bytes(float(value) * TRIAL_BYTES)} "
                             f"of memory, {format_bytes(avail)} available (at least {TRIAL_BYTES} bytes a trial): "
                             f"at most {most} trials fit")


def check_seed(value: Any, name: str = "seed", *, cli: bool = False) -> None:
    """An int in [0, 2**63 - 1]; None is refused (a run is reproduced from its seed)."""
    if value is None:
        raise ArgumentTypeError(f"{_shown(name, value, cli)}: pass an int (e.g. 0); the seed makes the run "
                                "reproducible (the same seed gives the same figures), so it is never drawn")
    if not _is_int(value):
        raise ArgumentTypeError(f"{_shown(name, value, cli)}: the seed must be an int, not {type(value).__name__}")
    if not 0 <= value <= MAX_SEED:
        raise UserInputError(f"{_shown(name, value, cli)}: must be in [0, 2**63 - 1]")


def check_workers(value: Any, name: str = "workers", *, cli: bool = False) -> None:
    """None (all cores) or an int of at least 1."""
    if value is None:
        return
    if not _is_int(value):
        raise ArgumentTypeError(f"{_shown(name, value, cli)}: the number of worker processes must be an int "
                                f"(e.g. 2), not {type(value).__name__}")
    if value < 1:
        raise UserInputError(f"{_shown(name, value, cli)}: must be at least 1")


def check_positive_number(value: Any, name: str, *, cli: bool = False, what: str = "a number") -> None:
    """None, or a finite number > 0 (``tolerance``, ``budget_hours``)."""
    if value is None:
        return
    if not _is_number(value):
        raise ArgumentTypeError(f"{_shown(name, value, cli)}: must be {what} > 0, not {type(value).__name__}")
    if not (math.isfinite(value) and value > 0):
        raise UserInputError(f"{_shown(name, value, cli)}: must be a finite number > 0 ({what})")


def check_confidence(value: Any, name: str = "confidence", *, cli: bool = False) -> None:
    """A probability in [0.5, 1) (``confidence``, ``sure``)."""
    if not _is_number(value):
        raise ArgumentTypeError(f"{_shown(name, value, cli)}: must be a number in [0.5, 1) (e.g. 0.95), "
                                f"not {type(value).__name__}")
    if not 0.5 <= value < 1.0:
        raise UserInputError(f"{_shown(name, value, cli)}: must be in [0.5, 1)")


def check_flag(value: Any, name: str, *, cli: bool = False) -> None:
    """True, False or None (``progress``: None is "on a terminal")."""
    if value is not None and not isinstance(value, bool):
        raise ArgumentTypeError(f"{_shown(name, value, cli)}: must be True or False, not {type(value).__name__}")


def check_require(value: Any, name: str = "require", *, cli: bool = False) -> None:
    """A requirement text ``CLASS.AXIS<=VALUE`` or a list or tuple of them (or of the
    planner's ``Requirement`` objects); the texts themselves are parsed by the planner."""
    if isinstance(value, str):
        return
    if isinstance(value, (list, tuple)) and all(isinstance(r, str) or hasattr(r, "bound") for r in value):
        return
    raise ArgumentTypeError(f"{_shown(name, value, cli)}: must be a requirement text 'CLASS.AXIS<=VALUE' or a "
                            f"list of them, not {type(value).__name__}")


def check_variant(value: Any, name: str = "variant", *, cli: bool = False) -> None:
    """None (the study's default) or a variant's name."""
    if value is not None and not isinstance(value, str):
        raise ArgumentTypeError(f"{_shown(name, value, cli)}: must be a variant's name (e.g. 'improved'), "
                                f"not {type(value).__name__}")


def check_fix(value: Any, name: str = "fix", *, cli: bool = False) -> None:
    """None, a mapping ``{field: value}``, or a list or tuple of texts ``FIELD=VALUE``."""
    if value is None or isinstance(value, Mapping):
        return
    if isinstance(value, (list, tuple)) and all(isinstance(f, str) for f in value):
        return
    raise ArgumentTypeError(f"{_shown(name, value, cli)}: must be a mapping {{field: value}} or a list of "
                            f"'FIELD=VALUE' texts, not {type(value).__name__}")


def check_path(value: Any, name: str, *, cli: bool = False, what: str = "file") -> None:
    """A path: a ``str`` or an ``os.PathLike`` (not bytes, not a number)."""
    if isinstance(value, bytes) or not isinstance(value, (str, os.PathLike)):
        raise ArgumentTypeError(f"{_shown(name, value, cli)}: the {what} must be a path (str or pathlib.Path), "
                                f"not {type(value).__name__}")


def check_out(value: Any, name: str = "out", *, cli: bool = False) -> None:
    """The sweep store's folder: a path."""
    check_path(value, name, cli=cli, what="sweep store's folder")


def check_study(value: Any, name: str = "study") -> Any:
    """A registered study's name or a :class:`~budget.runner.study.Study`; returns the study."""
    if isinstance(value, Study):
        return value
    if isinstance(value, str):
        return get_study(value)
    raise ArgumentTypeError(f"{name}={value!r}: a registered study's name ({', '.join(study_names())}) or a "
                            f"Study, not {type(value).__name__}")


def check_scenario(value: Any, study: Any, name: str = "scenario") -> None:
    """None (the embedded default), a path (str or ``os.PathLike``), a mapping, or a model of
    ``study``'s own scenario type (not bytes, a number, a list, or another study's model)."""
    if value is None or isinstance(value, Mapping):
        return
    if isinstance(value, (str, os.PathLike)) and not isinstance(value, bytes):
        return
    model = type(study.load_scenario())
    if isinstance(value, model):
        return
    kind = type(value).__name__
    if hasattr(value, "model_dump"):  # another study's (or another kind of) model
        raise ArgumentTypeError(f"{name}: a {kind} is not a scenario of the {study.name} study; pass a "
                                f"{model.__name__}, a path to its TOML file or a mapping")
    raise ArgumentTypeError(f"{name}={value!r}: must be None (the embedded default), a path (str or "
                            f"pathlib.Path), a mapping or a {model.__name__}, not {kind}")


#: the checker of each argument (and command option) by its name
_CHECKS: dict[str, Callable[..., None]] = {
    "trials": check_trials, "seed": check_seed, "workers": check_workers,
    "tolerance": lambda v, n, cli=False: check_positive_number(v, n, cli=cli, what="a tolerance in the classes' unit"),
    "budget_hours": lambda v, n, cli=False: check_positive_number(v, n, cli=cli, what="lab hours"),
    "confidence": check_confidence, "sure": check_confidence, "progress": check_flag,
    "require": check_require, "variant": check_variant, "fix": check_fix,
    "out": check_out, "sweep_file": lambda v, n, cli=False: check_path(v, n, cli=cli, what="sweep file"),
}


def check_arguments(arguments: Mapping[str, Any], *, cli: bool = False) -> None:
    """Check every argument of ``arguments`` (a facade's ``locals()``, or a command's option
    values with ``cli=True``) whose name has a checker; ``study`` first, then ``scenario``
    against it. Raises the first mistake found."""
    study = check_study(arguments["study"]) if "study" in arguments and not cli else None
    if study is not None and "scenario" in arguments:
        check_scenario(arguments["scenario"], study)
    for name, value in arguments.items():
        if name in _CHECKS:
            _CHECKS[name](value, name, cli=cli)


def checked_command(command):
    """``command`` (a click command) whose option values are checked by
    :func:`check_arguments` before its callback runs: the same checks as the API's, in the
    option's spelling (``--trials 1000000000000``). None stays None."""
    if command is None or command.callback is None:
        return command
    callback = command.callback

    @wraps(callback)
    def checked(**values):
        check_arguments(values, cli=True)
        return callback(**values)

    command.callback = checked
    return command
