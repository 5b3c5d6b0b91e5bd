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

One compiled kernel (numba, :mod:`.signature_kernel`) computes the whole signature of an
outline: the turning angles and centroid distances at the 256 points of the resampled outline,
their Gaussian smoothing evaluated at the signature's points only, and the local thickness at
those points.

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
    ok = _kernels().signature(
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
    return _kernels().thickness(p, int(step), 1.0 if ccw else -1.0, _THICKNESS_CHORD,
                               _THICKNESS_GAP)


#: The normal at vertex i is that of the chord from i − _THICKNESS_CHORD to i +
#: _THICKNESS_CHORD; vertices within _THICKNESS_GAP of i are not among the q's (of 256: with
#: 2 and 2 a raster copy turned by 0.6 rad lay at 14 % of the lobed test shape's distance to a
#: rectangle, with 4 and 4 at 7 %; MPEG-7 85.90 against 85.55 %).
_THICKNESS_CHORD = 4


_THICKNESS_GAP = 4


def _kernels():
    """The compiled kernels (:mod:`.signature_kernel`; importing it imports numba, which the
    rest of ``core`` does not need)."""
    from . import signature_kernel

    return signature_kernel


@lru_cache(maxsize=1)
def _arc_steps() -> np.ndarray:
    """The points (of the resampled outline) spanned by each arc of :data:`TURNING_ARCS`
    (read-only)."""
    out = np.array([max(1, int(round(a * _RESAMPLED))) for a in TURNING_ARCS], np.int64)
    out.flags.writeable = False
    return out
