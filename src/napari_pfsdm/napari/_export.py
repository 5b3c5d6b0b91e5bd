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

from ..analysis.reduction import distance_table as layout
from ..core.table_schema import has_channel
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
    from ..analysis.features import split_failed
    from ..analysis.tables import distance_matrix

    table = output.table
    if len(table) > MAX_DISTANCE_ROWS:
        raise ValueError(too_many_for_distances(len(table)))
    w = intensity_weight
    if w is None:
        w = output.options.get("intensity_weight", 0.0)
    if not has_channel(table.columns, "intensity"):
        w = 0.0
    table, left_out = split_failed(table, ("shape", "intensity") if w else ("shape",))
    d = np.asarray(distance_matrix(table, intensity_weight=w))
    return layout(table, d), left_out


def too_many_for_distances(n: int, prefix: str = "<layer>") -> str:
    """The sentence said (status line, sidecar) when the distance matrix is left out."""
    from ._graph import GRAPH_K

    return (f"The distance matrix was left out: {n:,} objects are more than the "
            f"{MAX_DISTANCE_ROWS:,} whose all-pairs distances the viewer exports (a matrix of "
            f"{n:,} × {n:,}); {prefix}_neighbours.csv lists each object's {GRAPH_K} nearest "
            "shapes instead (exact; row and neighbour are rows of the features file).")


def neighbour_export_steps(output: AnalysisOutput, prefix: str = "<layer>"):
    """The slow part of exporting more than :data:`MAX_DISTANCE_ROWS` objects, in steps for
    a worker (yields ``(rows done, rows)``): each measured object's nearest neighbours as an
    edge list (:func:`napari_pfsdm.analysis.reduction.neighbour_table`; ``row`` and
    ``neighbour`` are rows of the features file). Returns ``{"neighbours": edges, "note":
    sentence}``."""
    from ..analysis.reduction import neighbour_table
    from ._graph import graph_of

    table = output.table
    w = output.options.get("intensity_weight", 0.0)
    if not has_channel(table.columns, "intensity"):
        w = 0.0
    keep = output.measured()
    if w:  # rows whose reporter could not be described have no intensity features
        keep = keep & output.comparable(("shape", "intensity"))
    rows = np.flatnonzero(keep)  # positions = rows of the features file
    idx, dist = yield from graph_of(output, rows, w)
    edges = neighbour_table(table.iloc[rows], idx, dist, rows=rows)
    return {"neighbours": edges, "note": too_many_for_distances(len(table), prefix)}


def export_names(output: AnalysisOutput, prefix: str) -> list[str]:
    """The file names an export writes: features, one PCA per channel, distances (only when
    the collection is small enough for the all-pairs matrix)."""
    names = [f"{prefix}_features.csv", *(f"{prefix}_pca_{k}.csv" for k in output.pca)]
    big = len(output.table) > MAX_DISTANCE_ROWS
    names.append(f"{prefix}_neighbours.csv" if big else f"{prefix}_distances.csv")
    return names


def prepare_export(output: AnalysisOutput) -> dict:
    """The slow part of an export (the distance matrix), for a worker thread; ``{"distances":
    (table, left out)}`` or ``{"note": sentence}`` when the matrix is left out."""
    if len(output.table) > MAX_DISTANCE_ROWS:
        steps = neighbour_export_steps(output)
        while True:
            try:
                next(steps)
            except StopIteration as done:
                return done.value
    return {"distances": distance_table(output)}


def write_export(output: AnalysisOutput, folder, prefix: str, prepared: dict) -> list[Path]:
    """Write what :func:`prepare_export` made ready: ``<prefix>_features.csv``,
    ``<prefix>_pca_<channel>.csv`` and, for collections small enough, ``<prefix>_distances.csv``,
    each with its ``.csv.json`` sidecar. The feature table and the PCA scores are always
    written; when the distances are left out, the features' sidecar says so
    (``"distances": sentence``)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    names = export_names(output, prefix)
    for name in names:  # before writing anything: all or nothing
        check_overwrite(folder / name, what="file")
    opts = dict(output.options)
    note = prepared.get("note")
    written = [write_csv(output.table, folder / names[0], opts, table_type="features",
                         extra={"distances": note} if note else None)]
    for channel, scores in output.pca.items():
        ratios = scores.attrs.get("explained_variance_ratio", [])
        h = dict(opts, pca_features=channel, explained_variance_ratio=list(ratios))
        written.append(write_csv(scores, folder / f"{prefix}_pca_{channel}.csv", h,
                                 table_type="pca"))
    if "neighbours" in prepared:
        written.append(write_csv(prepared["neighbours"], folder / names[-1], opts,
                                 table_type="neighbours"))
    if "distances" in prepared:
        dist, left_out = prepared["distances"]
        written.append(write_table_csv(dist, folder / names[-1], opts, index=True,
                                       table_type="distances",
                                       extra={"left_out": left_out.to_dict("records")}))
    return written


def export_results(output: AnalysisOutput, folder, prefix: str) -> list[Path]:
    """Export one analysis (:func:`prepare_export`, then :func:`write_export`)."""
    return write_export(output, folder, prefix, prepare_export(output))
