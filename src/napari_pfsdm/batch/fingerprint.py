"""Whether a movie on disk changed: its file's identity and its data's fingerprint.

:func:`file_identity` (size, modification time, inode; a Zarr store's metadata files too)
tells a reader that the file it opened was replaced or rewritten; :func:`data_fingerprint`
names a movie's data for a resumed batch: a movie of at most :data:`CONTENT_HASH_BYTES` by its
content, a larger one by its files' sizes, times and identity. :func:`store_files` lists a
Zarr store's files.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["CONTENT_HASH_BYTES", "data_fingerprint", "file_identity", "store_files"]

#: Zarr metadata files whose change means new array content or shape (v2 and v3).
_ZARR_META = (".zarray", ".zgroup", ".zattrs", "zarr.json")


def file_identity(path: str | os.PathLike, component: str = "") -> tuple:
    """What identifies the content of a movie file: ``(size, mtime_ns, inode)``.

    A file replaced by another under the same name (``os.replace``, an atomic save) has a new
    inode, and a file rewritten in place a new modification time or size. For a Zarr store (a
    folder), the same of the folder and of the metadata files (``.zarray``, ``zarr.json``, …)
    at its top level and in the array ``component`` read (a group's array, OME-Zarr's level).
    The device number is left out: a cluster's machines mount a shared disk under different
    device numbers, and they must agree.

    Parameters
    ----------
    path : str or PathLike
    component : str
        The array inside a Zarr group (``""``: the store itself).

    Returns
    -------
    tuple
        Equal for the same unchanged file; ``()`` when the path does not exist.
    """
    p = Path(path)
    try:
        st = p.stat()
    except OSError:
        return ()
    ident: tuple = (st.st_size, st.st_mtime_ns, st.st_ino)
    if p.is_dir():
        metas = [p / m for m in _ZARR_META]
        if component:
            metas += [p / component / m for m in _ZARR_META]
        for m in metas:
            try:
                ms = m.stat()
            except OSError:
                continue
            ident += (m.name, ms.st_size, ms.st_mtime_ns, ms.st_ino)
    return ident


def store_files(folder: str | os.PathLike) -> dict[str, tuple[int, int]]:
    """Every file under a Zarr store's folder: ``{relative path with "/": (size, mtime_ns)}``
    (symbolic links are not followed out of the store)."""
    root = Path(folder)
    out: dict[str, tuple[int, int]] = {}
    for here, _dirs, names in os.walk(root):
        for name in names:
            full = Path(here) / name
            try:
                st = full.stat()
            except OSError:  # removed while listing: not there
                continue
            out[full.relative_to(root).as_posix()] = (st.st_size, st.st_mtime_ns)
    return out


#: Movies up to this size are fingerprinted by their content (:func:`data_fingerprint`).
CONTENT_HASH_BYTES = 16 * 2**20


def data_fingerprint(path: str | os.PathLike) -> str:
    """What identifies a movie's data, for a resumed batch to know it is unchanged.

    A Zarr store (a folder): every file in it, with its size and modification time, so that a
    chunk re-written in place (a store re-segmented) changes it; a TIFF: its size,
    modification time and inode. A movie of at most :data:`CONTENT_HASH_BYTES` is
    fingerprinted by its bytes as well (a rewrite of the same size within the file system's
    time resolution, or with the old time put back, is caught too).

    Returns
    -------
    str
        A SHA-1 hex digest; ``""`` when the path does not exist.
    """
    import hashlib

    p = Path(path)
    if not p.exists():
        return ""
    files = store_files(p) if p.is_dir() else {"": (p.stat().st_size, p.stat().st_mtime_ns)}
    digest = hashlib.sha1(repr(sorted(files.items())).encode())
    if not p.is_dir():
        digest.update(repr(file_identity(p)).encode())
    if sum(size for size, _ in files.values()) <= CONTENT_HASH_BYTES:
        for rel in sorted(files):
            full = p / rel if rel else p
            try:
                digest.update(full.read_bytes())
            except OSError:  # removed meanwhile: the listing above differs already
                continue
    return digest.hexdigest()
