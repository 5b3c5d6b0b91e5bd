"""A table's JSON sidecar: the options it was measured with, and the pairing of the two files.

``features.csv.json`` beside ``features.csv`` holds who wrote the table, what it is, its
options, the table file's size and SHA-256 (``table_bytes``, ``table_sha256``) and a
fingerprint of what it holds (``content``: its rows, its columns, the exact values of its
whole-number and text columns, sums of each column of decimals). :func:`paired_bytes` reads a
table's bytes with its sidecar, waiting a moment for a writer that is replacing the two;
:func:`judge_pair` then decides, whatever file name the sidecar records: the same bytes, or the
same content written again (a copy re-saved by pandas or a spreadsheet), is the sidecar's
table; a table changed after its sidecar was written (edited by hand) is read with a warning
that says what changed; anything else (another run's sidecar copied beside it) is refused in
plain words. Tables of older versions carried their options in a first ``# pfsdm: {json}``
comment line (:data:`HEADER_PREFIX`); they still read.
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

__all__ = ["HEADER_PREFIX", "SIDECAR_SUFFIX", "content_summary", "judge_pair", "read_options",
           "read_sidecar", "sidecar_path", "to_jsonable"]

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


def paired_bytes(path: Path, strict: bool = False) -> tuple[bytes, dict[str, Any] | None, bool]:
    """The bytes of a table, its sidecar, and whether the bytes are those the sidecar records.

    The sidecar of a table written by :func:`write_table` records the table's size and
    SHA-256; when they do not match the file, another run may be replacing the two right now:
    both are read again, up to :data:`PAIR_TRIES` times. A sidecar without them (older
    tables) is taken as it is. Whether a table that still differs belongs to its sidecar is
    :func:`judge_pair`'s to say, from what the table holds.
    """
    side = read_sidecar(path)
    for _ in range(PAIR_TRIES):
        data = path.read_bytes()
        if side is None or "table_sha256" not in side:
            return data, side, True
        if (len(data) == side.get("table_bytes")
                and hashlib.sha256(data).hexdigest() == side["table_sha256"]):
            return data, side, True
        time.sleep(PAIR_WAIT)
        side = read_sidecar(path)
    return data, side, False


def content_summary(df: Any, index: bool = False) -> dict[str, Any]:
    """A fingerprint of what a table holds, the same for every file that reads back as it
    (a copy re-saved by pandas, a spreadsheet's CSV): its rows and columns, a SHA-256 of its
    whole-number and text columns' values (as text) and of where its decimal columns hold
    NaN or infinities, and per decimal column the sum, the row-weighted sum and the sum of
    magnitudes of its finite values (compared within rounding, :func:`same_content`).

    Parameters
    ----------
    df : pandas.DataFrame
        The table as written (or as read back).
    index : bool
        The index is part of the table (written as its first column).
    """
    import pandas as pd

    frame = df.reset_index() if index else df
    digest = hashlib.sha256()
    sums: dict[str, list[float]] = {}
    n = len(frame)
    weights = (np.arange(n, dtype=float) + 1.0) / max(n, 1)
    for i, col in enumerate(frame.columns):
        name = "" if index and i == 0 else str(col)
        values = frame.iloc[:, i]
        digest.update(b"\x1e" + name.encode("utf-8", "surrogatepass"))
        if values.dtype.kind == "f":
            x = values.to_numpy(dtype=float)
            finite = np.isfinite(x)
            digest.update(b"f" + np.packbits(np.isnan(x)).tobytes()
                          + np.packbits(x == np.inf).tobytes()
                          + np.packbits(x == -np.inf).tobytes())
            f = np.where(finite, x, 0.0)
            sums[name] = [float(f.sum()), float((f * weights).sum()), float(np.abs(f).sum())]
        else:
            text = ["" if v is None or (isinstance(v, float) and np.isnan(v)) else str(v)
                    for v in values.tolist()] if values.dtype.kind == "O" else \
                pd.Series(values).astype(str).tolist()
            digest.update(b"t" + "\x1f".join(text).encode("utf-8", "surrogatepass"))
    return {"rows": n, "columns": [str(c) for c in frame.columns][int(index):],
            "exact_sha256": digest.hexdigest(), "sums": sums}


#: Relative tolerance of :func:`same_content` on the sums of decimal columns: far above the
#: rounding of a table written and read again, far below any edit or other run.
CONTENT_RTOL = 1e-9


def content_changes(now: dict[str, Any], was: dict[str, Any]) -> list[str]:
    """What differs between two :func:`content_summary` fingerprints, in words ([] when
    they describe the same table)."""
    out = []
    if now.get("rows") != was.get("rows"):
        out.append(f"{now.get('rows')} rows where it had {was.get('rows')}")
    cols, old = list(now.get("columns", [])), list(was.get("columns", []))
    if cols != old:
        gone = [c for c in old if c not in cols]
        new = [c for c in cols if c not in old]
        def names(cols: list[str]) -> str:
            return (f"column{'s' if len(cols) > 1 else ''} {', '.join(cols[:3])}"
                    f"{' …' if len(cols) > 3 else ''}")

        parts = ([f"no {names(gone)}"] if gone else []) + \
            ([f"new {names(new)}"] if new else [])
        out.append(" and ".join(parts) or "its columns in another order")
    if out:
        return out
    differ = [c for c, (s, w, a) in (now.get("sums") or {}).items()
              if c not in (was.get("sums") or {}) or not _close(
                  (s, w), was["sums"][c][:2], max(a, was["sums"][c][2]))]
    if differ:
        out.append(f"other values in column{'s' if len(differ) > 1 else ''} "
                   f"{', '.join(differ[:3])}{' …' if len(differ) > 3 else ''}")
    if now.get("exact_sha256") != was.get("exact_sha256"):
        out.append("other values in its whole-number or text columns (ids, frames, names) "
                   "or other missing values")
    return out


def _close(now: tuple, was: Any, scale: float) -> bool:
    tol = CONTENT_RTOL * max(scale, 1e-300)
    return all(abs(float(a) - float(b)) <= tol for a, b in zip(now, was, strict=True))


def judge_pair(df: Any, side: dict[str, Any] | None, path: Path, data: bytes,
               strict: bool = False, index: bool = False) -> None:
    """Decide whether a table whose bytes are not those its sidecar records belongs to it
    (:func:`paired_bytes`), from what it holds: the same content (a copy re-saved by pandas
    or a spreadsheet) is read as it is; a table changed after its sidecar was written is read
    with a ``UserWarning`` saying what changed (refused with ``strict``); any other pair is
    refused (``InputError``), whatever file name the sidecar records.
    """
    changes: list[str] = ["other bytes than those its sidecar records"]
    recorded = side.get("content") if side is not None else None
    if isinstance(recorded, dict):
        changes = content_changes(content_summary(df, index), recorded)
        if not changes:
            return  # the same table, written again
    what = "; ".join(changes)
    if not strict and changed_after(path):
        warnings.warn(
            f"{path} was changed after pfsdm wrote it (it now has {what}: edited by hand or by "
            f"another program?); it is read with the options of {sidecar_path(path).name}",
            UserWarning, stacklevel=4)
        return
    got = hashlib.sha256(data).hexdigest()
    raise InputError(
        f"{path} and {sidecar_path(path).name} do not belong together: the table has {what} "
        f"(the sidecar was written with a table of {side.get('table_bytes')} bytes, SHA-256 "
        f"{str(side.get('table_sha256'))[:12]}…; the file has {len(data)} bytes, SHA-256 "
        f"{got[:12]}…). The sidecar may be another run's, copied beside this table; another "
        "pfsdm run may be writing it (wait for it to finish); or a run was stopped between "
        "the two files. Write the table again with pfsdm, or put its own sidecar beside it"
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
    """The options a table was written with (checked as :func:`read_table` checks them):
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


