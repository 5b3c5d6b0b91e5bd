"""Objects linked into tracks: a ``track_id`` per row, by centroids (a frame-to-frame linear
assignment with gap closing, built in; or the ``laptrack`` package when installed) or by the
overlap of the label masks; :func:`link_movie` is what ``pfsdm measure --link`` and the plugin
do for each movie. Track ids start at 1, in order of first appearance; ``-1``
(:data:`~napari_pfsdm.core.table_schema.NO_TRACK`) is no track."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd
from scipy.optimize import linear_sum_assignment

from ...core.choices import IDENTITIES
from ...core.params import LINK_OPTION
from ...core.table_options import carry_options
from ...core.table_schema import NO_TRACK, TRACK_COLUMN
from ...errors import InputError
from .check import (
    PACKED,
    TrackingCheck,
    check_tracking,
    median_radius,
    position_columns,
    touching_fraction,
)

__all__ = ["DEFAULT_LINK", "LINK_METHODS", "LINK_RADII", "MIN_IOU", "add_track_ids", "link",
           "link_centroids", "link_labels", "link_movie", "renumber"]

#: Linking methods: ``"centroid"`` and ``"laptrack"`` (from the table's centroids),
#: ``"overlap"`` (from the labels): the identities of :data:`~napari_pfsdm.core.choices.
#: IDENTITIES` that always link.
LINK_METHODS = tuple(i for i in IDENTITIES if i not in ("auto", "labels"))


#: The method used when none is named: the best of ``benchmarks/linking.py`` (as accurate as
#: laptrack at the same settings or better, 70-100x faster; better than overlap when objects
#: move fast; needs no labels, so the table alone is enough).
DEFAULT_LINK = "centroid"


#: Largest link distance of centroid linking by default, in median object radii.
LINK_RADII = 2.0


#: Two objects of consecutive frames are the same only if their masks overlap at least this
#: much (intersection over union); ``benchmarks/linking.py`` sweeps it.
MIN_IOU = 0.1


def _frame_ids(frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    ids, counts = np.unique(frame, return_counts=True)
    keep = ids > 0
    return ids[keep].astype(np.int64), counts[keep]


def _iou(a: np.ndarray, b: np.ndarray, ids_a: np.ndarray, area_a: np.ndarray,
         ids_b: np.ndarray, area_b: np.ndarray) -> np.ndarray:
    """Intersection over union of every label of frame ``a`` with every label of ``b``."""
    both = (a > 0) & (b > 0)
    iou = np.zeros((len(ids_a), len(ids_b)))
    if not both.any() or not len(ids_a) or not len(ids_b):
        return iou
    # positions in ids_a / ids_b, not the ids: the code stays below len(a) * len(b) whatever
    # the ids (up to 2**63 - 1)
    pa = np.searchsorted(ids_a, a[both].astype(np.int64))
    pb = np.searchsorted(ids_b, b[both].astype(np.int64))
    code = pa * len(ids_b) + pb
    codes, inter = np.unique(code, return_counts=True)
    ia, ib = codes // len(ids_b), codes % len(ids_b)
    iou[ia, ib] = inter / (area_a[ia] + area_b[ib] - inter)
    return iou


def _match(iou: np.ndarray, min_iou: float) -> list[tuple[int, int]]:
    """Pairs (i, j) of a one-to-one matching maximising the summed IoU, each ≥ ``min_iou``."""
    if not iou.size or iou.max() < min_iou:
        return []
    gain = np.where(iou >= min_iou, iou, 0.0)
    rows = np.flatnonzero(gain.any(axis=1))
    cols = np.flatnonzero(gain.any(axis=0))
    r, c = linear_sum_assignment(-gain[np.ix_(rows, cols)])
    return [(int(rows[i]), int(cols[j])) for i, j in zip(r, c, strict=True)
            if gain[rows[i], cols[j]] >= min_iou]


def link_labels(
    labels: Any,
    *,
    min_iou: float = MIN_IOU,
    max_gap: int = 1,
    progress: Callable[[int, int], None] | None = None,
) -> pd.DataFrame:
    """Link the objects of a label movie by overlap: one ``track_id`` per (frame, label).

    Between consecutive frames, every pair of labels is scored by the intersection over union
    (IoU) of their masks, and the one-to-one matching with the largest total IoU is kept
    (Hungarian algorithm, :func:`scipy.optimize.linear_sum_assignment`), pairs below
    ``min_iou`` excluded. An object left unmatched starts a new track; a track that found no
    successor may still be continued by an object up to ``max_gap`` frames later that
    overlaps its last mask (a frame where segmentation missed the object). At a division the
    daughter that overlaps the mother most continues its track, the other starts a new one.

    Parameters
    ----------
    labels : array_like of int, (T, Y, X)
        Label movie (numpy, dask or zarr: read one frame at a time).
    min_iou : float
        Least IoU of two masks to be linked (:data:`MIN_IOU`).
    max_gap : int
        Frames an object may be missing from a track (0: none).
    progress : callable(done, total), optional
        Called after each frame.

    Returns
    -------
    DataFrame
        Columns ``frame``, ``label``, ``track_id`` (1, 2, … in order of first appearance),
        one row per object of every frame.

    Raises
    ------
    ValueError
        Labels that are not a (T, Y, X) integer movie.

    Examples
    --------
    >>> import numpy as np
    >>> labels = np.zeros((2, 20, 40), int)
    >>> labels[0, 2:10, 2:10], labels[0, 2:10, 20:28] = 1, 2
    >>> labels[1, 3:11, 21:29], labels[1, 3:11, 3:11] = 1, 2  # ids swapped
    >>> link_labels(labels)["track_id"].tolist()
    [1, 2, 2, 1]
    """
    shape = tuple(getattr(labels, "shape", ()))
    dtype = np.dtype(getattr(labels, "dtype", float))
    if len(shape) != 3 or not (np.issubdtype(dtype, np.integer) or dtype.kind == "b"):
        raise InputError(
            f"linking by overlap needs a label movie (T, Y, X) of whole numbers; got shape "
            f"{shape} and dtype {dtype}")
    n_frames = shape[0]
    frames, labs, tracks = [], [], []
    next_id = 1
    history: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []  # last frames
    ended: dict[tuple[int, int], int] = {}  # (frame, label) with no successor -> track
    prev_tracks: np.ndarray = np.zeros(0, np.int64)
    for t in range(n_frames):
        cur = np.asarray(labels[t])
        ids, area = _frame_ids(cur)
        tr = np.full(len(ids), -1, np.int64)
        matched_prev: set[int] = set()
        if history:
            prev, pids, parea, _ = history[-1]
            for i, j in _match(_iou(prev, cur, pids, parea, ids, area), min_iou):
                tr[j] = prev_tracks[i]
                matched_prev.add(i)
        if history:  # the previous frame's unmatched objects may be continued after a gap
            _, pids, _, ptr = history[-1]
            for i in range(len(pids)):
                if i not in matched_prev:
                    ended[(t - 1, int(pids[i]))] = int(ptr[i])
        for back in range(2, max_gap + 2):  # gap closing: frames t-2 ... t-1-max_gap
            if back > len(history) or (tr >= 0).all():
                break
            old, oids, oarea, _ = history[-back]
            open_ = np.array([(t - back, int(o)) in ended for o in oids], bool)
            free = tr < 0
            if not open_.any():
                continue
            iou = _iou(old, cur, oids, oarea, ids, area)
            iou[~open_] = 0
            iou[:, ~free] = 0
            for i, j in _match(iou, min_iou):
                tr[j] = ended.pop((t - back, int(oids[i])))
        for j in np.flatnonzero(tr < 0):
            tr[j] = next_id
            next_id += 1
        ended = {k: v for k, v in ended.items() if k[0] >= t - max_gap}
        history.append((cur, ids, area, tr))
        history = history[-(max_gap + 1):]
        prev_tracks = tr
        frames.append(np.full(len(ids), t, np.int64))
        labs.append(ids)
        tracks.append(tr)
        if progress is not None:
            progress(t + 1, n_frames)
    if not frames:
        return pd.DataFrame({"frame": [], "label": [], TRACK_COLUMN: []}, dtype=np.int64)
    return pd.DataFrame({"frame": np.concatenate(frames), "label": np.concatenate(labs),
                         TRACK_COLUMN: renumber(np.concatenate(tracks))})


def renumber(tracks: np.ndarray) -> np.ndarray:
    """Track ids 1, 2, … in order of first appearance (NO_TRACK kept)."""
    out = np.full(len(tracks), NO_TRACK, np.int64)
    ok = tracks != NO_TRACK
    _, first, inv = np.unique(tracks[ok], return_index=True, return_inverse=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(1, len(first) + 1)
    out[ok] = rank[inv]
    return out


def link_centroids(
    table: pd.DataFrame,
    *,
    method: str = "centroid",
    max_distance: float | None = None,
    max_gap: int = 1,
) -> np.ndarray:
    """Link a table's objects by their centroids: one track id per row.

    ``"centroid"``: between consecutive frames the one-to-one matching of centroids with the
    least summed distance (Hungarian algorithm), pairs further apart than ``max_distance``
    excluded; a track without successor may be continued up to ``max_gap`` frames later by an
    unmatched object within ``max_distance`` of its last centroid. ``"laptrack"``: the
    linear-assignment tracker of Jaqaman et al. (2008) as implemented by the ``laptrack``
    package (``pip install laptrack``), with gap closing over ``max_gap`` missing frames.
    Neither needs the label images, only the ``frame``, ``centroid_y``, ``centroid_x`` (and
    ``area``) columns, so they work on a table read from CSV. Overlap linking
    (:func:`link_labels`) needs the labels; see ``benchmarks/linking.py`` for how they compare.

    Parameters
    ----------
    table : DataFrame
        One movie's feature table (use :func:`link` for a table with a ``movie`` column).
    method : {"centroid", "laptrack"}
    max_distance : float, optional
        Largest distance (pixels) between the centroids of a linked pair. Default:
        :data:`LINK_RADII` (2) median object radii (the radius of a disk of the median area):
        on ``benchmarks/linking.py``'s fast movies one radius lost 6-25 % of the links, two
        lost none or at most 3 %, and made no more false links.
    max_gap : int
        Frames an object may be missing from a track (0: none).

    Returns
    -------
    ndarray of int64, (len(table),)
        Track ids 1, 2, … (order of first appearance); :data:`NO_TRACK` for rows without a
        centroid.
    """
    if method not in ("centroid", "laptrack"):
        raise InputError(f"method must be 'centroid' or 'laptrack', got {method!r}")
    dist = (float(max_distance) if max_distance is not None
            else LINK_RADII * median_radius(table))
    frame = table["frame"].to_numpy(np.int64)
    yx = table[position_columns(table)].to_numpy(float)  # (z,) y, x
    ok = np.isfinite(yx).all(axis=1)
    out = np.full(len(table), NO_TRACK, np.int64)
    pos = np.flatnonzero(ok)
    if not len(pos):
        return out
    if method == "laptrack":
        out[pos] = _laptrack(frame[pos], yx[pos], dist, max_gap)
        return out
    order = pos[np.lexsort((yx[pos, 1], yx[pos, 0], frame[pos]))]
    tr = np.full(len(table), NO_TRACK, np.int64)

    def nearest(a: np.ndarray, b: np.ndarray) -> list[tuple[int, int]]:
        """One-to-one pairs of rows a -> b with the least summed distance, each ≤ dist."""
        if not len(a) or not len(b):
            return []
        d = np.linalg.norm(yx[a, None, :] - yx[None, b, :], axis=-1)
        r, c = linear_sum_assignment(np.where(d <= dist, d, 1e12))
        return [(int(a[i]), int(b[j])) for i, j in zip(r, c, strict=True) if d[i, j] <= dist]

    next_id = 1
    ended: dict[int, int] = {}  # row without a successor -> its frame
    by_frame = {int(f): order[frame[order] == f] for f in np.unique(frame[order])}
    none = np.zeros(0, np.int64)
    # every frame from the first to the last, those without objects too: a track ends in the
    # frame after its last object, so that gap closing can continue it over an empty frame
    for f in range(min(by_frame), max(by_frame) + 1):
        cur = by_frame.get(f, none)
        prev = by_frame.get(f - 1, none)
        for i, j in nearest(prev, cur):
            tr[j] = tr[i]
        continued = set(tr[cur][tr[cur] != NO_TRACK].tolist())
        ended.update({int(i): f - 1 for i in prev if tr[i] not in continued})
        for back in range(2, max_gap + 2):  # gap closing over missed frames
            free = cur[tr[cur] == NO_TRACK]
            old = np.array([i for i, g in ended.items() if g == f - back], np.int64)
            for i, j in nearest(old, free):
                tr[j] = tr[i]
                del ended[i]
        for j in cur[tr[cur] == NO_TRACK]:
            tr[j] = next_id
            next_id += 1
        ended = {i: g for i, g in ended.items() if g >= f - max_gap}
    out[pos] = tr[pos]
    out[pos] = _renumber_rows(out[pos], frame[pos])
    return out


def _renumber_rows(tracks: np.ndarray, frame: np.ndarray) -> np.ndarray:
    order = np.argsort(frame, kind="stable")
    out = np.empty_like(tracks)
    out[order] = renumber(tracks[order])
    return out


def _laptrack(frame: np.ndarray, yx: np.ndarray, dist: float, max_gap: int) -> np.ndarray:
    try:
        from laptrack import LapTrack
    except ImportError:
        raise ImportError(
            "linking with 'laptrack' needs the laptrack package, which is not installed: "
            "pip install laptrack (or pip install 'napari-pfsdm[tracking]'); or choose "
            "'overlap' (from the labels) or 'centroid' linking, which need nothing more"
        ) from None
    axes = ["z", "y", "x"][-yx.shape[1]:]  # (z,) y, x
    df = pd.DataFrame({"frame": frame, **{a: yx[:, i] for i, a in enumerate(axes)},
                       "row": np.arange(len(frame))})
    lt = LapTrack(cutoff=dist**2, gap_closing_cutoff=dist**2 if max_gap > 0 else False,
                  gap_closing_max_frame_count=max(1, max_gap + 1), splitting_cutoff=False,
                  merging_cutoff=False)
    track_df, _, _ = lt.predict_dataframe(df, axes, only_coordinate_cols=False)
    tr = np.full(len(frame), NO_TRACK, np.int64)
    tr[track_df["row"].to_numpy(np.int64)] = track_df["track_id"].to_numpy(np.int64) + 1
    return _renumber_rows(tr, frame)


def add_track_ids(table: pd.DataFrame, track_ids: Any) -> pd.DataFrame:
    """A copy of ``table`` with a ``track_id`` column (after ``label``), options kept.

    ``track_ids``: one whole number per row, or a DataFrame with ``frame``, ``label`` and
    ``track_id`` columns (as :func:`link_labels` returns), matched on (``movie``,) frame and
    label; rows it does not name get :data:`NO_TRACK`.
    """
    out = table.drop(columns=[TRACK_COLUMN]) if TRACK_COLUMN in table.columns \
        else table.copy()
    if isinstance(track_ids, pd.DataFrame):
        keys = [k for k in ("movie", "frame", "label") if k in track_ids.columns]
        idx = pd.MultiIndex.from_frame(out[keys])
        lut = pd.Series(track_ids[TRACK_COLUMN].to_numpy(),
                        index=pd.MultiIndex.from_frame(track_ids[keys]))
        values = lut.reindex(idx).to_numpy()
        values = np.where(pd.isna(values), NO_TRACK, values).astype(np.int64)
    else:
        values = np.asarray(track_ids, np.int64)
        if values.shape != (len(out),):
            raise InputError(f"{len(values)} track ids for a table of {len(out)} rows")
    pos = list(out.columns).index("label") + 1 if "label" in out.columns else 0
    out.insert(pos, TRACK_COLUMN, values)
    return carry_options(table, out)


def link(
    table: pd.DataFrame,
    labels: Any = None,
    *,
    method: str = DEFAULT_LINK,
    min_iou: float = MIN_IOU,
    max_distance: float | None = None,
    max_gap: int = 1,
) -> pd.DataFrame:
    """Link a feature table's objects into tracks: the table with a ``track_id`` column.

    Parameters
    ----------
    table : DataFrame
        A feature table. With a ``movie`` column, each movie is linked on its own (track ids
        restart at 1 in each: an object is its movie and its track id).
    labels : array_like (T, Y, X), optional
        The label movie the table was measured from; needed by ``"overlap"`` (one movie only).
    method : {"overlap", "centroid", "laptrack"}
        See :func:`link_labels` and :func:`link_centroids`.
    min_iou, max_distance, max_gap
        As in :func:`link_labels` / :func:`link_centroids`.

    Returns
    -------
    DataFrame
        A copy with ``track_id`` after ``label`` (``-1``: no track).

    Raises
    ------
    ValueError
        An unknown method, or ``"overlap"`` without labels (the message says what to do).
    """
    if method not in LINK_METHODS:
        raise InputError(f"the linking method must be one of {', '.join(LINK_METHODS)}; "
                         f"got {method!r}")
    if method == "overlap":
        if labels is None:
            raise InputError(
                "linking by overlap needs the label images, not only the table; give the "
                "labels, or link from the table's centroids with method 'centroid' or "
                "'laptrack'")
        if "movie" in table.columns and table["movie"].nunique() > 1:
            raise InputError("linking by overlap takes one movie's labels at a time; link "
                             "each movie's rows with its own labels")
        return add_track_ids(table, link_labels(labels, min_iou=min_iou, max_gap=max_gap))
    if "movie" in table.columns:
        ids = np.full(len(table), NO_TRACK, np.int64)
        for _, rows in table.groupby("movie", sort=False).indices.items():
            ids[rows] = link_centroids(table.iloc[rows], method=method,
                                       max_distance=max_distance, max_gap=max_gap)
        return add_track_ids(table, ids)
    return add_track_ids(table, link_centroids(table, method=method, max_distance=max_distance,
                                               max_gap=max_gap))


def link_movie(
    table: pd.DataFrame, labels: Any = None, how: str = "auto"
) -> tuple[pd.DataFrame, TrackingCheck, str]:
    """Check one movie's table and link it when asked, or (``"auto"``) when it needs it.

    What ``pfsdm measure --link`` and the napari plugin do for each movie.

    Parameters
    ----------
    table : DataFrame
        One movie's feature table.
    labels : array_like (T, Y, X), optional
        Its labels (needed for ``"overlap"``; with ``"auto"``, they let packed objects be
        linked by overlap).
    how : {"auto", "labels", "centroid", "overlap", "laptrack"}
        The option ``link`` (:data:`~napari_pfsdm.core.params.LINK_OPTION`). ``"auto"``: link
        only when :func:`check_tracking` finds the labels untracked, by overlap when the
        labels of a 2-D movie are given and at least :data:`PACKED` of the objects touch
        another one (:func:`touching_fraction`), else with :data:`DEFAULT_LINK`; tracked
        labels get ``track_id = label``. ``"labels"``: the label ids are the identity (no
        ``track_id``). A method name: always link with it.

    Returns
    -------
    table : DataFrame
        With ``track_id`` (not for ``"labels"``).
    check : TrackingCheck
        The check of the labels as they were.
    method : str
        The linking method used, ``""`` when none was.
    """
    how = LINK_OPTION.check(how)
    check = check_tracking(table)
    if how == "labels":
        return table, check, ""
    if how == "auto":
        if check.tracked:
            return add_track_ids(table, table["label"].to_numpy(np.int64)), check, ""
        packed = labels is not None and len(labels.shape) == 3 \
            and touching_fraction(labels) >= PACKED
        how = "overlap" if packed else DEFAULT_LINK
    return link(table, labels, method=how), check, how

