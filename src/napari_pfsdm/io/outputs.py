"""Which files may be replaced, and one writer per output: ownership, collisions, locks and
leftovers.

:func:`check_outputs` is what every command (and every Python function that writes several
files) runs before any work: each output's folder exists and is writable, no output replaces a
file this program did not write (:func:`check_overwrite`, a user's image given as ``-o`` by
mistake), and no two outputs, their sidecars and locks, an input or an input's sidecar are one
file (:func:`same_file`: resolved paths, links, and upper and lower case where the file system
does not tell them apart, :func:`folds_case`). :func:`written_by_pfsdm` says which files it
wrote (a table with its sidecar, a marked PNG or TIFF, an HTML report), :func:`output_lock`
lets one run at a time write an output, and :func:`remove_leftovers` removes what a killed run
left behind.
"""

from __future__ import annotations

import contextlib
import os
import re
import socket
import tempfile
import time
import unicodedata
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError
from .atomic import PNG_SOFTWARE, new_file_mode, unlink_quietly
from .sidecar import (
    HEADER_PREFIX,
    changed_after,
    is_pfsdm_sidecar,
    read_sidecar,
    sidecar_path,
    size_and_digest,
)

__all__ = ["HTML_GENERATOR", "Input", "Output", "check_outputs", "check_overwrite",
           "file_name_part", "folds_case", "lock_path", "output_files", "output_lock",
           "remove_leftovers", "same_file", "written_by_pfsdm"]

#: What marks an HTML report napari-pfsdm wrote (napari_pfsdm.analysis.report.GENERATOR), in
#: its first few kilobytes.
HTML_GENERATOR = b'<meta name="generator" content="napari-pfsdm'

def written_by_pfsdm(path: str | os.PathLike) -> bool:
    """True when ``path`` is a file this program wrote: a table with a napari-pfsdm sidecar
    (or the comment line of older tables), a PNG marked by :func:`save_figure`, or an HTML
    report whose head names napari-pfsdm as its generator."""
    path = Path(path)
    if not path.is_file():
        return False
    try:
        side = read_sidecar(path)
    except ValueError:
        side = None
    if side is not None and str(side.get("written_by", "")).startswith("napari-pfsdm"):
        return not _edited_since(path, side)
    with open(path, "rb") as handle:
        head = handle.read(4096)
    if head.startswith(HEADER_PREFIX.encode()):
        return True
    if head.lstrip().lower().startswith(b"<!doctype html") and HTML_GENERATOR in head:
        return True  # a report (napari_pfsdm.report.write_report)
    if head[:4] in (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"):
        return _tiff_software(path).startswith(PNG_SOFTWARE)  # io.atomic.save_tiff
    return head[:8] == b"\x89PNG\r\n\x1a\n" and PNG_SOFTWARE.encode() in head


def _edited_since(path: Path, side: dict) -> bool:
    """Whether a table was changed after pfsdm wrote it and its sidecar (by hand, by another
    program): other bytes than the sidecar records, saved after it. Such a table is the
    user's now. (Other bytes saved before the sidecar are pfsdm's own write, stopped between
    the two files.)"""
    recorded = side.get("table_sha256")
    if recorded is None or not changed_after(path):
        return False
    size = path.stat().st_size
    return size != side.get("table_bytes") or size_and_digest(path)[1] != recorded


def _tiff_software(path: Path) -> str:
    """The Software tag of a TIFF's first page ("" when it has none or cannot be read)."""
    try:
        import tifffile

        with tifffile.TiffFile(str(path)) as tif:
            return str(tif.pages[0].software or "")
    except Exception:  # noqa: BLE001 - any reader's error: not a file pfsdm wrote
        return ""


#: What :func:`output_lock` writes into a lock file: "pid host 2026-12-06T14:00:00" (a
#: process number, then one line), or nothing (a run killed before it wrote).
_LOCK_TEXT = re.compile(r"(\d+ [^\n]*\n?)?")


def lock_path(path: str | os.PathLike) -> Path:
    """The lock file of an output (:func:`output_lock`): ``.features.csv.lock`` beside it."""
    path = Path(path)
    return path.with_name(f".{path.name}.lock")


def _is_pfsdm_lock(path: Path) -> bool:
    """Whether ``path`` is a lock file as :func:`output_lock` writes it (or an empty one)."""
    if path.is_symlink() or not path.is_file():
        return False
    try:
        with open(path, "rb") as handle:
            head = handle.read(300)
    except OSError:
        return False
    return _LOCK_TEXT.fullmatch(head.decode("utf-8", "replace")) is not None


def output_files(path: str | os.PathLike, *, table: bool = True) -> list[Path]:
    """Every file a run writing ``path`` makes beside it: the file itself and, for a table,
    its sidecar (``.json``) and its lock (``.name.lock``)."""
    path = Path(path)
    return [path, sidecar_path(path), lock_path(path)] if table else [path]


def check_overwrite(path: str | os.PathLike, *, force: bool = False, what: str = "output",
                    table: bool = True) -> None:
    """Refuse to replace an existing file that this program did not write.

    Checked are the output itself and, for a table (``table=True``), the files written beside
    it: its sidecar ``path + ".json"`` (a JSON file not written by napari-pfsdm, or any other
    file, under that name is the user's) and its lock ``.name.lock``.

    Raises
    ------
    InputError
        One of these exists, was not written by napari-pfsdm, and ``force`` is False.
    """
    path = Path(path)
    if force:
        return
    if path.exists() and not path.is_dir() and not written_by_pfsdm(path):
        raise InputError(
            f"the {what} {path} already exists and was not written by pfsdm (an input "
            "image?); nothing was changed. Choose another name, or add --force to replace it"
        )
    if not table:
        return
    side = sidecar_path(path)
    if (side.exists() or side.is_symlink()) and not (side.is_file()
                                                     and is_pfsdm_sidecar(side)):
        raise InputError(
            f"{side} already exists and was not written by pfsdm, but pfsdm writes the "
            f"options of the {what} {path} under that name; nothing was changed. Move that "
            "file, choose another output name, or add --force to replace it"
        )
    lock = lock_path(path)
    if (lock.exists() or lock.is_symlink()) and not _is_pfsdm_lock(lock):
        raise InputError(
            f"{lock} already exists and is not a lock file of pfsdm, but pfsdm locks the "
            f"{what} {path} under that name; nothing was changed. Move that file, choose "
            "another output name, or add --force to replace it"
        )


#: A temporary file of :func:`atomic_write` for ``name``: ``.name.XXXXXXXX.tmp`` (the eight
#: characters of :func:`tempfile.mkstemp`).
_TEMP_RE = r"\.{name}\.[a-z0-9_]{{8}}\.tmp"


def remove_leftovers(path: str | os.PathLike) -> list[Path]:
    """Remove the temporary files that a killed run writing ``path`` left behind: those of
    the table and of its sidecar (``.features.csv.XXXXXXXX.tmp``). Call it holding
    :func:`output_lock`: no other run is then writing them.

    Returns
    -------
    list of Path
        The files removed.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    names = "|".join(re.escape(n) for n in (path.name, sidecar_path(path).name))
    pattern = re.compile(_TEMP_RE.format(name=f"(?:{names})"))
    removed = []
    for entry in os.scandir(folder):
        if pattern.fullmatch(entry.name) and not entry.is_dir(follow_symlinks=False):
            unlink_quietly(entry.path)
            removed.append(Path(entry.path))
    return removed


def _lock_holder(fd: int) -> str:
    """What the lock file says about the run holding it ("process 123 on host, since ...")."""
    try:
        words = os.pread(fd, 200, 0).decode("utf-8", "replace").split()
    except OSError:
        words = []
    if len(words) >= 3:
        return f" (process {words[0]} on {words[1]}, since {words[2]})"
    return ""


@contextlib.contextmanager
def output_lock(path: str | os.PathLike) -> Iterator[Path]:
    """Hold the right to write ``path``: one run at a time per output.

    The lock is ``.<name>.lock`` beside the output, locked with ``flock`` (released by the
    system when the run ends, even when it is killed: a stale lock file is taken over) and
    removed when done. A symbolic link planted under that name is refused.

    Raises
    ------
    InputError
        Another run holds the lock; the message names it.

    Examples
    --------
    >>> import tempfile, os
    >>> out = os.path.join(tempfile.mkdtemp(), "t.csv")
    >>> with output_lock(out):
    ...     try:
    ...         with output_lock(out):
    ...             pass
    ...     except ValueError as exc:
    ...         print(str(exc).startswith("another pfsdm run is writing"))
    True
    """
    path = Path(path)
    lock = lock_path(path)
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows: a lock file created exclusively
        yield from _exclusive_lock(path, lock)
        return
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, new_file_mode())
        except OSError as exc:
            raise InputError(f"cannot lock {path} for writing: {lock} ({exc.strerror})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = _lock_holder(fd)
            os.close(fd)
            raise InputError(
                f"another pfsdm run is writing {path}{holder}; wait for it to finish, or "
                "choose another output name"
            ) from None
        try:  # the last holder may have removed the file between our open and flock
            same = os.stat(lock, follow_symlinks=False).st_ino == os.fstat(fd).st_ino
        except OSError:
            same = False
        if same:
            break
        os.close(fd)
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()} {socket.gethostname()} "
                  f"{time.strftime('%Y-%m-%dT%H:%M:%S')}\n".encode(), 0)
    try:
        yield lock
    finally:
        # while still holding it: a waiting run sees a removed file and retries
        unlink_quietly(lock)
        os.close(fd)


def _exclusive_lock(path: Path, lock: Path) -> Iterator[Path]:  # pragma: no cover - Windows
    """:func:`output_lock` where there is no ``flock``: the lock file created exclusively;
    a killed run's lock stays, and the message says to delete it."""
    try:
        fd = os.open(lock, os.O_WRONLY | os.O_CREAT | os.O_EXCL, new_file_mode())
    except FileExistsError:
        raise InputError(
            f"another pfsdm run is writing {path} (its lock {lock} exists); wait for it to "
            f"finish, or, if no run is going on (one was killed), delete {lock}"
        ) from None
    except OSError as exc:
        raise InputError(f"cannot lock {path} for writing: {lock} ({exc.strerror})") from None
    os.write(fd, f"{os.getpid()} {socket.gethostname()} "
                 f"{time.strftime('%Y-%m-%dT%H:%M:%S')}\n".encode())
    os.close(fd)
    try:
        yield lock
    finally:
        unlink_quietly(lock)


# --------------------------------------------------------------------------------------------
# outputs that collide with each other or with an input
# --------------------------------------------------------------------------------------------

#: What :func:`folds_case` found per folder (its device and inode): (case, normalisation).
_FOLDING: dict[tuple[int, int], tuple[bool, bool]] = {}


def folds_case(folder: str | os.PathLike) -> tuple[bool, bool]:
    """Whether the file system of ``folder`` takes names that differ only in upper and lower
    case (macOS, Windows), or only in Unicode normalisation (``é`` as one character or as ``e``
    and an accent, macOS), for one file: ``(case, normalisation)``.

    Found by creating a probe file in ``folder`` and asking for it under the other spelling,
    never assumed from the operating system; ``(False, False)`` when ``folder`` cannot be
    written (nothing will be written there either).
    """
    folder = Path(folder) if str(folder) else Path(".")
    try:
        st = os.stat(folder)
    except OSError:
        return False, False
    key = (st.st_dev, st.st_ino)
    if key in _FOLDING:
        return _FOLDING[key]
    case = _same_under(folder, ".pfsdm-case-", str.swapcase)
    normalisation = _same_under(folder, ".pfsdm-case-\u00e9-",
                                lambda name: unicodedata.normalize("NFD", name))
    _FOLDING[key] = (case, normalisation)
    return case, normalisation


def _same_under(folder: Path, prefix: str, spell) -> bool:
    """Whether a probe file made in ``folder`` is found under ``spell(name)`` too (False when
    no probe can be made there, e.g. a name with an accent on an old file system)."""
    try:
        fd, probe = tempfile.mkstemp(prefix=prefix, suffix=".tmp", dir=folder)
    except OSError:
        return False
    os.close(fd)
    try:
        other = os.path.join(folder, spell(os.path.basename(probe)))
        return other != probe and os.path.exists(other) and os.path.samefile(probe, other)
    finally:
        unlink_quietly(probe)


def _identity(path: Path) -> set[tuple]:
    """What one file is, for :func:`same_file`: its folder's (device, inode) with its name as
    the file system compares names (upper and lower case folded where it folds them), and for
    an existing file also its own (device, inode) (links and hard links included). Two paths
    are one file when these share a key."""
    path = Path(os.path.abspath(path))
    keys: set[tuple] = set()
    with contextlib.suppress(OSError):
        st = os.stat(path)
        keys.add(("file", st.st_dev, st.st_ino))
    try:
        st = os.stat(path.parent)
    except OSError:
        keys.add(("path", os.path.normcase(os.path.realpath(path))))
        return keys
    name = path.name
    case, normalisation = folds_case(path.parent)
    if normalisation:
        name = unicodedata.normalize("NFD", name)
    if case:
        name = name.casefold()
    keys.add(("name", st.st_dev, st.st_ino, name))
    return keys


def same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """Whether two paths name one file: the same file by any link or spelling when it exists;
    for a file still to be written, the same folder and a name its file system does not tell
    apart (upper and lower case on macOS and Windows, found by :func:`folds_case`).

    Examples
    --------
    >>> import tempfile, os
    >>> d = tempfile.mkdtemp()
    >>> same_file(os.path.join(d, "a.csv"), os.path.join(d, "sub", "..", "a.csv"))
    True
    """
    return bool(_identity(Path(a)) & _identity(Path(b)))


def _inside(path: Path, folder: Path) -> bool:
    """Whether ``path`` lies inside the existing folder ``folder`` (by any link)."""
    try:
        target = Path(os.path.realpath(path))
        root = Path(os.path.realpath(folder))
    except OSError:
        return False
    return root in target.parents


#: Characters a file name may not hold on some system (Windows' reserved ones, separators).
_NOT_IN_NAMES = re.compile(r'[<>:"/\\|?*\x00-\x1f]')


def file_name_part(text: str) -> str:
    """A name (a layer's, a movie's) as part of a file name: as written, but every character
    some system reads as a folder separator or forbids in names replaced by ``_``, and no
    leading dot (a hidden file) or ``..``; never empty.

    Examples
    --------
    >>> file_name_part("../embryo 3/a:b")
    '_._embryo 3_a_b'
    >>> file_name_part("..")
    '_.'
    """
    name = _NOT_IN_NAMES.sub("_", str(text)).strip()
    if name.startswith("."):
        name = "_" + name[1:]
    return name or "_"


@dataclass(frozen=True)
class Output:
    """A file a command or function is about to write.

    Attributes
    ----------
    path : Path
        The file (or, for ``kind="folder"``, the folder) to write.
    kind : str
        ``"table"`` (written with its sidecar ``.json`` and its lock ``.name.lock``),
        ``"plot"``, ``"report"``, ``"file"`` (one file) or ``"folder"`` (a folder pfsdm fills,
        such as a run's parts).
    name : str
        How the user named it, for messages: the option (``-o``, ``--plot``) or a word.
    """

    path: Path
    kind: str = "table"
    name: str = "output"

    def files(self) -> list[Path]:
        """Every file writing it makes (the table's sidecar and lock too)."""
        return output_files(self.path, table=self.kind == "table")


@dataclass(frozen=True)
class Input:
    """A file (or Zarr store) a command reads: ``kind`` ``"table"`` (its sidecar is part of
    it), ``"movie"`` (a TIFF or a Zarr store, a folder) or ``"file"``; ``name`` as in
    :class:`Output`."""

    path: Path
    kind: str = "file"
    name: str = "input"

    def files(self) -> list[Path]:
        return [self.path, sidecar_path(self.path)] if self.kind == "table" else [self.path]


def _called(what: str, path: Path) -> str:
    """``"-o p.csv"`` or ``"the plot p.csv"``: an output or input as the user named it."""
    return f"{what} {path}" if what.startswith("-") else f"the {what} {path}"


def _caseless_note(path: Path) -> str:
    folder = path.parent if str(path.parent) else Path(".")
    case, normalisation = folds_case(folder)
    if case or normalisation:
        return (" (this file system does not tell names apart that differ only in "
                + ("upper and lower case" if case else "accents written two ways") + ")")
    return ""


def check_outputs(outputs: Iterable[Output], inputs: Iterable[Input] = (), *,
                  force: bool = False) -> list[Path]:
    """Check, before any work, that the ``outputs`` of one command can be written and that
    writing them destroys nothing: each output's folder exists and can be written, no output
    is a folder, none replaces a file this program did not write (unless ``force``), no two
    outputs (with the sidecars and locks written beside tables) are one file, and no output is
    an input, an input table's sidecar, or a file inside an input Zarr store.

    Every command of the ``pfsdm`` command line runs it on the files it declares
    (``napari_pfsdm.cli.common``), and so do the Python functions that write several files
    (an export, a saved analysis, the demo).

    Parameters
    ----------
    outputs : iterable of Output
    inputs : iterable of Input
    force : bool
        Replace files napari-pfsdm did not write (never an input, never another output).

    Returns
    -------
    list of Path
        The outputs' paths, in order.

    Raises
    ------
    InputError
        The first problem found, naming the files and the options, and what to do.
    """
    outputs = [o for o in outputs if o.path is not None and str(o.path) != ""]
    inputs = [i for i in inputs if i.path is not None and str(i.path) != ""]
    for out in outputs:
        if out.kind != "folder":  # a folder is made, with its parents, when it is written
            _check_writable(out)
    _check_no_collision(outputs, inputs)
    for out in outputs:
        if out.kind == "folder":
            if (out.path.exists() or out.path.is_symlink()) and not out.path.is_dir():
                raise InputError(
                    f"{out.path} already exists and is not a folder, but pfsdm writes "
                    f"{_called(out.name, out.path)} as a folder; nothing was changed. Move "
                    "that file, or choose another name")
            continue
        check_overwrite(out.path, force=force, what=_what(out),
                        table=out.kind == "table")
        if out.kind == "table" and out.path.suffix.lower() == ".parquet":
            from .tables import require_pyarrow  # a missing package fails now, not later

            require_pyarrow(out.path, "writing")
    return [o.path for o in outputs]


def _what(out: Output) -> str:
    return out.kind if out.kind in ("plot", "report") else (
        "output" if out.name.startswith("-") else out.name)


def _check_writable(out: Output) -> None:
    p = out.path
    folder = p.parent if str(p.parent) else Path(".")
    what = _called(out.name, p)
    if out.kind != "folder" and p.is_dir():
        raise InputError(f"{what} is a folder; give a file name such as "
                         f"{p / ('out' + (p.suffix or '.csv'))}")
    if not folder.is_dir():
        raise InputError(f"cannot write {what}: the folder {folder} does not exist; create it "
                         "first")
    if not os.access(folder, os.W_OK):
        raise InputError(f"cannot write {what}: the folder {folder} is not writable; choose "
                         "another folder")


def _named_files(item: Output | Input) -> list[tuple[Path, str]]:
    """The files of an output (or input) with the words that name each for the user."""
    called = _called(item.name, item.path)
    out = []
    for f in item.files():
        if f == item.path:
            out.append((f, called))
        elif f.name.endswith(".json"):
            out.append((f, f"{f}, the options (sidecar) of {called}"))
        else:
            out.append((f, f"{f}, the lock file of {called}"))
    return out


def _check_no_collision(outputs: Sequence[Output], inputs: Sequence[Input]) -> None:
    seen: dict[tuple, tuple[Output, str, Path]] = {}
    for out in outputs:
        for f, words in _named_files(out):
            keys = _identity(f)
            for key in keys:
                if key in seen and seen[key][0] is not out:
                    raise InputError(
                        f"{words} and {seen[key][1]} are one file{_caseless_note(f)}: one "
                        "output would replace the other; nothing was changed. Give them "
                        "different names")
            seen.update(dict.fromkeys(keys, (out, words, f)))
    for inp in inputs:
        for f, words in _named_files(inp):
            if not (f.exists() or f.is_symlink()):
                continue
            hit = next((seen[k] for k in _identity(f) if k in seen), None)
            if hit is not None:
                _, out_words, g = hit
                what = (f"is also an input of this command ({words})" if f == inp.path else
                        f"would replace {words}, an input of this command")
                raise InputError(f"{out_words} {what}{_caseless_note(g)}; nothing was "
                                 "changed. Choose another output name")
        if inp.kind == "movie" and inp.path.is_dir():  # a Zarr store: its files are the movie
            for out in outputs:
                if _inside(out.path, inp.path):
                    raise InputError(
                        f"{_called(out.name, out.path)} lies inside the input movie "
                        f"{inp.path} (a Zarr store): writing there would change the movie; "
                        "nothing was changed. Choose a folder outside it")
