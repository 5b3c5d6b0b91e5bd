"""The k nearest neighbours under D + μ d_E (the default distance plus the elastic outline term).

The default search (:mod:`.neighbours`) is exact because D has a cheap lower bound close to it
for all pairs. d_E has none (docs/benchmarks.md, "Where the search's candidates could come
from": the best measured bounds are a median 9–22 % of it), and on round objects it orders
the neighbours much more than D does, so candidates taken in D's order miss them. This search
takes its candidates from the elastic term's own cheaper forms instead, in three stages per
block of queries (:func:`search_rows`):

1. **Pool** (all objects, by matrix products; :func:`pool_and_candidates`): the ``pool``
   objects of least LB + μ · :data:`PROFILE_WEIGHT` · ‖e(a) − e(b)‖, LB the default search's
   lower bound of D (:func:`.neighbours._lower_bound`) and e a start- and mirror-invariant
   vector of the signature (:func:`embedding`: each channel's values sorted and averaged in
   :data:`PROFILE_QUANTILES` parts, blind to any re-timing along the outline as d_E's warps
   are, and the magnitudes of its first :data:`PROFILE_HARMONICS` harmonics);
2. **Coarse** (the pool; :func:`_coarse`): the ``candidates`` objects of least LB + μ ·
   :data:`COARSE_SCALE` · d_E of the signatures averaged to :data:`COARSE_POINTS` points
   (band :data:`COARSE_BAND`: less than half the cost per pair), the pairs taken object by
   object of the pool so that each signature is read once for all its rows;
3. **Exact** (the candidates; :func:`_exact_totals`): d_E of each on the full signatures,
   then D (:func:`.neighbours._exact_pairs`, the dearer) in increasing order of LB + μ d_E
   until the k-th total found is below the next; the k of least D + μ d_E.

How deep stages 1 and 2 look is measured first (:func:`depth`) on :data:`SAMPLE` random
objects against all: objects whose neighbours the cheap forms rank badly (round nuclei) get a
deeper pool than kinds far apart (MPEG-7). The result is approximate: a true neighbour is lost
when stage 1 or 2 ranks it below the pool or the candidates. A row is *certified* exact when
its k-th total is below the lower bound LB of every object that is not among its candidates
(d_E ≥ 0, so D + μ d_E ≥ D ≥ LB: none of them can be nearer); when the candidates are all the
other objects every row is. The recall against the full matrix (docs/benchmarks.md, "The
elastic term's neighbours") is measured by ``benchmarks/neighbours_elastic.py``;
:func:`brute_rows` (``method="brute"``) is the exact reference. numpy and the compiled d_E on
the calling thread only (``here``), so that query blocks run on threads or dask tasks as the
default search's do.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .elastic import SignatureSet
from .neighbours import NeighbourIndex, _exact_pairs, _lower_bound, _top_k, _top_k_sparse

__all__ = ["COARSE_BAND", "COARSE_POINTS", "ElasticIndex", "brute_rows", "depth", "embedding",
           "pool_and_candidates", "search_rows", "sizes", "value_profile"]

#: Points of the coarse signatures of stage 2 (pairs of the signature's points averaged), and
#: the half-width of their DTW band (3 of 32 points, against the full signatures' 8 of 64: a
#: ninth fewer cells than 4, and its ranking of the nuclei's neighbours as good to 1e-3).
COARSE_POINTS, COARSE_BAND = 32, 3
#: d_E of the coarse signatures against the full ones' (least squares over all pairs: 1.09
#: on MPEG-7, 1.13 on nuclei): stage 2 ranks by LB + μ · COARSE_SCALE · coarse d_E.
COARSE_SCALE = 1.1
#: Parts each channel's sorted values are averaged in for the value profile.
PROFILE_QUANTILES = 8
#: Harmonics 1 … PROFILE_HARMONICS of each channel's magnitude spectrum in the embedding, and
#: their factor against the value profile.
PROFILE_HARMONICS, HARMONICS_FACTOR = 8, 4.0
#: Weight of the embedding's Euclidean distance in the pool's ranking (LB + μ ·
#: PROFILE_WEIGHT · ‖e(a) − e(b)‖).
PROFILE_WEIGHT = 0.25
#: Random objects whose rows against all objects set how deep the search looks
#: (:func:`depth`), and the share of their neighbours that depth must hold.
SAMPLE, SAMPLE_QUANTILE = 64, 0.99
#: Margins on the depths the sample asks for (the pool, the candidates).
POOL_MARGIN, CANDIDATE_MARGIN = 1.75, 1.5
#: Bounds of the pool and the candidates (besides n − 1, and k for the candidates).
MIN_POOL, MAX_POOL = 150, 600
MIN_CANDIDATES, MAX_CANDIDATES = 20, 60
#: Objects of each sampled row given the coarse d_E in :func:`depth` (its first in stage 1's
#: order; a neighbour further down counts as this deep).
SAMPLE_DEPTH = 300
#: Relative margin of the single-precision bound in the certification (as the default
#: search's).
_SAFE = 1 - 1e-6


def value_profile(signatures: np.ndarray, parts: int = PROFILE_QUANTILES) -> np.ndarray:
    """Each channel's values sorted and averaged in ``parts`` equal parts, per object.

    Parameters
    ----------
    signatures : ndarray, shape (n, channels, points)
        Outline signatures (``points`` a multiple of ``parts``).

    Returns
    -------
    ndarray, shape (n, channels · parts)
        The same for a signature started elsewhere or mirrored (a permutation of its
        columns). Twice the Euclidean distance of two profiles is the pool's stand-in for d_E.

    Examples
    --------
    >>> sig = np.arange(16.0).reshape(1, 2, 8)[:, :, ::-1]   # two channels, reversed
    >>> value_profile(sig, parts=2).tolist()
    [[1.5, 5.5, 9.5, 13.5]]
    """
    s = np.sort(np.asarray(signatures, float), axis=-1)
    n, c, m = s.shape
    return s.reshape(n, c, parts, m // parts).mean(axis=-1).reshape(n, c * parts)


def embedding(signatures: np.ndarray) -> np.ndarray:
    """The pool's start- and mirror-invariant vector of each signature: its value profile
    (:func:`value_profile`) and HARMONICS_FACTOR times the magnitudes of harmonics
    1 … PROFILE_HARMONICS of each channel (over the points: a start shift changes their
    phases only, a mirror conjugates them)."""
    s = np.asarray(signatures, float)
    mag = np.abs(np.fft.rfft(s, axis=-1)[:, :, 1:PROFILE_HARMONICS + 1]) / s.shape[2]
    return np.hstack([value_profile(s), HARMONICS_FACTOR * mag.reshape(len(s), -1)])


def coarse(signatures: np.ndarray, points: int = COARSE_POINTS) -> np.ndarray:
    """Signatures averaged to ``points`` columns (neighbouring columns' means)."""
    s = np.asarray(signatures, float)
    n, c, m = s.shape
    return s.reshape(n, c, points, m // points).mean(axis=-1)


@dataclass(frozen=True)
class ElasticIndex:
    """What the search needs about the n objects, prepared once.

    Attributes
    ----------
    index : NeighbourIndex
        The default distance's (``valid`` also False where the signature is not finite).
    full, rough : SignatureSet
        The signatures, and their coarse form (:func:`coarse`; band :data:`COARSE_BAND`).
    profile_rows, profile_cols : ndarray of float32, shape (n, d + 2)
        [p, |p|², 1] and [−2p, 1, |p|²] of the weighted value profile p: one matrix product
        gives the squared distances of a block of queries to all objects.
    """

    index: NeighbourIndex
    full: SignatureSet
    rough: SignatureSet
    profile_rows: np.ndarray
    profile_cols: np.ndarray

    @classmethod
    def build(cls, index: NeighbourIndex, signatures: np.ndarray) -> ElasticIndex:
        sig = np.asarray(signatures, float)
        ok = np.isfinite(sig).all(axis=(1, 2))
        sig = np.where(ok[:, None, None], sig, 0.0)  # read by number, never used
        index = NeighbourIndex(index.features, index.outline, index.boundary_weight,
                               index.valid & ok, index.bound_rows, index.bound_cols)
        full = SignatureSet(sig)
        rough = SignatureSet(coarse(sig), band=COARSE_BAND)
        p = PROFILE_WEIGHT * embedding(sig)
        sq = np.einsum("ij,ij->i", p, p)[:, None]
        one = np.ones((len(p), 1))
        rows = np.ascontiguousarray(np.hstack([p, sq, one]), np.float32)
        cols = np.ascontiguousarray(np.hstack([-2 * p, one, sq]), np.float32)
        return cls(index, full, rough, rows, cols)

    def __len__(self) -> int:
        return len(self.index)


def depth(ei: ElasticIndex, mu: float, k: int, sample: int = SAMPLE,
          seed: int = 0) -> tuple[int, int]:
    """(pool, candidates) per query: how deep each stage must look, measured on ``sample``
    random valid objects (seeded) against all objects.

    For each sampled object q: stage 1's order of all objects, the coarse total of stage 2 to
    its first SAMPLE_DEPTH, and the exact total to its MAX_CANDIDATES of least coarse total.
    The pool is POOL_MARGIN × the SAMPLE_QUANTILE quantile of the stage-1 ranks of each q's k
    nearest by coarse total; the candidates CANDIDATE_MARGIN × that quantile of the coarse
    ranks of each q's k nearest by exact total (within MIN_/MAX_POOL and MIN_/MAX_CANDIDATES,
    n − 1). The neighbours by coarse total stand in for the true ones in the first (ranks of
    the true ones run a fifth to a quarter deeper on MPEG-7 and the nuclei: the margin covers
    it).
    On MPEG-7 the pool comes out about half as deep as on round nuclei, whose neighbours the
    cheap forms rank worse (docs/benchmarks.md, "The elastic term's neighbours"). Costs
    ``sample`` × SAMPLE_DEPTH coarse pairs and ``sample`` × MAX_CANDIDATES exact ones."""
    n = len(ei)
    valid = np.flatnonzero(ei.index.valid)
    if len(valid) <= MIN_POOL + 1:
        return n - 1, n - 1
    rng = np.random.default_rng(seed)
    q = np.sort(rng.choice(valid, min(sample, len(valid)), replace=False))
    # stage 1's order of every object (the first MAX_POOL), and their coarse totals
    part, base, _ = pool_and_candidates(ei, q, mu, min(SAMPLE_DEPTH, n - 1), by="proxy")
    r_i, c_i = np.nonzero(part >= 0)
    coarse_total = np.full(part.shape, np.inf)
    coarse_total[r_i, c_i] = base[r_i, c_i] + mu * COARSE_SCALE * ei.rough.between(
        q[r_i], part[r_i, c_i])
    by_coarse = np.argsort(coarse_total, axis=1, kind="stable")  # positions in stage 1's order
    pool = POOL_MARGIN * np.quantile(by_coarse[:, :k] + 1, SAMPLE_QUANTILE)
    near = np.take_along_axis(part, by_coarse, 1)
    m = min(MAX_CANDIDATES, len(valid) - 1)
    near = near[:, :m]
    exact = np.full(near.shape, np.inf)
    r_i, c_i = np.nonzero(np.isfinite(np.take_along_axis(coarse_total, by_coarse[:, :m], 1)))
    exact[r_i, c_i] = (_exact_pairs(ei.index, q[r_i], near[r_i, c_i])
                       + mu * ei.full.between(q[r_i], near[r_i, c_i]))
    kth = np.argsort(exact, axis=1, kind="stable")[:, :k]  # coarse ranks of the k nearest
    cand = CANDIDATE_MARGIN * np.quantile(kth + 1, SAMPLE_QUANTILE)
    pool = int(np.clip(np.ceil(pool), MIN_POOL, min(MAX_POOL, n - 1)))
    cand = int(np.clip(np.ceil(cand), max(MIN_CANDIDATES, k), min(MAX_CANDIDATES, pool)))
    return pool, cand


def sizes(k: int, n: int, candidates: int) -> tuple[int, int]:
    """(pool, candidates) when the candidates are given: a pool ten times that (at least
    MIN_POOL), each at most n − 1."""
    c = min(n - 1, max(int(candidates), k))
    return min(n - 1, max(10 * c, MIN_POOL)), c


def pool_and_candidates(ei: ElasticIndex, rows: np.ndarray, mu: float, pool: int,
                        by: str = "lb") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stage 1 for the queries ``rows`` (module docstring): each one's pool (objects, -1
    for none, in increasing order of LB, or of the proxy with ``by="proxy"``), their LB, and
    the least LB of the objects left out of the pool (inf: none). numpy only (threads or
    dask tasks)."""
    lb = _lower_bound(ei.index, rows)  # (rows, n) float32, inf: itself, invalid objects
    d2 = ei.profile_rows[rows] @ ei.profile_cols.T
    np.maximum(d2, 0, out=d2)
    proxy = lb + np.float32(mu) * np.sqrt(d2)
    n = lb.shape[1]
    if pool < n:
        part = np.argpartition(proxy, pool - 1, axis=1)[:, :pool]
    else:
        part = np.broadcast_to(np.arange(n), lb.shape).copy()
    base = np.take_along_axis(lb, part, 1)
    order = np.argsort(base if by == "lb" else np.take_along_axis(proxy, part, 1), axis=1,
                       kind="stable")
    part = np.take_along_axis(part, order, 1)
    base = np.take_along_axis(base, order, 1).astype(float)
    lb[np.arange(len(rows))[:, None], part] = np.inf
    outside = lb.min(axis=1).astype(float) if pool < n else np.full(len(rows), np.inf)
    part = np.where(np.isfinite(base), part, -1)
    return part, base, outside


def search_rows(ei: ElasticIndex, rows: np.ndarray, k: int, mu: float, pool: int,
                candidates: int, here: bool = False
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The k nearest of the objects ``rows`` under D + μ d_E (module docstring): indices and
    distances (len(rows), k), nearest first (equal distances by object number), and whether
    each row is certified exact. ``here``: d_E on the calling thread only (a caller that runs
    blocks of rows on threads of its own), else on numba's threads. Rows that are not valid
    get index -1 and distance NaN."""
    rows = np.asarray(rows, np.int64)
    part, base, outside = pool_and_candidates(ei, rows, mu, pool)
    cand, lb, left = _coarse(ei, rows, part, base, mu, candidates, here)
    outside = np.minimum(outside, left)
    idx, dist = _exact_totals(ei, rows, cand, lb, k, mu, here)
    certified = dist[:, k - 1] < outside * _SAFE
    certified |= np.isinf(outside)
    bad = ~ei.index.valid[rows]
    idx[bad], dist[bad], certified[bad] = -1, np.nan, True
    return idx, dist, certified


def _coarse(ei: ElasticIndex, rows: np.ndarray, part: np.ndarray, base: np.ndarray,
            mu: float, candidates: int, here: bool
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stage 2: of each row's pool (``part``, -1: none; ``base``: their LB), the
    ``candidates`` of least LB + μ · COARSE_SCALE · d_E of the coarse signatures, with
    their LB (-1 and inf: none), and the least LB of the pool's objects left out (inf:
    none). The pairs are computed in the order of the pool's objects (each one's signature
    read once for all the rows whose pool holds it)."""
    r_i, c_i = np.nonzero(part >= 0)
    order = np.lexsort((r_i, part[r_i, c_i]))
    r_i, c_i = r_i[order], c_i[order]
    score = np.full(part.shape, np.inf)
    score[r_i, c_i] = base[r_i, c_i] + mu * COARSE_SCALE * ei.rough.between(
        rows[r_i], part[r_i, c_i], here=here)
    c = min(candidates, part.shape[1])
    pick = (np.argpartition(score, c - 1, axis=1)[:, :c] if c < part.shape[1]
            else np.broadcast_to(np.arange(part.shape[1]), part.shape).copy())
    cand = np.take_along_axis(part, pick, 1)
    lb = np.take_along_axis(base, pick, 1)
    none = ~np.isfinite(np.take_along_axis(score, pick, 1))
    cand[none], lb[none] = -1, np.inf
    out = base.copy()
    np.put_along_axis(out, pick, np.inf, 1)
    out[part < 0] = np.inf
    return cand, lb, out.min(axis=1, initial=np.inf)


def _exact_totals(ei: ElasticIndex, rows: np.ndarray, cand: np.ndarray, lb: np.ndarray,
                  k: int, mu: float, here: bool) -> tuple[np.ndarray, np.ndarray]:
    """Stage 3: the k least D + μ d_E among each row's candidates (-1: none), with d_E of
    every candidate and D (the dearer, ~15 µs a pair) only where it can matter: in
    increasing order of the lower bound LB + μ d_E, until the k-th total found is below the
    next bound."""
    r_i, c_i = np.nonzero(cand >= 0)
    d_e = np.full(cand.shape, np.inf)
    d_e[r_i, c_i] = ei.full.between(rows[r_i], cand[r_i, c_i], here=here)
    low = lb + mu * d_e
    order = np.argsort(low, axis=1, kind="stable")
    cand, d_e, low = (np.take_along_axis(x, order, 1) for x in (cand, d_e, low))
    total = np.full(cand.shape, np.inf)
    done = np.zeros(cand.shape, bool)
    todo = (cand >= 0) & (np.arange(cand.shape[1]) < k)  # first round: the k lowest bounds
    while todo.any():
        r_i, c_i = np.nonzero(todo)
        total[r_i, c_i] = (_exact_pairs(ei.index, rows[r_i], cand[r_i, c_i])
                           + mu * d_e[r_i, c_i])
        done |= todo
        kth = (np.partition(total, k - 1, axis=1)[:, k - 1] if cand.shape[1] >= k
               else np.full(len(rows), np.inf))
        todo = ~done & (cand >= 0) & (low <= kth[:, None])
    r_i, c_i = np.nonzero(done)
    idx, dist = _top_k_sparse(r_i, cand[r_i, c_i], total[r_i, c_i], len(rows), k)
    return idx.astype(np.int64), dist


def brute_rows(ei: ElasticIndex, rows: np.ndarray, k: int,
               mu: float) -> tuple[np.ndarray, np.ndarray]:
    """The exact reference: D + μ d_E of the queries ``rows`` to every object, its k least
    (nearest first, equal distances by object number; invalid rows -1 and NaN)."""
    from .elastic import elastic_distance_between

    rows = np.asarray(rows, np.int64)
    n = len(ei)
    ii = np.repeat(rows, n)
    jj = np.tile(np.arange(n), len(rows))
    total = (_exact_pairs(ei.index, ii, jj)
             + mu * elastic_distance_between(ei.full.values, ii, jj))
    total = total.reshape(len(rows), n)
    total[:, ~ei.index.valid] = np.inf
    total[np.arange(len(rows)), rows] = np.inf
    idx, dist = _top_k(total, None, k)
    bad = ~ei.index.valid[rows]
    idx[bad], dist[bad] = -1, np.nan
    return idx.astype(np.int64), dist
