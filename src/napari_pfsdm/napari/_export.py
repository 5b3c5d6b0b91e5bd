"""Export of one analysis as plain CSV tables, each with its ``.csv.json`` sidecar (no Qt).

``<prefix>_features.csv`` (one row per frame and label, exactly the run's table),
``<prefix>_columns.csv`` (what each of its columns means,
:mod:`napari_pfsdm.analysis.glossary`),
``<prefix>_pca_<channel>.csv`` and ``<prefix>_distances.csv`` (all pairs), or above
:data:`MAX_DISTANCE_ROWS` objects ``<prefix>_neighbours.csv`` (each object's
:data:`NEIGHBOURS` nearest shapes, exact) with a sentence saying so in the features' sidecar.
Files are written atomically; a file of the same name that napari-pfsdm did not write is never
replaced, and nothing is written when any name is taken.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..analysis.features import split_failed
from ..analysis.glossary import glossary
from ..analysis.reduction import distance_table, neighbour_table
from ..core.table_schema import has_channel
from ..io import Output, check_outputs, write_table
from ..io.outputs import file_name_part
from ._model import Analysis

#: Largest number of objects whose all-pairs distance matrix is exported.
MAX_DISTANCE_ROWS = 3000
#: Neighbours per object exported instead of the matrix.
NEIGHBOURS = 15


def file_names(analysis: Analysis, prefix: str) -> list[str]:
    """The files an export writes."""
    big = len(analysis.table) > MAX_DISTANCE_ROWS
    return [f"{prefix}_features.csv", f"{prefix}_columns.csv",
            *(f"{prefix}_pca_{k}.csv" for k in analysis.pca),
            f"{prefix}_neighbours.csv" if big else f"{prefix}_distances.csv"]


def export(analysis: Analysis, folder, prefix: str) -> tuple[list[Path], str]:
    """Write the tables of ``analysis`` into ``folder``; returns (paths, note)."""
    from ..analysis.neighbours import nearest_neighbours
    from ..analysis.tables import distance_matrix, key_rows

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    prefix = file_name_part(prefix)  # a layer's name is data: never a path out of the folder
    names = file_names(analysis, prefix)
    check_outputs([Output(folder / name, "table", "file") for name in names])  # all or none
    table, opts = analysis.table, dict(analysis.options)
    w = float(opts.get("intensity_weight", 0.0)) if has_channel(table.columns, "intensity") \
        else 0.0
    measured, left_out = split_failed(table, ("shape", "intensity") if w else ("shape",))
    note = ""
    if len(table) > MAX_DISTANCE_ROWS:
        note = (f"The distance matrix was left out: {len(table):,} objects are more than "
                f"{MAX_DISTANCE_ROWS:,}; {names[-1]} lists each object's {NEIGHBOURS} "
                "nearest shapes instead (exact; row and neighbour are rows of the features "
                "file).")
    paths = [write_table(table, folder / names[0], opts, table_type="features",
                             extra={"distances": note} if note else None),
             write_table(pd.DataFrame(glossary(table.columns), columns=["column", "meaning"]),
                             folder / names[1], table_type="glossary")]
    for channel, scores in analysis.pca.items():
        ratios = [float(r) for r in scores.attrs.get("explained_variance_ratio", [])]
        paths.append(write_table(scores, folder / f"{prefix}_pca_{channel}.csv",
                                     dict(opts, pca_features=channel,
                                          explained_variance_ratio=ratios), table_type="pca"))
    rows = key_rows(measured["frame"], measured["label"], table["frame"], table["label"])
    if note:
        k = min(NEIGHBOURS, len(measured) - 1)
        idx, dist = nearest_neighbours(measured, k, intensity_weight=w)
        edges = neighbour_table(measured, idx, dist, rows=rows)
        paths.append(write_table(edges, folder / names[-1], opts, table_type="neighbours"))
    elif len(measured) >= 2:
        d = np.asarray(distance_matrix(measured, intensity_weight=w))
        paths.append(write_table(distance_table(measured, d), folder / names[-1], opts,
                                     index=True, table_type="distances",
                                     extra={"left_out": left_out.to_dict("records")}))
    return paths, note
