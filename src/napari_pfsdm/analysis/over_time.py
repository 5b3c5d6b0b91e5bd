"""Any measure against time: each object's values frame by frame, and each group's mean ± spread.

:func:`over_time` turns a table's column (a classic measure, a PC score, a probability, a
midline measure: any number per row) into one line per object (its track through the frames)
and, per group, the mean and standard deviation at each time (the table's ``time`` when it has
one: uneven, in its unit, two frames at one time pooled; else the frame);
:func:`plot_over_time` draws them with matplotlib, time on the axis with its unit (the napari
plugin's "Over time" tab and ``pfsdm plot`` draw the same).

Examples
--------
>>> t = pd.DataFrame({"frame": [0, 1, 0, 1], "label": [1, 1, 2, 2], "area": [10, 12, 20, 26],
...                   "group": ["a", "a", "b", "b"]})
>>> lines, groups = over_time(t, "area")
>>> lines["object"].tolist(), lines["value"].tolist()
(['1', '1', '2', '2'], [10.0, 12.0, 20.0, 26.0])
>>> b = groups[groups["group"] == "b"]
>>> b["time"].tolist(), b["mean"].tolist(), b["n"].tolist()
([0.0, 1.0], [20.0, 26.0], [1, 1])
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np
import pandas as pd

from ..errors import InputError
from .physical import column_label, time_label, time_values
from .plot_text import plot_text
from .reduction import object_ids

__all__ = ["numeric_columns", "over_time", "plot_over_time"]


def numeric_columns(table: pd.DataFrame, raw: bool = False) -> list[str]:
    """The columns of ``table`` a person may plot against time: numbers, not the keys
    (``frame``, ``label``, ``track_id``), and without ``raw`` not the hundreds of feature
    columns (``shape_r…``, ``intensity_r…``, ``outline_…``, ``surface_l…``).

    >>> numeric_columns(pd.DataFrame({"frame": [0], "label": [1], "area": [3.0],
    ...                               "warnings": [""], "shape_r00_n00": [0.1]}))
    ['area']
    """
    raw_prefixes = ("shape_r", "intensity_r", "outline_", "surface_l")
    return [c for c in table.columns
            if c not in ("frame", "time", "label", "track_id", "movie", "index")
            and pd.api.types.is_numeric_dtype(table[c]) and not pd.api.types.is_bool_dtype(
                table[c]) and (raw or not str(c).startswith(raw_prefixes))]


def over_time(table: pd.DataFrame, column: str,
              groups: Mapping | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """One column of a table against time: per object, and per group.

    Parameters
    ----------
    table : DataFrame
        A feature table (any rows with ``frame``, ``label`` and ``column``; a ``track_id``
        makes objects of tracks, a ``movie`` column keeps movies apart, a ``group`` column
        gives the groups).
    column : str
        A numeric column (:func:`numeric_columns`).
    groups : mapping, optional
        Object (track id or label, as in the table) → group name, instead of a ``group``
        column.

    Returns
    -------
    lines : DataFrame
        ``object`` (:func:`~napari_pfsdm.analysis.reduction.object_ids`), ``frame``, ``time``
        (the frame's time, or the frame), ``label``, ``value``, ``group`` ("" without one),
        sorted by object, time and frame; rows whose value is not finite are left out.
    per_group : DataFrame
        ``group``, ``time``, ``mean``, ``sd`` (0 for one value), ``n`` (values: two frames of
        one object at one time count twice).

    Raises
    ------
    ValueError
        No such column, or not numbers.
    """
    if column not in table.columns:
        raise InputError(f"the table has no column {column!r}; columns that can be drawn "
                         f"against time: {', '.join(numeric_columns(table)[:20])}")
    if not pd.api.types.is_numeric_dtype(table[column]):
        raise InputError(f"the column {column!r} does not hold numbers")
    values = table[column].to_numpy(float)
    if groups is not None:
        key = "track_id" if "track_id" in table.columns else "label"
        group = [str(groups.get(int(k), "")) for k in table[key].to_numpy()]
    elif "group" in table.columns:
        group = table["group"].fillna("").astype(str).tolist()
    else:
        group = [""] * len(table)
    lines = pd.DataFrame({"object": object_ids(table).to_numpy(),
                          "frame": table["frame"].to_numpy().astype(np.int64),
                          "time": time_values(table),
                          "label": table["label"].to_numpy().astype(np.int64),
                          "value": values, "group": group})
    lines = lines[np.isfinite(values)].sort_values(["object", "time", "frame"], kind="stable")
    lines = lines.reset_index(drop=True)
    named = lines[lines["group"] != ""]
    per_group = (named.groupby(["group", "time"])["value"]
                 .agg(mean="mean", sd=lambda v: float(np.std(v, ddof=1)) if len(v) > 1 else 0.0,
                      n="count").reset_index())
    return lines, per_group


def plot_over_time(ax, table: pd.DataFrame, column: str, groups: Mapping | None = None,
                   selected: Iterable[str] = (), max_lines: int = 300):
    """Draw :func:`over_time` on a matplotlib ``ax``: each object's line (thin, grey; at most
    ``max_lines`` of them, every k-th), each group's mean ± sd (a band in the group's colour),
    and the ``selected`` objects' lines on top. Returns the lines table (what was drawn).

    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import matplotlib.pyplot as plt
    >>> t = pd.DataFrame({"frame": [0, 1, 0, 1], "label": [1, 1, 2, 2], "area": [1, 2, 3, 4]})
    >>> len(plot_over_time(plt.figure().add_subplot(), t, "area", selected=["2"]))
    4
    """
    import matplotlib
    import matplotlib.ticker

    lines, per_group = over_time(table, column, groups)
    objects = lines["object"].unique()
    every = -(-len(objects) // max_lines) if len(objects) else 1
    shown = set(objects[::every])
    for obj, rows in lines.groupby("object", sort=False):
        if obj in shown:
            ax.plot(rows["time"], rows["value"], color=(0.6, 0.6, 0.6, 0.45), lw=0.7,
                    zorder=1)
    tab = matplotlib.colormaps["tab10"]
    for k, (name, rows) in enumerate(per_group.groupby("group", sort=True)):
        colour = tab(k % 10)
        ax.fill_between(rows["time"], rows["mean"] - rows["sd"], rows["mean"] + rows["sd"],
                        color=colour, alpha=0.2, lw=0, zorder=2)
        ax.plot(rows["time"], rows["mean"], color=colour, lw=2, zorder=3,
                label=f"{plot_text(name)} (mean ± sd)")
    for obj in selected:
        rows = lines[lines["object"] == obj]
        if len(rows):
            ax.plot(rows["time"], rows["value"], "-o", color="#ff3c3c", ms=3, lw=1.6,
                    zorder=4)
    ax.set_xlabel(time_label(table))
    ax.set_ylabel(plot_text(column_label(table, column)))
    if len(lines):  # every time of the table, also when only some objects' lines are drawn
        times = time_values(table)
        first, last = float(np.nanmin(times)), float(np.nanmax(times))
        pad = 0.5 if "time" not in table.columns else max(0.02 * (last - first), 1e-9)
        ax.set_xlim(first - pad, last + pad)
        if "time" not in table.columns:
            ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(integer=True))
    if len(per_group):
        ax.legend(fontsize=7, loc="best")
    return lines
