"""The elastic outline term: a multi-scale outline signature compared by dynamic programming.

The boundary term (:mod:`.boundary`) lines two outlines up by one rigid start shift; detail that
is stretched or articulated differently along the outline (a longer leg, a shifted notch) then
falls out of phase and is lost. This term lets the correspondence bend.

Signature
    :func:`~.elastic_signature.outline_signature` (:mod:`.elastic_signature`): per object,
    :data:`N_SIGNATURE_POINTS` columns of :data:`N_CHANNELS` numbers along its outline,
    invariant to translation, rotation and scale; moving the start point shifts the columns
    cyclically, a mirror image reverses their order.

Distance (:func:`elastic_distance_pairs`, :func:`elastic_distance_matrix`)
    With the L1 cost between columns, ``c(i, j) = min(‖a(i) − b(j)‖₁, ‖a(i) − b(j + ½)‖₁,
    ‖a(i + ½) − b(j)‖₁)``, where ``x(i + ½)`` is the midpoint of two neighbouring columns
    (``half_steps``; the plain ``‖a(i) − b(j)‖₁`` without; the cost is symmetric either way):

    1. for both orientations of b (as is, and reversed: the mirror image), the cyclic start
       shifts s are scored by the rigid cost Σ_i ‖a(i) − b(i + s)‖² (a correlation, from the
       signatures' FFTs); of its local minima over s, the :data:`N_START_SHIFTS` lowest over
       both orientations are kept (one start per valley: neighbouring shifts of one valley
       would refine to the same path), and any other tied with the last of them (a symmetric
       outline has several equal valleys: rounding must not choose among them);
    2. each is refined by dynamic time warping in a band of ± :data:`BAND` points around the
       rigid diagonal (steps (1, 1), (1, 0), (0, 1), from (0, 0) to (n − 1, n − 1));
    3. the distance is the least warped cost over them, divided by n: the mean L1 cost per
       point along the best elastic correspondence.

    It is 0 between a signature and itself started elsewhere by whole points or mirrored
    (exactly), symmetric (each pair is put in a fixed order, :func:`_distances`), and never
    above the rigid mean cost at the shifts it refines (the diagonal is a path in the band).
    It is no metric (DTW breaks the triangle inequality).

    Between an outline and a copy of it rotated, rescaled or translated as a raster, it is
    small but not 0: besides the pixel staircase, the copy's start point falls between the
    signature's points, and a half-point offset costs about the signature's total variation
    / 2n per point, which no correspondence between the same n points removes. The channels
    are smoothed (:data:`SMOOTHING`) before they are sampled, and the half-point matches of
    the cost take up most of the offset (a lobed shape of ``tests/test_elastic.py`` turned by
    0.6 rad is at 7 % of its distance to a rectangle, 3 % without the thickness channel, whose
    normals the staircase tilts).

Compiled kernels (numba, parallel over pairs: :mod:`.elastic_kernel`)
    The DP of every start shift of a pair in single precision over costs computed once per
    pair; with a limit (:func:`elastic_nearest`), start shifts abandoned as soon as they
    cannot get under it (the same result). Compiled on first use after an install, then
    loaded from numba's cache in every later process (:mod:`.compiled`).

This module holds the public functions, their checks and the plain numpy reference of the DP
(:func:`banded_dtw`, which the tests hold the kernels to).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..errors import InputError
from .elastic_signature import (
    N_CHANNELS,
    N_SIGNATURE_POINTS,
)

__all__ = [
    "BAND",
    "N_CHANNELS",
    "N_SIGNATURE_POINTS",
    "N_START_SHIFTS",
    "banded_dtw",
    "elastic_distance_between",
    "elastic_distance_matrix",
    "elastic_distance_pairs",
    "elastic_nearest",
    "SignatureSet",
]

#: Half-width of the DTW band, in signature points (1/8 of the outline; MPEG-7's
#: leave-classes-out study chose 8 over 4 in 20 of 22 halves, docs/benchmarks.md).
BAND = 8
#: Rigid start shifts (over both orientations) refined by DTW (MPEG-7's leave-classes-out
#: study: 5 over 3, docs/benchmarks.md).
N_START_SHIFTS = 5
#: Whether a point may also be matched to the midpoint of two neighbours of the other
#: signature (half-point offsets of the start point then cost little).
HALF_STEPS = True


def _mirrored(sig: np.ndarray) -> np.ndarray:
    """The signature of the mirror image traced counter-clockwise: the columns reversed
    (column 0 stays first). Reversing the direction of travel and reflecting each flip the
    sign of a turning angle, so the angles keep theirs."""
    return np.roll(sig[..., ::-1], 1, axis=-1)


def banded_dtw(cost: np.ndarray) -> np.ndarray:
    """Least cost of a monotone path from (0, 0) to (n − 1, n − 1) through banded costs.

    Parameters
    ----------
    cost : ndarray, shape (..., n, 2B + 1)
        ``cost[..., i, B + d]`` is the cost of matching point i to point i + d; entries with
        i + d outside 0 … n − 1 are ignored.

    Returns
    -------
    ndarray, shape (...)
        The least sum of costs along a path of steps (1, 1), (1, 0), (0, 1) that stays in the
        band (each visited cell counted once).

    Examples
    --------
    >>> c = np.array([[[np.inf, 0, 5], [1, 0, 5], [1, 0, np.inf]]])  # n = 3, B = 1
    >>> float(banded_dtw(c)[0])
    0.0
    """
    c = np.asarray(cost, float)
    n, w = c.shape[-2], c.shape[-1]
    b = (w - 1) // 2
    d = np.arange(w) - b
    inf = np.inf
    prev = np.full(c.shape[:-2] + (w,), inf)
    for i in range(n):
        row = np.where(((i + d) >= 0) & ((i + d) < n), c[..., i, :], inf)
        if i == 0:
            # from (0, 0) rightwards only
            s = np.cumsum(np.where(d >= 0, row, 0.0), axis=-1)
            cur = np.where(d >= 0, s, inf)
        else:
            # diagonal: (i−1, j−1) is the same d; vertical: (i−1, j) is d + 1
            up = np.concatenate([prev[..., 1:], np.full(prev.shape[:-1] + (1,), inf)], -1)
            t = row + np.minimum(prev, up)
            # horizontal steps within the row: D[d] = min_{e ≤ d} t[e] + Σ_{e<f≤d} row[f]
            finite = np.where(np.isfinite(row), row, 0.0)
            s = np.cumsum(finite, axis=-1)
            cur = s + np.minimum.accumulate(t - s, axis=-1)
            cur = np.where(np.isfinite(row), cur, inf)
        prev = cur
    return prev[..., b]


def _check_signatures(sig: np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(sig, float)
    if a.ndim != 3 or a.shape[1] != N_CHANNELS or a.shape[2] < 8:
        old = (" (signatures of 6 channels come from before the local-thickness channel: "
               "measure the objects again)" if a.ndim == 3 and a.shape[1] == 6 else "")
        raise InputError(f"{name} must be outline signatures (n, {N_CHANNELS}, points ≥ 8); "
                         f"got shape {a.shape}{old}")
    return a


def _kernels():
    """The compiled kernels (:mod:`.elastic_kernel`; importing it imports numba, which the
    rest of ``core`` does not need)."""
    from . import elastic_kernel

    return elastic_kernel


#: Valleys tied with the last kept one (to 1e-9) refined besides the N_START_SHIFTS: an outline
#: with a symmetry has several equal valleys, and rounding must not choose among them.
_EXTRA_TIED = 16


@lru_cache(maxsize=4)
def _irfft_tables(n: int) -> tuple[np.ndarray, np.ndarray]:
    """cos and sin tables (H, n) with the inverse real FFT's weights: Σ_t a(t) b(t + s) =
    Σ_k Re(X_k e^{2πiks/n}) w_k / n for X = conj(A) B, w = 1 at k = 0 and n/2, else 2."""
    h = n // 2 + 1
    k = np.arange(h)[:, None]
    w = np.full((h, 1), 2.0)
    w[0] = 1.0
    if n % 2 == 0:
        w[-1] = 1.0
    ang = 2 * np.pi * k * np.arange(n)[None, :] / n
    return w * np.cos(ang) / n, w * np.sin(ang) / n


def _ordered(key: np.ndarray, ii: np.ndarray, jj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each pair (ii[p], jj[p]) in a fixed order: the signature with the smaller sum of
    squares ``key`` first (:func:`_distances`)."""
    swap = key[jj] < key[ii]
    return (np.where(swap, jj, ii).astype(np.int64), np.where(swap, ii, jj).astype(np.int64))


def _distances(a: np.ndarray, b: np.ndarray, ii: np.ndarray, jj: np.ndarray, band: int,
               n_shifts: int, half_steps: bool, chunk: int) -> np.ndarray:
    """d_E(a[ii[p]], b[jj[p]]) for every p (rows of a and b finite).

    DTW from a cut of one cyclic sequence is not symmetric in its two arguments; each pair is
    put in a fixed order first (the signature with the smaller sum of squares first), so that
    d_E(x, y) = d_E(y, x) exactly, whichever side and call a signature comes from. (Not the
    plain sum: that of the turning angles is the total turning, and that of the centroid
    distances n, for every outline.) Two signatures whose sums of squares agree to rounding
    may be put in either order by copies that differ by rounding (e.g. a table's and its
    results'), which can move their d_E by about 1 %.
    """
    if b is a:
        sig, jb = a, jj
    else:
        sig, jb = np.concatenate([a, b]), jj + len(a)
    prepared = SignatureSet(sig, band=band, n_shifts=n_shifts, half_steps=half_steps)
    return prepared.between(ii, jb, chunk)


def _spectral_parts(sig: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Real and imaginary parts of the signatures' FFT along the points, and their squared
    norms: what the compiled rigid start-shift scores need."""
    f = np.fft.rfft(sig, axis=-1)
    return (np.ascontiguousarray(f.real), np.ascontiguousarray(f.imag),
            (sig * sig).sum(axis=(1, 2)))


def elastic_nearest(signatures: np.ndarray, candidates: np.ndarray, base: np.ndarray,
                    weight: float, k: int, *, band: int = BAND,
                    n_shifts: int = N_START_SHIFTS, half_steps: bool = HALF_STEPS,
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each object's k nearest among its candidates under ``base + weight · d_E``.

    Parameters
    ----------
    signatures : ndarray, shape (n, N_CHANNELS, points)
        :func:`outline_signature` of every object (finite).
    candidates : ndarray of int, shape (n, C)
        Row q: object q's candidates in increasing order of ``base`` (-1: none; then the
        rest of the row is -1 too), never q itself.
    base : ndarray, shape (n, C)
        The other terms of the distance from q to each candidate.
    weight : float
        μ > 0.
    k : int
        Neighbours kept per object.
    band, n_shifts, half_steps
        As :func:`elastic_distance_pairs`.

    Returns
    -------
    indices : ndarray of int, shape (n, k)
        Nearest first, equal totals by object number; -1 where fewer than k candidates.
    distances : ndarray, shape (n, k)
        ``base + weight · d_E`` (inf where -1). d_E is
        ``elastic_distance_between(signatures, q, j)`` to single-precision rounding.
    computed : ndarray of int, shape (n,)
        The candidates whose d_E was computed (the DTW may have been abandoned).
    exact : ndarray of bool, shape (n,)
        Rows whose k nearest are those of all n objects, not only of the candidates: a
        candidate whose base alone was above the k-th total was reached (as d_E ≥ 0, no
        object after it, candidate or not, can be nearer), or the candidates were all the
        other objects.

    Notes
    -----
    The candidates are taken in order; once k are in, a candidate enters only if its
    d_E is below (k-th total − base) / μ, and its DTW is abandoned as soon as the least
    cost of a path through the current row plus the least cell of each row left exceeds
    that (:mod:`module docstring <napari_pfsdm.core.elastic>`); the first candidate whose
    base exceeds the k-th total ends the row. (The neighbour search with the term,
    :mod:`.elastic_neighbours`, takes its candidates otherwise: the rows' exactness here
    needs candidates in the order of a lower bound of the other terms over all objects.)
    """
    search = SignatureSet(signatures, band=band, n_shifts=n_shifts, half_steps=half_steps)
    return search.nearest(np.arange(len(search)), candidates, base, weight, k)


class SignatureSet:
    """Signatures prepared once (their spectra, a single-precision copy) for many calls of
    :meth:`nearest` on some of them: what :func:`elastic_nearest` does for all objects, and
    a neighbour search (:mod:`.elastic_neighbours`) block by block.

    Parameters
    ----------
    signatures : ndarray, shape (n, N_CHANNELS, points)
        :func:`outline_signature` of every object (finite).
    band, n_shifts, half_steps
        As :func:`elastic_distance_pairs`.
    """

    def __init__(self, signatures: np.ndarray, *, band: int = BAND,
                 n_shifts: int = N_START_SHIFTS, half_steps: bool = HALF_STEPS) -> None:
        a = _check_signatures(signatures, "signatures")
        _check_search(a, band, n_shifts)
        if not np.isfinite(a).all():
            raise InputError("the signatures must be finite")
        sig = np.ascontiguousarray(a, float)
        kernels = _kernels()
        self.values = sig
        self.sig = np.ascontiguousarray(sig, kernels.COST_DTYPE)
        self.fr, self.fi, self.norm = _spectral_parts(sig)
        self.cos_t, self.sin_t = _irfft_tables(sig.shape[2])
        self.band, self.n_shifts, self.half_steps = int(band), int(n_shifts), bool(half_steps)
        self.cap = min(2 * sig.shape[2], n_shifts + _EXTRA_TIED)

    def __len__(self) -> int:
        return len(self.sig)

    def between(self, ii: np.ndarray, jj: np.ndarray, chunk: int = 16384,
                here: bool = False) -> np.ndarray:
        """d_E(signature ii[p], signature jj[p]) for every p: each pair in the fixed order of
        :func:`_distances` (the smaller sum of squares first), the least warped cost per
        point. ``here``: on the calling thread only, without the GIL (for a caller's own
        threads); else on numba's threads."""
        first, second = _ordered(self.norm, np.asarray(ii, np.int64), np.asarray(jj, np.int64))
        n = self.sig.shape[2]
        kernels = _kernels()
        run = kernels.pairs_here if here else kernels.pairs
        out = np.empty(len(first))
        for p0 in range(0, len(first), chunk):
            sl = slice(p0, p0 + chunk)
            res = np.empty(len(first[sl]))
            run(self.sig, self.fr, self.fi, self.norm, first[sl], second[sl],
                np.full(len(res), np.inf), self.cos_t, self.sin_t, self.n_shifts, self.cap,
                self.band, self.half_steps, res)
            res[res >= kernels.BIG] = np.inf
            out[sl] = res / n
        return out

    def nearest(self, queries: np.ndarray, candidates: np.ndarray, base: np.ndarray,
                weight: float, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:func:`elastic_nearest` for the objects ``queries`` only: row r of
        ``candidates`` and ``base`` (and of the results) is object ``queries[r]``'s."""
        queries = np.ascontiguousarray(queries, np.int64)
        cand = np.ascontiguousarray(candidates, np.int64)
        base = np.ascontiguousarray(base, float)
        n = len(self)
        if cand.ndim != 2 or base.shape != cand.shape or len(cand) != len(queries):
            raise InputError(f"candidates and base must be (queries, C) for {len(queries)} "
                             f"queries; got {cand.shape} and {base.shape}")
        if not weight > 0 or not 1 <= k:
            raise InputError(f"weight must be > 0 and k ≥ 1; got {weight} and {k}")
        if len(queries) and (queries.min() < 0 or queries.max() >= n or cand.max() >= n):
            raise InputError(f"queries and candidates must be objects 0 … {n - 1}")
        idx = np.full((len(queries), k), -1, np.int64)
        dist = np.full((len(queries), k), np.inf)
        computed = np.zeros(len(queries), np.int64)
        exact = np.zeros(len(queries), bool)
        _kernels().nearest(self.sig, self.fr, self.fi, self.norm, self.norm, queries, cand,
                           base, float(weight), int(k), self.cos_t, self.sin_t, self.n_shifts,
                           self.cap, self.band, self.half_steps, idx, dist, computed,
                           exact)
        exact |= (cand >= 0).sum(axis=1) >= n - 1
        return idx, dist, computed, exact


def _check_search(a: np.ndarray, band: int, n_shifts: int) -> None:
    if not 0 <= band < a.shape[2] // 2 or not 1 <= n_shifts <= 2 * a.shape[2]:
        raise InputError(f"band must be in 0 … {a.shape[2] // 2 - 1} and n_shifts in 1 … "
                         f"{2 * a.shape[2]}; got {band} and {n_shifts}")


def elastic_distance_pairs(signatures: np.ndarray, others: np.ndarray, *, band: int = BAND,
                           n_shifts: int = N_START_SHIFTS, half_steps: bool = HALF_STEPS,
                           chunk: int = 16384) -> np.ndarray:
    """The elastic distance of aligned pairs: ``d_E(signatures[p], others[p])`` per row p.

    Parameters
    ----------
    signatures, others : ndarray, shape (P, N_CHANNELS, n)
        :func:`outline_signature` of both sides of each pair (rows with NaN give NaN).
    band : int
        Half-width of the DTW band, in points.
    n_shifts : int
        Rigid start shifts (over both orientations) refined by DTW.
    half_steps : bool
        Let a point match the midpoint of two neighbours of the other signature (module
        docstring); False: the plain L1 cost.
    chunk : int
        Pairs whose start shifts are scored at once (memory about chunk × 6 kB).

    Returns
    -------
    ndarray, shape (P,)
        Mean L1 cost per point of the best elastic correspondence (module docstring).
    """
    a = _check_signatures(signatures, "signatures")
    b = _check_signatures(others, "others")
    if a.shape != b.shape:
        raise InputError(f"pairs of signatures must have the same shape, got {a.shape} and "
                         f"{b.shape}")
    _check_search(a, band, n_shifts)
    ok = np.flatnonzero(np.isfinite(a).all(axis=(1, 2)) & np.isfinite(b).all(axis=(1, 2)))
    out = np.full(len(a), np.nan)
    if ok.size:
        a, b = np.ascontiguousarray(a[ok]), np.ascontiguousarray(b[ok])
        idx = np.arange(len(ok))
        out[ok] = _distances(a, b, idx, idx, band, n_shifts, half_steps, chunk)
    return out


def elastic_distance_between(signatures: np.ndarray, ii: np.ndarray, jj: np.ndarray, *,
                             band: int = BAND, n_shifts: int = N_START_SHIFTS,
                             half_steps: bool = HALF_STEPS, chunk: int = 16384) -> np.ndarray:
    """d_E(signatures[ii[p]], signatures[jj[p]]) for every p, without copying the pairs'
    signatures (what a nearest-neighbour search needs for its candidates).

    Returns
    -------
    ndarray, shape (len(ii),)
        The entries ``elastic_distance_matrix(signatures)[ii, jj]`` (NaN where either row has
        NaN; 0 where ii == jj).
    """
    a = _check_signatures(signatures, "signatures")
    _check_search(a, band, n_shifts)
    ii, jj = np.asarray(ii, np.int64).ravel(), np.asarray(jj, np.int64).ravel()
    if ii.shape != jj.shape:
        raise InputError(f"ii and jj must have the same length, got {ii.size} and {jj.size}")
    ok = np.isfinite(a).all(axis=(1, 2))
    a0 = np.ascontiguousarray(np.where(ok[:, None, None], a, 0.0))
    out = _distances(a0, a0, ii, jj, band, n_shifts, half_steps, chunk)
    out[ii == jj] = 0.0
    out[~(ok[ii] & ok[jj])] = np.nan
    return out


def elastic_distance_matrix(signatures: np.ndarray, others: np.ndarray | None = None, *,
                            band: int = BAND, n_shifts: int = N_START_SHIFTS,
                            half_steps: bool = HALF_STEPS, chunk: int = 16384) -> np.ndarray:
    """The elastic distance for all pairs (module docstring).

    Parameters
    ----------
    signatures : ndarray, shape (n, N_CHANNELS, points)
        :func:`outline_signature` of n objects (NaN rows give NaN).
    others : ndarray, shape (m, N_CHANNELS, points), optional
        A second set: distances of every row to every row of ``others``.
    band, n_shifts, half_steps, chunk
        As :func:`elastic_distance_pairs`.

    Returns
    -------
    ndarray, shape (n, n) or (n, m)
        Symmetric with zero diagonal when ``others`` is None (the upper triangle is computed,
        ``d(i, j)`` with i < j, and mirrored).
    """
    a = _check_signatures(signatures, "signatures")
    same = others is None
    b = a if same else _check_signatures(others, "others")
    if b.shape[1:] != a.shape[1:]:
        raise InputError(f"signatures of different shapes: {a.shape} and {b.shape}")
    _check_search(a, band, n_shifts)
    ok_a = np.isfinite(a).all(axis=(1, 2))
    ok_b = ok_a if same else np.isfinite(b).all(axis=(1, 2))
    a0 = np.ascontiguousarray(np.where(ok_a[:, None, None], a, 0.0))
    b0 = a0 if same else np.ascontiguousarray(np.where(ok_b[:, None, None], b, 0.0))
    if same:
        ii, jj = np.triu_indices(len(a), 1)
    else:
        ii, jj = (x.ravel() for x in np.indices((len(a), len(b))))
    out = np.zeros((len(a), len(b)))
    out[ii, jj] = _distances(a0, b0, ii, jj, band, n_shifts, half_steps, chunk)
    if same:
        out += out.T
    out[~ok_a] = np.nan
    out[:, ~ok_b] = np.nan
    return out
