"""The elastic term's compiled kernels (numba): the banded DTW of each pair over its start shifts.

What they compute is :mod:`.elastic`'s (its module docstring; :func:`.elastic.banded_dtw` is
the plain numpy reference the tests hold them to). Per pair: the rigid scores of both
orientations from the signatures' spectra in one pass (:func:`start_shifts`); the costs along
each cyclic diagonal of the (point of a, point of b) grid that a start shift's band needs,
computed once per pair (:func:`diagonal`, :func:`band_of`: shifts less than 2 ``band`` apart
share diagonals; the channels' loop unrolled, the loop along a diagonal vectorised); the DP
row by row, reading them in place (a band's diagonals sit in consecutive slots, so a cell's
place is computed, not loaded), in single precision (the distances agree with a float64
reference to ~1e-6 relative, tested). The lowest start shift is refined first and alone
(:func:`dtw1`); the others four at a time, their four DPs interleaved in one loop
(:func:`dtw4`: a DP row is a chain of dependent additions and minima, one chain leaves the
processor idle). With a limit (what :func:`nearest` passes: the cost a candidate must stay
under to enter a row's k nearest), a start shift is abandoned as soon as the least cost of a
path through the current row plus the least cell of every row left exceeds the limit or the
best shift's cost so far (costs are ≥ 0 and a path visits every row), so the result is the
same as refining every shift to the end. Without one (all pairs, :func:`pairs`) there are no
bounds: between a pair's own start shifts they rule out too little to pay for themselves (the
lowest rigid shift is often not the best one). docs/benchmarks.md gives the cost per pair.

Every kernel is a module-level function whose arrays and numbers are its arguments, so that
numba's cache finds it in every later process (:mod:`.compiled`). The cache watches this
file's time stamp only: the compiled kernels hold this file's constants and
:data:`~.elastic_signature.N_CHANNELS` as they were; a change to that number needs this file
touched (or the ``__pycache__`` cleared). All the kernels live in this one file for that
reason: a kernel that called one of another file would keep its old code after an edit there.
Importing this module imports numba (the rest of the package does not).
"""

from __future__ import annotations

import numba
import numpy as np

from .compiled import watch
from .elastic_signature import N_CHANNELS

__all__ = ["BIG", "COST_DTYPE", "nearest", "pairs", "pairs_here"]

#: What the kernels hold for "more than the limit" and "no cell" (a finite number: their
#: arithmetic is compiled with fastmath, which assumes no infinities).
BIG = 1e30
#: Precision of the DTW's costs and sums (float32: twice the numbers per vector instruction;
#: the distances agree with float64's to ~1e-6 relative; the start shifts are always scored
#: in float64).
COST_DTYPE = np.float32
#: Channels of a signature, a constant of the kernels (their loop over it is unrolled).
_C = N_CHANNELS
#: Unsigned indices in the loops: numba wraps negative signed indices around, and the code
#: for it (per access) keeps the loops from being vectorised.
_U = np.uint64
#: Pairs per parallel task of :func:`pairs` (its scratch arrays are allocated per task).
_TASK = 64


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
        rest[i] = BIG
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
    (not divided by n), or BIG as soon as it is sure to exceed ``limit``: the costs are
    ≥ 0 and a path visits every row, so the path's cost is at least the least cell of the
    current row plus, for each row left, that row's least cell. Cells outside the band's
    valid part hold BIG."""
    n = rest.shape[0]
    width = 2 * band + 1
    big = np.float32(BIG)
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
    minima, four independent chains keep the processor busy. ``out[c]``: on entry BIG
    for a shift already known to exceed ``limit`` (else 0), on return shift c's least
    cost, or BIG once it is sure to exceed ``limit`` (its bound is checked every fourth
    row: the loop is bound by its number of operations; never with ``bounds`` False);
    all four stop when all four are."""
    n = rest.shape[1]
    width = 2 * band + 1
    big = np.float32(BIG)
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
            out[0] = BIG
        if r1 + rest[1, i] > limit:
            out[1] = BIG
        if r2 + rest[2, i] > limit:
            out[2] = BIG
        if r3 + rest[3, i] > limit:
            out[3] = BIG
        if min(min(out[0], out[1]), min(out[2], out[3])) >= BIG:
            return
    if out[0] < BIG:
        out[0] = p0[band]
    if out[1] < BIG:
        out[1] = p1[band]
    if out[2] < BIG:
        out[2] = p2[band]
    if out[3] < BIG:
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
    its rigid start shifts, or BIG when it is sure to exceed ``limit``: the lowest shift
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
    best = BIG
    lim = min(limit, BIG)
    bounds = lim < BIG
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
                out4[c] = 0.0 if acc <= lim else BIG
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
    (ii[p], jj[p]) over its rigid start shifts; BIG when it exceeds limit[p]."""
    n_pairs = ii.shape[0]
    n_tasks = (n_pairs + _TASK - 1) // _TASK
    for task in numba.prange(n_tasks):
        work = scratch(sig, band, fr.shape[2], cap)
        for p in range(task * _TASK, min(n_pairs, (task + 1) * _TASK)):
            out[p] = pair_cost(sig, fr, fi, norm, ii[p], jj[p], limit[p], cos_t, sin_t,
                               n_cand, band, half, work)


@numba.njit(cache=True, fastmath=True, nogil=True)
def pairs_here(sig, fr, fi, norm, ii, jj, limit, cos_t, sin_t, n_cand, cap, band, half,
               out):  # pragma: no cover
    """:func:`pairs` on the calling thread, without holding the GIL: for callers that run
    blocks of pairs on threads of their own (the neighbour search's query blocks)."""
    work = scratch(sig, band, fr.shape[2], cap)
    for p in range(ii.shape[0]):
        out[p] = pair_cost(sig, fr, fi, norm, ii[p], jj[p], limit[p], cos_t, sin_t, n_cand,
                           band, half, work)


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
                lim = BIG
                if m == k:
                    lim = (out_dist[r, k - 1] - b) / mu * n * slack
                ia, ib = (j, q) if key[j] < key[q] else (q, j)
                v = pair_cost(sig, fr, fi, norm, ia, ib, lim, cos_t, sin_t, n_cand, band,
                              half, work)
                done += 1
                if v >= BIG:
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


watch(pairs, "the distance")
watch(pairs_here, "the distance, per thread")
watch(nearest, "the neighbour search")
