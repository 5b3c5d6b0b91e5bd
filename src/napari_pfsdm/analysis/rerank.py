"""Collection-level re-ranking of a distance matrix (docs/design.md §2.10).

A pairwise distance compares two objects and nothing else. In a large collection the other
objects carry information too: two views of the same kind of shape that differ a lot are often
joined by a chain of intermediate objects, each close to the next. Re-ranking turns the
distance matrix into a graph of nearest neighbours and measures how similar two objects'
*neighbourhoods* are, which follows such chains (the "manifold" of a class).

:func:`rerank` offers three variants from the shape-retrieval literature, all on the same
k-nearest-neighbour graph with locally scaled Gaussian affinities (Zelnik-Manor & Perona 2004:
w_ij = exp(−d_ij² / (σ_i σ_j)), σ_i the distance of i to its k-th neighbour):

``"diffusion"`` (default)
    P = the row-normalised kNN affinities (a random walk); two steps, P²; the new distance is
    1 − cosine similarity of the rows of P² (how much two objects' two-step neighbourhoods
    overlap), as in the diffusion / "shortest-path" re-ranking of shape retrieval (Yang,
    Köknar-Tezel & Latecki 2009; Donoser & Bischof 2013).
``"mutual"``
    Jaccard distance of the k-reciprocal neighbourhoods (weighted by the affinities), the
    k-reciprocal re-ranking of Zhong et al. 2017: two objects are close when they are each
    other's neighbours and share neighbours.
``"transduction"``
    Graph transduction / manifold ranking (Zhou et al. 2004; Bai et al. 2010): the closed
    form F = (I − α S)⁻¹ of label propagation from each object over the symmetric
    normalised kNN graph S, α = 0.9; distance 1 − F_ij / sqrt(F_ii F_jj).
``"tpg"``
    Diffusion on the tensor product graph (Yang, Prasad & Latecki 2013): with P the
    row-normalised kNN affinities, sharpened to w^:data:`TPG_SHARPNESS` (the same graph,
    σ_i σ_j / 4 in the exponent), Q = Σ_{t=0}^{T} P^t (Pᵀ)^t (the iteration
    Q ← P Q Pᵀ + I, T = 20 steps): the affinity of two objects is the number of walks of
    equal length that lead from one and the other to a common object, weighted (a sum of
    Gram matrices: Q_ij ≤ sqrt(Q_ii Q_jj)). Distance 1 − Q_ij / sqrt(Q_ii Q_jj). The best
    of the four on MPEG-7 (leave-classes-out study: ``benchmarks/mpeg7_rerank.py``).

Every variant adds 1 % of the original distance (divided by its median) to break the ties
between pairs whose neighbourhoods do not overlap at all (all at 1 otherwise); this keeps
their original order.

Measured on MPEG-7 (1,400 silhouettes, 20 per class; ``benchmarks/mpeg7.py --rerank``) with
the default PF-SDM distance (79.5 % bull's-eye, 96.5 % 1-NN): see :func:`rerank` Notes.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

__all__ = ["RERANK_METHODS", "SPARSE_RERANK_METHODS", "rerank", "rerank_neighbours"]

RERANK_METHODS = ("diffusion", "mutual", "transduction", "tpg")
#: The variants :func:`rerank_neighbours` computes on a neighbour graph (transduction inverts a
#: dense n x n matrix and tpg's Q is one: they need the full matrix).
SPARSE_RERANK_METHODS = ("diffusion", "mutual")

#: Share of the original distance (divided by its median) kept as a tie-breaker.
TIE_BREAK = 0.01


def _check(d: np.ndarray, k: int) -> np.ndarray:
    d = np.asarray(d, float)
    if d.ndim != 2 or d.shape[0] != d.shape[1]:
        raise InputError(f"rerank needs a square distance matrix, got shape {d.shape}.")
    if not np.isfinite(d).all():
        raise InputError("The distance matrix has NaN or infinite entries (objects without "
                         "features?); leave those objects out first, e.g. "
                         "napari_pfsdm.drop_failed(table).")
    if (d < 0).any():
        raise InputError("Distances must be >= 0.")
    n = len(d)
    if isinstance(k, bool) or int(k) != k or k < 1:
        raise InputError(f"k must be a whole number >= 1, got {k!r}.")
    if n < 3:
        raise InputError(f"Re-ranking needs at least 3 objects, got {n}.")
    return 0.5 * (d + d.T)


def _knn_affinities(d: np.ndarray, k: int) -> np.ndarray:
    """Locally scaled Gaussian affinities kept on each object's k nearest neighbours (itself
    included), symmetrised by the maximum."""
    n = len(d)
    k = min(k, n - 1)
    off = d + np.diag(np.full(n, np.inf))
    order = np.argsort(off, axis=1)[:, :k]
    sigma = np.take_along_axis(off, order[:, -1:], axis=1)[:, 0]
    sigma = np.maximum(sigma, np.finfo(float).tiny)
    w = np.exp(-(d**2) / np.outer(sigma, sigma))
    keep = np.zeros((n, n), bool)
    keep[np.arange(n)[:, None], order] = True
    np.fill_diagonal(keep, True)
    keep |= keep.T
    return np.where(keep, w, 0.0)


def _cosine_distance(f: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(f, axis=1)
    g = (f @ f.T) / np.outer(norm, norm)
    return 1.0 - np.clip(g, 0.0, 1.0)


def _diffusion(d: np.ndarray, k: int, steps: int) -> np.ndarray:
    w = _knn_affinities(d, k)
    p = w / w.sum(axis=1, keepdims=True)
    f = p
    for _ in range(steps - 1):
        f = f @ p
    return _cosine_distance(f)


def _mutual(d: np.ndarray, k: int) -> np.ndarray:
    n = len(d)
    kk = min(k, n - 1)
    order = np.argsort(d + np.diag(np.full(n, -1.0)), axis=1)[:, : kk + 1]  # self first
    nn = np.zeros((n, n), bool)
    nn[np.arange(n)[:, None], order] = True
    mutual = nn & nn.T
    w = np.where(mutual, _knn_affinities(d, k), 0.0)
    np.fill_diagonal(w, 1.0)
    w /= w.sum(axis=1, keepdims=True)
    # weighted Jaccard: Σ min / Σ max, with Σ max = 2 − Σ min for rows summing to one
    inter = np.zeros((n, n))
    for col in range(n):  # only objects sharing neighbour `col` gain: few per column
        rows = np.flatnonzero(w[:, col])
        v = w[rows, col]
        inter[np.ix_(rows, rows)] += np.minimum(v[:, None], v[None, :])
    return 1.0 - inter / (2.0 - inter)


#: Neighbours per object of a re-ranking by default: about the number of objects of a kind, at
#: most (docs/benchmarks.md); the command line's ``--rerank-k`` and the plugin's re-rank.
RERANK_K = 10


def _transduction(d: np.ndarray, k: int, alpha: float) -> np.ndarray:
    w = _knn_affinities(d, k)
    np.fill_diagonal(w, 0.0)
    s = 1.0 / np.sqrt(np.maximum(w.sum(axis=1), np.finfo(float).tiny))
    f = np.linalg.inv(np.eye(len(d)) - alpha * (s[:, None] * w * s[None, :]))
    f = 0.5 * (f + f.T)
    diag = np.sqrt(np.diag(f))
    return 1.0 - np.clip(f / np.outer(diag, diag), 0.0, 1.0)


#: Exponent of the kNN affinities of ``"tpg"`` (chosen on MPEG-7 by leave-classes-out
#: cross-validation among 1/0.5 … 1/0.15: ``benchmarks/mpeg7_rerank.py``, docs/benchmarks.md).
TPG_SHARPNESS = 4.0
#: Steps of ``"tpg"``'s iteration Q ← P Q Pᵀ + I (same study: 20 over 10).
TPG_STEPS = 20
#: Steps of ``"diffusion"``'s random walk.
DIFFUSION_STEPS = 2


def _tpg(d: np.ndarray, k: int, steps: int, sharpness: float) -> np.ndarray:
    from scipy import sparse

    w = _knn_affinities(d, k)
    w = np.where(w > 0, w**sharpness, 0.0)
    p = sparse.csr_matrix(w / w.sum(axis=1, keepdims=True))
    eye = np.eye(len(d))
    q = eye.copy()
    for _ in range(steps):  # Q stays symmetric: P Q Pᵀ = P (P Q)ᵀ
        q = p @ (p @ q).T + eye
    q = 0.5 * (q + q.T)  # symmetric but for rounding
    diag = np.sqrt(np.diag(q))
    return 1.0 - np.clip(q / np.outer(diag, diag), 0.0, 1.0)


def rerank(d: np.ndarray, method: str = "diffusion", *, k: int = RERANK_K,
           steps: int | None = None, alpha: float = 0.9,
           sharpness: float = TPG_SHARPNESS) -> np.ndarray:
    """Re-rank a distance matrix by the neighbourhoods of the collection.

    Parameters
    ----------
    d : array_like, shape (n, n)
        Any distance matrix (e.g. :func:`napari_pfsdm.distance_matrix`), n ≥ 3, finite.
    method : {"diffusion", "mutual", "transduction"}
        The variant (module docstring).
    k : int
        Neighbours per object in the graph: about the number of objects per class you expect
        to find, at most. MPEG-7 (20 per class), diffusion with 2 steps: k = 5, 10, 15, 20 give
        86.6, 88.7, 88.0, 86.8 % bull's-eye.
    steps : int, optional
        Random-walk steps of ``"diffusion"`` (default :data:`DIFFUSION_STEPS`). MPEG-7,
        k = 10: 1, 2, 3 steps give 86.7, 88.7, 89.0 % bull's-eye and 96.9, 96.1, 95.7 % 1-NN;
        2 is the compromise. Steps of ``"tpg"`` (default :data:`TPG_STEPS`).
    alpha : float
        Propagation weight of ``"transduction"``, in (0, 1). MPEG-7, k = 10: 0.5, 0.9, 0.99
        give 87.4, 88.7, 87.9 % (1-NN 97.4, 96.8, 95.7 %); ``"mutual"`` is best at k = 20
        (86.2 %) and weaker at k = 10 (80.9 %).
    sharpness : float
        Exponent of ``"tpg"``'s affinities (default :data:`TPG_SHARPNESS`).

    Returns
    -------
    ndarray, shape (n, n)
        A new distance matrix: symmetric, zero diagonal, in [0, 1 + 0.01 · max(d)/median(d)];
        pairs whose neighbourhoods do not overlap keep their original order.

    Notes
    -----
    When it helps: retrieval in a collection with many objects of each kind (tens per
    class), where a class is a chain of gradually varying shapes. On MPEG-7 (20 per class)
    the default PF-SDM distance goes from 79.5 % to 88 % bull's-eye with ``"diffusion"``
    (``benchmarks/mpeg7.py --rerank``).

    When it hurts: few objects per class (fewer than k: the neighbourhoods mix classes), and
    the single nearest neighbour (1-NN accuracy drops on MPEG-7 and fell from 0.77 to 0.72 on
    a held-out real set): re-ranking makes the *group* around an object count, which helps
    ranking many similar objects and can move a lone close match down. Use it for retrieval
    and for maps (MDS) of large collections; compare objects one to one without it.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.r_[np.linspace(0, 1, 12), np.linspace(10, 11, 12)]
    >>> d = np.abs(x[:, None] - x[None, :])
    >>> r = rerank(d, k=5)
    >>> bool(np.allclose(r, r.T)), bool(np.all(np.diag(r) == 0))
    (True, True)
    >>> bool(r[:12, :12].max() < r[:12, 12:].min())
    True
    """
    if method not in RERANK_METHODS:
        raise InputError(f"method must be one of {', '.join(RERANK_METHODS)}; got {method!r}.")
    d = _check(d, k)
    if steps is None:
        steps = TPG_STEPS if method == "tpg" else DIFFUSION_STEPS
    if isinstance(steps, bool) or int(steps) != steps or steps < 1:
        raise InputError(f"steps must be a whole number >= 1, got {steps!r}.")
    if not sharpness > 0:
        raise InputError(f"sharpness must be > 0, got {sharpness!r}.")
    if not 0 < alpha < 1:
        raise InputError(f"alpha must lie in (0, 1), got {alpha!r}.")
    if method == "diffusion":
        out = _diffusion(d, int(k), int(steps))
    elif method == "mutual":
        out = _mutual(d, int(k))
    elif method == "tpg":
        out = _tpg(d, int(k), int(steps), float(sharpness))
    else:
        out = _transduction(d, int(k), float(alpha))
    off = d[~np.eye(len(d), dtype=bool)]
    med = float(np.median(off))
    if med > 0:
        out = out + TIE_BREAK * d / med
    out = 0.5 * (out + out.T)
    np.fill_diagonal(out, 0.0)
    return out


# --------------------------------------------------------------------------------------------
# the same on a neighbour graph: (indices, distances) of napari_pfsdm.nearest_neighbours
# --------------------------------------------------------------------------------------------

def _check_graph(indices, distances, k: int) -> tuple[np.ndarray, np.ndarray]:
    idx = np.asarray(indices)
    dist = np.asarray(distances, float)
    if idx.ndim != 2 or idx.shape != dist.shape:
        raise InputError(f"indices and distances must be two (n, K) arrays of the same shape; "
                         f"got {idx.shape} and {dist.shape}.")
    n, kk = idx.shape
    if n < 3:
        raise InputError(f"Re-ranking needs at least 3 objects, got {n}.")
    if isinstance(k, bool) or int(k) != k or k < 1:
        raise InputError(f"k must be a whole number >= 1, got {k!r}.")
    if kk < min(int(k), n - 1):
        raise InputError(f"the graph holds {kk} neighbours per object; re-ranking with k = {k} "
                         f"needs at least {min(int(k), n - 1)}: ask nearest_neighbours for more.")
    if idx.dtype.kind not in "iu" or idx.min() < 0 or idx.max() >= n:
        raise InputError(f"indices must be whole numbers in 0 … {n - 1}.")
    if (idx == np.arange(n)[:, None]).any():
        raise InputError("indices must exclude each object itself (as nearest_neighbours "
                         "returns them).")
    if not np.isfinite(dist).all() or (dist < 0).any():
        raise InputError("The neighbour distances must be finite and >= 0.")
    return idx.astype(np.int64), dist


def _graph(idx: np.ndarray, values: np.ndarray, n: int, *, diagonal: float | None = None):
    """Symmetric sparse matrix holding ``values`` on the pairs (i, idx[i, j]) and their mirror
    images (the larger value where both are given), ``diagonal`` on the diagonal."""
    from scipy import sparse

    rows = np.repeat(np.arange(n), idx.shape[1])
    a = sparse.coo_matrix((values.ravel(), (rows, idx.ravel())), shape=(n, n)).tocsr()
    a = a.maximum(a.T)
    if diagonal is not None:  # the graph holds no (i, i): self is excluded
        a = a + sparse.identity(n, format="csr") * diagonal
    a = a.tocsr()
    a.sort_indices()
    return a


def _sparse_affinities(idx: np.ndarray, dist: np.ndarray, k: int):
    """:func:`_knn_affinities` on the graph: the k nearest of each object (and itself) and
    their mirror images, w_ij = exp(-d_ij² / (σ_i σ_j)), σ_i the k-th neighbour's distance."""
    n = len(idx)
    k = min(k, n - 1)
    sigma = np.maximum(dist[:, k - 1], np.finfo(float).tiny)
    ik, dk = idx[:, :k], dist[:, :k]
    w = np.exp(-(dk**2) / (sigma[:, None] * sigma[ik]))
    # exp(-d²/σσ) is symmetric in i, j: the mirror image of a kept pair carries the same value
    # (the maximum only matters for distances that differ in the last bits)
    return _graph(ik, np.maximum(w, np.finfo(float).tiny), n, diagonal=1.0)


def _sparse_cosine(f):
    """Cosine similarity of the rows of a sparse matrix, on the pairs whose rows overlap."""
    from scipy import sparse

    g = (f @ f.T).tocsr()
    norm = np.sqrt(np.maximum(g.diagonal(), np.finfo(float).tiny))
    inv = sparse.diags(1.0 / norm)
    g = (inv @ g @ inv).tocsr()
    g.data = np.clip(g.data, 0.0, 1.0)
    return g


def _sparse_diffusion(idx, dist, k: int, steps: int):
    from scipy import sparse

    w = _sparse_affinities(idx, dist, k)
    p = (sparse.diags(1.0 / np.asarray(w.sum(axis=1)).ravel()) @ w).tocsr()
    f = p
    for _ in range(steps - 1):
        f = (f @ p).tocsr()
    return _sparse_cosine(f)


def _sparse_mutual(idx, dist, k: int):
    """Weighted Jaccard similarity of the mutual-neighbour rows (:func:`_mutual`)."""
    from scipy import sparse

    n = len(idx)
    kk = min(k, n - 1)
    one_way = sparse.coo_matrix((np.ones(n * kk), (np.repeat(np.arange(n), kk),
                                                    idx[:, :kk].ravel())), shape=(n, n)).tocsr()
    mutual = one_way.multiply(one_way.T).tocsr()  # i among j's k nearest and j among i's
    w = _sparse_affinities(idx, dist, k).multiply(mutual).tocsr()
    w = w + sparse.identity(n, format="csr")
    w = (sparse.diags(1.0 / np.asarray(w.sum(axis=1)).ravel()) @ w).tocsc()
    # Σ_c min(w_ic, w_jc): every pair of rows that share a column c gains min of the two
    counts = np.diff(w.indptr)
    start = w.indptr[:-1]
    # all ordered pairs (a, b) of entries within each column
    pair_col = np.repeat(np.arange(n), counts**2)
    offs = np.arange(int((counts**2).sum())) - np.repeat(np.cumsum(counts**2) - counts**2,
                                                          counts**2)
    ca = np.repeat(counts, counts**2)
    a = start[pair_col] + offs // ca
    b = start[pair_col] + offs % ca
    inter = sparse.coo_matrix((np.minimum(w.data[a], w.data[b]),
                               (w.indices[a], w.indices[b])), shape=(n, n)).tocsr()
    inter.sum_duplicates()
    inter.data = inter.data / (2.0 - inter.data)  # Jaccard similarity = 1 - distance
    return inter


def rerank_neighbours(
    indices, distances, method: str = "diffusion", *, k: int = RERANK_K,
    steps: int = DIFFUSION_STEPS,
    scale: float | None = None, n_neighbours: int | None = None, return_exact: bool = False,
):
    """Re-rank a neighbour graph: :func:`rerank` without the n x n matrix.

    Takes the graph of :func:`napari_pfsdm.nearest_neighbours` (each object's K nearest,
    nearest first, itself excluded) and returns each object's neighbours re-ranked by the
    same neighbourhood similarity as :func:`rerank` (same ``k``, ``steps``, tie-break). The
    candidates of an object are the pairs whose distance the graph holds: its K nearest and
    the objects that have it among theirs. Every value computed is the one :func:`rerank`
    gives on the full matrix (when ``scale`` is that matrix's median distance); the result
    differs from the full route's top neighbours only where the full route brings up an
    object beyond these candidates (two steps away in the graph). ``return_exact=True``
    says for which objects that provably cannot happen.

    Parameters
    ----------
    indices, distances : array_like, shape (n, K)
        The graph: K ≥ k neighbours per object, nearest first, itself excluded. Several
        times k (e.g. K = 3k) lets more objects be certified exact.
    method : {"diffusion", "mutual"}
        As in :func:`rerank`; ``"transduction"`` needs the full matrix (a dense inverse).
    k, steps : int
        As in :func:`rerank` (k nearest of each object in the affinity graph).
    scale : float, optional
        The median distance between two objects of the collection, the unit of the
        tie-break (:data:`TIE_BREAK` × d / scale) as in :func:`rerank`. Default: the median
        of the graph's distances (smaller than the collection's median, so the tie-break
        weighs more than in :func:`rerank`); ``pfsdm compare`` estimates it from 400
        random objects.
    n_neighbours : int, optional
        Neighbours returned per object (default K).
    return_exact : bool
        Also return a boolean array: True where the returned neighbours are provably those
        of :func:`rerank` on the full matrix (no object outside the candidates can score
        below the last one returned).

    Returns
    -------
    indices : ndarray of int64, shape (n, n_neighbours)
    distances : ndarray, shape (n, n_neighbours)
        The re-ranked distances (as :func:`rerank` gives them), nearest first.
    exact : ndarray of bool, shape (n,)
        Only with ``return_exact=True``.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.r_[np.linspace(0, 1, 12), np.linspace(10, 11, 12)]
    >>> d = np.abs(x[:, None] - x[None, :])
    >>> order = np.argsort(d + np.diag(np.full(24, np.inf)), axis=1)[:, :15]
    >>> idx, dist = rerank_neighbours(order, np.take_along_axis(d, order, 1), k=5,
    ...                               scale=float(np.median(d[~np.eye(24, dtype=bool)])))
    >>> full = rerank(d, k=5)
    >>> bool(np.allclose(dist, np.take_along_axis(full, idx, 1)))
    True
    >>> bool((idx[:12, :5] < 12).all() and (idx[12:, :5] >= 12).all())
    True
    """
    if method not in SPARSE_RERANK_METHODS:
        extra = (" (its result is dense: it needs the full matrix, napari_pfsdm.rerank)"
                 if method in ("transduction", "tpg") else "")
        raise InputError(f"method must be one of {', '.join(SPARSE_RERANK_METHODS)} on a "
                         f"neighbour graph; got {method!r}{extra}.")
    if isinstance(steps, bool) or int(steps) != steps or steps < 1:
        raise InputError(f"steps must be a whole number >= 1, got {steps!r}.")
    idx, dist = _check_graph(indices, distances, k)
    n, kk = idx.shape
    m = kk if n_neighbours is None else int(n_neighbours)
    if not 1 <= m <= kk:
        raise InputError(f"n_neighbours must lie in 1 … {kk}, got {n_neighbours!r}.")
    if scale is None:
        scale = float(np.median(dist))
    scale = float(scale)
    if not scale > 0:
        scale = 1.0
    sim = (_sparse_diffusion(idx, dist, int(k), int(steps)) if method == "diffusion"
           else _sparse_mutual(idx, dist, int(k)))
    # the candidates: every pair whose distance the graph holds (both directions)
    d_graph = _graph(idx, dist + 1.0, n)  # + 1: a zero distance stays a stored entry
    d_graph.data -= 1.0
    sim = sim.tocsr()
    # sim on the candidate pattern: elementwise product with a pattern of ones
    pattern = d_graph.copy()
    pattern.data = np.ones_like(pattern.data)
    s_cand = sim.multiply(pattern).tocsr()
    # align s_cand with d_graph's pattern (sim may be zero: no overlap)
    s_aligned = (pattern + s_cand).tocsr()  # 1 + sim on the pattern
    s_aligned.sort_indices()
    score = (1.0 - (s_aligned.data - 1.0)) + TIE_BREAK * d_graph.data / scale
    rows = np.repeat(np.arange(n), np.diff(d_graph.indptr))
    cols = d_graph.indices
    order = np.lexsort((cols, score, rows))  # by row, then score, ties by index
    counts = np.diff(d_graph.indptr)
    first = d_graph.indptr[:-1]
    take = first[:, None] + np.arange(m)[None, :]
    out_idx = cols[order][take]
    out_dist = score[order][take]
    if not return_exact:
        return out_idx, out_dist
    # a non-candidate j of i has d_ij >= i's K-th distance (the graph holds i's K nearest),
    # and its similarity is what sim holds (0 where no overlap): a lower bound of its score
    from scipy import sparse

    outside = (sim - sim.multiply(pattern)).tocsr()
    outside = (outside - sparse.diags(outside.diagonal())).tocsr()  # itself: no candidate
    outside.eliminate_zeros()
    best_out = np.zeros(n)
    if outside.nnz:
        best_out = np.asarray(outside.max(axis=1).todense()).ravel()
    bound = 1.0 - best_out + TIE_BREAK * dist[:, -1] / scale
    bound[counts >= n - 1] = np.inf  # every other object is a candidate
    exact = out_dist[:, -1] <= bound
    return out_idx, out_dist, exact
