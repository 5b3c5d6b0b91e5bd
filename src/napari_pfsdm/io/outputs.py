"""Which files may be replaced, and one writer per output: ownership, locks and leftovers.

:func:`check_overwrite` refuses to replace a file that this program did not write (a user's
image given as ``-o`` by mistake), :func:`written_by_pfsdm` says which files it wrote (a table
with its sidecar, a marked PNG, an HTML report), :func:`output_lock` lets one run at a time
write an output, and :func:`remove_leftovers` removes what a killed run left behind.
"""

from __future__ import annotations

import contextlib
import os
import re
import socket
import time
from collections.abc import Iterator
from pathlib import Path

from ..errors import InputError
from .atomic import PNG_SOFTWARE, new_file_mode, unlink_quietly
from .sidecar import HEADER_PREFIX, is_pfsdm_sidecar, read_sidecar, sidecar_path

__all__ = ["HTML_GENERATOR", "check_overwrite", "lock_path", "output_files", "output_lock",
           "remove_leftovers", "written_by_pfsdm"]

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
        return True
    with open(path, "rb") as handle:
        head = handle.read(4096)
    if head.startswith(HEADER_PREFIX.encode()):
        return True
    if head.lstrip().lower().startswith(b"<!doctype html") and HTML_GENERATOR in head:
        return True  # a report (napari_pfsdm.report.write_report)
    return head[:8] == b"\x89PNG\r\n\x1a\n" and PNG_SOFTWARE.encode() in head


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
