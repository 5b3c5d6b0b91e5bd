"""A table's times and sizes in their units: the ``time`` column, the record's units, and what
plots put on their axes.

A feature table records (``attrs["pfsdm"]``, its sidecar) the unit of its sizes
(``space_unit``, with the pixel size of its movie, ``pixel_size``, or of each movie,
``pixel_sizes``) and of its times (``time_unit``); without them its sizes are in pixels and its
time is the frame. :func:`add_times` gives a table its ``time`` column (after ``frame``): the
frames' times, which may be uneven and may repeat (a day imaged twice).

Examples
--------
>>> import pandas as pd
>>> t = pd.DataFrame({"frame": [0, 1, 2], "label": [1, 1, 1], "area": [10.0, 12.0, 15.0]})
>>> t = add_times(t, [2, 5, 5], "day")
>>> t.columns.tolist(), t["time"].tolist(), time_label(t)
(['frame', 'time', 'label', 'area'], [2.0, 5.0, 5.0], 'time (day)')
>>> column_label(t, "area")
'area (pixels)'
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from ..core.columns import unit_text
from ..core.table_options import carry_options, set_options, table_options
from ..core.units import check_times, time_unit
from ..errors import InputError

__all__ = ["add_times", "column_label", "pixel_areas", "space_unit_of", "time_label",
           "time_unit_of", "time_values"]


def add_times(table: pd.DataFrame, times: Sequence[float] | Mapping[int, float],
              unit: str | None) -> pd.DataFrame:
    """``table`` with a ``time`` column after ``frame``: ``times[frame]`` of each row
    (``times``: one per frame, in frame order, never decreasing; or ``{frame: time}``), and
    ``time_unit`` in its record (:data:`~napari_pfsdm.core.units.TIMES`' name of ``unit``;
    None: frames)."""
    if isinstance(times, Mapping):
        lookup = {int(k): float(v) for k, v in times.items()}
    else:
        values = check_times(times)
        lookup = dict(enumerate(values))
    frames = table["frame"].to_numpy(np.int64) if len(table) else np.zeros(0, np.int64)
    missing = sorted({int(f) for f in frames} - set(lookup))
    if missing:
        shown = ", ".join(map(str, missing[:5])) + (" …" if len(missing) > 5 else "")
        raise InputError(f"no time was given for frame{'s' if len(missing) > 1 else ''} "
                         f"{shown}: give one time per frame of the movie")
    out = table.drop(columns=["time"], errors="ignore")
    at = list(out.columns).index("frame") + 1 if "frame" in out.columns else 0
    out.insert(at, "time", np.array([lookup[int(f)] for f in frames], float))
    out = carry_options(table, out)
    record = dict(table_options(out) or {})
    record["time_unit"] = time_unit(unit)[0] if unit else None
    set_options(out, record)
    return out


def time_unit_of(table: pd.DataFrame) -> str | None:
    """The unit of the table's ``time`` column (None: it has none, or it counts frames)."""
    if "time" not in table.columns:
        return None
    return (table_options(table) or {}).get("time_unit")


def space_unit_of(table: pd.DataFrame) -> str | None:
    """The unit of the table's sizes (None: pixels)."""
    return (table_options(table) or {}).get("space_unit")


def time_values(table: pd.DataFrame) -> np.ndarray:
    """Each row's time: its ``time`` when the table has one, else its frame."""
    column = "time" if "time" in table.columns else "frame"
    return table[column].to_numpy(float)


def time_label(table: pd.DataFrame) -> str:
    """The time axis' label: ``time (day)``, ``time`` (no unit known) or ``frame``."""
    if "time" not in table.columns:
        return "frame"
    unit = time_unit_of(table)
    return f"time ({unit})" if unit else "time"


def column_label(table: pd.DataFrame, column: str) -> str:
    """A column's name with its unit for an axis or a caption: ``area (µm²)``,
    ``perimeter (pixels)``, ``circularity`` (no unit)."""
    from .glossary import unit_of

    unit = unit_text(unit_of(column), space_unit_of(table), time_unit_of(table))
    return f"{column} ({unit})" if unit else column


def pixel_areas(table: pd.DataFrame, column: str = "area") -> np.ndarray:
    """``table[column]`` (areas, or volumes of 3-D objects) in pixels (voxels), whatever unit
    the table's sizes are in: what the tracking needs beside the centroids, which stay in
    pixels of the image."""
    values = table[column].to_numpy(float)
    record: dict[str, Any] = dict(table_options(table) or {})
    sizes = record.get("pixel_sizes")
    if isinstance(sizes, Mapping) and "movie" in table.columns:  # a pixel's area (voxel's
        cell = np.array([float(np.prod(sizes[m])) if m in sizes else 1.0  # volume) per row
                         for m in table["movie"].astype(str)])
        return values / cell
    size = record.get("pixel_size")
    return values if size is None else values / float(np.prod(size))
