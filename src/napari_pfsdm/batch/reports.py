"""Plots made from a feature table (PCA trajectories, MDS map) and the checked reading of a
features CSV, for the command line.

The reductions themselves (PCA, MDS, the distance-table layout) are
:mod:`napari_pfsdm.analysis.reduction`, shared with the napari plugin. Headless: figures are
drawn with :class:`matplotlib.figure.Figure` (no
pyplot, no GUI backend) and saved to PNG atomically.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd

from ..analysis.features import FOLDED_WARNING
from ..analysis.physical import time_label, time_values
from ..analysis.plot_text import plot_text
from ..analysis.reduction import object_ids
from ..analysis.tables import check_table_cells
from ..core.table_schema import check_feature_table, pc_column
from ..errors import InputError
from ..io import read_table, save_figure

__all__ = ["load_features", "plot_mds", "plot_trajectories"]


def _colour_key(frame: pd.DataFrame, by: str) -> tuple[np.ndarray, list[str] | None]:
    if by == "group" and "group" in frame.columns:
        names = sorted(set(frame["group"].astype(str)))
        return frame["group"].astype(str).map({n: i for i, n in enumerate(names)}).to_numpy(), names
    return frame["frame"].to_numpy(float), None


def plot_trajectories(
    scores: pd.DataFrame,
    path: str | os.PathLike,
    *,
    components: tuple[int, int] = (1, 2),
    explained: np.ndarray | dict[str, np.ndarray] | None = None,
    title: str = "PF-SDM trajectories",
    time_unit: str | None = None,
) -> Path:
    """One line per object through time in the PCA plane; points coloured by time or group.

    Several channels (e.g. ``shape_PC*`` and ``intensity_PC*`` columns) give side-by-side
    panels. ``explained``: each channel's explained-variance ratios (a dict by channel, or one
    array for ``shape``), shown in the axis labels; ``time_unit``: the unit of the scores'
    ``time`` column (the colour bar's title). Returns the PNG path.
    """
    if explained is not None and not isinstance(explained, dict):
        explained = {"shape": explained}
    explained = explained or {}
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    channels = sorted({c.rsplit("_PC", 1)[0] for c in scores.columns if "_PC" in c},
                      key=lambda c: (c != "shape", c))
    fig = Figure(figsize=(5.2 * len(channels), 4.6), layout="constrained")
    axes = fig.subplots(1, len(channels), squeeze=False)[0]
    by_group = "group" in scores.columns and scores["group"].astype(str).ne("").any()
    ids = object_ids(scores)
    names = sorted(set(scores["group"].astype(str))) if by_group else None
    tab10 = colormaps["tab10"]
    when = time_values(scores)
    for ax, ch in zip(axes, channels, strict=True):
        cx, cy = pc_column(ch, components[0]), pc_column(ch, components[1])
        if cx not in scores or cy not in scores:
            raise InputError(f"no {cx}/{cy} in the PCA table; choose other components")
        sc = None
        for oid in pd.unique(ids):
            obj = scores[ids == oid].sort_values(["time", "frame"] if "time" in scores
                                                 else "frame")
            colour = (tab10(names.index(str(obj["group"].iloc[0])) % 10) if by_group
                      else "0.6")
            ax.plot(obj[cx], obj[cy], "-", color=colour, lw=1.0, alpha=0.7, zorder=1)
            if by_group:
                ax.scatter(obj[cx], obj[cy], s=10, color=colour, zorder=2)
                ax.scatter(obj[cx].iloc[-1:], obj[cy].iloc[-1:], s=40, marker="s",
                           color=colour, edgecolor="k", lw=0.5, zorder=3)
            else:
                sc = ax.scatter(obj[cx], obj[cy], c=time_values(obj), cmap="viridis", s=14,
                                vmin=when.min(), vmax=when.max(), zorder=2)
        ev = explained.get(ch)
        if ev is not None and len(ev) < max(components):
            ev = None
        xl, yl = f"PC{components[0]}", f"PC{components[1]}"
        if ev is not None:
            xl += f" ({100 * ev[components[0] - 1]:.2g} % of variance)"
            yl += f" ({100 * ev[components[1] - 1]:.2g} % of variance)"
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
        ax.set_title(f"{ch} features")
        if by_group:
            for i, n in enumerate(names):
                ax.plot([], [], "-o", color=tab10(i % 10), label=plot_text(n) or "(no group)",
                        ms=4)
            last = "time" if "time" in scores else "frame"
            ax.legend(fontsize=8, title=f"group (■ = last {last})", title_fontsize=8)
        elif sc is not None:
            fig.colorbar(sc, ax=ax, label=time_label(scores) if time_unit is None
                         else f"time ({time_unit})")
    fig.suptitle(plot_text(title))
    save_figure(fig, path, dpi=120)
    return Path(path)


def plot_mds(
    coords: np.ndarray, table: pd.DataFrame, path: str | os.PathLike, *, title: str = "",
    axis_name: str = "MDS",
) -> Path:
    """Scatter of 2-D map coordinates (MDS, or a neighbour-graph map: ``axis_name``), coloured
    by group (or frame), labelled by object."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5.6, 4.8), layout="constrained")
    ax = fig.subplots()
    by_group = "group" in table.columns and table["group"].astype(str).ne("").any()
    size = 28.0 if len(coords) <= 500 else max(2.0, 28.0 * (500 / len(coords)) ** 0.5)
    if by_group:
        names = sorted(set(table["group"].astype(str)))
        tab10 = colormaps["tab10"]
        for i, n in enumerate(names):
            m = (table["group"].astype(str) == n).to_numpy()
            ax.scatter(coords[m, 0], coords[m, 1], s=size, color=tab10(i % 10),
                       label=plot_text(n) or "(no group)")
        ax.legend(fontsize=8)
    elif table["frame"].nunique() > 1:
        sc = ax.scatter(coords[:, 0], coords[:, 1], c=table["frame"], cmap="viridis", s=size)
        fig.colorbar(sc, ax=ax, label="frame")
    else:  # one frame: a colour scale would say nothing
        ax.scatter(coords[:, 0], coords[:, 1], s=size, color="tab:blue")
    # objects cut by the border or folded by the map are often the outliers: ring them (holes
    # are filled before measuring and do not change the shape, so they are not ringed)
    flagged = np.zeros(len(table), bool)
    if "touches_border" in table.columns:
        flagged |= table["touches_border"].fillna(False).astype(bool).to_numpy()
    if "folded_fraction" in table.columns:
        flagged |= (table["folded_fraction"].astype(float) > FOLDED_WARNING).to_numpy()
    if flagged.any():
        ax.scatter(coords[flagged, 0], coords[flagged, 1], s=110, facecolors="none",
                   edgecolors="tab:red", linewidths=1.2,
                   label=f"{int(flagged.sum())} touch the border or fold (see 'warnings')")
        ax.legend(fontsize=8)
    if len(table) <= 60:
        names = "l" + table["label"].astype(str)
        if table["frame"].nunique() > 1:
            names = "t" + table["frame"].astype(str) + "/" + names
        if "movie" in table.columns and table["movie"].nunique() > 1:
            names = table["movie"].astype(str) + "/" + names
        for (x, y), oid in zip(coords, names, strict=True):
            if np.isfinite(x):
                ax.annotate(plot_text(oid), (x, y), fontsize=7, xytext=(3, 3),
                            textcoords="offset points")
    ax.set_xlabel(f"{axis_name} 1")
    ax.set_ylabel(f"{axis_name} 2")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(plot_text(title) if title else "PF-SDM distances, 2-D MDS")
    save_figure(fig, path, dpi=120)
    return Path(path)


def load_features(path: str | os.PathLike) -> pd.DataFrame:
    """Read a features CSV and check it is a complete :func:`napari_pfsdm.measure` table.

    Refused, with a message that says what to do: a file that is not a CSV table (an image
    given by mistake), a table without ``frame``/``label`` or feature columns, a table whose
    options (the ``.csv.json`` sidecar, or the comment line of older tables) cannot be found,
    a table missing some feature columns, and a table with no rows.
    """
    try:
        table = read_table(path)
    except ValueError as exc:
        raise InputError(
            f"{exc}; give the table written by 'pfsdm measure' (e.g. pfsdm measure "
            "LABELS.tif -o features.csv, then use features.csv here)"
        ) from None
    need = {"frame", "label"}
    if not need <= set(table.columns):
        raise InputError(
            f"{path} is not a PF-SDM feature table (it needs frame, label and shape_rXX_nYY "
            "columns); make one with: pfsdm measure LABELS -o features.csv"
        )
    check_feature_table(table, ["shape"], where=str(path))
    check_table_cells(table, ["shape"], where=str(path))
    if len(table) == 0:
        raise InputError(
            f"{path} holds no objects (0 rows): its labels had only background; measure "
            "labels that contain objects"
        )
    return table
