"""Files written atomically, with the permissions of any new file, marked as napari-pfsdm's.

:func:`atomic_write` fills a temporary file of a unique name, created exclusively in the
target's folder (never through a file or symbolic link already there), and moves it onto the
target in one step: an error or a killed process never leaves a half-written file under the
final name. The file gets ``0o666`` less the umask, not the ``0o600`` of a temporary file.
:func:`save_figure` writes a matplotlib figure so, and :func:`save_tiff` an image, marked as
written by napari-pfsdm (:data:`PNG_SOFTWARE`), so that a re-run may replace them.
"""

from __future__ import annotations

import errno
import os
import tempfile
import threading
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from ..errors import InputError

__all__ = ["PNG_SOFTWARE", "WRITE_HINTS", "atomic_write", "new_file_mode", "save_figure",
           "save_tiff", "unlink_quietly", "write_fault", "write_temp", "writer_name"]

#: Marker written into PNG files (metadata ``Software``) so that a re-run may replace them.
PNG_SOFTWARE = "napari-pfsdm"

_UMASK_LOCK = threading.Lock()


def writer_name() -> str:
    """What the files name as their writer: ``"napari-pfsdm <version>"``."""
    from .._version import __version__

    return f"napari-pfsdm {__version__}"


def new_file_mode() -> int:
    """Permissions of a newly created file under the current umask (``0o666 & ~umask``)."""
    try:  # Linux says it without changing it (no window where another thread sees another)
        with open("/proc/self/status", encoding="ascii") as status:
            line = next(ln for ln in status if ln.startswith("Umask:"))
        mask = int(line.split()[1], 8)
    except (OSError, StopIteration, ValueError, IndexError):
        with _UMASK_LOCK:  # elsewhere os.umask can only be read by setting it
            mask = os.umask(0o022)
            os.umask(mask)
    return 0o666 & ~mask


def atomic_write(
    path: str | os.PathLike, write: Callable[[IO], None], *, binary: bool = False
) -> Path:
    """Write a file atomically, with the permissions of a normal new file.

    ``write(handle)`` fills a temporary file created in the target's folder; only when it
    returns without error is the temporary file given the umask's permissions and moved onto
    ``path`` with :func:`os.replace`. On any error the temporary file is removed and ``path``
    is left as it was.

    Parameters
    ----------
    path : str or PathLike
        Final file name. Its folder must exist and be writable.
    write : callable
        Called with an open handle: text (UTF-8, ``newline=""``) or, with ``binary=True``,
        bytes.
    binary : bool
        Open the temporary file in binary mode (e.g. for ``Figure.savefig(handle)``).

    Returns
    -------
    Path
        The path written.
    """
    path = Path(path)
    tmp = write_temp(path, write, binary=binary)
    try:
        os.replace(tmp, path)
    except BaseException:
        unlink_quietly(tmp)
        raise
    return path


def unlink_quietly(path: str | os.PathLike) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass


#: What to do when the system refuses a write, by its error number (the command line adds it to
#: the system's words).
WRITE_HINTS = {
    errno.ENOSPC: "the disk is full: free some space, or write to another disk (another -o "
                  "folder); nothing was half-written and the previous file is as it was",
    errno.EDQUOT: "your disk quota is used up: free some space, or write to another disk; "
                  "nothing was half-written",
    errno.EROFS: "the file system is read-only: write to a folder you can change",
    errno.EACCES: "permission denied: write to a folder you can change, or ask for the right",
    errno.EPERM: "permission denied: write to a folder you can change",
    errno.EFBIG: "the file is larger than this file system takes: write to another disk, or "
                 "a .parquet table (smaller)",
}


def write_fault(exc: OSError, path: str | os.PathLike) -> OSError:
    """The system's error while writing ``path``, naming the file and saying what to do
    (:data:`WRITE_HINTS`): an ``OSError`` still, with the same error number."""
    words = exc.strerror or str(exc)
    hint = WRITE_HINTS.get(exc.errno or 0)
    fault = OSError(exc.errno, f"cannot write it: {words}" + (f"; {hint}" if hint else ""),
                    str(path))
    return fault


def write_temp(path: Path, write: Callable[[IO], None], *, binary: bool = False) -> str:
    """Fill a temporary file next to ``path`` (umask permissions, synced); return its name."""
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(
            f"cannot write {path}: the folder {folder} does not exist; create it first"
        )
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    except OSError as exc:
        if exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
            raise InputError(
                f"cannot write {path}: the folder {folder} is not writable ({exc.strerror}); "
                "choose a folder you can write") from exc
        raise write_fault(exc, path) from exc
    try:
        os.fchmod(fd, new_file_mode())  # mkstemp makes 0o600: colleagues could not read it
        kw: dict[str, Any] = {} if binary else {"encoding": "utf-8", "newline": ""}
        with os.fdopen(fd, "wb" if binary else "w", **kw) as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
    except OSError as exc:
        unlink_quietly(tmp)
        if exc.filename is None or exc.errno in WRITE_HINTS:  # ours: name it, say what to do
            raise write_fault(exc, path) from exc
        raise
    except BaseException:
        unlink_quietly(tmp)
        raise
    return tmp


def save_figure(fig: Any, path: str | os.PathLike, **kwargs: Any) -> Path:
    """Save a matplotlib figure as PNG atomically, marked as written by napari-pfsdm."""
    meta = {"Software": f"{PNG_SOFTWARE} {writer_name().split()[-1]}"}
    return atomic_write(
        path, lambda h: fig.savefig(h, format="png", metadata=meta, **kwargs), binary=True
    )



def save_tiff(path: str | os.PathLike, data: Any, **kwargs: Any) -> Path:
    """Write an image as TIFF atomically (``tifffile.imwrite``'s keywords, e.g.
    ``compression="zlib"``), its Software tag naming napari-pfsdm so that a re-run may
    replace it."""
    import tifffile

    path = Path(path)
    tmp = write_temp(path, lambda handle: None, binary=True)  # ours: made exclusively, empty
    try:
        try:
            tifffile.imwrite(tmp, data, software=writer_name(), **kwargs)
        except OSError as exc:
            raise write_fault(exc, path) from exc
        os.replace(tmp, path)
    except BaseException:
        unlink_quietly(tmp)
        raise
    return path
