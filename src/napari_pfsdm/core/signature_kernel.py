"""The outline signature's compiled kernels (numba): the local thickness and the whole signature.

What they compute is :mod:`.elastic_signature`'s (its module docstring and
:func:`~.elastic_signature.outline_signature`, which calls them): the turning angles and
centroid distances at the points of the resampled outline, their Gaussian smoothing evaluated
at the signature's points only (:func:`smoothed`), and the local thickness at those points
(:func:`thickness`). Module-level functions with every array and number an argument, so that
numba's cache finds them in every later process (:mod:`.compiled`); in one file, which the
cache watches. Importing this module imports numba.
"""

from __future__ import annotations

import numba
import numpy as np

from .compiled import watch

__all__ = ["signature", "thickness"]

#: "No vertex in front" inside :func:`thickness` (a finite number: its arithmetic is compiled
#: with fastmath, which assumes no infinities).
_NONE = 1e300


@numba.njit(cache=True, fastmath=True, error_model="numpy")
def thickness(p, step, sign, chord, gap_min):  # pragma: no cover
    m = p.shape[0]
    n = m // step
    # the vertices twice over, coordinates apart: the q's of vertex i are the
    # contiguous i + gap_min + 1 … i + m − gap_min − 1
    xs = np.empty(2 * m)
    ys = np.empty(2 * m)
    for j in range(m):
        xs[j] = xs[j + m] = p[j, 0]
        ys[j] = ys[j + m] = p[j, 1]
    out = np.empty(n)
    for r in range(n):
        i = r * step
        tx = p[(i + chord) % m, 0] - p[(i - chord) % m, 0]
        ty = p[(i + chord) % m, 1] - p[(i - chord) % m, 1]
        norm = np.sqrt(tx * tx + ty * ty)
        if norm == 0.0:
            norm = 1.0
        nx, ny = -sign * ty / norm, sign * tx / norm
        px, py = xs[i], ys[i]
        best = _NONE
        for j in range(i + gap_min + 1, i + m - gap_min):
            dx, dy = xs[j] - px, ys[j] - py
            proj = dx * nx + dy * ny
            v = (dx * dx + dy * dy) / (2.0 * proj)
            best = min(best, v if proj > 0.0 else _NONE)
        out[r] = best if best < _NONE else np.inf
    return out


@numba.njit(cache=True, fastmath=True)
def smoothed(x, w, step, out):  # pragma: no cover
    """``out[c] = ndi.correlate1d(x[c], w, mode="wrap")[::step]`` for an odd-length w."""
    m = x.shape[1]
    half = w.shape[0] // 2
    pad = np.empty(m + 2 * half)
    for c in range(x.shape[0]):
        for j in range(m + 2 * half):
            pad[j] = x[c, (j - half) % m]
        for r in range(out.shape[1]):
            acc = 0.0
            i = r * step
            for t in range(w.shape[0]):
                acc += w[t] * pad[i + t]
            out[c, r] = acc


@numba.njit(cache=True)
def signature(p, arcs, w, w_thick, step, thickness_weight, chord, gap_min,
              out):  # pragma: no cover
    """The signature of the outline p (resampled, uniform in arc length) into out
    (N_CHANNELS, len(p) // step); False when p encloses no area."""
    m = p.shape[0]
    n = m // step
    # centroid of the enclosed area
    area = 0.0
    cx = 0.0
    cy = 0.0
    for i in range(m):
        j = i + 1 if i + 1 < m else 0
        cr = p[i, 0] * p[j, 1] - p[j, 0] * p[i, 1]
        area += cr
        cx += (p[i, 0] + p[j, 0]) * cr
        cy += (p[i, 1] + p[j, 1]) * cr
    area *= 0.5
    if not abs(area) > 0.0:
        return False
    cx /= 6.0 * area
    cy /= 6.0 * area
    q = np.empty((m, 2))
    for i in range(m):
        q[i, 0] = p[i, 0] - cx
        q[i, 1] = p[i, 1] - cy
    n_arcs = arcs.shape[0]
    chan = np.empty((n_arcs + 1, m))
    # turning angle between the chord arriving at i and the one leaving it
    for a in range(n_arcs):
        k = arcs[a]
        for i in range(m):
            b = (i - k) % m
            f = (i + k) % m
            ux, uy = q[i, 0] - q[b, 0], q[i, 1] - q[b, 1]
            vx, vy = q[f, 0] - q[i, 0], q[f, 1] - q[i, 1]
            chan[a, i] = np.arctan2(ux * vy - uy * vx, ux * vx + uy * vy)
    mean = 0.0
    for i in range(m):
        rad = np.sqrt(q[i, 0] * q[i, 0] + q[i, 1] * q[i, 1])
        chan[n_arcs, i] = rad
        mean += rad
    mean /= m
    for i in range(m):
        chan[n_arcs, i] /= mean
    smoothed(chan, w, step, out[: n_arcs + 1])  # at the signature's points only
    r_t = thickness(q, step, 1.0 if area > 0 else -1.0, chord, gap_min)
    top = -np.inf
    for r in range(n):
        if np.isfinite(r_t[r]) and r_t[r] > top:
            top = r_t[r]
    if top == -np.inf:  # (no vertex in front of any point: a degenerate outline)
        top = 1.0
    mean = 0.0
    for r in range(n):
        if not np.isfinite(r_t[r]):
            r_t[r] = top
        mean += r_t[r]
    mean /= n
    lt = np.empty((1, n))
    for r in range(n):
        lt[0, r] = np.log(max(r_t[r] / mean, 1e-3))
    smoothed(lt, w_thick, 1, out[n_arcs + 1:])
    for r in range(n):
        out[n_arcs + 1, r] *= thickness_weight
    return True


watch(thickness, "the local thickness")
watch(signature, "the outline signature")
