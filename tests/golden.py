"""Figures recorded from an earlier commit, compared with a tolerance that follows from the
computation.

A recorded figure is the result of a trial or a validation: up to about 1e6
floating-point operations. The same code with another numpy (or on another CPU) may round
some of them differently without any defect: numpy picks its SIMD kernels for sums, exp,
sin... by CPU and version, and each operation rounds to within half a unit in the last
place (1.1e-16 relative). Summed over 1e6 operations that is at most about 1e-10
relative, so figures are compared to a relative 1e-9; figures that are zero or a
difference of nearly equal numbers are compared to an absolute floor of a few last bits
of the inputs they are computed from, in their own unit (each test states its floor).
Measured: with numpy's AVX2 and AVX-512 kernels disabled (``NPY_DISABLE_CPU_FEATURES=
"X86_V3 X86_V4 AVX512_ICL"``) the recorded figures of the star camera, the inductosyn, the
scan mirror and the line camera moved by at most 1.2e-11 relative and 5e-13 absolute,
and a change of the computation (another random stream, another model) moves them by
1e-4 relative or more.

Where bit identity is itself the property under test (the same results on one and two
workers, the same pixels whatever the thread count, two routes through the same
operations in the same order) the tests compare exactly: that is a property of this
code, not of the toolchain.
"""

from __future__ import annotations

import math

#: relative tolerance of a recorded figure (about 1e6 operations of 1.1e-16 each, times 10)
REL = 1e-9


def assert_close_to_recorded(got: dict, recorded: dict, *, abs_floor: float) -> None:
    """Every key of ``recorded`` is in ``got`` and within :data:`REL` relative or
    ``abs_floor`` absolute of its recorded value (NaN matches NaN); the keys match."""
    assert set(got) == set(recorded), sorted(set(got) ^ set(recorded))
    off = [(k, got[k], v) for k, v in recorded.items() if not _close(got[k], v, abs_floor)]
    assert not off, "moved from the recorded figures (key, now, recorded): " + repr(off[:10])


def _close(a, b, abs_floor: float) -> bool:
    if a is None or b is None:
        return a is b
    if isinstance(b, (list, tuple)):
        return isinstance(a, (list, tuple)) and len(a) == len(b) and all(
            _close(x, y, abs_floor) for x, y in zip(a, b))
    if isinstance(b, dict):
        return isinstance(a, dict) and set(a) == set(b) and all(_close(a[k], b[k], abs_floor) for k in b)
    if isinstance(b, float) or isinstance(a, float):
        if math.isnan(b):
            return math.isnan(a)
        return math.isclose(a, b, rel_tol=REL, abs_tol=abs_floor)
    return a == b
