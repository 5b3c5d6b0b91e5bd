"""The elastic term's outline signature: what it compares, one column per point of an outline.

At :data:`N_SIGNATURE_POINTS` points equally spaced in arc length along the normalised
outline (counter-clockwise, uniform in arc length, centroid at the origin), one column of
:data:`N_CHANNELS` numbers: the turning angle of the outline over arcs of
:data:`TURNING_ARCS` (fractions of the perimeter: the signed angle between the chord that
arrives at the point and the chord that leaves it), the distance to the centroid
divided by its mean along the outline, and :data:`THICKNESS_WEIGHT` times the log of the
local thickness over its mean (:func:`local_thickness`: the radius of the largest disk
inside the outline that touches it at the point, the depth of the signed distance
function's ridge behind it; a limb keeps it when it bends, where the centroid distance
changes). Each is invariant to translation, rotation and
scale; moving the start point shifts the columns cyclically; a mirror image, traced
counter-clockwise again, reverses their order.

One compiled kernel (numba) computes the whole signature of an outline: the turning angles
and centroid distances at the 256 points of the resampled outline, their Gaussian smoothing
evaluated at the signature's points only, and the local thickness at those points.

The distance that compares two signatures is :mod:`.elastic`.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy import ndimage as ndi

from ..errors import InputError

__all__ = ["N_CHANNELS", "N_SIGNATURE_POINTS", "SMOOTHING", "THICKNESS_WEIGHT", "TURNING_ARCS",
           "local_thickness", "outline_signature"]


#: Points of the signature along the outline.
N_SIGNATURE_POINTS = 64


#: Arcs (fractions of the perimeter) over which the turning angle is measured: 1/128 … 1/8.
TURNING_ARCS = (1 / 128, 1 / 64, 1 / 32, 1 / 16, 1 / 8)


#: Numbers per signature point: one turning angle per arc, the relative centroid distance and
#: the local thickness.
N_CHANNELS = len(TURNING_ARCS) + 2


#: Weight of the local-thickness channel, ``THICKNESS_WEIGHT · log(r / mean r)`` (its L1 cost
#: counts that much against the other channels'; chosen on MPEG-7 by leave-classes-out
#: cross-validation among 0 … 4: docs/benchmarks.md).
THICKNESS_WEIGHT = 3.0


#: σ of the Gaussian (in 1/256 of the perimeter) that smooths each channel along the outline
#: before it is sampled at the signature's points: the ``elastic_smoothing`` option's
#: default (chosen on MPEG-7 by leave-classes-out cross-validation among 0, 2, 4, 8).
SMOOTHING = 4.0


#: Points the outline is resampled to before the turning angles are measured.
_RESAMPLED = 256


def _resample(points: np.ndarray, m: int) -> np.ndarray:
    """A closed polyline resampled to m points equally spaced in arc length, from point 0."""
    closed = np.vstack([points, points[:1]])
    seg = np.hypot(*np.diff(closed, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    t = np.arange(m) * (s[-1] / m)
    return np.column_stack([np.interp(t, s, closed[:, 0]), np.interp(t, s, closed[:, 1])])


def outline_signature(points: np.ndarray, n_points: int = N_SIGNATURE_POINTS, *,
                      smoothing: float = SMOOTHING,
                      thickness_weight: float = THICKNESS_WEIGHT) -> np.ndarray:
    """The elastic term's signature of one closed outline (module docstring).

    Parameters
    ----------
    points : ndarray, shape (M, 2)
        The outline, counter-clockwise (in the array's (row, col) axes, as
        ``result.contour.normalized``), M ≥ 8. It is resampled to 256 points uniformly in
        arc length (256 points are taken as they are: ``contour.normalized`` is already
        uniform); the centroid is that of the enclosed area.
    n_points : int
        Columns of the signature (a divisor of 256).
    smoothing : float
        σ of the Gaussian that smooths each channel along the outline before it is sampled,
        in 1/256 of the perimeter (0: none).
    thickness_weight : float
        Factor of the local-thickness channel (0: a channel of zeros, the term as it was
        without it).

    Returns
    -------
    ndarray of float, shape (N_CHANNELS, n_points)
        Rows: turning angles (radians, in (−π, π]) over each arc of :data:`TURNING_ARCS`, the
        centroid distance over its mean, and :data:`THICKNESS_WEIGHT` times the log of the
        local thickness (:func:`local_thickness`, at the signature's points, smoothed by
        ``smoothing`` in the same units) over its mean.

    Examples
    --------
    >>> t = 2 * np.pi * np.arange(256) / 256
    >>> circle = np.column_stack([np.cos(t), np.sin(t)])
    >>> sig = outline_signature(circle, 16)
    >>> np.round(sig[:, 0], 4).tolist()  # turning over an arc a: 2π a; thickness 1 / mean
    [0.0491, 0.0982, 0.1963, 0.3927, 0.7854, 1.0, 0.0]
    """
    pts = np.asarray(points, float)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 8 or not np.isfinite(pts).all():
        raise InputError(f"an outline of at least 8 finite points (M, 2) is needed; got shape "
                         f"{pts.shape}")
    if n_points < 8 or _RESAMPLED % n_points:
        raise InputError(f"n_points must divide {_RESAMPLED} and be at least 8, got {n_points}")
    p = pts if len(pts) == _RESAMPLED else _resample(pts, _RESAMPLED)
    step = _RESAMPLED // n_points
    out = np.empty((N_CHANNELS, n_points))
    flat = np.ones(1)
    ok = _signature_kernel()(
        np.ascontiguousarray(p, float), _arc_steps(),
        _gaussian(smoothing) if smoothing > 0 else flat,
        _gaussian(smoothing / step) if smoothing > 0 else flat,
        step, float(thickness_weight), _THICKNESS_CHORD, _THICKNESS_GAP, out)
    if not ok:
        raise InputError("the outline encloses no area")
    return out


@lru_cache(maxsize=8)
def _gaussian(sigma: float) -> np.ndarray:
    """The weights ``ndi.gaussian_filter1d(x, sigma)`` correlates x with (read from the filter's
    response to an impulse, so that ``ndi.correlate1d(x, _gaussian(sigma))`` is the same
    filter, number for number, without rebuilding the kernel at each call)."""
    radius = int(4.0 * float(sigma) + 0.5)
    impulse = np.zeros(2 * radius + 1)
    impulse[radius] = 1.0
    out = ndi.gaussian_filter1d(impulse, sigma, mode="constant")[::-1].copy()
    out.flags.writeable = False
    return out


def local_thickness(points: np.ndarray, step: int = 1, ccw: bool = True) -> np.ndarray:
    """The radius of the largest disk inside a closed polygon that touches it at its vertices.

    For a vertex p with inward unit normal ν, the disk of centre p + rν and radius r holds no
    vertex q while |p + rν − q| ≥ r, i.e. r ≤ |p − q|² / (2 ν·(q − p)) for every q with
    ν·(q − p) > 0: r is the least of these (vertices within 2 of p, which set the normal,
    are left out). An inner-distance-like quantity of the object (the depth of the signed
    distance function's ridge behind the point): a limb keeps its thickness when it bends.

    Parameters
    ----------
    points : ndarray, shape (M, 2)
        The polygon's vertices, evenly spaced along it.
    step : int
        Every ``step``-th vertex gets its radius (all vertices are the q's).
    ccw : bool
        Whether the vertices run counter-clockwise in the array's axes (the interior on the
        left).

    Returns
    -------
    ndarray, shape (M // step,)
        Positive radii (+inf for none: a polygon with fewer than 6 vertices).

    Examples
    --------
    >>> t = 2 * np.pi * np.arange(64) / 64
    >>> circle = np.column_stack([3 * np.cos(t), 3 * np.sin(t)])
    >>> np.allclose(local_thickness(circle), 3)
    True
    """
    p = np.ascontiguousarray(points, float)
    return _thickness_kernel()(p, int(step), 1.0 if ccw else -1.0, _THICKNESS_CHORD,
                               _THICKNESS_GAP)


#: The normal at vertex i is that of the chord from i − _THICKNESS_CHORD to i +
#: _THICKNESS_CHORD; vertices within _THICKNESS_GAP of i are not among the q's (of 256: with
#: 2 and 2 a raster copy turned by 0.6 rad lay at 14 % of the lobed test shape's distance to a
#: rectangle, with 4 and 4 at 7 %; MPEG-7 85.90 against 85.55 %).
_THICKNESS_CHORD = 4


_THICKNESS_GAP = 4


@lru_cache(maxsize=1)
def _thickness_kernel():
    return _kernels()[0]


@lru_cache(maxsize=1)
def _signature_kernel():
    return _kernels()[1]


#: "No vertex in front" inside the thickness kernel (a finite number: its arithmetic is compiled
#: with fastmath, which assumes no infinities).
_NONE = 1e300


@lru_cache(maxsize=1)
def _kernels():
    """The compiled kernels (numba, compiled on first use and cached on disk): the local
    thickness, and the whole signature of a resampled outline."""
    import numba

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

    return thickness, signature


@lru_cache(maxsize=1)
def _arc_steps() -> np.ndarray:
    """The points (of the resampled outline) spanned by each arc of :data:`TURNING_ARCS`
    (read-only)."""
    out = np.array([max(1, int(round(a * _RESAMPLED))) for a in TURNING_ARCS], np.int64)
    out.flags.writeable = False
    return out
