"""The error types of a user's mistake or of the machine's limits, shared by every module.

Each is one line (or a few) that the command line prints as ``error: ...`` with exit status 2
(:func:`simcam.infra.cli.run_cli`), or, for :class:`Interrupted`, ``interrupted (SIGNAL)`` with
status 128 + signal. Only the standard library is imported, so an estimator that raises
:class:`UserInputError` imports neither click nor the command line.
"""

from __future__ import annotations

import signal

__all__ = ["Interrupted", "ResourceLimitError", "ScenarioError", "UserInputError", "WorkersLost"]

#: exit status of a command whose workers were lost (a killed local worker, a Dask cluster
#: without workers): the run stopped; what was finished is kept where the command resumes
WORKERS_LOST_STATUS = 3


class ScenarioError(ValueError):
    """A scenario (or sweep, or manifest) file is invalid.

    The message names the file (when known), the dotted field path and what is wrong,
    one line per problem, so the CLI can print it without a traceback.
    """


class UserInputError(ValueError):
    """Bad user input other than a scenario (a frame directory, a manifest, a table)."""


class ResourceLimitError(ValueError):
    """A request needs more disk or memory than there is (message: figure and limit)."""


class WorkersLost(RuntimeError):
    """The processes running a command's tasks are gone: a local worker killed (``kill -9``,
    the kernel's out-of-memory killer), or every worker of a Dask cluster lost, or the
    scheduler itself. The message is one line naming what was lost; the command line
    prints it as ``error: ...`` and exits with :data:`WORKERS_LOST_STATUS` (3): not a user
    mistake (2), not an interruption (128 + signal)."""


class Interrupted(BaseException):
    """The run was stopped by a signal (SIGINT, SIGTERM, SIGHUP).

    A :class:`BaseException` like :class:`KeyboardInterrupt`, so ``except Exception``
    does not swallow it while ``finally`` and ``except BaseException`` clean-up runs.

    Attributes
    ----------
    signum : int
        The signal number; the command exits with status ``128 + signum``.
    """

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = int(signum)

    @property
    def exit_status(self) -> int:
        """Shell convention: 128 + the signal number (130 for SIGINT, 143 for SIGTERM)."""
        return 128 + self.signum

    @property
    def name(self) -> str:
        """The signal's name, e.g. ``SIGTERM``."""
        try:
            return signal.Signals(self.signum).name
        except ValueError:
            return f"signal {self.signum}"
