"""The numbers an analysed Labels layer carries in ``layer.features`` (no Qt, no napari).

napari's features table has one row per label and no time axis: on a time-lapse its status
bar would show, for a label hovered in one frame, the row of the same label in another frame.
So a time-lapse's layer carries the rows of the frame shown (:func:`frame_rows`), refreshed by
the model at each step; the whole table is in the export and in the ``<layer> objects`` layer
(one id per object and frame) for plotters.
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

    kept = [c for c in table.columns
            if c not in TEXT_COLUMNS and not str(c).startswith(RAW_PREFIXES)]
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


def frame_rows(features: pd.DataFrame, frame: int) -> pd.DataFrame:
    """The rows of one frame, numbered from 0 (what a time-lapse's ``layer.features`` holds).

    >>> f = pd.DataFrame({"index": [1, 2, 1], "frame": [0, 0, 1], "area": [5, 6, 7]})
    >>> frame_rows(f, 1).to_dict("list")
    {'index': [1], 'frame': [1], 'area': [7]}
    """
    return features[features["frame"].to_numpy() == frame].reset_index(drop=True)


def _take(values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """``values[at]``, NaN where ``at`` is −1."""
    return np.where(at >= 0, values[np.maximum(at, 0)], np.nan) if len(values) else \
        np.full(len(at), np.nan)
