"""How a plan writes lab time, knob settings and shares in its words: the progress lines, the
findings and report, the recommended scenario's header."""

from __future__ import annotations

from budget.runner.numbers import fmt
from simcam.units import SECONDS_PER_HOUR

__all__ = ["knobs_text", "lab_time_text", "number_text", "percent_text"]


def lab_time_text(s: float) -> str:
    """Lab time ``s`` (seconds) for prose: hours from 0.1 h, minutes below (``0.343 h``, ``5.2 min``)."""
    return f"{fmt(s / SECONDS_PER_HOUR, 3)} h" if s >= 360 else f"{fmt(s / 60, 3)} min"


def number_text(v) -> str:
    """A knob's value for prose: a whole number as it is, a real one to 4 significant digits."""
    return f"{v:d}" if isinstance(v, int) else fmt(v)


def knobs_text(knobs: dict) -> str:
    """``frames 100, positions 4``: each knob by its last name, by its dotted field where two
    knobs share a last name (``te.frames 10, distortion.frames 20``)."""
    last = [f.rsplit(".", 1)[-1] for f in knobs]
    return ", ".join(f"{f if last.count(n) > 1 else n} {number_text(v)}"
                     for f, n, v in zip(knobs, last, knobs.values()))


def percent_text(p: float) -> str:
    """``0.95`` -> ``"95 %"``."""
    return f"{100 * p:.0f} %"
