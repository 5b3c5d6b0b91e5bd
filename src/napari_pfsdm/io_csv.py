"""Feature tables as CSV files that remember how they were made.

A table written by :func:`write_table_csv` starts with one comment line holding the
options used, as JSON::

    # pfsdm: {"n_fourier": 10, "mapping": "harmonic", ...}
    frame,label,area,...

:func:`read_table_csv` reads such a file back, with the options in
``df.attrs["pfsdm"]`` (numbers round-trip exactly). Writing is atomic: the table goes to a
temporary file in the same folder, which then replaces the target in one step, so an error
or a killed process never leaves a half-written CSV behind.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import IO, Any

import numpy as np
import pandas as pd

__all__ = ["HEADER_PREFIX", "atomic_write", "read_table_csv", "write_table_csv"]

# pandas < 3 needs float_precision="round_trip" to read floats back exactly; pandas 3 does
# it by default and deprecates the argument.
_FLOAT_KW: dict[str, Any] = (
    {} if int(pd.__version__.split(".")[0]) >= 3 else {"float_precision": "round_trip"}
)

#: The comment line that carries the options starts with this.
HEADER_PREFIX = "# pfsdm: "


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


def atomic_write(path: str | os.PathLike, write: Callable[[IO[str]], None]) -> Path:
    """Write a text file atomically.

    ``write(handle)`` fills a temporary file created in the target's folder; only when it
    returns without error is the temporary file moved onto ``path`` with :func:`os.replace`.
    On any error the temporary file is removed and ``path`` is left as it was.

    Parameters
    ----------
    path : str or PathLike
        Final file name. Its folder must exist and be writable.
    write : callable
        Called with an open text handle (UTF-8, ``newline=""``).

    Returns
    -------
    Path
        The path written.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ValueError(
            f"cannot write {path}: the folder {folder} does not exist; create it first"
        )
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    except OSError as exc:
        raise ValueError(
            f"cannot write {path}: the folder {folder} is not writable ({exc.strerror})"
        ) from exc
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return path


def write_table_csv(
    df: pd.DataFrame,
    path: str | os.PathLike,
    options: Mapping[str, Any] | None = None,
    *,
    index: bool = False,
) -> Path:
    """Write a table to CSV with its options in a ``# pfsdm: {json}`` header line.

    Parameters
    ----------
    df : pandas.DataFrame
        The table (e.g. from :func:`napari_pfsdm.measure`).
    path : str or PathLike
        Output file; written atomically (temporary file + :func:`os.replace`).
    options : mapping, optional
        Options to record. Defaults to ``df.attrs["pfsdm"]`` when present. numpy arrays and
        scalars are stored as JSON lists and numbers.
    index : bool
        Also write the index (e.g. for a distance matrix). Default False.

    Returns
    -------
    Path
        The path written.

    Examples
    --------
    >>> import pandas as pd, tempfile, os
    >>> df = pd.DataFrame({"frame": [0, 1], "label": [1, 1], "area": [10.5, 12.25]})
    >>> p = os.path.join(tempfile.mkdtemp(), "t.csv")
    >>> _ = write_table_csv(df, p, {"n_fourier": 10})
    >>> read_table_csv(p).attrs["pfsdm"]
    {'n_fourier': 10}
    """
    if options is None:
        options = df.attrs.get("pfsdm")
    header = ""
    if options is not None:
        header = HEADER_PREFIX + json.dumps(_to_jsonable(dict(options)), sort_keys=False) + "\n"

    out = df.copy()
    out.attrs = {}  # pandas must not try to serialise attrs itself

    def _write(handle: IO[str]) -> None:
        handle.write(header)
        out.to_csv(handle, index=index, lineterminator="\n")

    return atomic_write(path, _write)


def read_options(path: str | os.PathLike) -> dict[str, Any] | None:
    """Return the options stored in the header line of a CSV, or None if it has none."""
    with open(path, encoding="utf-8") as handle:
        first = handle.readline()
    if first.startswith(HEADER_PREFIX):
        return json.loads(first[len(HEADER_PREFIX):])
    return None


def read_table_csv(path: str | os.PathLike, *, index_col: int | None = None) -> pd.DataFrame:
    """Read a table written by :func:`write_table_csv`.

    Floats are parsed so that they round-trip exactly; the ``error`` column (if any) comes
    back as strings with ``""`` for rows without error; the header options are in
    ``df.attrs["pfsdm"]`` (absent when the file has no header line, e.g. a CSV from
    elsewhere).

    Parameters
    ----------
    path : str or PathLike
        CSV file.
    index_col : int, optional
        Column to use as the index (e.g. 0 for a distance matrix written with ``index=True``).
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"cannot read {path}: no such file")
    options = read_options(path)
    df = pd.read_csv(
        path,
        skiprows=1 if options is not None else 0,
        **_FLOAT_KW,
        index_col=index_col,
        dtype={"error": str, "movie": str},
    )
    for col in ("error", "movie"):
        if col in df.columns:
            df[col] = df[col].fillna("")
    if options is not None:
        df.attrs["pfsdm"] = options
    return df
