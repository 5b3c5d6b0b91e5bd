"""A table's JSON sidecar: the options it was measured with, and the pairing of the two files.

``features.csv.json`` beside ``features.csv`` holds who wrote the table, what it is, its
options and the table file's size and SHA-256 (``table_bytes``, ``table_sha256``).
:func:`paired_bytes` reads a table with its sidecar and checks that they belong together,
waiting a moment for a writer that is replacing the two, and refuses a table whose sidecar is
of another write in plain words; a table changed after its sidecar was written (edited by
hand) is read with a warning. A copy saved under another name with the sidecar copied beside
it is the user's own pair and reads as it is. Tables of older versions carried their options
in a first ``# pfsdm: {json}`` comment line (:data:`HEADER_PREFIX`); they still read.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..core.params import check_record
from ..errors import InputError

__all__ = ["HEADER_PREFIX", "SIDECAR_SUFFIX", "read_options", "read_sidecar", "sidecar_path",
           "to_jsonable"]

#: The comment line of older tables (before the sidecar) started with this.
HEADER_PREFIX = "# pfsdm: "
#: ``features.csv`` -> ``features.csv.json``.
SIDECAR_SUFFIX = ".json"


def sidecar_path(path: str | os.PathLike) -> Path:
    """The sidecar of a table: ``features.csv`` -> ``features.csv.json``."""
    path = Path(path)
    return path.with_name(path.name + SIDECAR_SUFFIX)


def to_jsonable(value: Any) -> Any:
    """Convert numpy scalars/arrays (and nested containers) into JSON-friendly values."""
    if isinstance(value, Mapping):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    return repr(value)


def size_and_digest(path: str | os.PathLike) -> tuple[int, str]:
    """A file's size in bytes and its SHA-256 (hex)."""
    digest = hashlib.sha256()
    size = 0
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(2**20), b""):
            digest.update(block)
            size += len(block)
    return size, digest.hexdigest()


#: How often, and how long apart, a reader re-reads a table whose sidecar does not match it
#: (a writer replacing the two files in turn takes milliseconds).
PAIR_TRIES, PAIR_WAIT = 10, 0.1


def paired_bytes(path: Path, strict: bool = False) -> tuple[bytes, dict[str, Any] | None]:
    """The bytes of a table and its sidecar, checked to belong together.

    The sidecar of a table written by :func:`write_table_csv` records the table's size and
    SHA-256; when they do not match the file, another run may be replacing the two right now:
    both are read again, up to :data:`PAIR_TRIES` times. A sidecar without them (older
    tables), or naming another file (a copy the user made, sidecar copied beside it), is
    taken as it is.
    """
    side = read_sidecar(path)
    for _ in range(PAIR_TRIES):
        data = path.read_bytes()
        if side is None or "table_sha256" not in side or side.get("csv") != path.name:
            return data, side
        if (len(data) == side.get("table_bytes")
                and hashlib.sha256(data).hexdigest() == side["table_sha256"]):
            return data, side
        time.sleep(PAIR_WAIT)
        side = read_sidecar(path)
    if not strict and changed_after(path):
        warnings.warn(
            f"{path} was changed after pfsdm wrote it (its size or checksum is not the one "
            f"{sidecar_path(path).name} records: edited by hand or by another program?); it "
            "is read with the options of that sidecar", UserWarning, stacklevel=3)
        return data, side
    raise InputError(
        f"{path} and {sidecar_path(path).name} do not belong together: the sidecar was written "
        f"with a table of {side.get('table_bytes')} bytes (SHA-256 {str(side['table_sha256'])[:12]}"
        f"…), the file has {len(data)} bytes (SHA-256 {hashlib.sha256(data).hexdigest()[:12]}…). "
        "Another pfsdm run may be writing it (wait for it to finish), a run was stopped between "
        "the two files, or the table was changed in place. Write the table again; to read an "
        "edited table, save it under a new name with its sidecar copied beside it"
    )


def changed_after(path: Path) -> bool:
    """Whether a table was modified after its sidecar was written (an edit): the writer
    writes the table's temporary file before the sidecar, so in the pair it wrote, and in a
    pair where the sidecar is of a later write, the table is the older file."""
    try:
        return path.stat().st_mtime_ns > sidecar_path(path).stat().st_mtime_ns
    except OSError:
        return False


def read_options(path: str | os.PathLike) -> dict[str, Any] | None:
    """The options a table was written with (checked as :func:`read_table_csv` checks them):
    from its sidecar, else from the comment line of an older table; None when neither is
    there."""
    side = read_sidecar(path)
    options = (side.get("options") or {}) if side is not None else legacy_options(path)
    if options is not None:
        check_record(options, f"the options of {path}"
                     + (" (its .json file)" if side is not None else ""))
        options = dict(options)
    return options


def legacy_options(path: str | os.PathLike) -> dict[str, Any] | None:
    try:
        with open(path, encoding="utf-8") as handle:
            first = handle.readline()
    except UnicodeDecodeError:
        return None
    if first.startswith(HEADER_PREFIX):
        return json.loads(first[len(HEADER_PREFIX):])
    return None


def read_sidecar(path: str | os.PathLike) -> dict[str, Any] | None:
    """The sidecar of a table as a dict (None when there is none)."""
    side = sidecar_path(path)
    if not side.is_file():
        return None
    try:
        data = json.loads(side.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(
            f"{side} is damaged ({exc}); delete it and write the table again"
        ) from None
    if not isinstance(data, dict) or "options" not in data:
        raise InputError(f"{side} is not a napari-pfsdm sidecar (no 'options' in it)")
    return data


def is_pfsdm_sidecar(path: Path) -> bool:
    """Whether ``path`` is a sidecar napari-pfsdm wrote (JSON naming napari-pfsdm)."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError):
        return False
    return isinstance(data, dict) and str(data.get("written_by", "")).startswith("napari-pfsdm")


