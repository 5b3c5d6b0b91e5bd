"""Synthetic label movies with known identities, for checking and benchmarking linking.

:func:`make_moving_blobs` draws deforming blobs that drift (a common stage drift plus each
object's own persistent random motion), push each other apart but touch when they meet (the
border between two touching blobs runs where their outlines meet), enter and leave the field
of view, optionally divide once, and may be missed by the "segmentation" in a few frames. Its
labels are *tracked*: every object keeps its id. :func:`relabel` turns them into what
per-frame segmentation gives (ids shuffled every frame, a new id for every object in every
frame, or ids numbered in scan order as most segmenters do) while the true identity of every
(frame, label) stays known.

Used by ``benchmarks/linking.py`` and the tests of :mod:`napari_pfsdm.analysis.tracking`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..errors import InputError

__all__ = ["MovingBlobs", "RELABELLINGS", "centroid_table", "make_moving_blobs", "relabel"]

#: What :func:`relabel` can do to tracked labels.
RELABELLINGS = ("tracked", "shuffled", "new_ids", "scan_order")


@dataclass
class MovingBlobs:
    """A movie from :func:`make_moving_blobs`.

    Attributes
    ----------
    labels : ndarray, uint16, (T, Y, X)
        Tracked labels: the label of a pixel is its object's true id (1, 2, ...).
    parents : dict
        Daughter id -> parent id for the objects born by division.
    """

    labels: np.ndarray
    parents: dict[int, int]

    def truth(self, labels: np.ndarray | None = None) -> pd.DataFrame:
        """One row per (frame, label) of ``labels`` (default: the tracked ones) with the
        object's true id (``true_id``), read from where the label lies in the tracked movie."""
        labels = self.labels if labels is None else labels
        rows = []
        for t in range(labels.shape[0]):
            fg = labels[t] > 0
            pairs = np.unique(np.stack([labels[t][fg], self.labels[t][fg]]), axis=1)
            rows.append(pd.DataFrame({"frame": t, "label": pairs[0], "true_id": pairs[1]}))
        return pd.concat(rows, ignore_index=True).astype(np.int64)


def _radial(n_theta: int, coefs: np.ndarray, phases: np.ndarray) -> np.ndarray:
    theta = np.linspace(0, 2 * np.pi, n_theta, endpoint=False)
    k = np.arange(2, 2 + len(coefs))
    return 1.0 + (coefs[:, None] * np.cos(k[:, None] * theta[None] + phases[:, None])).sum(0)


def make_moving_blobs(
    n_objects: int = 25,
    n_frames: int = 40,
    size: int = 512,
    *,
    radius: tuple[float, float] = (16.0, 26.0),
    speed: float = 2.0,
    drift: float = 1.5,
    entering: int = 4,
    leaving: int = 4,
    division: bool = True,
    dropout: float = 0.0,
    seed: int = 0,
) -> MovingBlobs:
    """Tracked label movie of deforming, drifting, touching blobs.

    Parameters
    ----------
    n_objects : int
        Objects at the start (a division adds one).
    n_frames, size : int
        Frames; frame side in pixels.
    radius : (float, float)
        Range of the objects' mean radii (pixels).
    speed : float
        Typical speed of an object's own motion (pixels per frame).
    drift : float
        Speed of the common drift of the whole field (pixels per frame).
    entering, leaving : int
        How many of the objects start outside the field and move in, or start near the
        border and move out.
    division : bool
        One object divides in the middle of the movie into two daughters (new ids).
    dropout : float
        Probability that an object is missing from a frame (a segmentation failure).
    seed : int
        Seed of the random generator.

    Returns
    -------
    MovingBlobs
    """
    if n_objects < 1 or n_frames < 1:
        raise InputError("n_objects and n_frames must be at least 1")
    if entering + leaving > n_objects:
        raise InputError("entering + leaving must not exceed n_objects")
    rng = np.random.default_rng(seed)
    n_total = n_objects + (2 if division else 0)
    r0 = rng.uniform(*radius, n_total)
    pos = np.zeros((n_total, 2))
    vel = rng.normal(0, speed / np.sqrt(2), (n_total, 2))
    margin = radius[1] * 1.2
    pos[:n_objects] = rng.uniform(margin, size - margin, (n_objects, 2))
    for i in range(entering):  # outside, heading into the field
        side = rng.integers(4)
        along = rng.uniform(margin, size - margin)
        out = -r0[i] * 1.5 - rng.uniform(0, 10 * speed)
        pos[i] = [(along, out), (along, size - out), (out, along), (size - out, along)][side]
        inward = np.array([(0, 1), (0, -1), (1, 0), (-1, 0)][side], float)
        vel[i] = inward * speed * 2.5 + rng.normal(0, speed / 3, 2)
    for i in range(entering, entering + leaving):  # near the border, heading out
        side = rng.integers(4)
        along = rng.uniform(margin, size - margin)
        near = r0[i] + rng.uniform(5, 40)
        pos[i] = [(along, near), (along, size - near), (near, along), (size - near, along)][side]
        outward = -np.array([(0, 1), (0, -1), (1, 0), (-1, 0)][side], float)
        vel[i] = outward * speed * 2.5 + rng.normal(0, speed / 3, 2)
    free = np.arange(entering + leaving, n_objects)
    n_h = 4
    coefs = rng.normal(0, 0.06, (n_total, n_h))
    phases = rng.uniform(0, 2 * np.pi, (n_total, n_h))
    alive = np.zeros(n_total, bool)
    alive[:n_objects] = True
    steady = np.zeros(n_total, bool)  # persistent heading: entering/leaving objects
    steady[: entering + leaving] = True
    t_div = n_frames // 2 if division and n_frames > 2 and len(free) else None
    parent = int(rng.choice(free)) if t_div is not None else -1
    parents: dict[int, int] = {}
    stage = rng.normal(0, 1, 2)
    stage = drift * stage / max(np.hypot(*stage), 1e-9)

    n_theta = 128
    labels = np.zeros((n_frames, size, size), np.uint16)
    best = np.empty((size, size))
    for t in range(n_frames):
        if t == t_div:
            axis = rng.normal(0, 1, 2)
            axis /= np.hypot(*axis)
            for k, d in enumerate((n_objects, n_objects + 1)):
                sign = 1 if k == 0 else -1
                r0[d] = r0[parent] / np.sqrt(2)
                pos[d] = pos[parent] + sign * axis * r0[d] * 0.9
                vel[d] = vel[parent] + sign * axis * speed
                alive[d] = True
                parents[d + 1] = parent + 1
            alive[parent] = False
        best.fill(np.inf)
        frame = labels[t]
        for i in np.flatnonzero(alive):
            if dropout and rng.random() < dropout:
                continue
            rr = r0[i] * _radial(n_theta, coefs[i], phases[i])
            reach = rr.max() + 1
            y0, y1 = int(max(0, pos[i, 0] - reach)), int(min(size, pos[i, 0] + reach + 1))
            x0, x1 = int(max(0, pos[i, 1] - reach)), int(min(size, pos[i, 1] + reach + 1))
            if y0 >= y1 or x0 >= x1:
                continue
            yy, xx = np.mgrid[y0:y1, x0:x1]
            dy, dx = yy - pos[i, 0], xx - pos[i, 1]
            ang = ((np.arctan2(dy, dx) % (2 * np.pi)) / (2 * np.pi) * n_theta).astype(int)
            d = np.hypot(dy, dx) / rr[ang % n_theta]  # < 1 inside, the outline at 1
            win = best[y0:y1, x0:x1]
            take = (d < 1.0) & (d < win)
            win[take] = d[take]
            frame[y0:y1, x0:x1][take] = i + 1
        # motion: own persistent random walk, the stage drift, a push from overlapping blobs
        idx = np.flatnonzero(alive)
        push = np.zeros((n_total, 2))
        if len(idx) > 1:
            diff = pos[idx, None] - pos[None, idx]
            dist = np.hypot(diff[..., 0], diff[..., 1]) + np.eye(len(idx))
            reach = 0.9 * (r0[idx, None] + r0[None, idx])
            over = np.clip(reach - dist, 0, None) * (1 - np.eye(len(idx)))
            push[idx] = 0.5 * (over[..., None] * diff / dist[..., None]).sum(1)
        turn = np.where(steady, 0.0, 0.6)[:, None]  # steady ones keep their heading
        vel = (1 - turn / 2) * vel + (turn + 0.1) * rng.normal(0, speed / np.sqrt(2),
                                                               (n_total, 2))
        for i in free:  # free objects turn back before the border
            for a in range(2):
                if pos[i, a] < margin and vel[i, a] < 0 or pos[i, a] > size - margin \
                        and vel[i, a] > 0:
                    vel[i, a] *= -1
        pos += vel + push + stage
        coefs += rng.normal(0, 0.015, coefs.shape) - 0.05 * coefs  # shapes change slowly
        phases += rng.normal(0, 0.05, phases.shape)
    return MovingBlobs(labels=labels, parents=parents)


def relabel(labels: np.ndarray, how: str, seed: int = 0) -> np.ndarray:
    """Give tracked labels the ids a per-frame segmentation would.

    Parameters
    ----------
    labels : ndarray, (T, Y, X)
        Tracked labels.
    how : {"tracked", "shuffled", "new_ids", "scan_order"}
        ``"tracked"``: unchanged (a copy). ``"shuffled"``: the ids present in a frame are
        permuted at random in every frame. ``"new_ids"``: every object of every frame gets its
        own id (1 … number of objects in the movie). ``"scan_order"``: in each frame objects
        are numbered 1, 2, … in the order their first pixel is met row by row, as
        ``skimage.measure.label`` and many segmenters number them.
    seed : int
        Seed for ``"shuffled"``.

    Returns
    -------
    ndarray, same shape and dtype
    """
    if how not in RELABELLINGS:
        raise InputError(f"how must be one of {RELABELLINGS}, got {how!r}")
    out = labels.copy()
    if how == "tracked":
        return out
    rng = np.random.default_rng(seed)
    next_id = 1
    lut = np.zeros(int(labels.max()) + 1, np.int64)
    for t in range(labels.shape[0]):
        ids = np.unique(labels[t])
        ids = ids[ids > 0]
        lut[:] = 0
        if how == "shuffled":
            lut[ids] = rng.permutation(ids)
        elif how == "new_ids":
            lut[ids] = np.arange(next_id, next_id + len(ids))
            next_id += len(ids)
        else:  # scan order
            flat = labels[t].ravel()
            first = np.unique(flat, return_index=True)
            order = [v for _, v in sorted(zip(first[1], first[0], strict=True)) if v > 0]
            lut[np.asarray(order, np.int64)] = np.arange(1, len(order) + 1)
        out[t] = lut[labels[t]]
    return out


def centroid_table(labels: np.ndarray) -> pd.DataFrame:
    """``frame``, ``label``, ``area``, ``centroid_y``, ``centroid_x`` of every object of a
    (T, Y, X) label movie: what checking and linking read, without measuring shapes."""
    from skimage.measure import regionprops_table

    parts = []
    for t in range(labels.shape[0]):
        p = pd.DataFrame(regionprops_table(labels[t], properties=("label", "area", "centroid")))
        p.insert(0, "frame", t)
        parts.append(p)
    return pd.concat(parts, ignore_index=True).rename(
        columns={"centroid-0": "centroid_y", "centroid-1": "centroid_x"})
