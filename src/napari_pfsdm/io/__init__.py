"""Reading and writing napari-pfsdm's files: tables with their sidecars, atomically, safely.

A table written by :func:`write_table` is two files::

    features.csv        a plain CSV: pandas.read_csv(path), Excel or R read it as it is
    features.csv.json   {"written_by": "napari-pfsdm 0.1.0", "table": "features",
                         "options": {"n_fourier": 10, "weights": [...], ...}, ...}

and :func:`read_table` reads it back with the options in ``df.attrs["pfsdm"]``. The rooms:

:mod:`.tables`
    the table reader and writer (CSV and Parquet), the text columns, the chunked writing;
:mod:`.sidecar`
    the sidecar: where it is, what it holds, and the check that a table and its sidecar belong
    together;
:mod:`.formulas`
    text a spreadsheet would run as a formula, written as text and read back as it was;
:mod:`.atomic`
    files written atomically with the permissions of any new file (tables, sidecars, PNGs);
:mod:`.outputs`
    which files may be replaced (those this program wrote), outputs that would collide with
    each other or with an input, one writer per output (a lock file), and the leftovers of a
    killed run.

The names below are the package's public ones; the modules' own helpers are for the package.
"""

from .atomic import PNG_SOFTWARE, atomic_write, save_figure, save_tiff, writer_name
from .formulas import escape_formulas, unescape_formulas
from .outputs import (
    Input,
    Output,
    check_outputs,
    check_overwrite,
    lock_path,
    output_files,
    output_lock,
    remove_leftovers,
    same_file,
    written_by_pfsdm,
)
from .sidecar import (
    HEADER_PREFIX,
    SIDECAR_SUFFIX,
    read_options,
    read_sidecar,
    sidecar_path,
    to_jsonable,
)
from .tables import PARQUET_INSTALL, is_parquet, read_table, require_pyarrow, write_table

__all__ = [
    "HEADER_PREFIX",
    "Input",
    "Output",
    "PARQUET_INSTALL",
    "PNG_SOFTWARE",
    "SIDECAR_SUFFIX",
    "atomic_write",
    "check_outputs",
    "check_overwrite",
    "escape_formulas",
    "is_parquet",
    "lock_path",
    "output_files",
    "output_lock",
    "read_options",
    "read_sidecar",
    "read_table",
    "remove_leftovers",
    "require_pyarrow",
    "save_figure",
    "save_tiff",
    "same_file",
    "sidecar_path",
    "to_jsonable",
    "unescape_formulas",
    "write_table",
    "writer_name",
    "written_by_pfsdm",
]
