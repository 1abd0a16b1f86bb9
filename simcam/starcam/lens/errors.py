"""Errors and warnings of the lens package."""

from __future__ import annotations

from simcam.infra.errors import ScenarioError

__all__ = ["LensBackendWarning", "LensError"]


class LensError(ScenarioError):
    """A lens prescription (or a request made of it) is invalid.

    The message names the file (when known) and the surface, glass or setting at fault,
    e.g. ``lens.toml: surfaces.3.glass: unknown glass 'N-BK8' (did you mean N-BK7?)``.
    It derives from :class:`simcam.infra.errors.ScenarioError`, so the command lines
    print it as ``error: ...`` without a traceback.
    """


class LensBackendWarning(UserWarning):
    """The vectorised (llvm) Mitsuba variant is unavailable: tracing falls back to scalar."""
