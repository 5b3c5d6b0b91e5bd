"""Are a table's labels tracked? The check behind ``pfsdm measure --link auto`` and the
plugin's Identity "auto": how often a label lands nearer another object than its own from one
frame to the next, how far it jumps relative to the object's size, and how many of a frame's
ids are still there in the next frame (docs/design.md §2.11)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from ...core.table_options import set_options, table_options
from ...errors import InputError
from ..physical import pixel_areas
from ..tables import key_rows

__all__ = ["JUMP_RADII", "MAX_SWITCHED", "MIN_PERSISTENCE", "PACKED", "TrackingCheck",
           "check_tracking", "label_steps", "median_radius", "position_columns",
           "rows_by_value", "touching_fraction", "with_area"]

#: ``"auto"`` links by overlap (:func:`link_labels`) rather than by centroids when at least this
#: fraction of the objects touch another object (:func:`touching_fraction`): packed cells,
#: whose centroids lie about one object apart, are where centroid linking swaps neighbours.
PACKED = 0.5


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


def position_columns(table: pd.DataFrame) -> list[str]:
    """The centroid columns to compare: (z, y, x) for objects of Z-stacks, else (y, x). In
    a time-lapse of Z-stacks, two nuclei above one another share (y, x): without z, true ids
    look like jumps between them."""
    if "centroid_z" in table.columns:
        return ["centroid_z", "centroid_y", "centroid_x"]
    return ["centroid_y", "centroid_x"]


def label_steps(table: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int]:
    """For each label present in consecutive frames t, t + 1: its jump (px), its jump (radii),
    and whether its centroid at t + 1 lies nearer another object's centroid at t than its own
    (a switch); then the number of such steps and of ids that could persist (the labels of
    every frame but the last). ``table`` has one row per (frame, label)."""
    from scipy.spatial import cKDTree

    frame = table["frame"].to_numpy(np.int64)
    label = table["label"].to_numpy(np.int64)
    area = pixel_areas(table)  # the centroids are pixels, whatever unit the sizes are in
    yx = table[position_columns(table)].to_numpy(float)
    following = key_rows(frame + 1, label, frame, label)  # the same label's row at t + 1
    here = np.flatnonzero(following >= 0)
    there = following[here]
    jump = np.linalg.norm(yx[there] - yx[here], axis=1)
    radius = np.sqrt(0.5 * (area[here] + area[there]) / np.pi)
    switched = np.zeros(len(here), bool)
    rows_of = rows_by_value(frame)
    for f, steps in rows_by_value(frame[here]).items():
        rows = rows_of[f]
        nearest = cKDTree(yx[rows]).query(yx[there[steps]])[1]
        switched[steps] = rows[nearest] != here[steps]
    frames = np.unique(frame)
    has_next = np.isin(frame, frames[np.isin(frames + 1, frames)])
    return jump, jump / np.maximum(radius, 0.5), switched, len(here), int(has_next.sum())


def rows_by_value(values: np.ndarray) -> dict[int, np.ndarray]:
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
    table = with_area(table)
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
        j, r, w, n, c = label_steps(g)
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


def with_area(table: pd.DataFrame) -> pd.DataFrame:
    """The table with its ``area`` in pixels, the unit of its centroids, whatever unit its
    sizes are in (its record then says pixels); a table of 3-D objects (``volume``, no
    ``area``) gets the area of the disk whose radius is that of the sphere of the same volume
    (voxels): the checks and the linking then work on its (z, y, x) centroids with the
    object's radius as their scale."""
    record = dict(table_options(table) or {})
    if "area" in table.columns:
        out = table.assign(area=pixel_areas(table))
    elif "volume" in table.columns:
        radius = np.cbrt(3 * pixel_areas(table, "volume") / (4 * np.pi))
        out = table.assign(area=np.pi * radius**2)
    else:
        return table
    for key in ("pixel_size", "pixel_sizes", "space_unit"):
        record.pop(key, None)
    set_options(out, record)
    return out


def median_radius(table: pd.DataFrame) -> float:
    """The radius of a disk of the median object area (pixels; 10 without areas)."""
    table = with_area(table)
    area = table["area"].to_numpy(float) if "area" in table.columns else np.zeros(0)
    area = area[np.isfinite(area) & (area > 0)]
    return float(np.sqrt(np.median(area) / np.pi)) if len(area) else 10.0


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
    >>> packed = np.array([[1, 1, 2, 2], [3, 3, 0, 0], [0, 0, 0, 4]])
    >>> float(touching_fraction(packed))  # 1-2 and 1-3 touch, 2-3 only at a corner; 4 alone
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

