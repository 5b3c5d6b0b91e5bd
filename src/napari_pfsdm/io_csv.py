"""Tables as plain CSV files, with what they need to be read correctly in a JSON sidecar.

A table written by :func:`write_table_csv` is two files::

    features.csv        a plain CSV: pandas.read_csv(path), Excel or R read it as it is
    features.csv.json   {"written_by": "napari-pfsdm 0.1.0", "table": "features",
                         "options": {"n_fourier": 10, "weights": [...], ...}, ...}

:func:`read_table_csv` reads the table with its sidecar's options in ``df.attrs["pfsdm"]``
(numbers round-trip exactly), checked first (:func:`~napari_pfsdm.core.params.check_record`:
an option out of its range, a NaN or negative weight, or a wrong number of weights is refused
in plain words before the table is read). A copy of the table re-saved by pandas
(``df.to_csv(path)``, even with its index) reads back the same, as long as the sidecar travels
with it. Tables of older versions, which carried the options in a first ``# pfsdm: {json}``
comment line, still read.

Text cells a spreadsheet would run as a formula (starting with ``= + - @``, a tab or a
carriage return: a movie or group named ``=cmd|...``) are written with a single quote in
front, so that Excel or LibreOffice show them as text; numbers, negative ones included, are
left alone. The sidecar says so (``"text_escape": "'"``) and :func:`read_table_csv` removes
exactly that quote again: names read back as they were.

A name ending in ``.parquet`` is written (and read) as Apache Parquet instead, with the same
sidecar (``features.parquet.json``): the columns and their dtypes come back exactly as written,
and reading or writing 50,000 rows x 350 columns takes a fraction of a second where CSV takes
seconds (docs/benchmarks.md). It needs pyarrow: ``pip install "napari-pfsdm[parquet]"``.
A Parquet file is recognised by its first bytes too, whatever its name.

Writing is atomic: each file goes to a temporary file of a unique name, created exclusively in
the same folder (never through a file or symbolic link already there), which then replaces the
target in one step, so an error or a killed process never leaves a half-written file under the
final name. The files get the permissions of any new file (``0o666`` less the umask), not the
``0o600`` of a temporary file. :func:`check_overwrite` refuses to replace a file that this
program did not write (a user's image given as ``-o`` by mistake).

A table and its sidecar are a pair: the sidecar records the table file's size and SHA-256
(``table_bytes``, ``table_sha256``), and the reader checks them, waiting a moment for a writer
that is replacing the two, and refuses a table whose sidecar belongs to another write in plain
words; a table changed after its sidecar was written (edited by hand) is read with a warning.
A copy saved under another name with the sidecar copied beside it is the user's own pair and
reads as it is. :func:`output_lock` lets one run at a time write an output, and
:func:`remove_leftovers` removes what a killed run left behind.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import json
import os
import re
import socket
import tempfile
import threading
import time
import warnings
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import IO, Any

import numpy as np
import pandas as pd

from .core.params import check_record
from .core.table_options import plain, set_options, table_options
from .core.table_schema import NO_TRACK, TRACK_COLUMN
from .errors import InputError

__all__ = [
    "HEADER_PREFIX",
    "PARQUET_INSTALL",
    "SIDECAR_SUFFIX",
    "atomic_write",
    "check_overwrite",
    "is_parquet",
    "lock_path",
    "output_files",
    "output_lock",
    "read_options",
    "read_sidecar",
    "read_table_csv",
    "remove_leftovers",
    "escape_formulas",
    "unescape_formulas",
    "sidecar_path",
    "write_table_csv",
    "written_by_pfsdm",
]

# pandas < 3 needs float_precision="round_trip" to read floats back exactly; pandas 3 does
# it by default and deprecates the argument.
_FLOAT_KW: dict[str, Any] = (
    {} if int(pd.__version__.split(".")[0]) >= 3 else {"float_precision": "round_trip"}
)

#: The comment line of older tables (before the sidecar) started with this.
HEADER_PREFIX = "# pfsdm: "
#: ``features.csv`` -> ``features.csv.json``.
SIDECAR_SUFFIX = ".json"
#: Marker written into PNG files (metadata ``Software``) so that a re-run may replace them.
PNG_SOFTWARE = "napari-pfsdm"
#: What marks an HTML report napari-pfsdm wrote (napari_pfsdm.analysis.report.GENERATOR), in
#: its first few kilobytes.
HTML_GENERATOR = b'<meta name="generator" content="napari-pfsdm'

_UMASK_LOCK = threading.Lock()

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


def _pyarrow(path: Path, doing: str) -> Any:
    try:
        import pyarrow
        import pyarrow.parquet  # noqa: F401
    except ImportError:
        raise InputError(
            f"{doing} {path} as Parquet needs the pyarrow package, which is not installed: "
            f"{PARQUET_INSTALL} (or use a .csv name)"
        ) from None
    return pyarrow


def _version() -> str:
    from ._version import __version__

    return f"napari-pfsdm {__version__}"


def _to_jsonable(value: Any) -> Any:
    """Convert numpy scalars/arrays (and nested containers) into JSON-friendly values."""
    if isinstance(value, Mapping):
        return {str(k): _to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_to_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _to_jsonable(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    return repr(value)


def _new_file_mode() -> int:
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


def sidecar_path(path: str | os.PathLike) -> Path:
    """The sidecar of a table: ``features.csv`` -> ``features.csv.json``."""
    path = Path(path)
    return path.with_name(path.name + SIDECAR_SUFFIX)


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
    tmp = _write_temp(path, write, binary=binary)
    try:
        os.replace(tmp, path)
    except BaseException:
        _unlink(tmp)
        raise
    return path


def _unlink(path: str | os.PathLike) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass


def _write_temp(path: Path, write: Callable[[IO], None], *, binary: bool = False) -> str:
    """Fill a temporary file next to ``path`` (umask permissions, synced); return its name."""
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(
            f"cannot write {path}: the folder {folder} does not exist; create it first"
        )
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    except OSError as exc:
        raise InputError(
            f"cannot write {path}: the folder {folder} is not writable ({exc.strerror})"
        ) from exc
    try:
        os.fchmod(fd, _new_file_mode())  # mkstemp makes 0o600: colleagues could not read it
        kw: dict[str, Any] = {} if binary else {"encoding": "utf-8", "newline": ""}
        with os.fdopen(fd, "wb" if binary else "w", **kw) as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
    except BaseException:
        _unlink(tmp)
        raise
    return tmp


def save_figure(fig: Any, path: str | os.PathLike, **kwargs: Any) -> Path:
    """Save a matplotlib figure as PNG atomically, marked as written by napari-pfsdm."""
    meta = {"Software": f"{PNG_SOFTWARE} {_version().split()[-1]}"}
    return atomic_write(
        path, lambda h: fig.savefig(h, format="png", metadata=meta, **kwargs), binary=True
    )


#: A text cell that a spreadsheet would run as a formula starts with one of these (OWASP's
#: "CSV injection"); such a cell is written with a single quote in front, which a spreadsheet
#: shows as text and :func:`read_table_csv` removes again.
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")
#: A cell written with the quote: the quote(s), then a formula's first character. A name that
#: already starts with quotes before such a character gets one more, so that reading back
#: removes exactly the one that writing added.
_ESCAPED = re.compile(r"'+[=+\-@\t\r]")
_TO_ESCAPE = re.compile(r"'*[=+\-@\t\r]")
#: The sidecar's entry saying that text cells were written escaped (its value: the prefix).
ESCAPE_KEY = "text_escape"


def _escape_cell(value: Any) -> Any:
    if isinstance(value, str) and _TO_ESCAPE.match(value):
        return "'" + value
    return value


def _unescape_cell(value: Any) -> Any:
    if isinstance(value, str) and _ESCAPED.match(value):
        return value[1:]
    return value


def _text_like(values: pd.Index | pd.Series) -> bool:
    return values.dtype == object or pd.api.types.is_string_dtype(values.dtype)


def _has_carriage_return(df: pd.DataFrame) -> bool:
    """Whether a text cell, column name or index label of ``df`` holds a carriage return."""
    names = [*df.columns, *(df.index if _text_like(df.index) else [])]
    if any(isinstance(v, str) and "\r" in v for v in names):
        return True
    return any(df[c].map(lambda v: isinstance(v, str) and "\r" in v).any()
               for c in df.columns if _text_like(df[c]))


def escape_formulas(df: pd.DataFrame) -> pd.DataFrame:
    """A copy of ``df`` whose text cells (and text column names and index labels) that a
    spreadsheet would run as a formula (starting with ``= + - @``, a tab or a carriage
    return) start with a single quote instead; numbers, negative ones included, are left as
    they are. :func:`unescape_formulas` undoes it exactly.

    Examples
    --------
    >>> import pandas as pd
    >>> escape_formulas(pd.DataFrame({"movie": ["=1+1", "e1"], "x": [-1.5, 2.0]})).values.tolist()
    [["'=1+1", -1.5], ['e1', 2.0]]
    """
    # the numbers are not copied: only text columns change
    return _map_text(df.copy(deep=False), _escape_cell)


def unescape_formulas(df: pd.DataFrame) -> pd.DataFrame:
    """Undo :func:`escape_formulas` (in place; returns ``df``): one leading quote removed from
    text cells, column names and index labels that start with quotes and then ``= + - @``,
    a tab or a carriage return."""
    return _map_text(df, _unescape_cell)


def _map_text(df: pd.DataFrame, cell) -> pd.DataFrame:
    """``cell`` applied to ``df``'s text columns, column names and text index (in place)."""
    for col in df.columns:
        if _text_like(df[col]):
            df[col] = df[col].map(cell)
    df.columns = pd.Index([cell(c) for c in df.columns], name=df.columns.name)
    if _text_like(df.index) and not isinstance(df.index, pd.MultiIndex):
        df.index = pd.Index([cell(v) for v in df.index], name=df.index.name)
    return df


#: Cells pandas formats per chunk when writing a CSV. Each chunk holds Python's lock from
#: start to end: at pandas' default (100,000 cells) a worker thread writing a 3,000 × 3,001
#: distance table froze the GUI thread for up to 164 ms per chunk; at 15,000 for 33 ms, in the
#: same total time (17.1 against 17.5 s; a /tmp probe, a thread writing while the main
#: thread slept in 5 ms steps).
CSV_CHUNK_CELLS = 10_000


def write_table_csv(
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
    with the same sidecar; :func:`read_table_csv` reads either back.

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
    >>> _ = write_table_csv(df, p, {"n_fourier": 10})
    >>> read_table_csv(p).attrs["pfsdm"]
    {'n_fourier': 10}
    >>> list(pd.read_csv(p).columns)
    ['frame', 'label', 'area']
    """
    if options is None:
        options = table_options(df)
    side = {
        "written_by": _version(),
        "table": table_type,
        "csv": Path(path).name,
        "rows": len(df),
        "options": _to_jsonable(dict(options)),
        **_to_jsonable(dict(extra or {})),
    }
    out = plain(df)  # pandas must not try to serialise attrs itself

    path = Path(path)
    if is_parquet(path):
        _pyarrow(path, "writing")
        side["format"] = "parquet"

        def fill(handle: IO) -> None:
            out.to_parquet(handle, engine="pyarrow", index=index)

        tmp = _write_temp(path, fill, binary=True)
    else:
        # text a spreadsheet would run as a formula is written so that it is not run
        out = escape_formulas(out)
        side[ESCAPE_KEY] = "'"
        # Python's csv writer quotes a cell holding "\n" (the line end) but not a lone "\r",
        # which every reader takes for a line end: such a table has every text cell quoted
        quoting = csv.QUOTE_NONNUMERIC if _has_carriage_return(out) else csv.QUOTE_MINIMAL
        # the table first into a temporary file: if that fails, neither file has changed
        rows = max(1, CSV_CHUNK_CELLS // max(1, out.shape[1]))
        tmp = _write_temp(path, lambda h: out.to_csv(h, index=index, lineterminator="\n",
                                                     chunksize=rows, quoting=quoting))
    try:
        side["table_bytes"], side["table_sha256"] = _size_and_digest(tmp)
        text = json.dumps(side, indent=1) + "\n"
        # the sidecar first: a reader in between sees a pair that does not match, and waits
        atomic_write(sidecar_path(path), lambda h: h.write(text))
        os.replace(tmp, path)
    except BaseException:
        _unlink(tmp)
        raise
    return path


def _size_and_digest(path: str | os.PathLike) -> tuple[int, str]:
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


def _paired_bytes(path: Path, strict: bool = False) -> tuple[bytes, dict[str, Any] | None]:
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
    if not strict and _changed_after(path):
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


def _changed_after(path: Path) -> bool:
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
    options = (side.get("options") or {}) if side is not None else _legacy_options(path)
    if options is not None:
        check_record(options, f"the options of {path}"
                     + (" (its .json file)" if side is not None else ""))
        options = dict(options)
    return options


def _legacy_options(path: str | os.PathLike) -> dict[str, Any] | None:
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


def read_table_csv(path: str | os.PathLike, *, index_col: int | None = None,
                   strict: bool = False) -> pd.DataFrame:
    """Read a table written by :func:`write_table_csv` (or by pandas from one).

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
    legacy_options = _legacy_options(path)  # the first line is read once
    data, side = _paired_bytes(path, strict)  # the table's bytes, checked against its sidecar
    side_options = (side.get("options") or {}) if side is not None else legacy_options
    if side_options is not None:  # before the table is read: refused in plain words
        check_record(side_options, f"the options of {path}"
                     + (" (its .json file)" if side is not None else ""))
        side_options = dict(side_options)
    legacy = legacy_options is not None
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
    if side_options is not None:
        set_options(df, side_options)
    return df


def _read_parquet(path: Path, strict: bool = False) -> pd.DataFrame:
    """A Parquet table with its sidecar's options: the columns and dtypes as written."""
    _pyarrow(path, "reading")
    data, side = _paired_bytes(path, strict)  # the table's bytes, checked against its sidecar
    if side is not None:  # before the table is read: refused in plain words
        check_record(side.get("options") or {}, f"the options of {path} (its .json file)")
    try:
        df = pd.read_parquet(io.BytesIO(data), engine="pyarrow")
    except Exception as exc:  # pyarrow's own errors: a damaged or truncated file
        raise InputError(f"{path} is not a readable Parquet table ({exc})") from None
    df = plain(df)  # pandas restores attrs from the file's metadata: the sidecar's count
    if side is not None:
        set_options(df, dict(side.get("options") or {}))
    return df


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


def _is_pfsdm_sidecar(path: Path) -> bool:
    """Whether ``path`` is a sidecar napari-pfsdm wrote (JSON naming napari-pfsdm)."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError):
        return False
    return isinstance(data, dict) and str(data.get("written_by", "")).startswith("napari-pfsdm")


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
                                                     and _is_pfsdm_sidecar(side)):
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
            _unlink(entry.path)
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
            fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, _new_file_mode())
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
        _unlink(lock)  # while still holding it: a waiting run sees a removed file and retries
        os.close(fd)


def _exclusive_lock(path: Path, lock: Path) -> Iterator[Path]:  # pragma: no cover - Windows
    """:func:`output_lock` where there is no ``flock``: the lock file created exclusively;
    a killed run's lock stays, and the message says to delete it."""
    try:
        fd = os.open(lock, os.O_WRONLY | os.O_CREAT | os.O_EXCL, _new_file_mode())
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
        _unlink(lock)
