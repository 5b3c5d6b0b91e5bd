"""Time done right: are a table's labels tracked, and linking them into tracks when not.

Per-frame segmentation (cellpose, StarDist, a threshold and ``skimage.measure.label``) numbers
the objects of each frame anew: label 3 in frame 0 and label 3 in frame 1 are usually
different objects, and a "trajectory" drawn by label jumps between objects. This module

* **detects** such labels from the feature table alone (:func:`check_tracking`): how often a
  label lands nearer another object than its own from one frame to the next, how far it
  jumps relative to the object's size, and how many of a frame's ids are still there in the
  next frame;
* **links** objects into tracks, giving each row a ``track_id`` (:func:`link`,
  :func:`link_movie`, :func:`add_track_ids`): by centroids (:func:`link_centroids`, the
  default: a frame-to-frame linear assignment with gap closing, built in; or the ``laptrack``
  package when installed), or by the overlap of the label masks (:func:`link_labels`);
* takes the identities from a **napari Tracks layer** (:func:`track_ids_from_tracks`).

Rows that no track reaches get ``track_id = -1`` (:data:`NO_TRACK`): the column stays whole
numbers, which CSV readers, pandas and Excel read without fuss (an empty cell would turn it
into floats, 3.0). Our own track ids start at 1, in order of first appearance. Which linking
is the default, and why, is measured by ``benchmarks/linking.py`` (docs/design.md §2.11).

Its length (about 830 lines) is three sections that share the per-frame steps, the object
radius and the renumbering: the check, the linkers (one per method, with the gates their
benchmark set) and the Tracks-layer source.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from scipy.optimize import linear_sum_assignment

from ..core.choices import IDENTITIES
from ..core.params import LINK_OPTION
from ..core.table_options import carry_options
from ..core.table_schema import NO_TRACK, TRACK_COLUMN
from ..errors import InputError
from .tables import key_rows

__all__ = [
    "DEFAULT_LINK",
    "LINK_METHODS",
    "LINK_RADII",
    "MIN_IOU",
    "NO_TRACK",
    "PACKED",
    "TrackingCheck",
    "add_track_ids",
    "check_tracking",
    "link",
    "link_centroids",
    "link_labels",
    "link_movie",
    "touching_fraction",
    "track_ids_from_tracks",
]

#: Linking methods: ``"centroid"`` and ``"laptrack"`` (from the table's centroids),
#: ``"overlap"`` (from the labels): the identities of :data:`~napari_pfsdm.core.choices.
#: IDENTITIES` that always link.
LINK_METHODS = tuple(i for i in IDENTITIES if i not in ("auto", "labels"))
#: The method used when none is named: the best of ``benchmarks/linking.py`` (as accurate as
#: laptrack at the same settings or better, 70-100x faster; better than overlap when objects
#: move fast; needs no labels, so the table alone is enough).
DEFAULT_LINK = "centroid"
#: ``"auto"`` links by overlap (:func:`link_labels`) rather than by centroids when at least this
#: fraction of the objects touch another object (:func:`touching_fraction`): packed cells,
#: whose centroids lie about one object apart, are where centroid linking swaps neighbours.
PACKED = 0.5
#: Largest link distance of centroid linking by default, in median object radii.
LINK_RADII = 2.0
#: Two objects of consecutive frames are the same only if their masks overlap at least this
#: much (intersection over union); ``benchmarks/linking.py`` sweeps it.
MIN_IOU = 0.1

#: A label step longer than this many object radii counts as a "jump" (reported only).
JUMP_RADII = 1.0
#: Labels are called untracked when more than this fraction of label steps "switch": the
#: label's centroid in frame t + 1 is nearer another object's centroid in frame t than its
#: own. Scale-free and crowding-aware: a tracked object moving half its radius per frame
#: still lands nearest itself. On benchmarks/linking.py's movies (6 scenarios x 3 seeds)
#: tracked labels switched in at most 1.6 % of steps (small objects moving 0.6 radii a frame),
#: labels numbered in scan order in at least 15.6 %, shuffled ones in at least 94 %; a jump
#: threshold of one radius would have called up to 29 % of those tracked steps jumps
#: (docs/design.md §2.11).
MAX_SWITCHED = 0.05
#: ... or when fewer than this fraction of a frame's ids are present in the next frame.
MIN_PERSISTENCE = 0.5


@dataclass(frozen=True)
class TrackingCheck:
    """What :func:`check_tracking` found.

    Attributes
    ----------
    verdict : {"tracked", "untracked", "one frame", "no objects"}
    tracked : bool
        False only for ``"untracked"``: trajectories by label would be meaningless.
    median_jump : float
        Median distance (pixels) a label's centroid moves between consecutive frames (NaN when
        no label is in two consecutive frames).
    median_jump_radii : float
        The same in object radii (radius of the disk of the object's area).
    jumping : float
        Fraction of label steps (a label in frames t and t + 1) that move more than
        :data:`JUMP_RADII` object radii.
    switched : float
        Fraction of label steps whose centroid in frame t + 1 is nearer another object's
        centroid in frame t than its own: the label moved to another object.
    persistence : float
        Fraction of the labels of a frame that are present in the next frame (over all pairs of
        consecutive frames; 1 when every id continues).
    n_frames, n_labels, n_rows, n_steps : int
        Frames, distinct label ids, rows used, label steps measured.
    message : str
        What it means, in plain words.
    """

    verdict: str
    tracked: bool
    median_jump: float
    median_jump_radii: float
    jumping: float
    switched: float
    persistence: float
    n_frames: int
    n_labels: int
    n_rows: int
    n_steps: int
    message: str


def _position_columns(table: pd.DataFrame) -> list[str]:
    """The centroid columns to compare: (z, y, x) for objects of Z-stacks, else (y, x). In
    a time-lapse of Z-stacks, two nuclei above one another share (y, x): without z, true ids
    look like jumps between them."""
    if "centroid_z" in table.columns:
        return ["centroid_z", "centroid_y", "centroid_x"]
    return ["centroid_y", "centroid_x"]


def _steps(table: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int]:
    """For each label present in consecutive frames t, t + 1: its jump (px), its jump (radii),
    and whether its centroid at t + 1 lies nearer another object's centroid at t than its own
    (a switch); then the number of such steps and of ids that could persist (the labels of
    every frame but the last). ``table`` has one row per (frame, label)."""
    from scipy.spatial import cKDTree

    frame = table["frame"].to_numpy(np.int64)
    label = table["label"].to_numpy(np.int64)
    area = table["area"].to_numpy(float)
    yx = table[_position_columns(table)].to_numpy(float)
    following = key_rows(frame + 1, label, frame, label)  # the same label's row at t + 1
    here = np.flatnonzero(following >= 0)
    there = following[here]
    jump = np.linalg.norm(yx[there] - yx[here], axis=1)
    radius = np.sqrt(0.5 * (area[here] + area[there]) / np.pi)
    switched = np.zeros(len(here), bool)
    rows_of = _by_value(frame)
    for f, steps in _by_value(frame[here]).items():
        rows = rows_of[f]
        nearest = cKDTree(yx[rows]).query(yx[there[steps]])[1]
        switched[steps] = rows[nearest] != here[steps]
    frames = np.unique(frame)
    has_next = np.isin(frame, frames[np.isin(frames + 1, frames)])
    return jump, jump / np.maximum(radius, 0.5), switched, len(here), int(has_next.sum())


def _by_value(values: np.ndarray) -> dict[int, np.ndarray]:
    """The positions of each value of ``values``, in increasing order (one sort, not one scan
    per value)."""
    if not len(values):
        return {}
    order = np.argsort(values, kind="stable")
    keys, starts = np.unique(values[order], return_index=True)
    return dict(zip(keys.tolist(), np.split(order, starts[1:]), strict=True))


def check_tracking(table: pd.DataFrame) -> TrackingCheck:
    """Do the table's label ids follow objects from frame to frame?

    Looks at the ``frame``, ``label``, ``area``, ``centroid_y`` and ``centroid_x`` columns,
    and ``centroid_z`` for the objects of Z-stacks (per ``movie`` when there is one); rows
    without an area or centroid are skipped. Labels are
    called untracked when more than :data:`MAX_SWITCHED` of the label steps land nearer
    another object than their own (an id handed to another object), or when fewer than
    :data:`MIN_PERSISTENCE` of a frame's ids are still there in the next frame (a new id for
    every object of every frame).

    Parameters
    ----------
    table : DataFrame
        A feature table (:func:`napari_pfsdm.measure`, ``read_table``).

    Returns
    -------
    TrackingCheck

    Examples
    --------
    >>> import pandas as pd
    >>> rows = [(t, lab, 400.0, 50.0 + 100 * lab, 50.0 + t) for t in range(3) for lab in (1, 2)]
    >>> table = pd.DataFrame(rows, columns=["frame", "label", "area", "centroid_y",
    ...                                     "centroid_x"])
    >>> check_tracking(table).verdict
    'tracked'
    >>> table["label"] = [1, 2, 2, 1, 1, 2]  # ids swapped in frame 1
    >>> check = check_tracking(table)
    >>> check.verdict, round(check.median_jump)
    ('untracked', 100)
    """
    table = _with_area(table)
    need = ["frame", "label", "area", "centroid_y", "centroid_x"]
    missing = [c for c in need if c not in table.columns]
    if missing:
        raise InputError(
            f"the table has no {', '.join(missing)} column(s): it is not a feature table from "
            "'pfsdm measure' (napari_pfsdm.measure), so its tracking cannot be checked")
    ok = np.isfinite(table[need[2:]].to_numpy(float)).all(axis=1)
    ok &= table["area"].to_numpy(float) > 0
    table = table.loc[ok]
    groups = [g for _, g in table.groupby("movie", sort=False)] if "movie" in table.columns \
        else [table]
    jumps, radii, switches, n_steps, n_could = [], [], [], 0, 0
    for g in groups:
        j, r, w, n, c = _steps(g)
        jumps.append(j)
        radii.append(r)
        switches.append(w)
        n_steps, n_could = n_steps + n, n_could + c
    jump = np.concatenate(jumps) if jumps else np.zeros(0)
    rel = np.concatenate(radii) if radii else np.zeros(0)
    switch = np.concatenate(switches) if switches else np.zeros(0, bool)
    n_frames = int(table["frame"].nunique()) if len(table) else 0
    n_labels = int(table["label"].nunique()) if len(table) else 0
    med = float(np.median(jump)) if len(jump) else float("nan")
    med_r = float(np.median(rel)) if len(rel) else float("nan")
    jumping = float(np.mean(rel > JUMP_RADII)) if len(rel) else float("nan")
    switched = float(np.mean(switch)) if len(switch) else float("nan")
    persistence = n_steps / n_could if n_could else float("nan")
    common = dict(median_jump=med, median_jump_radii=med_r, jumping=jumping,
                  switched=switched, persistence=persistence, n_frames=n_frames, n_labels=n_labels,
                  n_rows=len(table), n_steps=n_steps)
    if len(table) == 0:
        return TrackingCheck("no objects", True, message="no objects to check", **common)
    if n_could == 0:
        msg = ("one frame only: there is nothing to track" if n_frames < 2 else
               "no two consecutive frames: whether labels follow objects cannot be checked")
        return TrackingCheck("one frame", True, message=msg, **common)
    advice = ("Link the objects (napari: Identity 'auto', or link by centroids or overlap; "
              "command line: pfsdm measure --link auto) before reading trajectories: until "
              "then a label's 'trajectory' jumps between objects")
    if persistence < MIN_PERSISTENCE:
        msg = (f"label ids do not follow objects between frames: only {persistence:.0%} of a "
               f"frame's ids are still there in the next frame ({n_labels:,} ids for "
               f"{len(table):,} objects in {n_frames} frames), as when every frame is "
               f"segmented and numbered anew. {advice}")
        return TrackingCheck("untracked", False, message=msg, **common)
    if switched > MAX_SWITCHED:
        if med_r > JUMP_RADII:
            what = (f"the median label jumps {med:.0f} px ({med_r:.1f} object radii) from one "
                    f"frame to the next; {switched:.0%} of the labels land on another object")
        else:  # most ids stay, some move to another object (e.g. numbered in scan order)
            what = (f"{switched:.0%} of the labels land on another object from one frame to "
                    f"the next (the median label moves {med:.1f} px), as when objects are "
                    "numbered anew in every frame")
        msg = f"label ids do not follow objects between frames: {what}. {advice}"
        return TrackingCheck("untracked", False, message=msg, **common)
    msg = (f"label ids follow objects: the median label moves {med:.1f} px "
           f"({med_r:.2f} object radii) between frames and {persistence:.0%} of a frame's ids "
           "are there in the next")
    return TrackingCheck("tracked", True, message=msg, **common)


# ------------------------------------------------------------------------------------------
# linking
# ------------------------------------------------------------------------------------------

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
                         TRACK_COLUMN: _renumber(np.concatenate(tracks))})


def _renumber(tracks: np.ndarray) -> np.ndarray:
    """Track ids 1, 2, … in order of first appearance (NO_TRACK kept)."""
    out = np.full(len(tracks), NO_TRACK, np.int64)
    ok = tracks != NO_TRACK
    _, first, inv = np.unique(tracks[ok], return_index=True, return_inverse=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(1, len(first) + 1)
    out[ok] = rank[inv]
    return out


def _with_area(table: pd.DataFrame) -> pd.DataFrame:
    """A table of 3-D objects (``volume``, no ``area``) gets the area of the disk whose radius
    is that of the sphere of the same volume: the checks and the linking then work on its
    (z, y, x) centroids with the object's radius as their scale."""
    if "area" in table.columns or "volume" not in table.columns:
        return table
    radius = np.cbrt(3 * table["volume"].to_numpy(float) / (4 * np.pi))
    return table.assign(area=np.pi * radius**2)


def _median_radius(table: pd.DataFrame) -> float:
    """The radius of a disk of the median object area (pixels; 10 without areas)."""
    table = _with_area(table)
    area = table["area"].to_numpy(float) if "area" in table.columns else np.zeros(0)
    area = area[np.isfinite(area) & (area > 0)]
    return float(np.sqrt(np.median(area) / np.pi)) if len(area) else 10.0


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
            else LINK_RADII * _median_radius(table))
    frame = table["frame"].to_numpy(np.int64)
    yx = table[_position_columns(table)].to_numpy(float)  # (z,) y, x
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
    out[order] = _renumber(tracks[order])
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


def touching_fraction(labels: Any, n_frames: int = 3) -> float:
    """Fraction of the objects that share an edge with another object.

    Counted on up to ``n_frames`` frames of a movie (first, middle, last) or on one image;
    neighbours along every axis of a frame.

    Parameters
    ----------
    labels : array_like of int, (T, Y, X) or (Y, X)
        Label image or movie (numpy, dask or zarr).
    n_frames : int
        Frames of a movie looked at.

    Returns
    -------
    float
        In [0, 1]; NaN without objects.

    Examples
    --------
    >>> packed = np.array([[1, 1, 2, 2], [3, 3, 0, 4]])
    >>> float(touching_fraction(packed))  # 1-2, 1-3, 2-3 (diagonal: no) touch; 4 alone
    0.75
    """
    shape = tuple(labels.shape)
    if len(shape) == 2:
        planes = [np.asarray(labels)]
    else:
        picks = sorted({int(round(i)) for i in np.linspace(0, shape[0] - 1, n_frames)})
        planes = [np.asarray(labels[t]) for t in picks]
    touching = total = 0
    for plane in planes:
        ids = set(np.unique(plane[plane > 0]).tolist())
        near: set = set()
        for axis in range(plane.ndim):
            a = np.moveaxis(plane, axis, 0)
            first, second = a[:-1], a[1:]
            edge = (first != second) & (first > 0) & (second > 0)
            near.update(np.unique(first[edge]).tolist(), np.unique(second[edge]).tolist())
        touching += len(near)
        total += len(ids)
    return touching / total if total else float("nan")


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


# ------------------------------------------------------------------------------------------
# a napari Tracks layer as the identity source
# ------------------------------------------------------------------------------------------

def track_ids_from_tracks(
    tracks: Any,
    table: pd.DataFrame,
    labels: Any = None,
    *,
    max_distance: float | None = None,
) -> np.ndarray:
    """Each table row's track id from napari Tracks data.

    Parameters
    ----------
    tracks : array_like, (N, 4)
        Rows ``(track_id, t, y, x)``, as a napari Tracks layer holds them (``layer.data``).
        Time must be the table's frame index; ``y``, ``x`` in pixels of the labels.
    table : DataFrame
        One movie's feature table (``frame``, ``label``, ``centroid_y``, ``centroid_x``).
    labels : array_like (T, Y, X), optional
        With labels, a track point names the object whose label lies under it. Without, it
        names the object of its frame whose centroid is nearest, within ``max_distance``.
    max_distance : float, optional
        Without labels: the farthest a track point may be from the centroid it names (pixels;
        default: the median object radius).

    Returns
    -------
    ndarray of int64, (len(table),)
        The track id of each row; :data:`NO_TRACK` (-1) for rows no track point reaches. When
        several tracks name the same object in a frame, the one whose point is nearest its
        centroid wins; a track naming several objects in a frame keeps the nearest.

    Raises
    ------
    ValueError
        Tracks data that is not (N, 4).
    """
    data = np.asarray(tracks, float)
    if data.ndim != 2 or data.shape[1] != 4:
        shape = data.shape
        raise InputError(
            f"Tracks data must have 4 columns (track_id, t, y, x), as a 2-D napari Tracks "
            f"layer holds them; got shape {shape}. A 3-D Tracks layer (track_id, t, z, y, x) "
            "cannot name objects of 2-D frames")
    out = np.full(len(table), NO_TRACK, np.int64)
    if not len(data) or not len(table):
        return out
    frame = table["frame"].to_numpy(np.int64)
    cy = table["centroid_y"].to_numpy(float)
    cx = table["centroid_x"].to_numpy(float)
    tid = data[:, 0].astype(np.int64)
    tt = np.rint(data[:, 1]).astype(np.int64)
    candidates = []  # (distance to centroid, row, track id)
    if labels is not None:
        row_of = {(int(f), int(lab)): i for i, (f, lab) in
                  enumerate(zip(frame, table["label"].to_numpy(np.int64), strict=True))}
        n_t, ny, nx = (int(s) for s in labels.shape)
        for f in np.unique(tt):
            if not 0 <= f < n_t:
                continue
            sel = np.flatnonzero(tt == f)
            yy = np.rint(data[sel, 2]).astype(np.int64)
            xx = np.rint(data[sel, 3]).astype(np.int64)
            inside = (yy >= 0) & (yy < ny) & (xx >= 0) & (xx < nx)
            img = np.asarray(labels[int(f)])
            for k in np.flatnonzero(inside):
                lab = int(img[yy[k], xx[k]])
                row = row_of.get((int(f), lab)) if lab else None
                if row is not None:
                    d = np.hypot(data[sel[k], 2] - cy[row], data[sel[k], 3] - cx[row])
                    candidates.append((float(d), row, int(tid[sel[k]])))
    else:
        dist = float(max_distance) if max_distance is not None else _median_radius(table)
        for f in np.unique(tt):
            rows = np.flatnonzero(frame == f)
            sel = np.flatnonzero(tt == f)
            if not len(rows):
                continue
            d = np.hypot(data[sel, 2][:, None] - cy[rows][None],
                         data[sel, 3][:, None] - cx[rows][None])
            d = np.where(np.isfinite(d), d, np.inf)
            r, c = linear_sum_assignment(np.where(d <= dist, d, 1e12))
            for i, j in zip(r, c, strict=True):
                if d[i, j] <= dist:
                    candidates.append((float(d[i, j]), int(rows[j]), int(tid[sel[i]])))
    taken: set[tuple[int, int]] = set()  # (track, frame) already placed
    for _d, row, track in sorted(candidates):
        key = (track, int(frame[row]))
        if out[row] != NO_TRACK or key in taken:
            continue
        out[row] = track
        taken.add(key)
    return out
