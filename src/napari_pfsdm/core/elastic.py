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

Compiled kernel (numba, parallel over pairs)
    Per pair: the rigid scores of both orientations from the signatures' spectra in one pass;
    the costs along each cyclic diagonal of the (point of a, point of b) grid that a start
    shift's band needs, computed once per pair (shifts less than 2 :data:`BAND` apart share
    diagonals; the channels' loop unrolled, the loop along a diagonal vectorised); the DP row
    by row, reading them in place (a band's diagonals sit in consecutive slots, so a cell's
    place is computed, not loaded), in single precision (the distances agree with a float64
    reference to ~1e-6 relative, tested). The lowest start shift is refined first and alone;
    the others four at a time, their four DPs interleaved in one loop (a DP row is a chain of
    dependent additions and minima: one chain leaves the processor idle). With a limit (what
    :func:`elastic_nearest` passes: the cost a candidate must stay under to enter a row's k
    nearest), a start shift is abandoned as soon as the least cost of a path through the
    current row plus the least cell of every row left exceeds the limit or the best shift's
    cost so far (costs are ≥ 0 and a path visits every row), so the result is the same as
    refining every shift to the end. Without one (all pairs) there are no bounds: between a
    pair's own start shifts they rule out too little to pay for themselves (the lowest rigid
    shift is often not the best one). docs/benchmarks.md gives the cost per pair.

Its length (about 890 lines) is the DP twice, held against each other by the tests: the
compiled kernel (numba: the banded DTW with its bounds, the rigid start shifts) and its plain
numpy reference (:func:`banded_dtw`), with the searches that call them.
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


def _kernel():
    """The compiled kernels (numba, compiled on first use and cached on disk)."""
    global _KERNEL
    if _KERNEL is None:
        _KERNEL = _compile()
    return _KERNEL


_KERNEL = None

#: What the compiled kernel holds for "more than the limit" and "no cell" (a finite number:
#: its arithmetic is compiled with fastmath, which assumes no infinities).
_BIG = 1e30
#: Precision of the DTW's costs and sums (float32: twice the numbers per vector instruction;
#: the distances agree with float64's to ~1e-6 relative; the start shifts are always scored
#: in float64).
_COST_DTYPE = np.float32
#: Channels of a signature, a constant of the compiled kernel.
_C = N_CHANNELS
#: Unsigned indices in the compiled loops: numba wraps negative signed indices around, and
#: the code for it (per access) keeps the loops from being vectorised.
_U = np.uint64
#: Pairs per parallel task of the compiled kernel (its scratch arrays are allocated per task).
_TASK = 64


def _compile():
    import numba

    @numba.njit(cache=True, fastmath=True, inline="always")
    def start_shifts(fr, fi, norm, ia, ib, cos_t, sin_t, n_cand, xr, xi, vals, v_list, code,
                     mirror, shift):  # pragma: no cover
        """The n_cand lowest local minima over cyclic shifts s (both orientations) of the
        rigid cost Σ_i ‖a(i) − b(i + s)‖², from the signatures' spectra (real and imaginary
        parts, (objects, C, H); the mirror image's spectrum is the conjugate), plus any other
        minimum tied with the last (to 1e-9), lowest first: their number, written to
        ``mirror`` and ``shift``."""
        n_ch, n_h = fr.shape[1], fr.shape[2]
        n = cos_t.shape[1]
        cap = shift.shape[0]
        # X = Σ_ch conj(A) B, and with B conjugated for the mirror image (row 1)
        for k in range(n_h):
            xr[0, k] = 0.0
            xi[0, k] = 0.0
            xr[1, k] = 0.0
            xi[1, k] = 0.0
        for ch in range(n_ch):
            for k in range(n_h):
                ar, ai = fr[ia, ch, k], fi[ia, ch, k]
                br, bi = fr[ib, ch, k], fi[ib, ch, k]
                xr[0, k] += ar * br + ai * bi
                xi[0, k] += ar * bi - ai * br
                xr[1, k] += ar * br - ai * bi
                xi[1, k] -= ar * bi + ai * br
        base = norm[ia] + norm[ib]
        for s_ in range(n):
            vals[0, s_] = 0.0
            vals[1, s_] = 0.0
        for k in range(n_h):
            x0, y0, x1, y1 = xr[0, k], xi[0, k], xr[1, k], xi[1, k]
            for s_ in range(n):
                c, sn = cos_t[k, s_], sin_t[k, s_]
                vals[0, s_] += x0 * c - y0 * sn
                vals[1, s_] += x1 * c - y1 * sn
        for s_ in range(n):
            vals[0, s_] = base - 2.0 * vals[0, s_]
            vals[1, s_] = base - 2.0 * vals[1, s_]
        # the local minima over s (neighbouring shifts of one valley: one candidate; on a
        # flat valley floor, equal to rounding, every shift), kept sorted (insertion, stable:
        # equal values in the order met) as far as they can be among the n_cand lowest or
        # tied with the last of them
        flat = 1e-9 * (norm[ia] + norm[ib])
        n_min = 0
        for m in range(2):
            for s_ in range(n):
                v = vals[m, s_]
                before = vals[m, s_ - 1 if s_ > 0 else n - 1]
                after = vals[m, s_ + 1 if s_ < n - 1 else 0]
                if v <= before + flat and v <= after + flat:
                    q = n_min
                    while q > 0 and v_list[q - 1] > v:
                        if q < v_list.shape[0]:
                            v_list[q] = v_list[q - 1]
                            code[q] = code[q - 1]
                        q -= 1
                    if q < v_list.shape[0]:
                        v_list[q] = v
                        code[q] = m * n + s_
                    if n_min < v_list.shape[0]:
                        n_min += 1
        last = v_list[min(n_cand, n_min) - 1]
        tol = flat + 1e-9 * abs(last)
        got = 0
        for q in range(n_min):
            v = v_list[q]
            if got >= cap or (q >= n_cand and v > last + tol):
                break
            mirror[got] = code[q] // n
            shift[got] = code[q] % n
            got += 1
        return got

    @numba.njit(cache=True, fastmath=True, inline="always")
    def diagonal(a, g, bx, hx, m, half, o, diag, at):  # pragma: no cover
        """diag[at + i] = c(a(i), b(i + o)) for every i: the costs along one cyclic diagonal
        of orientation m of b, given as ``bx[m]`` (C, 2n): b(j mod n), and ``hx[m]``: its
        midpoints between j and j + 1. The channels' loop has a constant length (unrolled:
        the loop along the diagonal is vectorised)."""
        n = a.shape[1]
        ou = _U(o)
        if half:
            for i in range(n):
                j = ou + _U(i)
                x0 = np.float32(0.0)
                x1 = np.float32(0.0)
                x2 = np.float32(0.0)
                for ch in range(_C):
                    v = bx[m, ch, j]
                    x0 += abs(a[ch, i] - v)
                    x1 += abs(a[ch, i] - hx[m, ch, j])
                    x2 += abs(g[ch, i] - v)
                diag[at + _U(i)] = np.minimum(x0, np.minimum(x1, x2))
        else:
            for i in range(n):
                j = ou + _U(i)
                x0 = np.float32(0.0)
                for ch in range(_C):
                    x0 += abs(a[ch, i] - bx[m, ch, j])
                diag[at + _U(i)] = x0

    @numba.njit(cache=True, fastmath=True, inline="always")
    def band_of(a, g, bx, hx, diag, have, mirror, s, band, half, col, rest,
                bounds):  # pragma: no cover
        """The band of start shift s of orientation ``mirror`` of b. Its column w matches a(i)
        to b(i + s + w − band) in the rows max(0, band − w) ≤ i < min(n, n + band − w): the
        cyclic diagonal o = s + w − band mod n, whose costs are ``diag[col[w] + i]``, with
        ``col[w] = col[0] + w n`` (the DP computes a cell's place instead of loading it).
        ``diag`` holds n + 2 band slots of n costs per orientation, slot k the diagonal
        (k − band) mod n: the diagonals within band of the cut are held twice, so that a
        band's columns are consecutive slots (s + w). They are computed once per pair
        (``have[mirror, o]`` says whether they are there): start shifts less than 2 band
        apart share diagonals. ``rest[i]``: Σ over the rows after i of their least cell;
        returns the Σ over all rows (with ``bounds`` False: 0, no bound)."""
        n = a.shape[1]
        width = 2 * band + 1
        slots = n + 2 * band
        for w in range(width):
            o = s + w - band
            if o < 0:
                o += n
            elif o >= n:
                o -= n
            col[w] = _U((mirror * slots + s + w) * n)
            if not have[mirror, o]:
                at = _U((mirror * slots + o + band) * n)
                diagonal(a, g, bx, hx, mirror, half, o, diag, at)
                if o < band:  # its second slot, after the last diagonal's
                    to = at + _U(n * n)
                    for i in range(_U(n)):
                        diag[to + i] = diag[at + i]
                elif o >= n - band:  # before the first's
                    to = at - _U(n * n)
                    for i in range(_U(n)):
                        diag[to + i] = diag[at + i]
                have[mirror, o] = True
        if not bounds:
            for i in range(n):
                rest[i] = 0.0
            return 0.0
        for i in range(n):
            rest[i] = _BIG
        for w in range(width):
            at = col[w]
            for i in range(_U(max(0, band - w)), _U(min(n, n + band - w))):
                rest[i] = np.minimum(rest[i], diag[at + i])
        acc = 0.0
        for i in range(n - 1, -1, -1):
            r = rest[i]
            rest[i] = acc
            acc += r
        return acc

    @numba.njit(cache=True, fastmath=True, inline="always")
    def dtw1(diag, col, band, limit, rest, prev, cur):  # pragma: no cover
        """The banded DTW of one start shift (:func:`band_of`) row by row: its least cost
        (not divided by n), or _BIG as soon as it is sure to exceed ``limit``: the costs are
        ≥ 0 and a path visits every row, so the path's cost is at least the least cell of the
        current row plus, for each row left, that row's least cell. Cells outside the band's
        valid part hold _BIG."""
        n = rest.shape[0]
        width = 2 * band + 1
        big = np.float32(_BIG)
        for w in range(width + 1):
            prev[w] = big
            cur[w] = big
        run = np.float32(0.0)
        for w in range(band, width):
            run += diag[col[w]]
            prev[w] = run
        nu = _U(n)
        for i in range(1, n):
            r = col[0] + _U(i)
            hi = _U(min(width, n + band - i))
            lo = _U(max(0, band - i))
            left = big
            row_min = big
            p = prev[lo]
            for w in range(lo, hi):
                q = prev[w + _U(1)]
                left = diag[r + w * nu] + min(min(p, q), left)
                p = q
                cur[w] = left
                row_min = min(row_min, left)
            for w in range(hi, _U(width)):
                cur[w] = big
            prev, cur = cur, prev
            if row_min + rest[i] > limit:
                return big
        return prev[band]

    @numba.njit(cache=True, fastmath=True, inline="always")
    def dtw4(diag, col, band, limit, rest, prev, cur, out, bounds):  # pragma: no cover
        """:func:`dtw1` for four start shifts at once (``col[c]``, ``rest[c]``, c = 0 … 3),
        their DPs interleaved in one loop: a DP row is a chain of dependent additions and
        minima, four independent chains keep the processor busy. ``out[c]``: on entry _BIG
        for a shift already known to exceed ``limit`` (else 0), on return shift c's least
        cost, or _BIG once it is sure to exceed ``limit`` (its bound is checked every fourth
        row: the loop is bound by its number of operations; never with ``bounds`` False);
        all four stop when all four are."""
        n = rest.shape[1]
        width = 2 * band + 1
        big = np.float32(_BIG)
        for c in range(4):
            for w in range(width + 1):
                prev[c, w] = big
                cur[c, w] = big
            run = np.float32(0.0)
            for w in range(band, width):
                run += diag[col[c, w]]
                prev[c, w] = run
        p0, p1, p2, p3 = prev[0], prev[1], prev[2], prev[3]
        q0, q1, q2, q3 = cur[0], cur[1], cur[2], cur[3]
        one = _U(1)
        nu = _U(n)
        for i in range(1, n):
            iu = _U(i)
            r0, r1, r2, r3 = col[0, 0] + iu, col[1, 0] + iu, col[2, 0] + iu, col[3, 0] + iu
            hi = _U(min(width, n + band - i))
            lo = _U(max(0, band - i))
            x0 = big
            x1 = big
            x2 = big
            x3 = big
            a0, a1, a2, a3 = p0[lo], p1[lo], p2[lo], p3[lo]
            for w in range(lo, hi):
                wn = w * nu
                b0, b1, b2, b3 = p0[w + one], p1[w + one], p2[w + one], p3[w + one]
                x0 = diag[r0 + wn] + min(min(a0, b0), x0)
                x1 = diag[r1 + wn] + min(min(a1, b1), x1)
                x2 = diag[r2 + wn] + min(min(a2, b2), x2)
                x3 = diag[r3 + wn] + min(min(a3, b3), x3)
                a0, a1, a2, a3 = b0, b1, b2, b3
                q0[w] = x0
                q1[w] = x1
                q2[w] = x2
                q3[w] = x3
            for w in range(hi, _U(width)):
                q0[w] = big
                q1[w] = big
                q2[w] = big
                q3[w] = big
            p0, q0 = q0, p0
            p1, q1 = q1, p1
            p2, q2 = q2, p2
            p3, q3 = q3, p3
            if not bounds or (i & 3 and i < n - 1):  # every fourth row (and the last)
                continue
            r0 = big
            r1 = big
            r2 = big
            r3 = big
            for w in range(lo, hi):
                r0 = np.minimum(r0, p0[w])
                r1 = np.minimum(r1, p1[w])
                r2 = np.minimum(r2, p2[w])
                r3 = np.minimum(r3, p3[w])
            if r0 + rest[0, i] > limit:
                out[0] = _BIG
            if r1 + rest[1, i] > limit:
                out[1] = _BIG
            if r2 + rest[2, i] > limit:
                out[2] = _BIG
            if r3 + rest[3, i] > limit:
                out[3] = _BIG
            if min(min(out[0], out[1]), min(out[2], out[3])) >= _BIG:
                return
        if out[0] < _BIG:
            out[0] = p0[band]
        if out[1] < _BIG:
            out[1] = p1[band]
        if out[2] < _BIG:
            out[2] = p2[band]
        if out[3] < _BIG:
            out[3] = p3[band]

    @numba.njit(cache=True, inline="always")
    def scratch(sig, band, n_h, cap):  # pragma: no cover
        """The per-task work arrays of :func:`pair_cost`."""
        n_ch, n = sig.shape[1], sig.shape[2]
        width = 2 * band + 1
        dt = sig.dtype
        return (np.empty((n_ch, n), dt), np.empty((n_ch, n), dt),
                np.empty((2, n_ch, 2 * n), dt), np.empty((2, n_ch, 2 * n), dt),
                np.empty(2 * (n + 2 * band) * n, dt), np.empty((2, n), np.bool_),
                np.empty((4, width), np.uint64), np.empty((4, n), dt),
                np.empty((4, width + 1), dt), np.empty((4, width + 1), dt),
                np.empty(4), np.empty((2, n_h)), np.empty((2, n_h)),
                np.empty((2, n)), np.empty(cap + 1), np.empty(cap + 1, np.int64),
                np.empty(cap, np.int64), np.empty(cap, np.int64))

    @numba.njit(cache=True, fastmath=True, inline="always")
    def pair_cost(sig, fr, fi, norm, ia, ib, limit, cos_t, sin_t, n_cand, band, half,
                  work):  # pragma: no cover
        """The least banded-DTW cost (not divided by n) of the ordered pair (ia, ib) over
        its rigid start shifts, or _BIG when it is sure to exceed ``limit``: the lowest shift
        alone first, then the others four at a time (:func:`dtw4`; a group's last shift
        repeated where fewer are left). The bounds (the rows' least cells, the abandoning)
        serve a finite ``limit`` only (module docstring)."""
        (a, g, bx, hx, diag, have, offs, rest, prev, cur, out4, xr, xi, vals, v_list, code,
         mirror, shift) = work
        n_ch, n = sig.shape[1], sig.shape[2]
        got = start_shifts(fr, fi, norm, ia, ib, cos_t, sin_t, n_cand, xr, xi, vals, v_list,
                           code, mirror, shift)
        for ch in range(n_ch):
            for i in range(n):
                a[ch, i] = sig[ia, ch, i]
            for i in range(n - 1):
                g[ch, i] = 0.5 * (a[ch, i] + a[ch, i + 1])
            g[ch, n - 1] = 0.5 * (a[ch, n - 1] + a[ch, 0])
            # b as is, and its mirror image b(−j mod n), both repeated once
            for j in range(n):
                v = sig[ib, ch, j]
                bx[0, ch, j] = v
                bx[0, ch, n + j] = v
            bx[1, ch, 0] = sig[ib, ch, 0]
            bx[1, ch, n] = sig[ib, ch, 0]
            for j in range(1, n):
                v = sig[ib, ch, n - j]
                bx[1, ch, j] = v
                bx[1, ch, n + j] = v
            if half:
                for m in range(2):
                    for j in range(_U(n)):
                        v = np.float32(0.5) * (bx[m, ch, j] + bx[m, ch, j + _U(1)])
                        hx[m, ch, j] = v
                        hx[m, ch, j + _U(n)] = v
        for m in range(2):
            for o in range(n):
                have[m, o] = False
        best = _BIG
        lim = min(limit, _BIG)
        bounds = lim < _BIG
        if got == 0:
            return best
        if band_of(a, g, bx, hx, diag, have, mirror[0], shift[0], band, half, offs[0],
                   rest[0], bounds) <= lim:
            best = dtw1(diag, offs[0], band, lim, rest[0], prev[0], cur[0])
            if best < lim:
                lim = best
        for k0 in range(1, got, 4):
            live = 0
            for c in range(4):
                k = min(k0 + c, got - 1)
                if c == 0 or k0 + c < got:
                    acc = band_of(a, g, bx, hx, diag, have, mirror[k], shift[k], band, half,
                                  offs[c], rest[c], bounds)
                    out4[c] = 0.0 if acc <= lim else _BIG
                    if acc <= lim:
                        live += 1
                else:  # a repeat of the group's last shift
                    out4[c] = out4[c - 1]
                    for w in range(offs.shape[1]):
                        offs[c, w] = offs[c - 1, w]
                    for i in range(n):
                        rest[c, i] = rest[c - 1, i]
            if live == 0:
                continue
            dtw4(diag, offs, band, lim, rest, prev, cur, out4, bounds)
            for c in range(4):
                if out4[c] < best:
                    best = out4[c]
            if best < lim:
                lim = best
        return best

    @numba.njit(parallel=True, cache=True, fastmath=True)
    def pairs(sig, fr, fi, norm, ii, jj, limit, cos_t, sin_t, n_cand, cap, band, half,
              out):  # pragma: no cover
        """out[p] = the least banded-DTW cost (not divided by n) of the ordered pair
        (ii[p], jj[p]) over its rigid start shifts; _BIG when it exceeds limit[p]."""
        n_pairs = ii.shape[0]
        n_tasks = (n_pairs + _TASK - 1) // _TASK
        for task in numba.prange(n_tasks):
            work = scratch(sig, band, fr.shape[2], cap)
            for p in range(task * _TASK, min(n_pairs, (task + 1) * _TASK)):
                out[p] = pair_cost(sig, fr, fi, norm, ii[p], jj[p], limit[p], cos_t, sin_t,
                                   n_cand, band, half, work)

    @numba.njit(parallel=True, cache=True, fastmath=True)
    def nearest(sig, fr, fi, norm, key, queries, cand, base, mu, k, cos_t, sin_t, n_cand,
                cap, band, half, out_idx, out_dist, computed, exact):  # pragma: no cover
        """For each query q (object ``queries[r]``): of its candidates ``cand[r]`` (objects,
        -1 for none, in increasing order of the other terms ``base[r]``), the k of least
        base + mu d_E (ties by object number), with d_E computed for as few as possible: a
        candidate whose base exceeds the k-th total so far cannot enter (nor can any after
        it: then the row is ``exact``, no object left out of the candidates can enter
        either), and the DTW of one whose d_E must be below (k-th total − base) / mu is
        abandoned as soon as it cannot be."""
        n_q, n_c = cand.shape
        n = sig.shape[2]
        slack = 1.0 + 1e-5  # the abandoning compares single-precision sums
        n_tasks = (n_q + 7) // 8
        for task in numba.prange(n_tasks):
            work = scratch(sig, band, fr.shape[2], cap)
            for r in range(task * 8, min(n_q, (task + 1) * 8)):
                q = queries[r]
                m = 0
                done = 0
                exact[r] = False
                for c in range(n_c):
                    j = cand[r, c]
                    if j < 0:
                        break
                    b = base[r, c]
                    if m == k and b > out_dist[r, k - 1]:
                        exact[r] = True
                        break
                    lim = _BIG
                    if m == k:
                        lim = (out_dist[r, k - 1] - b) / mu * n * slack
                    ia, ib = (j, q) if key[j] < key[q] else (q, j)
                    v = pair_cost(sig, fr, fi, norm, ia, ib, lim, cos_t, sin_t, n_cand, band,
                                  half, work)
                    done += 1
                    if v >= _BIG:
                        continue
                    t = b + mu * (v / n)
                    if m == k and (t > out_dist[r, k - 1]
                                   or (t == out_dist[r, k - 1] and j > out_idx[r, k - 1])):
                        continue
                    pos = m if m < k else k - 1
                    while pos > 0 and (out_dist[r, pos - 1] > t
                                       or (out_dist[r, pos - 1] == t
                                           and out_idx[r, pos - 1] > j)):
                        if pos < k:
                            out_dist[r, pos] = out_dist[r, pos - 1]
                            out_idx[r, pos] = out_idx[r, pos - 1]
                        pos -= 1
                    out_dist[r, pos] = t
                    out_idx[r, pos] = j
                    if m < k:
                        m += 1
                computed[r] = done
                for c in range(m, k):
                    out_idx[r, c] = -1
                    out_dist[r, c] = np.inf

    return pairs, nearest


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


def _ordered(sig: np.ndarray, ii: np.ndarray, jj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each pair (ii[p], jj[p]) in a fixed order: the signature with the smaller sum of
    squares first (:func:`_distances`)."""
    key = (sig * sig).sum(axis=(1, 2))
    swap = key[jj] < key[ii]
    return (np.where(swap, jj, ii).astype(np.int64), np.where(swap, ii, jj).astype(np.int64))


def _costs(sig: np.ndarray, first: np.ndarray, second: np.ndarray, limit: np.ndarray | None,
           band: int, n_shifts: int, half_steps: bool, chunk: int) -> np.ndarray:
    """The compiled kernel on the ordered pairs (first[p], second[p]) of ``sig`` (finite,
    C-contiguous): the least warped cost per point, +inf where it exceeds ``limit[p]``
    (per point; None: no limit)."""
    n = sig.shape[2]
    fr, fi, norm = _spectral_parts(sig)
    cos_t, sin_t = _irfft_tables(n)
    cap = min(2 * n, n_shifts + _EXTRA_TIED)
    sig_c = np.ascontiguousarray(sig, _COST_DTYPE)
    pairs = _kernel()[0]
    out = np.empty(len(first))
    for p0 in range(0, len(first), chunk):
        sl = slice(p0, p0 + chunk)
        lim = (np.full(len(first[sl]), np.inf) if limit is None
               else np.asarray(limit[sl], float) * n)
        res = np.empty(len(first[sl]))
        pairs(sig_c, fr, fi, norm, first[sl], second[sl], lim, cos_t, sin_t, n_shifts, cap,
              band, half_steps, res)
        res[res >= _BIG] = np.inf
        out[sl] = res / n
    return out


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
    sig = np.ascontiguousarray(sig, float)
    first, second = _ordered(sig, np.asarray(ii, np.int64), np.asarray(jb, np.int64))
    return _costs(sig, first, second, None, band, n_shifts, half_steps, chunk)


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
    base exceeds the k-th total ends the row. On MPEG-7 this computes d_E fully for a few
    candidates per object (docs/benchmarks.md, "The elastic outline term").
    """
    a = _check_signatures(signatures, "signatures")
    _check_search(a, band, n_shifts)
    cand = np.ascontiguousarray(candidates, np.int64)
    base = np.ascontiguousarray(base, float)
    if cand.ndim != 2 or base.shape != cand.shape or len(cand) != len(a):
        raise InputError(f"candidates and base must be (n, C) for n = {len(a)} objects; got "
                         f"{cand.shape} and {base.shape}")
    if not weight > 0 or not 1 <= k:
        raise InputError(f"weight must be > 0 and k ≥ 1; got {weight} and {k}")
    if not np.isfinite(a).all():
        raise InputError("the signatures must be finite")
    sig = np.ascontiguousarray(a, float)
    fr, fi, norm = _spectral_parts(sig)
    cos_t, sin_t = _irfft_tables(sig.shape[2])
    cap = min(2 * sig.shape[2], n_shifts + _EXTRA_TIED)
    n = len(sig)
    idx = np.full((n, k), -1, np.int64)
    dist = np.full((n, k), np.inf)
    computed = np.zeros(n, np.int64)
    exact = np.zeros(n, bool)
    nearest = _kernel()[1]
    nearest(np.ascontiguousarray(sig, _COST_DTYPE), fr, fi, norm, norm, np.arange(n), cand,
            base, float(weight), int(k), cos_t, sin_t, n_shifts, cap, band, half_steps, idx,
            dist, computed, exact)
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
