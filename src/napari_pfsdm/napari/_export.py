"""CSV export of one analysis: features, PCA scores, distance matrix (no Qt).

Every file is written atomically by :func:`napari_pfsdm.io_csv.write_table_csv` (a temporary file
in the same folder, then ``os.replace``), so an error never leaves a half-written CSV, with the
umask's permissions. Each CSV is plain (``pandas.read_csv(path)`` reads it); the options of the
run go into its sidecar ``<name>.csv.json``. A file of the same name that napari-pfsdm did not
write is never replaced.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..analysis.features import split_failed
from ..analysis.reduction import distance_table as layout
from ..io_csv import check_overwrite, read_table_csv, write_table_csv
from ._compute import AnalysisOutput

#: Largest number of objects for which the all-pairs distance matrix is exported.
MAX_DISTANCE_ROWS = 3000


def write_csv(table: pd.DataFrame, path, options: dict | None = None, *,
              table_type: str = "table",
              extra: dict | None = None) -> Path:
    """Write ``table`` atomically as plain CSV, ``options`` in its ``.csv.json`` sidecar."""
    return write_table_csv(table, Path(path), options, table_type=table_type, extra=extra)


def read_csv(path) -> pd.DataFrame:
    """Read a CSV written by :func:`write_csv` (options in ``attrs["pfsdm"]``)."""
    return read_table_csv(path)


def distance_table(
    output: AnalysisOutput, intensity_weight: float | None = None
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """All-pairs PF-SDM distances of the measured objects, in the command line's layout (rows
    and columns ``t<frame>/l<label>``, index ``object``), and the rows left out (``frame``,
    ``label``, ``reason``) because they have no features."""
    from ..analysis.tables import distance_matrix

    table = output.table
    if len(table) > MAX_DISTANCE_ROWS:
        raise ValueError(f"{len(table)} objects are too many for an all-pairs distance matrix in "
                         f"the viewer (limit {MAX_DISTANCE_ROWS}); use the command line instead.")
    w = intensity_weight
    if w is None:
        w = output.options.get("intensity_weight", 0.0)
    if not any(c.startswith("intensity_") for c in table.columns):
        w = 0.0
    table, left_out = split_failed(table, ("shape", "intensity") if w else ("shape",))
    d = np.asarray(distance_matrix(table, intensity_weight=w))
    return layout(table, d), left_out


def export_results(output: AnalysisOutput, folder, prefix: str) -> list[Path]:
    """Write ``<prefix>_features.csv``, ``<prefix>_pca_<channel>.csv`` and
    ``<prefix>_distances.csv``, each with its ``.csv.json`` sidecar."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    names = [f"{prefix}_features.csv", *(f"{prefix}_pca_{k}.csv" for k in output.pca),
             f"{prefix}_distances.csv"]
    for name in names:  # before writing anything: all or nothing
        check_overwrite(folder / name, what="file")
    dist, left_out = distance_table(output)  # may refuse (too many objects): nothing written
    left = {"left_out": left_out.to_dict("records")}
    opts = dict(output.options)
    written = [write_csv(output.table, folder / names[0], opts, table_type="features")]
    for channel, scores in output.pca.items():
        ratios = scores.attrs.get("explained_variance_ratio", [])
        h = dict(opts, pca_features=channel, explained_variance_ratio=list(ratios))
        written.append(write_csv(scores, folder / f"{prefix}_pca_{channel}.csv", h,
                                 table_type="pca"))
    written.append(write_table_csv(dist, folder / names[-1], opts, index=True,
                                   table_type="distances", extra=left))
    return written
