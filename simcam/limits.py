"""Checks shared by the scenario models of the newer studies: epochs parsed when
the scenario loads, every number finite.

Kept apart from :mod:`simcam.config_base` so that the models only gain a validator line.
"""

from __future__ import annotations

import math
from datetime import datetime

__all__ = ["check_epoch_utc", "nonfinite_fields"]


def check_epoch_utc(value: str) -> str:
    """``value`` if it is an ISO 8601 UTC time (``2025-06-01T00:00:00``); else ValueError
    with one line (not astropy's multi-line list of every format it tried).

    Python's :meth:`datetime.fromisoformat` is tried first (fast, no astropy import);
    what it refuses is tried with astropy's ``Time(value, scale="utc")``, which also
    reads a leap second (``23:59:60``).
    """
    if not isinstance(value, str) or not value.strip():
        raise ValueError("not an ISO UTC time (e.g. 2025-06-01T00:00:00)")
    try:
        datetime.fromisoformat(value)
        return value
    except ValueError:
        pass
    try:
        from astropy.time import Time

        Time(value, scale="utc", format="isot")
    except Exception:  # noqa: BLE001 - astropy raises several kinds, all mean "not a time"
        raise ValueError("not an ISO UTC time (e.g. 2025-06-01T00:00:00)") from None
    return value


def nonfinite_fields(model, prefix: str = "") -> list[str]:
    """Dotted paths of the float fields of a pydantic model (nested models, lists and
    tuples included) that are NaN or infinite, each as ``path: must be a finite number (got inf)``."""
    from pydantic import BaseModel

    out: list[str] = []

    def walk(v, path):
        if isinstance(v, BaseModel):
            for name in type(v).model_fields:
                walk(getattr(v, name), f"{path}.{name}" if path else name)
        elif isinstance(v, (list, tuple)):
            for i, x in enumerate(v):
                walk(x, f"{path}[{i}]")
        elif isinstance(v, dict):
            for k, x in v.items():
                walk(x, f"{path}.{k}")
        elif isinstance(v, float) and not math.isfinite(v):
            out.append(f"{path}: must be a finite number (got {v})")

    walk(model, prefix)
    return out
