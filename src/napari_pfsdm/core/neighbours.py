"""The k nearest neighbours of every object under the default distance, never all pairs at once.

The default distance (docs/design.md §2.6, §2.9) is D = d_SDF + λ d_B: d_SDF is the Euclidean
distance of the weighted magnitude features (:func:`.distances.weighted_features`, the
intensity channel appended with the factor √w_I), d_B the outline's full Procrustes distance
(:mod:`.boundary`). This module works on those arrays only; the public
:func:`napari_pfsdm.nearest_neighbours` turns results, embeddings or a feature table into them.

``method="brute"``
    Rows in blocks against all objects: the block's D (as :func:`.distances.distance_matrix`
    computes it), then its k smallest by ``argpartition``. Exact, memory bounded by
    block × n, as slow as the matrix itself (~2 µs per pair).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .boundary import boundary_distance_matrix

__all__ = ["NeighbourIndex", "METHODS", "search", "search_rows"]

METHODS = ("brute",)


@dataclass(frozen=True)
class NeighbourIndex:
    """What a search needs about the n objects (small: n × (features + 2K) numbers), shared by
    every block of queries (and sent once to a dask cluster).

    Attributes
    ----------
    features : ndarray, shape (n, d)
        Weighted magnitude features: their Euclidean distances are d_SDF.
    outline : ndarray of complex, shape (n, 2K), or None
        Outline coefficients (None when ``boundary_weight`` is 0, e.g. 3-D objects).
    boundary_weight : float
        λ.
    valid : ndarray of bool, shape (n,)
        Rows with finite features (and outline): the others are nobody's neighbour.
    """

    features: np.ndarray
    outline: np.ndarray | None
    boundary_weight: float
    valid: np.ndarray

    @classmethod
    def build(cls, features: np.ndarray, outline: np.ndarray | None,
              boundary_weight: float) -> NeighbourIndex:
        f = np.ascontiguousarray(features, float)
        if f.ndim != 2:
            raise InputError(f"features must be an (n, d) array, got shape {f.shape}")
        valid = np.isfinite(f).all(axis=1)
        a = None
        if boundary_weight:
            if outline is None:
                raise InputError("boundary_weight > 0 needs the objects' outline coefficients")
            a = np.asarray(outline, complex)
            if a.shape[0] != len(f):
                raise InputError(f"{len(f)} feature rows but {a.shape[0]} outlines")
            valid &= np.isfinite(a).all(axis=1)
        return cls(f, a, float(boundary_weight), valid)

    def __len__(self) -> int:
        return len(self.features)


def check_k(k: int, n: int) -> int:
    """k as an int in 1 … n − 1 (every object but itself), else :class:`InputError`."""
    if isinstance(k, bool) or not isinstance(k, int | np.integer):
        raise InputError(f"k must be an integer, got {k!r}")
    if n < 2:
        raise InputError(f"nearest neighbours need at least 2 objects, got {n}")
    if not 1 <= k <= n - 1:
        raise InputError(f"k must be between 1 and n - 1 = {n - 1} (the object itself is "
                         f"never its own neighbour), got {k}")
    return int(k)


def _sq_dist(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    g = a @ b.T
    g *= -2.0
    g += np.einsum("ij,ij->i", a, a)[:, None]
    g += np.einsum("ij,ij->i", b, b)[None, :]
    return np.maximum(g, 0.0, out=g)


def _top_k(dist: np.ndarray, cols: np.ndarray | None, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The k smallest of each row of ``dist`` (inf: not a candidate), nearest first, equal
    distances by column index; ``cols`` maps columns to object indices (None: identity).
    Rows with fewer than k finite entries are padded with index -1, distance inf."""
    m = dist.shape[1]
    kk = min(k, m)
    part = np.argpartition(dist, kk - 1, axis=1)[:, :kk] if kk < m else \
        np.broadcast_to(np.arange(m), dist.shape).copy()
    d = np.take_along_axis(dist, part, 1)
    idx = part if cols is None else np.take_along_axis(cols, part, 1)
    # ties at the k-th value: argpartition keeps an arbitrary one; take the smallest indices
    kth = d.max(axis=1) if kk else np.zeros(len(d))
    tied = np.flatnonzero(np.isfinite(kth) & ((dist == kth[:, None]).sum(axis=1)
                                              > (d == kth[:, None]).sum(axis=1)))
    for r in tied:
        inside = np.flatnonzero(dist[r] < kth[r])
        at = np.flatnonzero(dist[r] == kth[r])
        ids = at if cols is None else cols[r, at]
        at = at[np.argsort(ids, kind="stable")][: kk - len(inside)]
        part[r] = np.concatenate([inside, at])
        d[r] = dist[r, part[r]]
        idx[r] = part[r] if cols is None else cols[r, part[r]]
    order = np.lexsort((idx, d), axis=1)
    d = np.take_along_axis(d, order, 1)
    idx = np.take_along_axis(idx, order, 1)
    idx = np.where(np.isfinite(d), idx, -1)
    if kk < k:
        d = np.hstack([d, np.full((len(d), k - kk), np.inf)])
        idx = np.hstack([idx, np.full((len(d), k - kk), -1)])
    return idx.astype(np.intp), d


def _brute_rows(index: NeighbourIndex, rows: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    f = index.features
    q = np.where(index.valid[rows, None], f[rows], 0.0)
    all_f = np.where(index.valid[:, None], f, 0.0)
    d = np.sqrt(_sq_dist(q, all_f))
    if index.boundary_weight:
        a = index.outline
        d += index.boundary_weight * boundary_distance_matrix(
            np.where(index.valid[rows, None], a[rows], 0),
            np.where(index.valid[:, None], a, 0))
    d[:, ~index.valid] = np.inf
    d[np.arange(len(rows)), rows] = np.inf  # never itself
    return _top_k(d, None, k)


def search_rows(index: NeighbourIndex, rows: np.ndarray, k: int,
                method: str = "brute") -> tuple[np.ndarray, np.ndarray]:
    """Neighbours of the objects ``rows`` among all of ``index``: (indices, distances), each
    (len(rows), k), nearest first. Rows that are not valid get index -1 and distance NaN."""
    rows = np.asarray(rows, np.intp)
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}, got {method!r}")
    idx, dist = _brute_rows(index, rows, k)
    bad = ~index.valid[rows]
    idx[bad] = -1
    dist[bad] = np.nan
    return idx, dist


def blocks(n: int, block: int) -> list[np.ndarray]:
    """Consecutive row blocks of at most ``block`` rows."""
    return [np.arange(i, min(i + block, n)) for i in range(0, n, block)]


def search(index: NeighbourIndex, k: int, *, method: str = "brute",
           block: int = 512) -> tuple[np.ndarray, np.ndarray]:
    """Neighbours of every object of ``index`` (:func:`search_rows` over row blocks)."""
    k = check_k(k, len(index))
    parts = [search_rows(index, rows, k, method) for rows in blocks(len(index), block)]
    return np.vstack([p[0] for p in parts]), np.vstack([p[1] for p in parts])
