"""Where a command may write, checked before the work starts; several outputs written all or nothing.

The rules (docs/reliability.md):

* an output is a regular file or a folder that the command creates or was told to
  overwrite, never a device, a FIFO or a socket (an atomic rename over ``/dev/null``
  would replace the device node), and never the same file as one of the command's inputs;
* the inputs are sacred: every file a command reads (its scenario, tables, a manifest and
  the frames it lists) is compared by its real path (symbolic links followed) with every
  output before any work (:class:`CommandInputs`); an output that is an input, or a folder
  that holds one, is refused, with or without ``--overwrite``;
* its location is checked before any work: the parent is a folder (not a file), it is
  writable, the file system is not read-only, the name fits the file system's limit, and
  there is room for the estimated size;
* files and folders are created with the user's umask (``mkstemp``/``mkdtemp`` make them
  ``0600``/``0700``; :func:`apply_umask` gives them the mode an ordinary ``open`` would);
* :class:`StagedOutputs` writes several outputs (the JSON and the report of a run) into
  temporary siblings and renames them into place together at the end, with the stop
  signals held back during the renames: an interruption leaves none of them.

Every refusal is a :class:`~simcam.infra.errors.UserInputError` naming the option and the path.
"""

from __future__ import annotations

import errno
import os
import shutil
import signal
import stat
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Iterator

from simcam.infra.errors import UserInputError
from simcam.infra.lifecycle import check_disk, partial_prefix, remove_stale_partials

__all__ = [
    "CommandInputs", "StagedOutputs", "apply_umask", "check_distinct_inputs", "check_input_file",
    "check_output_dir", "check_output_file", "command_inputs", "failed_write", "file_kind", "naming_failed_writes",
    "os_error_message", "umask",
]


def umask() -> int:
    """The process umask (read without changing it for longer than one call)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def apply_umask(path: str | os.PathLike, *, is_dir: bool | None = None) -> None:
    """Give ``path`` the mode an ordinary ``open``/``mkdir`` would: ``0o666``/``0o777`` less the umask."""
    p = Path(path)
    if is_dir is None:
        is_dir = p.is_dir()
    os.chmod(p, (0o777 if is_dir else 0o666) & ~umask())


def file_kind(mode: int) -> str:
    """``'a character device'``, ``'a FIFO'``, ... for an ``st_mode``."""
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISREG(mode):
        return "a regular file"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def input_file_problem(path: str | os.PathLike) -> str | None:
    """Why ``path`` cannot be read as an input file (``"is a FIFO (named pipe), not a
    regular file"``), or None when it is a regular file or does not exist (the reader
    says "file not found" itself). Never opens it: opening a FIFO blocks."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    if stat.S_ISDIR(st.st_mode):
        return "is a folder, not a file"
    if not stat.S_ISREG(st.st_mode):
        return f"is {file_kind(st.st_mode)}, not a regular file"
    return None


def check_input_file(path: str | os.PathLike, *, what: str = "file") -> Path:
    """An input must be an existing regular file (a FIFO would block the reader forever,
    ``/dev/null`` reads as empty). Returns the path; raises :class:`UserInputError`."""
    p = Path(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise UserInputError(f"{p}: file not found (the {what})") from None
    except OSError as exc:
        raise UserInputError(f"{p}: cannot read the {what} ({os_error_message(exc)})") from None
    if stat.S_ISDIR(st.st_mode):
        raise UserInputError(f"{p}: is a folder; give the {what} itself")
    if not stat.S_ISREG(st.st_mode):
        raise UserInputError(f"{p}: is {file_kind(st.st_mode)}, not a regular file; give the {what} as a file")
    return p


def _places(path: str | os.PathLike) -> tuple[str, str]:
    """Where ``path`` is: its absolute path as given and its real path (links followed)."""
    return os.path.abspath(path), os.path.realpath(path)


@dataclass(frozen=True)
class CommandInputs:
    """The files a command reads, each as given and where it really is.

    Attributes
    ----------
    given : tuple of str
        The inputs as the user (or the command) named them.
    places : tuple of tuple of str
        For each input its absolute path and its real path (symbolic links followed), so
        that an input reached through a link, or a link inside a folder, is recognised.
    """

    given: tuple[str, ...] = ()
    places: tuple[tuple[str, str], ...] = ()

    def same_as(self, path: str | os.PathLike) -> str | None:
        """The input (as given) that ``path`` is, by real path or as the same file (a hard
        link), or None."""
        real = os.path.realpath(path)
        for src, (_, src_real) in zip(self.given, self.places):
            if real == src_real:
                return src
            try:
                if os.path.samefile(path, src_real):
                    return src
            except OSError:
                pass
        return None

    def inside(self, folder: str | os.PathLike) -> str | None:
        """The input (as given) that is ``folder`` or lies inside it (as given or by real
        path), or None: replacing the folder would delete it."""
        roots = {os.path.join(r, "") for r in _places(folder)}
        for src, places in zip(self.given, self.places):
            if any(os.path.join(p, "").startswith(root) for p in places for root in roots):
                return src
        return None


def command_inputs(*inputs) -> CommandInputs:
    """The :class:`CommandInputs` of ``inputs``: paths, None (skipped), iterables of paths
    (a manifest's frames) or other :class:`CommandInputs`, in order, each once."""
    given: list[str] = []
    places: list[tuple[str, str]] = []

    def add(item) -> None:
        if item is None:
            return
        if isinstance(item, CommandInputs):
            pairs = zip(item.given, item.places)
        elif isinstance(item, (str, bytes, os.PathLike)):
            pairs = [(os.fsdecode(item), _places(item))]
        else:
            for sub in item:
                add(sub)
            return
        for g, p in pairs:
            if p not in places:
                given.append(g)
                places.append(p)

    for item in inputs:
        add(item)
    return CommandInputs(tuple(given), tuple(places))


def check_distinct_inputs(paths: Iterable, *, what: str = "input") -> None:
    """Refuse one file given twice (also through a link or a hard link): a table counted twice
    would shrink the stated uncertainties by sqrt(2)."""
    seen = command_inputs()
    for path in paths:
        if (first := seen.same_as(path)) is not None:
            via = "" if os.fspath(first) == os.fspath(path) else f" ({path} is {first})"
            raise UserInputError(f"{path}: the same {what} given twice{via}; give each once")
        seen = command_inputs(seen, path)


#: how much longer than an output's name the name of its temporary sibling may be: a
#: staged output is ``.NAME.partial.<pid>.<random>`` (:func:`simcam.infra.lifecycle.partial_prefix`,
#: a PID of up to 7 digits, ``mkstemp``'s 8 random characters: 26 bytes more), and a JSON file
#: is written there through ``write_json_atomic``'s own ``.STAGED.<random>`` (10 more)
STAGED_NAME_BYTES = len(".") + len(".partial.") + 7 + len(".") + 8
#: the same for a file written directly by ``write_json_atomic`` (``.NAME.<random>``)
JSON_TEMPORARY_NAME_BYTES = len("..") + 8
TEMPORARY_NAME_BYTES = STAGED_NAME_BYTES + JSON_TEMPORARY_NAME_BYTES


def _check_location(p: Path, *, option: str, need_bytes: float, temp_bytes: int = TEMPORARY_NAME_BYTES) -> None:
    """Parent is a folder, writable, on a writable file system; name short enough; space."""
    # the nearest existing ancestor must be a folder (a path under a regular file is refused)
    anc = p.absolute().parent
    while not os.path.lexists(anc) and anc != anc.parent:
        anc = anc.parent
    if not anc.is_dir():
        raise UserInputError(f"{option} {p}: {anc} is {file_kind(os.stat(anc).st_mode)}, not a folder")
    try:
        name_max = os.pathconf(anc, "PC_NAME_MAX")
    except (OSError, ValueError):
        name_max = 255
    parts = p.absolute().parts[len(anc.parts):]
    for i, part in enumerate(parts):
        size = len(os.fsencode(part))
        if size > name_max:
            raise UserInputError(f"{option} {p}: the name {part[:40]}... has {size} bytes; "
                                 f"this file system allows at most {name_max}")
        if i == len(parts) - 1 and size + temp_bytes > name_max:
            # the output is written first under a longer temporary name beside it
            raise UserInputError(f"{option} {p}: the name {part[:40]}... has {size} bytes; it is written first "
                                 f"under a temporary name up to {temp_bytes} bytes longer, and this file system "
                                 f"allows at most {name_max}: give a name of at most {name_max - temp_bytes} bytes")
    try:
        vfs = os.statvfs(anc)
        read_only = bool(vfs.f_flag & os.ST_RDONLY)
    except (OSError, AttributeError):
        read_only = False
    if read_only:
        raise UserInputError(f"{option} {p}: {anc} is on a read-only file system")
    if not os.access(anc, os.W_OK | os.X_OK):
        raise UserInputError(f"{option} {p}: {anc} is not writable")
    if need_bytes > 0:
        check_disk(anc, need_bytes, what=f"{option} {p}")


def check_output_file(path: str | os.PathLike, *, option: str = "--json", inputs: Iterable = (),
                      need_bytes: float = 0.0, temp_bytes: int = TEMPORARY_NAME_BYTES) -> Path:
    """Check, before the work, that ``path`` can take a file output. Returns the path to
    write (a symbolic link to a regular file is followed, so the link stays a link).

    Refused: a device, FIFO or socket (also through a link), a folder, a link to a
    folder, one of ``inputs`` (paths or :class:`CommandInputs`; the same file by real path,
    links followed), a parent that is a file, not writable or read-only, a name longer than
    the file system allows (with its temporary name, ``temp_bytes`` longer), too little free space.
    """
    p = Path(path)
    target = p
    if os.path.lexists(p):
        try:
            st = os.stat(p)
        except OSError:  # a dangling link: written as a new file where it points
            st = None
        if st is not None:
            if stat.S_ISDIR(st.st_mode):
                via = " (through a symbolic link)" if p.is_symlink() else ""
                raise UserInputError(f"{option} {p}: is a folder{via}; give a file name")
            if not stat.S_ISREG(st.st_mode):
                raise UserInputError(f"{option} {p}: is {file_kind(st.st_mode)}; outputs are written only "
                                     "to regular files")
        if p.is_symlink():
            target = Path(os.path.realpath(p))
    if (src := command_inputs(inputs).same_as(p)) is not None:
        raise UserInputError(f"{option} {p}: is an input of this command ({src}); give another name")
    _check_location(target, option=option, need_bytes=need_bytes, temp_bytes=temp_bytes)
    return target


def check_output_dir(path: str | os.PathLike, *, option: str = "--out", inputs: Iterable = (),
                     need_bytes: float = 0.0, replaceable=None, overwrite: bool = False) -> Path:
    """Check, before the work, that ``path`` can take a folder output.

    The one rule of every command that writes a folder: an existing folder is used only
    when it is empty, is an earlier output of the same kind (``replaceable(path)``, e.g.
    :func:`is_earlier_report`), or the user gave ``--overwrite`` (``overwrite=True``).
    Refused otherwise, naming ``--overwrite``; refused always (``--overwrite`` never deletes
    an input): an existing file or device, an input of the command or a folder holding one
    (``inputs`` as for :func:`check_output_file`; as given and by real path), and the
    location checks of :func:`check_output_file`.
    """
    p = Path(path)
    if os.path.lexists(p):
        try:
            st = os.stat(p)
        except OSError:
            st = None
        if st is not None and not stat.S_ISDIR(st.st_mode):
            raise UserInputError(f"{option} {p}: is {file_kind(st.st_mode)}, not a folder")
        if p.is_symlink():
            raise UserInputError(f"{option} {p}: is a symbolic link; give the folder itself")
        # before the --overwrite rule: replacing the folder would delete the input, with or without it
        if (src := command_inputs(inputs).inside(p)) is not None:
            what = "is" if command_inputs(src).same_as(p) else "holds"
            raise UserInputError(f"{option} {p}: {what} an input of this command ({src}); give another folder")
        if (st is not None and not overwrite and any(p.iterdir())
                and not (replaceable is not None and replaceable(p))):
            raise UserInputError(f"{option} {p}: exists, is not empty and is not an earlier output of this "
                                 "command; give a new folder, or add --overwrite to replace it")
    _check_location(p, option=option, need_bytes=need_bytes, temp_bytes=STAGED_NAME_BYTES)
    return p


#: errors of a write that are the machine's state, not a bug: reported as one line naming the file
WRITE_ERRNOS = frozenset(getattr(errno, n) for n in ("ENOSPC", "EROFS", "ENAMETOOLONG", "ENOTDIR", "EACCES",
                                                     "EPERM", "EDQUOT", "EISDIR", "EFBIG") if hasattr(errno, n))


def failed_write(exc: BaseException, final: str | os.PathLike, *, tmp: str | os.PathLike | None = None,
                 option: str | None = None) -> UserInputError | None:
    """The one-line error of a write into ``final`` that failed for the machine's state
    (``WRITE_ERRNOS``: the disk full, a read-only file system ...), naming the file: the
    error's own file name (inside the temporary ``tmp`` it is written to, the name it would
    have had under ``final``), else ``final`` itself (a write to an open file names none).
    None for any other exception."""
    if not isinstance(exc, OSError) or exc.errno not in WRITE_ERRNOS:
        return None
    where = os.fsdecode(exc.filename) if exc.filename else str(final)
    if tmp is not None and exc.filename:
        t = os.fspath(tmp)
        if where == t or where.startswith(t + os.sep):
            where = str(final) + where[len(t):]
    lead = f"{option} " if option and where == str(final) else ""
    return UserInputError(f"{lead}{where}: {os_error_message(exc)}")


@contextmanager
def naming_failed_writes(final: str | os.PathLike, *, tmp: str | os.PathLike | None = None,
                         option: str | None = None) -> Iterator[None]:
    """A write into ``final`` (a file or a folder, written at ``tmp`` if given) that fails
    for the machine's state is one :class:`UserInputError` naming the file
    (:func:`failed_write`)."""
    try:
        yield
    except OSError as exc:
        err = failed_write(exc, final, tmp=tmp, option=option)
        if err is None:
            raise
        raise err from None


def os_error_message(exc: OSError) -> str:
    """A short reason for a failed write: ``no space left on the device`` and the like."""
    reasons = {errno.ENOSPC: "no space left on the device", errno.EROFS: "read-only file system",
               errno.ENAMETOOLONG: "file name too long", errno.ENOTDIR: "a part of the path is not a folder",
               errno.EACCES: "permission denied", errno.EPERM: "operation not permitted",
               errno.EDQUOT: "disk quota exceeded", errno.EISDIR: "is a folder"}
    return reasons.get(exc.errno, exc.strerror or type(exc).__name__)


_HELD = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


@contextmanager
def held_signals() -> Iterator[None]:
    """Hold back SIGINT/SIGTERM/SIGHUP for the block (delivered after it): a few renames
    that must happen together are not split by an interruption."""
    try:
        old = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD)
    except (AttributeError, ValueError, OSError):
        yield
        return
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


class StagedOutputs:
    """Several outputs of one run, written into temporary siblings and put in place together.

    Use::

        with StagedOutputs() as st:
            write_json_atomic(st.file(json_out), ...)
            write_report(result, st.folder(report_dir))

    Leaving the block normally renames every staged output into place (an existing
    folder, already checked replaceable, is replaced), with the stop signals held back;
    an exception or an interruption removes every staged output, so none of the outputs
    appears. The staged names are ``.NAME.partial.<pid>.<random>`` so a run killed
    outright is cleaned up by the next (:func:`simcam.infra.lifecycle.remove_stale_partials`).
    """

    def __init__(self) -> None:
        self._items: list[tuple[Path, Path, bool]] = []

    def _stage(self, final: str | os.PathLike, is_dir: bool) -> Path:
        final = Path(final)
        final.parent.mkdir(parents=True, exist_ok=True)
        remove_stale_partials(final)
        fd, tmp = tempfile.mkstemp(prefix=partial_prefix(final), dir=final.parent)
        os.close(fd)
        os.unlink(tmp)  # the writer creates it (a file, or a folder it renames into place)
        self._items.append((Path(tmp), final, is_dir))
        return Path(tmp)

    def file(self, final: str | os.PathLike) -> Path:
        """A temporary path to write the file ``final`` to."""
        return self._stage(final, False)

    def folder(self, final: str | os.PathLike) -> Path:
        """A temporary path (not yet existing) to create the folder ``final`` at."""
        return self._stage(final, True)

    def _named(self, exc: BaseException) -> UserInputError | None:
        """:func:`failed_write` of ``exc`` for the staged output it names (or the last staged)."""
        if not self._items or not isinstance(exc, OSError):
            return None
        name = os.fsdecode(exc.filename) if exc.filename else ""
        for tmp, final, _is_dir in self._items:
            if name == str(tmp) or name.startswith(str(tmp) + os.sep):
                return failed_write(exc, final, tmp=tmp)
        tmp, final, _ = self._items[-1]
        return failed_write(exc, final, tmp=tmp)

    def __enter__(self) -> "StagedOutputs":
        return self

    def _discard(self) -> None:
        for tmp, _final, _is_dir in self._items:
            if tmp.is_dir() and not tmp.is_symlink():
                shutil.rmtree(tmp, ignore_errors=True)
            elif os.path.lexists(tmp):
                try:
                    os.unlink(tmp)
                except OSError:
                    pass

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is not None:
            self._discard()
            if (err := self._named(exc)) is not None:  # the disk filled: name the output, not its temporary
                raise err from None
            return False
        try:
            with held_signals():
                for tmp, final, is_dir in self._items:
                    if not os.path.lexists(tmp):
                        continue
                    apply_umask(tmp)  # mkdtemp/mkstemp made it 0700/0600
                    if is_dir and final.is_dir() and not final.is_symlink():
                        shutil.rmtree(final)
                    os.replace(tmp, final)
        except BaseException:
            self._discard()
            raise
        return False


#: the page of each kind of report folder a command writes (validate, synthesize and
#: scanmirror simulate: report.md; linecam simulate / calibrate: their own page)
REPORT_PAGES = ("report.md", "simulate.md", "calibrate.md")
#: what marks a folder as an earlier output of the commands that write frames or tables
#: (``simcam render``, ``budget starcam simulate``: a manifest and the truth; ``simcam
#: optics``: the lens table)
OUTPUT_MARKERS = (("manifest.csv", "truth.csv"), ("table.csv",))


def is_earlier_report(path: Path) -> bool:
    """A folder that ``--report`` may replace: empty, or an earlier report (holds one of
    :data:`REPORT_PAGES`)."""
    return not any(path.iterdir()) or any((path / n).is_file() for n in REPORT_PAGES)


def is_earlier_output(path: Path) -> bool:
    """A folder that ``--out`` may replace: empty, or an earlier output of a command that
    writes frames or tables (holds every file of one of :data:`OUTPUT_MARKERS`)."""
    return not any(path.iterdir()) or any(all((path / n).is_file() for n in group) for group in OUTPUT_MARKERS)


def is_earlier_plots(path: Path) -> bool:
    """A folder ``budget plot`` may write into: empty, or holding only its own figures
    (PNG files) and pages."""
    return all(f.is_file() and f.suffix in (".png", ".md", ".html") for f in path.iterdir())


def check_run_outputs(*, json_out=None, report_dir=None, inputs: Iterable = (), files: dict | None = None,
                      overwrite: bool = False) -> None:
    """The checks of a command's outputs before its work: a file location for the JSON
    (and each of ``files``, option -> path, e.g. ``{"--csv": csv_out}``), a new folder or
    an earlier report for the report, none of them an input, no two the same path."""
    inputs = command_inputs(inputs)
    outs = [("--json", json_out)] + list((files or {}).items())
    given = [(o, p) for o, p in outs if p]
    for opt, p in given:
        check_output_file(p, option=opt, inputs=inputs)
    for i, (o1, p1) in enumerate(given):
        for o2, p2 in given[i + 1:]:
            if os.path.abspath(p1) == os.path.abspath(p2):
                raise UserInputError(f"{o1} {p1} and {o2} {p2}: the same path; give two")
    if report_dir:
        check_output_dir(report_dir, option="--report", inputs=inputs, replaceable=is_earlier_report,
                         overwrite=overwrite)
    if json_out and report_dir and os.path.abspath(json_out) == os.path.abspath(report_dir):
        raise UserInputError(f"--json {json_out} and --report {report_dir}: the same path; give two")
