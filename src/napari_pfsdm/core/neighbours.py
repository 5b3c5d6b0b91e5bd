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

import threading
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .boundary import boundary_distance_matrix, boundary_distance_pairs

__all__ = ["NeighbourIndex", "METHODS", "search", "search_rows"]

METHODS = ("bound", "brute")

#: Relative safety margins of the single-precision lower bound (its rounding error is far
#: smaller: ~r × 6e-8 of the squared norms for r projected features, ~2K × 6e-8 for Σ|a||b|).
_MARGIN_SQ = 1e-5
_MARGIN_C = 1e-5
_MARGIN_LB = 1e-6
#: Principal components of the features kept for the bound (or fewer, when they hold all but
#: 1e-4 of the variance): a projection never lengthens a difference, so the bound stays valid.
_MAX_COMPONENTS = 32
#: Candidates evaluated exactly in the first round, per query: max(2 k, k + 16).


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
    bound_rows: np.ndarray | None = None
    bound_cols: np.ndarray | None = None

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
        lam = float(boundary_weight)
        rows, cols = _bound_arrays(np.where(valid[:, None], f, 0.0),
                                   None if a is None else np.where(valid[:, None], a, 0), lam)
        return cls(f, a, lam, valid, rows, cols)

    def __len__(self) -> int:
        return len(self.features)


def _bound_arrays(f: np.ndarray, a: np.ndarray | None,
                  lam: float) -> tuple[np.ndarray, np.ndarray]:
    """Single-precision rows and columns whose products give the two parts of the lower bound
    by one matrix product each (see :func:`_lower_bound`): for the SDF term
    [x, (1 − m)|x|², 1] · [−2y, 1, (1 − m)|y|²] = (1 − m)(|x|² + |y|²) − 2 x·y ≤ |x − y|²
    on centred, projected features x, y; for the boundary term [λ|a|, λ m] · [|b|, 1] =
    λ (Σ|a||b| + m) ≥ λ C (docs/design.md §2.9, :func:`.boundary.boundary_lower_bound`)."""
    n = len(f)
    x = f - f.mean(axis=0) if n else f
    if n > 1 and x.shape[1] > 1:
        cov = x.T @ x
        vals, vecs = np.linalg.eigh(cov)
        vals, vecs = vals[::-1], vecs[:, ::-1]
        total = max(vals.sum(), 1e-300)
        r = int(np.searchsorted(np.cumsum(vals) / total, 1 - 1e-4) + 1)
        x = x @ vecs[:, : min(r, _MAX_COMPONENTS, x.shape[1])]
    sq = np.einsum("ij,ij->i", x, x) * (1 - _MARGIN_SQ)
    one = np.ones((n, 1))
    rows = [x, sq[:, None], one]
    cols = [-2 * x, one, sq[:, None]]
    if lam:
        mag = np.abs(a)
        rows += [lam * mag, np.full((n, 1), lam * _MARGIN_C)]
        cols += [mag, one]
    return (np.ascontiguousarray(np.hstack(rows), np.float32),
            np.ascontiguousarray(np.hstack(cols), np.float32))


_WORKSPACE = threading.local()


def _buffer(name: str, shape: tuple[int, int]) -> np.ndarray:
    """A float32 array of ``shape`` re-used by the same thread from block to block (fresh
    100 MB arrays cost as much in page faults as the arithmetic on them)."""
    size = shape[0] * shape[1]
    flat = getattr(_WORKSPACE, name, None)
    if flat is None or flat.size < size:
        flat = np.empty(size, np.float32)
        setattr(_WORKSPACE, name, flat)
    return flat[:size].reshape(shape)


def _lower_bound(index: NeighbourIndex, rows: np.ndarray, chunk: int = 1024) -> np.ndarray:
    """LB ≤ D for the queries ``rows`` against all objects (len(rows), n), float32:
    sqrt of the projected squared distance (with its margin) plus λ sqrt(1 − min(1, Σ|a||b|)²);
    inf for itself and for invalid objects."""
    d = index.features.shape[0]
    q, c = index.bound_rows[rows], index.bound_cols
    w = c.shape[1] - (0 if not index.boundary_weight else index.outline.shape[1] + 1)
    lam = np.float32(index.boundary_weight)
    out = _buffer("bound", (len(rows), d))
    for j0 in range(0, d, chunk):
        j1 = min(j0 + chunk, d)
        o = q[:, :w] @ c[j0:j1, :w].T  # contiguous, small enough to stay in cache
        np.maximum(o, 0, out=o)
        np.sqrt(o, out=o)
        if lam:
            b = q[:, w:] @ c[j0:j1, w:].T  # λ (Σ|a||b| + margin)
            np.minimum(b, lam, out=b)
            b *= b
            np.subtract(lam * lam, b, out=b)
            np.sqrt(b, out=b)
            o += b
        out[:, j0:j1] = o
    out[:, ~index.valid] = np.inf
    out[np.arange(len(rows)), rows] = np.inf
    return out


def _exact_pairs(index: NeighbourIndex, ii: np.ndarray, jj: np.ndarray) -> np.ndarray:
    """D for the pairs (ii, jj), in double precision; each pair in the orientation that
    :func:`.distances.distance_matrix` computes (smaller row first)."""
    lo, hi = np.minimum(ii, jj), np.maximum(ii, jj)
    out = np.empty(len(ii))
    f = index.features
    step = 4096  # temporaries of a few MB: re-used by malloc, no page faults
    for p0 in range(0, len(ii), step):
        p1 = min(p0 + step, len(ii))
        diff = f[lo[p0:p1]] - f[hi[p0:p1]]
        out[p0:p1] = np.sqrt(np.einsum("ij,ij->i", diff, diff))
    if index.boundary_weight:
        out += index.boundary_weight * boundary_distance_pairs(index.outline[lo],
                                                               index.outline[hi])
    return out


#: Objects of smallest bound kept per query for the rounds (the rest is looked at again only
#: for a query whose k-th distance is above its pool's largest bound).
_POOL = 1024


def _bound_rows(index: NeighbourIndex, rows: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Exact search by the lower bound, in rounds: the queries' bound LB against all objects,
    a pool of the ``_POOL`` smallest per query sorted by LB; round r computes D exactly for
    pool ranks 2^r·2k … 2^(r+1)·2k whose LB is at most the k-th distance found so far; a
    query is done when its k-th distance is below its next LB. Nothing left out can be
    nearer: its bound, hence its distance, is at least the k-th distance found."""
    lb = _lower_bound(index, rows)
    n_rows, n = lb.shape
    safe = np.float32(1 - _MARGIN_LB)
    size = min(max(_POOL, 2 * k), n - 1)
    if size < n - 1:
        work = _buffer("partition", lb.shape)
        np.copyto(work, lb)
        work.partition(size, axis=1)
        edge = work[:, size].copy()  # outside the pool: LB ≥ edge
        pr, pc = np.nonzero(lb < edge[:, None])
    else:
        edge = np.full(n_rows, np.inf, np.float32)
        pr, pc = np.nonzero(np.isfinite(lb))
    # the pool as (rows, size), sorted by LB, padded with column -1 and LB inf
    start = np.searchsorted(pr, np.arange(n_rows))
    slot = np.arange(len(pr)) - start[pr]
    cols = np.full((n_rows, size), -1, np.intp)
    vals = np.full((n_rows, size), np.inf, np.float32)
    cols[pr, slot] = pc
    vals[pr, slot] = lb[pr, pc]
    order = np.argsort(vals, axis=1, kind="stable")
    cols = np.take_along_axis(cols, order, 1)
    vals = np.take_along_axis(vals, order, 1)
    exact = np.full((n_rows, size), np.inf)
    kth = np.full(n_rows, np.inf)
    todo = np.flatnonzero(np.isfinite(vals[:, 0]))
    lo, hi = 0, min(2 * k, size)
    while todo.size:
        v = vals[todo, lo:hi]
        ri, sj = np.nonzero(v * safe <= kth[todo, None])
        ri, sj = todo[ri], sj + lo
        exact[ri, sj] = _exact_pairs(index, rows[ri], cols[ri, sj])
        kth[todo] = np.partition(exact[todo, :hi], k - 1, axis=1)[:, k - 1] \
            if hi >= k else np.inf
        nxt = vals[todo, hi] if hi < size else edge[todo]
        todo = todo[~(kth[todo] < nxt * safe)]
        if hi >= size:
            break
        lo, hi = hi, min(2 * hi, size)
    idx, dist = _top_k(exact, cols, k)
    if todo.size:  # the pool was not enough (or fewer than k objects): every other object
        sub = lb[todo]
        r2, c2 = np.nonzero((sub >= edge[todo, None]) & (sub * safe <= kth[todo, None]))
        r2 = todo[r2]
        fin = np.isfinite(exact[todo])
        r1, s1 = np.nonzero(fin)
        r1 = todo[r1]
        ri = np.concatenate([r1, r2])
        cj = np.concatenate([cols[r1, s1], c2])
        d = np.concatenate([exact[r1, s1], _exact_pairs(index, rows[r2], c2)])
        i2, d2 = _top_k_sparse(np.searchsorted(todo, ri), cj, d, len(todo), k)
        idx[todo], dist[todo] = i2, d2
    return idx, dist


def _kth_per_row(ri: np.ndarray, dist: np.ndarray, n_rows: int, k: int) -> np.ndarray:
    """The k-th smallest ``dist`` of each row (inf where a row has fewer than k)."""
    order = np.lexsort((dist, ri))
    start = np.searchsorted(ri[order], np.arange(n_rows))
    count = np.bincount(ri, minlength=n_rows)
    out = np.full(n_rows, np.inf)
    ok = count >= k
    out[ok] = dist[order[start[ok] + k - 1]]
    return out


def _top_k_sparse(ri: np.ndarray, cj: np.ndarray, dist: np.ndarray, n_rows: int,
                  k: int) -> tuple[np.ndarray, np.ndarray]:
    """The k nearest of each row among candidate triples (row, column, distance), nearest
    first, equal distances by column; padded with -1 / inf."""
    order = np.lexsort((cj, dist, ri))
    ri, cj, dist = ri[order], cj[order], dist[order]
    start = np.searchsorted(ri, np.arange(n_rows))
    rank = np.arange(len(ri)) - start[ri]
    keep = rank < k
    idx = np.full((n_rows, k), -1, np.intp)
    out = np.full((n_rows, k), np.inf)
    idx[ri[keep], rank[keep]] = cj[keep]
    out[ri[keep], rank[keep]] = dist[keep]
    return idx, out


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
    idx, dist = (_brute_rows if method == "brute" else _bound_rows)(index, rows, k)
    bad = ~index.valid[rows]
    idx[bad] = -1
    dist[bad] = np.nan
    return idx, dist


def blocks(n: int, block: int) -> list[np.ndarray]:
    """Consecutive row blocks of at most ``block`` rows."""
    return [np.arange(i, min(i + block, n)) for i in range(0, n, block)]


def search(index: NeighbourIndex, k: int, *, method: str = "bound",
           block: int = 512) -> tuple[np.ndarray, np.ndarray]:
    """Neighbours of every object of ``index`` (:func:`search_rows` over row blocks)."""
    k = check_k(k, len(index))
    parts = [search_rows(index, rows, k, method) for rows in blocks(len(index), block)]
    return np.vstack([p[0] for p in parts]), np.vstack([p[1] for p in parts])
