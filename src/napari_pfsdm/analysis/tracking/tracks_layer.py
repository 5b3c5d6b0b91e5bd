"""Identities from a napari Tracks layer: each row's track from the track points that land on
its object."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
from scipy.optimize import linear_sum_assignment

from ...core.table_schema import NO_TRACK
from ...errors import InputError
from .check import median_radius

__all__ = ["track_ids_from_tracks"]

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
        dist = float(max_distance) if max_distance is not None else median_radius(table)
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

