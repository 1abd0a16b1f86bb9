"""The one rule by which reports write a number of any magnitude: :func:`fmt`.

Every report-writing site (the runner's table and findings, robustness summaries, the plan's
answer, sweep pages, the studies' captions and likely causes) renders an estimate, a bias, a
truth, a ratio or a condition number through :func:`fmt`, so one number reads the same
wherever it is printed:

* ``digits`` significant digits (4 unless the site asks for fewer), trailing zeros dropped;
* fixed notation for magnitudes in ``[1e-3, 1e5)`` (after rounding), never an exponent there;
* scientific notation outside it, with the same significant digits: ``1.5e+05``, ``2.35e-04``;
* ``"n/a"`` for a missing (``None``) or non-finite value; zero as ``0``;
* ``sign=True`` writes a ``+`` before a positive number (biases, differences).

A number in a fixed unit at a known resolution (``0.123 px``, ``45 %``) keeps its fixed
decimals at its site (``:.3f``, ``:.0f``); an error message keeps whatever its check needs.

Lives beside the runner's report modules, apart from :mod:`budget.runner.findings`, because
figure captions and sweep pages use it without the findings' rules; standard library only, so
any module of ``budget`` may import it.
"""

from __future__ import annotations

import math

__all__ = ["fmt"]

#: the smallest magnitude written in fixed notation (as a power of ten)
_FIXED_MIN_EXP = -3
#: the first magnitude written in scientific notation (as a power of ten)
_FIXED_END_EXP = 5


def fmt(value, digits: int = 4, *, sign: bool = False) -> str:
    """``value`` for a report: ``digits`` significant digits, fixed in ``[1e-3, 1e5)``,
    scientific outside (module docstring); ``"n/a"`` for None, NaN or an infinity."""
    if isinstance(digits, bool) or not isinstance(digits, int) or digits < 1:
        raise ValueError(f"digits: a whole number of significant digits >= 1, got {digits!r}")
    if value is None:
        return "n/a"
    v = float(value)
    if not math.isfinite(v):
        return "n/a"
    plus = "+" if sign else ""
    if v == 0:
        return f"{v:{plus}g}"
    mantissa, exponent = f"{v:{plus}.{digits - 1}e}".split("e")
    e = int(exponent)
    if not _FIXED_MIN_EXP <= e < _FIXED_END_EXP:
        return _trim(mantissa) + "e" + exponent
    if e < digits:  # rounds at the same decimal place as the mantissa above
        return _trim(f"{v:{plus}.{digits - 1 - e}f}")
    # more integer digits than significant ones: the mantissa's digits, then zeros
    head = mantissa[0] if mantissa[0] in "+-" else ""
    return head + mantissa.lstrip("+-").replace(".", "") + "0" * (e - digits + 1)


def _trim(number: str) -> str:
    """Trailing zeros (and a bare point) of a decimal fraction dropped."""
    return number.rstrip("0").rstrip(".") if "." in number else number
