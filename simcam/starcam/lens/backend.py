"""Choice of the Mitsuba 3 variant, and the libLLVM that its vectorised variant needs.

Mitsuba's ``llvm_ad_*`` variants JIT-compile through Dr.Jit's LLVM backend, which loads a
shared ``libLLVM`` when ``drjit`` is first imported: from ``DRJIT_LIBLLVM_PATH`` if set,
else from the system's library path. LLVM 14 is refused and LLVM 15-16 abort in some
kernels (see docs/lens.md); LLVM 19 or newer works. The PyPI package
``karellen-llvm-core`` (a dependency of simcam) ships ``libLLVM.so`` in the environment's
``lib`` directory; before importing ``drjit`` this module points ``DRJIT_LIBLLVM_PATH``
at it unless the user has set the variable. That wheel's ``libLLVM`` needs the libc++
it ships, whose ``.so.1`` links the wheel's ``.pth`` hook creates on the first interpreter
start; if they are missing, the ``.so.1.0`` files are preloaded instead (the dynamic
linker matches an already loaded library by its soname).

If no usable LLVM is found (or ``drjit`` was imported before this module could set the
path and found an old one), tracing falls back to the ``scalar_rgb`` variant with a
:class:`~simcam.starcam.lens.errors.LensBackendWarning`: correct, about 10 us per ray and surface.
"""

from __future__ import annotations

import ctypes
import glob
import os
import re
import sys
import warnings
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cache, lru_cache
from pathlib import Path

from simcam.starcam.lens.errors import LensBackendWarning, LensError

__all__ = [
    "MIN_LLVM_MAJOR",
    "SCALAR_VARIANT",
    "VECTOR_VARIANT",
    "Backend",
    "configure_libllvm",
    "find_libllvm",
    "get_backend",
    "in_variant",
]

#: Oldest LLVM major version that Dr.Jit 1.5 runs correctly with.
MIN_LLVM_MAJOR = 19
#: Mitsuba variant used for vectorised intersections.
VECTOR_VARIANT = "llvm_ad_rgb"
#: Fallback variant (one ray per call).
SCALAR_VARIANT = "scalar_rgb"
_VARIANTS = (VECTOR_VARIANT, SCALAR_VARIANT)


def _karellen_libllvm() -> Path | None:
    """``libLLVM.so`` installed by the ``karellen-llvm-core`` wheel, if any."""
    from importlib import metadata

    try:
        dist = metadata.distribution("karellen-llvm-core")
    except (ImportError, metadata.PackageNotFoundError, OSError, ValueError):  # absent or broken metadata
        return None
    found = {}
    for f in dist.files or ():
        name = Path(str(f)).name
        if name.startswith("libLLVM") and ".so" in name:
            p = Path(os.path.normpath(dist.locate_file(f)))
            if p.exists():
                found[name] = p
    for name in ("libLLVM.so", *sorted(found)):
        if name in found:
            return found[name]
    return None


def _llvm_major_from_name(path: str) -> int | None:
    m = re.search(r"libLLVM[-.]?(\d+)", Path(path).name) or re.search(r"\.so\.(\d+)", Path(path).name)
    return int(m.group(1)) if m else None


def _system_libllvm() -> Path | None:
    """Newest ``libLLVM-N.so`` with N >= MIN_LLVM_MAJOR in the usual system directories."""
    cands = []
    for pat in ("/usr/lib/x86_64-linux-gnu/libLLVM*.so*", "/usr/lib/aarch64-linux-gnu/libLLVM*.so*",
                "/usr/lib/llvm-*/lib/libLLVM*.so*", "/usr/lib64/libLLVM*.so*", "/usr/local/lib/libLLVM*.so*",
                "/opt/homebrew/opt/llvm/lib/libLLVM.dylib"):
        for p in glob.glob(pat):
            major = _llvm_major_from_name(p)
            if major is None:
                m = re.search(r"llvm-(\d+)", p)
                major = int(m.group(1)) if m else None
            if major is not None and major >= MIN_LLVM_MAJOR:
                cands.append((major, p))
    if not cands:
        return None
    return Path(max(cands)[1])


def _preload_libcxx(libllvm: Path) -> None:
    """Load the wheel's libc++/libc++abi/libunwind by their real files if the ``.so.1`` links are absent."""
    d = libllvm.parent / "x86_64-unknown-linux-gnu"
    if not d.is_dir():
        d = libllvm.parent
    for stem in ("libunwind", "libc++abi", "libc++"):
        if (d / f"{stem}.so.1").exists():
            continue
        real = d / f"{stem}.so.1.0"
        if real.exists():
            try:
                ctypes.CDLL(str(real), mode=ctypes.RTLD_GLOBAL)
            except OSError:  # not loadable here: the LLVM check below then falls back, with a warning
                pass


def find_libllvm() -> tuple[Path | None, str]:
    """A libLLVM >= 19 for Dr.Jit: the karellen-llvm-core wheel's, else the system's.

    Returns
    -------
    path : Path or None
    origin : str
        ``"karellen-llvm-core"``, ``"system"`` or ``"none"``.
    """
    p = _karellen_libllvm()
    if p is not None:
        return p, "karellen-llvm-core"
    p = _system_libllvm()
    if p is not None:
        return p, "system"
    return None, "none"


@lru_cache(maxsize=1)
def configure_libllvm() -> str:
    """Set ``DRJIT_LIBLLVM_PATH`` (if unset and drjit not yet imported); describe what was done."""
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        p = Path(os.environ["DRJIT_LIBLLVM_PATH"])
        if p.exists():
            _preload_libcxx(p.resolve())
        return f"DRJIT_LIBLLVM_PATH set by the user ({p})"
    if "drjit" in sys.modules:
        return "drjit was imported before simcam.starcam.lens could set DRJIT_LIBLLVM_PATH"
    path, origin = find_libllvm()
    if path is None:
        return f"no libLLVM >= {MIN_LLVM_MAJOR} found (install karellen-llvm-core)"
    _preload_libcxx(path.resolve())
    os.environ["DRJIT_LIBLLVM_PATH"] = str(path)
    return f"DRJIT_LIBLLVM_PATH={path} ({origin})"


@dataclass(frozen=True)
class Backend:
    """The Mitsuba variant in use.

    Attributes
    ----------
    variant : str
        ``llvm_ad_rgb`` (vectorised) or ``scalar_rgb``.
    vectorised : bool
    llvm_version : tuple
        Version of the libLLVM that Dr.Jit loaded ((0, 0, 0) if none).
    note : str
        How the libLLVM was found.
    """

    variant: str
    vectorised: bool
    llvm_version: tuple
    note: str

    def mitsuba(self):
        """``(mitsuba, types)``: the module and this variant's ``Ray3f``, ``Point3f``,
        ``Vector3f``, ``Float``, ``Float64``, ``UInt32``, ``Bool`` (captured in a scoped
        variant, so simcam never changes Mitsuba's global variant)."""
        return _variant_types(self.variant)


@contextmanager
def in_variant(variant: str):
    """Run a block with Mitsuba's global variant set to ``variant``, then restore the
    previous one (Mitsuba's own ``scoped_set_variant`` fails when none was set)."""
    import mitsuba as mi

    old = mi.variant()
    if old != variant:
        mi.set_variant(variant)
    try:
        yield mi
    finally:
        if old is not None and old != variant:
            mi.set_variant(old)


@cache
def _variant_types(variant: str):
    from types import SimpleNamespace

    import drjit as dr
    import mitsuba as mi

    with in_variant(variant):
        t = SimpleNamespace(Ray3f=mi.Ray3f, Point3f=mi.Point3f, Vector3f=mi.Vector3f, Float=mi.Float,
                            UInt32=mi.UInt32, Bool=mi.Bool)
    if variant == VECTOR_VARIANT:
        t.Float64 = dr.llvm.ad.Float64
    else:
        t.Float64 = float
    return mi, t


@cache
def get_backend(variant: str | None = None) -> Backend:
    """The Mitsuba variant to trace with.

    Parameters
    ----------
    variant : {None, "llvm_ad_rgb", "scalar_rgb"}
        None: ``llvm_ad_rgb`` when a libLLVM >= 19 is loaded, else ``scalar_rgb`` with a
        :class:`~simcam.starcam.lens.errors.LensBackendWarning`. ``llvm_ad_rgb``: that or an error.

    Raises
    ------
    LensError
        An unknown variant, or ``llvm_ad_rgb`` asked for and unavailable.
    """
    if variant is not None and variant not in _VARIANTS:
        raise LensError(f"variant: expected one of {', '.join(_VARIANTS)}, got {variant!r}")
    note = configure_libllvm()
    import drjit as dr

    try:
        llvm_version = tuple(dr.detail.llvm_version()) if dr.has_backend(dr.JitBackend.LLVM) else (0, 0, 0)
    except (AttributeError, RuntimeError):  # pragma: no cover - a drjit without llvm_version()
        llvm_version = (0, 0, 0)
    llvm_ok = llvm_version[0] >= MIN_LLVM_MAJOR
    if variant in (None, VECTOR_VARIANT) and llvm_ok:
        try:
            _variant_types(VECTOR_VARIANT)
            return Backend(VECTOR_VARIANT, True, llvm_version, note)
        except (ImportError, AttributeError) as exc:
            reason = f"{VECTOR_VARIANT} failed to load: {exc}"
        if variant == VECTOR_VARIANT:
            raise LensError(reason)
    else:
        reason = (f"Dr.Jit's LLVM backend has LLVM {'.'.join(map(str, llvm_version))} (needs >= "
                  f"{MIN_LLVM_MAJOR}); {note}")
        if variant == VECTOR_VARIANT:
            raise LensError(f"variant {VECTOR_VARIANT} unavailable: {reason}")
    if variant is None:
        warnings.warn(
            f"simcam.starcam.lens: the vectorised Mitsuba variant is unavailable ({reason}); tracing with "
            f"{SCALAR_VARIANT}, one ray per call (slow). Install karellen-llvm-core or set "
            "DRJIT_LIBLLVM_PATH to a libLLVM >= 19 before simcam imports drjit.",
            LensBackendWarning, stacklevel=2,
        )
    return Backend(SCALAR_VARIANT, False, llvm_version, note)
