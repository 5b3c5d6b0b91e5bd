"""Tables as plain CSV (or Parquet) files, with what they need to be read correctly in a sidecar.

:func:`write_table` writes a table and its sidecar (:mod:`.sidecar`) atomically
(:mod:`.atomic`), text that a spreadsheet would run escaped (:mod:`.formulas`);
:func:`read_table` reads it back with the sidecar's options in ``df.attrs["pfsdm"]``,
checked first (numbers round-trip exactly; an option out of its range is refused in plain
words before the table is read). A copy of the table re-saved by pandas (``df.to_csv(path)``,
even with its index) reads back the same, as long as the sidecar travels with it. A name
ending in ``.parquet`` is written (and read) as Apache Parquet instead, with the same sidecar;
it needs pyarrow (:data:`PARQUET_INSTALL`). A Parquet file is recognised by its first bytes
too, whatever its name.
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import IO, Any

import numpy as np
import pandas as pd

from ..core.params import check_record
from ..core.table_options import plain, set_options, table_options
from ..core.table_schema import NO_TRACK, TRACK_COLUMN
from ..errors import InputError
from .atomic import atomic_write, unlink_quietly, write_temp, writer_name
from .formulas import ESCAPE_KEY, escape_formulas, has_carriage_return, unescape_formulas
from .sidecar import (
    content_summary,
    judge_pair,
    legacy_options,
    paired_bytes,
    sidecar_path,
    size_and_digest,
    to_jsonable,
)

__all__ = ["CSV_CHUNK_CELLS", "PARQUET_INSTALL", "TEXT_COLUMNS", "is_parquet", "read_table",
           "require_pyarrow", "write_table"]

# pandas < 3 needs float_precision="round_trip" to read floats back exactly; pandas 3 does
# it by default and deprecates the argument.
_FLOAT_KW: dict[str, Any] = (
    {} if int(pd.__version__.split(".")[0]) >= 3 else {"float_precision": "round_trip"}
)


#: What to install for Parquet tables (the ``parquet`` extra: pyarrow).
PARQUET_INSTALL = 'pip install "napari-pfsdm[parquet]"'


def is_parquet(path: str | os.PathLike) -> bool:
    """Whether ``path`` is (to be) a Parquet table: its name ends in ``.parquet``, or the file
    exists and starts with Parquet's magic bytes ``PAR1``."""
    path = Path(path)
    if path.suffix.lower() == ".parquet":
        return True
    try:
        with open(path, "rb") as handle:
            return handle.read(4) == b"PAR1"
    except OSError:
        return False


def require_pyarrow(path: Path, doing: str) -> Any:
    try:
        import pyarrow
        import pyarrow.parquet  # noqa: F401
    except ImportError:
        raise InputError(
            f"{doing} {path} as Parquet needs the pyarrow package, which is not installed: "
            f"{PARQUET_INSTALL} (or use a .csv name)"
        ) from None
    return pyarrow

#: Cells pandas formats per chunk when writing a CSV. Each chunk holds Python's lock from
#: start to end: at pandas' default (100,000 cells) a worker thread writing a 3,000 × 3,001
#: distance table froze the GUI thread for up to 164 ms per chunk; at 15,000 for 33 ms, in the
#: same total time (17.1 against 17.5 s; a /tmp probe, a thread writing while the main
#: thread slept in 5 ms steps).
CSV_CHUNK_CELLS = 10_000


def write_table(
    df: pd.DataFrame,
    path: str | os.PathLike,
    options: Mapping[str, Any] | None = None,
    *,
    index: bool = False,
    table_type: str = "table",
    extra: Mapping[str, Any] | None = None,
) -> Path:
    """Write a table as plain CSV (or Parquet) plus its JSON sidecar (``path + ".json"``).

    A ``path`` ending in ``.parquet`` writes Apache Parquet (pyarrow, the ``parquet`` extra)
    with the same sidecar; :func:`read_table` reads either back.

    Parameters
    ----------
    df : pandas.DataFrame
        The table (e.g. from :func:`napari_pfsdm.measure`).
    path : str or PathLike
        Output file. Both files are written atomically (nothing changes when writing the
        table fails), with the umask's permissions.
    options : mapping, optional
        The options to record (sidecar key ``"options"``). Defaults to ``df.attrs["pfsdm"]``.
        numpy arrays and scalars are stored as JSON lists and numbers.
    index : bool
        Also write the index (e.g. for a distance matrix). Default False.
    table_type : str
        What the table is (``"features"``, ``"pca"``, ``"distances"``, ...), for the sidecar.
    extra : mapping, optional
        More sidecar entries, e.g. ``{"left_out": [...]}`` for rows that were left out.

    Returns
    -------
    Path
        The table's path.

    Examples
    --------
    >>> import pandas as pd, tempfile, os
    >>> df = pd.DataFrame({"frame": [0, 1], "label": [1, 1], "area": [10.5, 12.25]})
    >>> p = os.path.join(tempfile.mkdtemp(), "t.csv")
    >>> _ = write_table(df, p, {"n_fourier": 10})
    >>> read_table(p).attrs["pfsdm"]
    {'n_fourier': 10}
    >>> list(pd.read_csv(p).columns)
    ['frame', 'label', 'area']
    """
    if options is None:
        options = table_options(df)
    side = {
        "written_by": writer_name(),
        "table": table_type,
        "csv": Path(path).name,
        "rows": len(df),
        "options": to_jsonable(dict(options)),
        **to_jsonable(dict(extra or {})),
    }
    out = plain(df)  # pandas must not try to serialise attrs itself
    side["index"] = bool(index)
    side["content"] = content_summary(out, index)  # what it holds, for judge_pair

    path = Path(path)
    if is_parquet(path):
        require_pyarrow(path, "writing")
        side["format"] = "parquet"

        def fill(handle: IO) -> None:
            out.to_parquet(handle, engine="pyarrow", index=index)

        tmp = write_temp(path, fill, binary=True)
    else:
        # text a spreadsheet would run as a formula is written so that it is not run
        out = escape_formulas(out)
        side[ESCAPE_KEY] = "'"
        # Python's csv writer quotes a cell holding "\n" (the line end) but not a lone "\r",
        # which every reader takes for a line end: such a table has every text cell quoted
        quoting = csv.QUOTE_NONNUMERIC if has_carriage_return(out) else csv.QUOTE_MINIMAL
        # the table first into a temporary file: if that fails, neither file has changed
        rows = max(1, CSV_CHUNK_CELLS // max(1, out.shape[1]))
        tmp = write_temp(path, lambda h: out.to_csv(h, index=index, lineterminator="\n",
                                                     chunksize=rows, quoting=quoting))
    try:
        side["table_bytes"], side["table_sha256"] = size_and_digest(tmp)
        text = json.dumps(side, indent=1) + "\n"
        # the sidecar first: a reader in between sees a pair that does not match, and waits
        atomic_write(sidecar_path(path), lambda h: h.write(text))
        os.replace(tmp, path)
    except BaseException:
        unlink_quietly(tmp)
        raise
    return path


def _looks_binary(path: Path) -> str | None:
    """A plain-words name for a binary file (TIFF, PNG, Zarr, ...) given where a CSV is
    expected, or None when it looks like text."""
    if path.is_dir():
        return "a folder (a Zarr movie?)" if path.suffix.lower() == ".zarr" else "a folder"
    with open(path, "rb") as handle:
        head = handle.read(2048)
    if head[:4] in (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"):
        return "a TIFF image"
    if head[:8] == b"\x89PNG\r\n\x1a\n":
        return "a PNG image"
    if head[:4] == b"PAR1":
        return "a Parquet file"
    if b"\x00" in head:
        return "a binary file"
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start < len(head) - 4:  # not just a character cut at the end of the block
            return "not a UTF-8 text file"
    return None


#: Columns read back as text, as written: names and messages, never numbers or NaN.
TEXT_COLUMNS = ("movie", "group", "error", "warnings")

#: What pandas reads as missing by default (its documented ``na_values``), for the other columns.
_NA_WORDS = ["", "#N/A", "#N/A N/A", "#NA", "-1.#IND", "-1.#QNAN", "-NaN", "-nan", "1.#IND",
             "1.#QNAN", "<NA>", "N/A", "NA", "NULL", "NaN", "None", "n/a", "nan", "null"]


def read_table(path: str | os.PathLike, *, index_col: int | None = None,
                   strict: bool = False) -> pd.DataFrame:
    """Read a table written by :func:`write_table` (or by pandas from one).

    A Parquet table (a ``.parquet`` name, or a file starting with Parquet's magic bytes) is read
    with pyarrow: every column and dtype as written (``index_col`` is not needed: the index a
    table was written with comes back); the rest of this note is about CSV.

    Floats are parsed so that they round-trip exactly; the text columns (``movie``,
    ``group``, ``error``, ``warnings``: :data:`TEXT_COLUMNS`) come back as the strings written
    (``"001"`` stays ``"001"``, ``"NA"`` stays ``"NA"``) with ``""`` for empty cells,
    ``track_id`` as whole numbers (an empty cell: -1, no track); the sidecar's options are in
    ``df.attrs["pfsdm"]`` (older tables: from their ``# pfsdm:`` comment line; absent for a CSV
    from elsewhere). An unnamed first column holding 0, 1, 2, ... (the index pandas adds
    when re-saving) is dropped.

    Parameters
    ----------
    path : str or PathLike
        CSV file.
    index_col : int, optional
        Column to use as the index (e.g. 0 for a distance matrix written with ``index=True``).
    strict : bool
        A table that does not match its sidecar's size and checksum is refused (InputError)
        when it is older than the sidecar (the sidecar is of another write); a newer one (an
        edit) is read with a ``UserWarning``, unless ``strict``.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(f"cannot read {path}: no such file")
    if not path.is_file() and not path.is_dir():  # reading a pipe would wait for ever
        raise InputError(f"cannot read {path}: it is not a file (a pipe or a device?); give "
                         "the table's file")
    if path.is_file() and is_parquet(path):
        return _read_parquet(path, strict)
    what = _looks_binary(path)
    if what is not None:
        raise InputError(f"{path} is {what}, not a CSV table")
    old_options = legacy_options(path)  # the first line is read once
    data, side, matched = paired_bytes(path, strict)  # the table's bytes and its sidecar
    side_options = (side.get("options") or {}) if side is not None else old_options
    if side_options is not None:  # before the table is read: refused in plain words
        check_record(side_options, f"the options of {path}"
                     + (" (its .json file)" if side is not None else ""))
        side_options = dict(side_options)
    legacy = old_options is not None
    try:
        header = pd.read_csv(io.BytesIO(data), skiprows=1 if legacy else 0, nrows=0,
                             index_col=index_col)
        names = [c for c in [header.index.name, *header.columns] if c is not None]
        text = [c for c in TEXT_COLUMNS if c in names]
        # text columns keep every value as written ("001", "NA", "None" are movie names);
        # the other columns read pandas' usual missing-value words as NaN
        df = pd.read_csv(io.BytesIO(data), skiprows=1 if legacy else 0, **_FLOAT_KW,
                         index_col=index_col, dtype=dict.fromkeys(text, str),
                         keep_default_na=False,
                         na_values={c: _NA_WORDS for c in names if c not in text})
    except pd.errors.EmptyDataError:
        raise InputError(f"{path} is empty: it holds no table") from None
    except (pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise InputError(f"{path} is not a readable CSV table ({exc})") from None
    text_cols = text
    first = df.columns[0] if len(df.columns) else None
    if (index_col is None and isinstance(first, str) and first.startswith("Unnamed: 0")
            and df[first].dtype.kind in "iu"
            and np.array_equal(df[first].to_numpy(), np.arange(len(df)))):
        df = df.drop(columns=first)
    for col in text_cols:
        if col in df.columns:
            df[col] = df[col].fillna("")
    if TRACK_COLUMN in df.columns and df[TRACK_COLUMN].dtype.kind == "f":
        # empty cells (a table edited by hand): no track, and whole numbers again
        tracks = df[TRACK_COLUMN].fillna(NO_TRACK)
        if np.array_equal(tracks, np.round(tracks)):
            df[TRACK_COLUMN] = tracks.astype(np.int64)
    if side is not None and side.get(ESCAPE_KEY) == "'":
        unescape_formulas(df)  # what writing added, exactly
    if not matched:  # other bytes: the same table written again, an edit, or another's pair
        _judge(df, side, path, data, strict, index_col)
    if side_options is not None:
        set_options(df, side_options)
    return df


def _judge(df: pd.DataFrame, side: dict, path: Path, data: bytes, strict: bool,
           index_col: int | None) -> None:
    """:func:`~.sidecar.judge_pair` on the table as read (its index as the writer wrote it)."""
    written_index = bool(side.get("index"))
    if written_index and index_col is None and len(df.columns):
        df = df.set_index(df.columns[0])
    judge_pair(df, side, path, data, strict, index=written_index or index_col is not None)


def _read_parquet(path: Path, strict: bool = False) -> pd.DataFrame:
    """A Parquet table with its sidecar's options: the columns and dtypes as written."""
    require_pyarrow(path, "reading")
    data, side, matched = paired_bytes(path, strict)  # the table's bytes and its sidecar
    if side is not None:  # before the table is read: refused in plain words
        check_record(side.get("options") or {}, f"the options of {path} (its .json file)")
    try:
        df = pd.read_parquet(io.BytesIO(data), engine="pyarrow")
    except Exception as exc:  # pyarrow's own errors: a damaged or truncated file
        raise InputError(f"{path} is not a readable Parquet table ({exc})") from None
    df = plain(df)  # pandas restores attrs from the file's metadata: the sidecar's count
    if not matched:
        judge_pair(df, side, path, data, strict, index=bool(side.get("index")))
    if side is not None:
        set_options(df, dict(side.get("options") or {}))
    return df
