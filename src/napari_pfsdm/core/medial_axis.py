"""Skeleton (medial axis) from the singularities of the signed distance (docs/design.md §2.7).

The distance to the outline is differentiable everywhere inside the object except on the medial
axis, where two or more boundary points are closest. There a central difference of φ over a
small step has magnitude below 1 (the two sides' gradients cancel in part). We mark the pixels
where |∇φ| < ``threshold`` and that lie deeper than ``min_depth`` pixels, thin them to one
pixel, keep the largest connected piece, and prune the short side branches that the pixel
staircase of the outline creates.

A big object is traced on a coarser grid: every ``step``-th pixel of its box, the step the
smallest whole number of pixels that puts at most ``samples_across`` samples along the box's
longer side (:func:`grid_step`). The SDF is that of the sub-pixel outline at any resolution, so
the coarser grid loses only the grid's own quantisation (on a 1-megapixel object traced with
512 samples across, a step of 3–4 px, the skeleton lies ~0.6 px on average from the one traced
at every pixel; ``tests/test_big_objects.py`` holds the bounds) and costs ``step``² times less.
Objects up to ``samples_across`` pixels across are traced at every pixel, as before.

The ridge is located with the *exact* distance even when the result uses the viscous SDF: the
viscous one is smoothed precisely on the ridge.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage as ndi
from skimage.morphology import skeletonize

from .pushforward import push_to_disk
from .sdf import ViscousSDF

__all__ = ["Skeleton", "skeleton", "ridge_mask", "prune_branches", "end_points", "branch_paths",
           "grid_step", "SAMPLES_ACROSS", "distance_to_paths", "paths_distance"]

#: Default of :func:`skeleton`'s ``samples_across``: at most this many grid samples along the
#: longer side of the object's box (4× the plugin's 128-pixel pictures).
SAMPLES_ACROSS = 512

_EIGHT = np.array([[1, 1, 1], [1, 0, 1], [1, 1, 1]])


@dataclass(frozen=True)
class Skeleton:
    """A pruned medial axis.

    Attributes
    ----------
    points : ndarray of int, shape (K, 2)
        Skeleton pixels, image ``(row, col)`` coordinates: samples of a grid of ``step``
        pixels, so consecutive points of a branch are 8-neighbours on that grid (``step``
        pixels apart along rows or columns).
    disk_points : ndarray, shape (K, 2)
        The same points pushed onto the unit disk, ``(u, v)``, in the frame of
        :func:`~napari_pfsdm.core.descriptor.render_disk` (which turns the disk for display).
    depth : ndarray, shape (K,)
        Distance to the outline at each point, in pixels (the local half-thickness).
    step : int
        The grid step the skeleton was traced on, in pixels (1: every pixel; see
        :func:`grid_step`).
    """

    points: np.ndarray
    disk_points: np.ndarray
    depth: np.ndarray
    step: int = 1

    @property
    def cells(self) -> np.ndarray:
        """The points as indices ``(K, 2)`` of their grid (the points themselves when
        ``step`` is 1), where branches are 8-connected."""
        pts = np.asarray(self.points, dtype=int).reshape(-1, 2)
        if self.step == 1 or len(pts) == 0:
            return pts
        return (pts - pts.min(axis=0)) // self.step

    def paths(self, where: str = "image") -> list[np.ndarray]:
        """The skeleton as polylines (one per branch), for drawing it as lines.

        ``where`` is ``"image"`` (``(row, col)`` pixels) or ``"disk"`` (``(u, v)`` on the
        unit disk); see :func:`branch_paths`.
        """
        coords = self.points if where == "image" else self.disk_points
        return [np.asarray(coords)[idx] for idx in branch_paths(self.cells)]

    @property
    def n_end_points(self) -> int:
        """Number of branch ends (points with one 8-neighbour on their grid)."""
        return len(end_points(self.cells))


def grid_step(shape: tuple[int, ...], samples_across: int | None = SAMPLES_ACROSS) -> int:
    """The grid step (whole pixels) that samples a box of ``shape`` with at most
    ``samples_across`` samples along its longer side; 1 when ``samples_across`` is None.

    >>> grid_step((2000, 1200)), grid_step((300, 500)), grid_step((2000, 1200), None)
    (4, 1, 1)
    """
    if samples_across is None:
        return 1
    if int(samples_across) < 1:
        raise ValueError(f"samples_across must be at least 1 or None, got {samples_across}.")
    return max(1, -(-max(shape) // int(samples_across)))


def _as_image(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lo = points.min(axis=0) - 1
    img = np.zeros(tuple(points.max(axis=0) - lo + 2), bool)
    img[tuple((points - lo).T)] = True
    return img, lo


def branch_paths(points: np.ndarray) -> list[np.ndarray]:
    """Split a one-pixel-wide skeleton into branches: index arrays into ``points``.

    A branch runs between two nodes (ends, with one 8-neighbour, or junctions, with three or
    more) through pixels with exactly two neighbours; a closed loop without nodes is one branch
    that returns to its start. Every pixel lies on at least one branch, and consecutive pixels of
    a branch are 8-neighbours, so each branch draws as a connected line.

    Parameters
    ----------
    points : ndarray of int, shape (K, 2)

    Returns
    -------
    list of ndarray of int
        Each of length ≥ 2 (a single isolated pixel gives ``[i, i]``).

    Examples
    --------
    >>> pts = np.array([[0, 0], [0, 1], [0, 2], [1, 1], [2, 1]])  # a T
    >>> [b.tolist() for b in branch_paths(pts)]
    [[0, 1], [1, 2], [1, 3, 4]]
    """
    points = np.asarray(points, dtype=int).reshape(-1, 2)
    if len(points) == 0:
        return []
    index = {(int(r), int(c)): i for i, (r, c) in enumerate(points)}
    offsets = [(dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if dr or dc]

    def linked(r: int, c: int, dr: int, dc: int) -> bool:
        # a diagonal step is an edge only when no 4-neighbour path of two steps exists:
        # otherwise the staircase would be drawn twice, as a triangle
        if (r + dr, c + dc) not in index:
            return False
        return not (dr and dc) or ((r + dr, c) not in index and (r, c + dc) not in index)

    nbrs = [[index[(int(r) + dr, int(c) + dc)] for dr, dc in offsets
             if linked(int(r), int(c), dr, dc)] for r, c in points]
    node = [len(n) != 2 for n in nbrs]
    used: set[tuple[int, int]] = set()  # undirected edges already drawn
    paths: list[np.ndarray] = []

    def walk(start: int, nxt: int) -> list[int]:
        path, prev, cur = [start], start, nxt
        used.add((min(start, nxt), max(start, nxt)))
        while True:
            path.append(cur)
            if node[cur] or cur == start:
                return path
            step = next((n for n in nbrs[cur] if n != prev
                         and (min(cur, n), max(cur, n)) not in used), None)
            if step is None:
                return path
            used.add((min(cur, step), max(cur, step)))
            prev, cur = cur, step

    for i in range(len(points)):
        if node[i]:
            if not nbrs[i]:
                paths.append(np.array([i, i]))
            for n in nbrs[i]:
                if (min(i, n), max(i, n)) not in used:
                    paths.append(np.array(walk(i, n)))
    for i in range(len(points)):  # loops without nodes
        for n in nbrs[i]:
            if (min(i, n), max(i, n)) not in used:
                paths.append(np.array(walk(i, n)))
    return paths


def end_points(points: np.ndarray) -> np.ndarray:
    """The points (K, 2) of a one-pixel-wide curve set that have exactly one 8-neighbour."""
    if len(points) == 0:
        return points
    img, lo = _as_image(points)
    count = ndi.convolve(img.astype(int), _EIGHT, mode="constant")
    return np.argwhere(img & (count == 1)) + lo


def ridge_mask(sdf, mask: np.ndarray, to_normalized, step: float, threshold: float = 0.7,
               min_depth: float = 1.5) -> tuple[np.ndarray, np.ndarray]:
    """Pixels of ``mask`` where the central-difference gradient of ``sdf`` is below
    ``threshold``; returns (ridge mask, depth in pixels at every pixel of ``mask``)."""
    pix = np.argwhere(mask).astype(float)
    p = to_normalized(pix)
    phi = sdf(p)
    g = np.zeros(len(p))
    for axis in range(2):
        e = np.zeros(2)
        e[axis] = step
        g += ((sdf(p + e) - sdf(p - e)) / (2 * step)) ** 2
    depth = np.zeros(mask.shape)
    depth[mask] = -phi
    ridge = np.zeros(mask.shape, bool)
    ridge[mask] = np.sqrt(g) < threshold
    return ridge, depth


def prune_branches(skel: np.ndarray, min_length: float, rounds: int = 3) -> np.ndarray:
    """Remove side branches shorter than ``min_length`` pixels from a one-pixel skeleton image.

    A branch is the path from an end point to the first junction (a pixel with three or more
    neighbours). Branches that reach no junction (an isolated curve) are kept.
    """
    skel = skel.copy()
    for _ in range(rounds):
        count = ndi.convolve(skel.astype(int), _EIGHT, mode="constant")
        ends = np.argwhere(skel & (count == 1))
        removed = False
        for start in ends:
            path = [tuple(start)]
            prev = None
            cur = tuple(start)
            junction = False
            while len(path) <= min_length:
                r, c = cur
                nbrs = [(r + dr, c + dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1)
                        if (dr or dc) and 0 <= r + dr < skel.shape[0]
                        and 0 <= c + dc < skel.shape[1] and skel[r + dr, c + dc]
                        and (r + dr, c + dc) != prev and (r + dr, c + dc) not in path]
                if not nbrs:
                    break
                if len(nbrs) > 1 or count[nbrs[0]] > 2:
                    junction = True
                    break
                prev, cur = cur, nbrs[0]
                path.append(cur)
            if junction and len(path) < min_length:
                for q in path:
                    skel[q] = False
                removed = True
        if not removed:
            break
        skel = skeletonize(skel)
    return skel


def skeleton(result, *, threshold: float = 0.7, min_depth: float = 1.5,
             prune: float = 0.5, samples_across: int | None = SAMPLES_ACROSS,
             disk: bool = True) -> Skeleton:
    """Thin, pruned medial axis of a :class:`~napari_pfsdm.core.descriptor.PFSDMResult`.

    Parameters
    ----------
    result : PFSDMResult
    threshold : float
        Grid samples where |∇φ| is below this are ridge candidates (central difference over
        one grid step); 0.7 keeps branches whose two closest boundary points are > 90° apart.
    min_depth : float
        Ridge samples closer than this (pixels) to the outline are ignored.
    prune : float
        Side branches shorter than ``prune`` × the largest depth (the radius of the largest
        inscribed circle) are removed.
    samples_across : int or None
        At most this many grid samples along the longer side of the object's box: a bigger
        object is traced every ``step`` pixels (:func:`grid_step`), which costs ``step``²
        times less and moves the skeleton by about a step at most. None traces every pixel.
    disk : bool
        Push the points onto the unit disk (``disk_points``). False leaves ``disk_points`` NaN
        and saves about three quarters of the cost on small objects (the midline measures,
        :mod:`napari_pfsdm.core.midline`, need the image points only).

    Returns
    -------
    Skeleton

    Examples
    --------
    >>> import numpy as np
    >>> from napari_pfsdm.core.descriptor import pfsdm
    >>> yy, xx = np.mgrid[:1200, :700]
    >>> res = pfsdm(((yy - 600) / 560) ** 2 + ((xx - 350) / 300) ** 2 < 1)
    >>> sk = skeleton(res)
    >>> sk.step, sk.n_end_points
    (3, 2)
    """
    info = result.mask_info
    contour = result.contour
    sdf = result.sdf.exact if isinstance(result.sdf, ViscousSDF) else result.sdf
    step = grid_step(info.mask.shape, samples_across)
    mask = info.mask[::step, ::step]

    def to_normalized(cell):
        return (cell * step + info.offset - contour.center) / contour.scale

    ridge, depth = ridge_mask(sdf, mask, to_normalized, step / contour.scale, threshold)
    depth_px = depth * contour.scale
    ridge &= depth_px > min_depth
    if not ridge.any():  # a round object: the axis degenerates to its deepest point
        ridge = depth_px == depth_px.max()
    # The medial axis of a simply connected object is connected: bridge one-sample gaps of the
    # sampled ridge, thin, and keep the largest connected piece.
    thin = skeletonize(ndi.binary_dilation(ridge, np.ones((3, 3), bool)) & mask)
    lab, n = ndi.label(thin, structure=np.ones((3, 3), bool))
    if n > 1:
        thin = lab == np.argmax(np.bincount(lab.ravel())[1:]) + 1
    thin = prune_branches(thin, prune * depth_px.max() / step)
    local = np.argwhere(thin)
    points = (local * step + info.offset).astype(int)
    on_disk = (push_to_disk(result, to_normalized(local.astype(float))) if disk
               else np.full((len(local), 2), np.nan))
    return Skeleton(points=points, disk_points=on_disk, depth=depth_px[tuple(local.T)], step=step)


def distance_to_paths(points: np.ndarray, paths: list[np.ndarray]) -> np.ndarray:
    """Distance from each of ``points`` (K, 2) to the nearest segment of the polylines
    ``paths`` (e.g. a skeleton's branches).

    >>> distance_to_paths(np.array([[1.0, 5.0], [0.0, 12.0]]), [np.array([[0, 0], [0, 10]])])
    array([1., 2.])
    """
    points = np.asarray(points, float)
    segs = np.concatenate([np.stack([p[:-1], p[1:]], axis=1) for p in
                           (np.asarray(q, float) for q in paths)])
    a, e = segs[:, 0], segs[:, 1] - segs[:, 0]
    length2 = np.maximum((e ** 2).sum(axis=1), 1e-12)
    best = np.full(len(points), np.inf)
    for i in range(0, len(segs), 256):  # 256 segments at a time: memory stays small
        g = points[:, None, :] - a[None, i:i + 256]
        t = np.clip((g * e[None, i:i + 256]).sum(-1) / length2[i:i + 256], 0, 1)
        d = np.linalg.norm(g - t[..., None] * e[None, i:i + 256], axis=-1)
        best = np.minimum(best, d.min(axis=1))
    return best


def paths_distance(a: list[np.ndarray], b: list[np.ndarray]) -> tuple[float, float]:
    """How far two sets of polylines (two skeletons' branches) lie from each other: the mean
    distance of one's vertices to the other (the larger of both ways) and the Hausdorff
    distance.

    >>> paths_distance([np.array([[0, 0], [0, 10]])], [np.array([[3, 0], [3, 10]])])
    (3.0, 3.0)
    """
    pa, pb = np.concatenate(a).astype(float), np.concatenate(b).astype(float)
    ab, ba = distance_to_paths(pa, b), distance_to_paths(pb, a)
    return float(max(ab.mean(), ba.mean())), float(max(ab.max(), ba.max()))
