"""Synthetic shapes: the paper's five base shapes, similarity transforms, rasterisation.

The synthetic benchmark (paper §3.1, docs/design.md §2.8) compares five base shapes —
a circle, an elongated shape, an asymmetrically folded shape, a rounded square and a branched
shape with three arms — each rasterised many times under random translations, rotations,
reflections and isotropic scalings (0.5×–2×), and, in a second variant, with a mild random
deformation of each copy (real objects of one kind are never identical).

Outlines are smooth closed polygons in normalised units: ``(row, col)`` coordinates centred
near the origin, the farthest point at distance 1, counter-clockwise (positive shoelace area in
``(row, col)``). :func:`rasterize` turns an outline into a boolean mask with sub-pixel accurate
fill (area coverage ≥ ½ on an oversampled grid). Everything is deterministic from a seed.

Examples
--------
>>> masks, labels, names = make_benchmark_set(n_per_class=2, seed=1, size=128)
>>> len(masks), masks[0].shape, labels.tolist(), names[0]
(10, (128, 128), [0, 0, 1, 1, 2, 2, 3, 3, 4, 4], 'circle')
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..core.contour import polygon_area_centroid, signed_area
from ..errors import InputError

__all__ = [
    "CLASS_NAMES",
    "Similarity",
    "base_shape",
    "base_shapes",
    "circle",
    "elongated",
    "folded",
    "rounded_square",
    "branched",
    "ellipse",
    "three_armed",
    "ellipse_mask",
    "three_armed_mask",
    "bent_capsule_mask",
    "rasterize",
    "random_similarity",
    "perturb",
    "make_benchmark_set",
]

#: Number of vertices of the base outlines (smooth at any raster size used here).
N_VERTICES = 720

#: Names of the five base shapes, in class-label order.
CLASS_NAMES: tuple[str, ...] = ("circle", "elongated", "folded", "rounded square", "branched")


# --------------------------------------------------------------------------- outlines


def _angles(n: int) -> np.ndarray:
    return np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)


def _from_polar(radius: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """(row, col) points of a radial function, counter-clockwise in (row, col)."""
    # row = r cos t, col = r sin t: the shoelace area in (row, col) is positive.
    return np.column_stack([radius * np.cos(theta), radius * np.sin(theta)])


def _unit(points: np.ndarray) -> np.ndarray:
    """Centre on the area centroid and scale so that the farthest point is at distance 1."""
    points = _ccw(points)
    center = polygon_area_centroid(points)[1]
    points = points - center
    return points / np.linalg.norm(points, axis=1).max()


def _ccw(points: np.ndarray) -> np.ndarray:
    return points if signed_area(points) > 0 else points[::-1].copy()


def circle(n: int = N_VERTICES) -> np.ndarray:
    """The unit circle, ``(n, 2)`` ``(row, col)`` vertices."""
    return _unit(_from_polar(np.ones(n), _angles(n)))


def ellipse(aspect: float = 0.45, n: int = N_VERTICES) -> np.ndarray:
    """An ellipse with semi-axes 1 (along rows) and ``aspect`` (along columns)."""
    t = _angles(n)
    return _unit(np.column_stack([np.cos(t), aspect * np.sin(t)]))


def elongated(n: int = N_VERTICES) -> np.ndarray:
    """The elongated base shape: an ellipse of aspect ratio 0.45."""
    return ellipse(0.45, n)


def folded(n: int = N_VERTICES) -> np.ndarray:
    """The asymmetrically folded base shape: an egg with a deep fold on one flank.

    A radial function around the centre: an egg profile (thicker on one end) from which a
    smooth, off-centre Gaussian notch is cut, so that the outline is non-convex and has no
    mirror symmetry.
    """
    t = _angles(n)
    fold = 0.6 * np.exp(-(_wrap(t - 1.9) ** 2) / (2 * 0.32**2))
    radius = 1.0 + 0.22 * np.cos(t) + 0.10 * np.cos(2 * t + 0.6) - fold
    return _unit(_from_polar(radius, t))


def rounded_square(n: int = N_VERTICES, exponent: float = 5.0) -> np.ndarray:
    """The rounded-square base shape: the superellipse ``|y|^p + |x|^p = 1`` (p = 5)."""
    t = _angles(n)
    c, s = np.cos(t), np.sin(t)
    radius = (np.abs(c) ** exponent + np.abs(s) ** exponent) ** (-1.0 / exponent)
    return _unit(_from_polar(radius, t))


def three_armed(
    arm_width: float = 0.28,
    core: float = 0.38,
    n: int = N_VERTICES,
    arm_angles: tuple[float, float, float] = (0.0, 2.0 * np.pi / 3, 4.0 * np.pi / 3),
) -> np.ndarray:
    """A branched shape with three smooth arms.

    Parameters
    ----------
    arm_width : float
        Angular half-width (radians) of each arm, as the standard deviation of a Gaussian bump
        of the radius.
    core : float
        Radius of the body between the arms (the arm tips are at radius 1).
    n : int
        Number of vertices.
    arm_angles : tuple of float
        Directions of the three arms (radians, measured from the row axis towards columns).
    """
    t = _angles(n)
    bumps = np.zeros_like(t)
    for a in arm_angles:
        bumps = np.maximum(bumps, np.exp(-(_wrap(t - a) ** 2) / (2 * arm_width**2)))
    # Smooth the max of the bumps (it has kinks where neighbouring bumps meet).
    bumps = _lowpass_periodic(bumps, 24)
    radius = core + (1.0 - core) * bumps
    return _unit(_from_polar(radius, t))


def branched(n: int = N_VERTICES) -> np.ndarray:
    """The branched base shape: three arms of unequal spacing (100°, 120°, 140°)."""
    deg = np.pi / 180.0
    return three_armed(arm_width=0.26, core=0.36, n=n, arm_angles=(0.0, 100 * deg, 220 * deg))


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


def _lowpass_periodic(values: np.ndarray, n_keep: int) -> np.ndarray:
    spec = np.fft.rfft(values)
    spec[n_keep + 1 :] = 0.0
    return np.fft.irfft(spec, len(values))


_BASE: dict[str, Callable[[int], np.ndarray]] = {
    "circle": circle,
    "elongated": elongated,
    "folded": folded,
    "rounded square": rounded_square,
    "branched": branched,
}


def base_shape(name: str, n: int = N_VERTICES) -> np.ndarray:
    """One of :data:`CLASS_NAMES` as ``(n, 2)`` normalised ``(row, col)`` vertices."""
    try:
        return _BASE[name](n)
    except KeyError:
        raise InputError(
            f"Unknown base shape {name!r}; choose one of {', '.join(CLASS_NAMES)}."
        ) from None


def base_shapes(n: int = N_VERTICES) -> list[np.ndarray]:
    """The five base outlines, in the order of :data:`CLASS_NAMES`."""
    return [base_shape(name, n) for name in CLASS_NAMES]


# --------------------------------------------------------------------------- transforms


@dataclass(frozen=True)
class Similarity:
    """A similarity transform of normalised outlines into image pixel coordinates.

    ``p_image = center + scale * R(angle) @ F @ p`` where ``F`` flips the column axis when
    ``reflect`` is true and ``R`` rotates counter-clockwise by ``angle`` radians.

    Attributes
    ----------
    angle : float
        Rotation in radians.
    reflect : bool
        Mirror the outline (before rotating).
    scale : float
        Pixels per normalised unit.
    center : tuple of float
        Image ``(row, col)`` position of the outline's origin.
    """

    angle: float
    reflect: bool
    scale: float
    center: tuple[float, float]

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Transform ``(K, 2)`` normalised ``(row, col)`` points into pixel coordinates."""
        p = np.asarray(points, float)
        if self.reflect:
            p = p * np.array([1.0, -1.0])
        c, s = np.cos(self.angle), np.sin(self.angle)
        rot = np.array([[c, -s], [s, c]])
        return self.scale * p @ rot.T + np.asarray(self.center, float)


def random_similarity(
    rng: np.random.Generator,
    *,
    size: int | tuple[int, int] = 256,
    base_scale: float | None = None,
    scale_range: tuple[float, float] = (0.5, 2.0),
    margin: float = 3.0,
    points: np.ndarray | None = None,
) -> Similarity:
    """A random rotation, reflection, isotropic scaling and translation.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of randomness (the result is deterministic given its state).
    size : int or (int, int)
        Image shape the outline must fit in.
    base_scale : float, optional
        Pixels per normalised unit at scaling factor 1. Default: ``0.21 * min(size)``, so that
        an outline of radius 1 at 2× still fits with room to move.
    scale_range : (float, float)
        Range of the isotropic scaling factor, drawn log-uniformly.
    margin : float
        Minimum distance in pixels between the outline and the image edge.
    points : ndarray, optional
        The outline to be placed: the translation is drawn uniformly among positions keeping
        it ``margin`` pixels inside the image. Without it, the unit disk is assumed.

    Returns
    -------
    Similarity
    """
    shape = (size, size) if np.isscalar(size) else tuple(size)
    if base_scale is None:
        base_scale = 0.21 * min(shape)
    angle = float(rng.uniform(0.0, 2.0 * np.pi))
    reflect = bool(rng.integers(0, 2))
    lo, hi = np.log(scale_range[0]), np.log(scale_range[1])
    scale = float(base_scale * np.exp(rng.uniform(lo, hi)))
    placed = Similarity(angle, reflect, scale, (0.0, 0.0)).apply(
        circle(64) if points is None else points
    )
    low = margin - 0.5 - placed.min(axis=0)
    high = np.array(shape, float) - 0.5 - margin - placed.max(axis=0)
    if np.any(high < low):
        raise InputError(
            f"An outline {np.ptp(placed, axis=0).round(1).tolist()} pixels across does not fit in "
            f"an image of {shape} with a margin of {margin} pixels; use a larger image or a "
            "smaller base_scale."
        )
    center = rng.uniform(low, high)
    return Similarity(angle, reflect, scale, (float(center[0]), float(center[1])))


def perturb(
    points: np.ndarray,
    rng: np.random.Generator,
    *,
    strength: float = 1.0,
) -> np.ndarray:
    """A mild random smooth deformation of a normalised outline.

    Three effects, all small and low-frequency so that the shape stays recognisably of its
    class: radial noise ``r → r (1 + Σ_{k=2..5} a_k cos(k θ + φ_k))`` with ``a_k`` of order
    ``0.035 / k`` (×``strength``); a bend ``y → y + b x²`` along a random direction with
    ``|b| ≤ 0.12``; and a stretch of up to ±8 % along a random direction.

    Parameters
    ----------
    points : ndarray, shape (K, 2)
        Normalised outline (centred near the origin).
    rng : numpy.random.Generator
        Source of randomness.
    strength : float
        Multiplies all three amplitudes (0 returns the outline re-normalised).

    Returns
    -------
    ndarray, shape (K, 2)
        The deformed outline, re-centred and scaled to unit maximum radius.
    """
    p = np.asarray(points, float)
    theta = np.arctan2(p[:, 1], p[:, 0])
    k = np.arange(2, 6)
    amp = strength * rng.normal(0.0, 0.035, size=k.size) / k * 2.0
    phase = rng.uniform(0.0, 2.0 * np.pi, size=k.size)
    factor = 1.0 + (amp[None, :] * np.cos(k[None, :] * theta[:, None] + phase)).sum(axis=1)
    p = p * factor[:, None]
    # Bend along a random direction.
    a = rng.uniform(0.0, 2.0 * np.pi)
    c, s = np.cos(a), np.sin(a)
    rot = np.array([[c, -s], [s, c]])
    q = p @ rot
    q[:, 1] += strength * rng.uniform(-0.12, 0.12) * q[:, 0] ** 2
    # Mild anisotropic stretch along the same frame.
    q[:, 0] *= 1.0 + strength * rng.uniform(-0.08, 0.08)
    p = q @ rot.T
    return _unit(p)


_perturb_outline = perturb  # ``make_benchmark_set`` has an argument of the same name


# --------------------------------------------------------------------------- raster


def rasterize(
    polygon: np.ndarray,
    shape: tuple[int, int] = (256, 256),
    *,
    transform: Similarity | None = None,
    oversample: int = 4,
) -> np.ndarray:
    """Fill a closed outline into a boolean mask with sub-pixel accuracy.

    A pixel is set when at least half of its area lies inside the outline, estimated on a
    grid ``oversample`` times finer in each direction.

    Parameters
    ----------
    polygon : ndarray, shape (K, 2)
        Closed outline (without repeating the first vertex): pixel ``(row, col)`` coordinates,
        pixel centres at integers; or normalised coordinates when ``transform`` is given.
    shape : (int, int)
        Shape of the output mask.
    transform : Similarity, optional
        Applied to ``polygon`` first.
    oversample : int
        Sub-samples per pixel and direction (1 = plain centre sampling).

    Returns
    -------
    ndarray of bool, shape ``shape``

    Examples
    --------
    >>> yy, xx = np.mgrid[:64, :64]
    >>> t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    >>> disk = rasterize(np.column_stack([32 + 20 * np.cos(t), 30 + 20 * np.sin(t)]), (64, 64))
    >>> abs(int(disk.sum()) - round(np.pi * 20**2)) < 10
    True
    """
    pts = np.asarray(polygon, float)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 3:
        raise InputError(
            f"Expected an outline of at least 3 (row, col) vertices, got shape {pts.shape}."
        )
    if transform is not None:
        pts = transform.apply(pts)
    oversample = int(oversample)
    if oversample < 1:
        raise InputError(f"oversample must be a positive integer, got {oversample}.")
    h, w = int(shape[0]), int(shape[1])
    fine = (pts + 0.5) * oversample - 0.5
    grid = _scanline_fill(fine, (h * oversample, w * oversample))
    cover = grid.reshape(h, oversample, w, oversample).sum(axis=(1, 3))
    return cover * 2 >= oversample * oversample


def _scanline_fill(pts: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Even-odd fill of a polygon, sampled at integer pixel centres (vectorised scanlines)."""
    h, w = shape
    y0, x0 = pts[:, 0], pts[:, 1]
    y1, x1 = np.roll(y0, -1), np.roll(x0, -1)
    lo = np.ceil(np.minimum(y0, y1)).astype(int)
    hi = np.ceil(np.maximum(y0, y1)).astype(int)  # rows lo <= y < hi cross the edge
    lo, hi = np.clip(lo, 0, h), np.clip(hi, 0, h)
    count = hi - lo
    edge = np.repeat(np.arange(len(pts)), count)
    rows = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count) + lo[edge]
    t = (rows - y0[edge]) / (y1[edge] - y0[edge])
    x = x0[edge] + t * (x1[edge] - x0[edge])
    cols = np.clip(np.floor(x).astype(int) + 1, 0, w)
    parity = np.zeros((h, w + 1), np.int32)
    np.add.at(parity, (rows, cols), 1)
    return (np.cumsum(parity, axis=1)[:, :w] % 2).astype(np.uint8)


def ellipse_mask(
    shape: tuple[int, int] = (128, 128),
    *,
    center: tuple[float, float] | None = None,
    axes: tuple[float, float] = (40.0, 18.0),
    angle: float = 0.0,
) -> np.ndarray:
    """A rasterised ellipse (for tests of the skeleton: its medial axis is the major axis).

    Parameters
    ----------
    shape : (int, int)
        Mask shape.
    center : (float, float), optional
        ``(row, col)`` centre; default the image centre.
    axes : (float, float)
        Semi-axes in pixels, the first along the direction ``angle``.
    angle : float
        Direction of the first axis in radians, from the row axis towards the column axis.
    """
    if center is None:
        center = ((shape[0] - 1) / 2.0, (shape[1] - 1) / 2.0)
    t = _angles(N_VERTICES)
    local = np.column_stack([axes[0] * np.cos(t), axes[1] * np.sin(t)])
    transform = Similarity(angle=angle, reflect=False, scale=1.0, center=tuple(center))
    return rasterize(local, shape, transform=transform)


def three_armed_mask(
    shape: tuple[int, int] = (128, 128),
    *,
    center: tuple[float, float] | None = None,
    radius: float = 50.0,
    arm_width: float = 0.28,
    angle: float = 0.0,
) -> np.ndarray:
    """A rasterised three-armed shape (its skeleton has three end points, one per arm tip).

    Parameters
    ----------
    shape : (int, int)
        Mask shape.
    center : (float, float), optional
        ``(row, col)`` centre; default the image centre.
    radius : float
        Distance of the arm tips from the centre, in pixels.
    arm_width : float
        Angular half-width of each arm (see :func:`three_armed`).
    angle : float
        Rotation in radians.
    """
    if center is None:
        center = ((shape[0] - 1) / 2.0, (shape[1] - 1) / 2.0)
    outline = three_armed(arm_width=arm_width)
    transform = Similarity(angle=angle, reflect=False, scale=float(radius), center=tuple(center))
    return rasterize(outline, shape, transform=transform)


def bent_capsule_mask(
    radius: float = 50.0,
    *,
    half_width: float = 0.3,
    span: float = 1.2,
    angle: float = 0.0,
    margin: int = 4,
) -> np.ndarray:
    """A bent capsule (a banana): the pixels within ``half_width`` × ``radius`` of an arc of
    radius ``radius`` and opening ``span`` radians, in a mask just large enough for it.

    Pixel centres are tested against the exact distance to the arc, so any size costs one
    pass over the mask (a 1-megapixel one at ``radius`` 1,000 in about a second).

    Parameters
    ----------
    radius : float
        Radius of the arc (the capsule's midline), in pixels.
    half_width : float
        The capsule's half-thickness, as a fraction of ``radius``.
    span : float
        Opening of the arc, in radians.
    angle : float
        Direction of the arc's middle from its centre, radians from the row axis towards the
        column axis.
    margin : int
        Empty pixels on every side of the capsule.

    Examples
    --------
    >>> m = bent_capsule_mask(100.0)
    >>> m.shape, int(m.sum())
    ((87, 183), 10035)
    """
    w = half_width * radius
    # the arc and its end points, in coordinates centred on the arc's centre
    t = angle + np.array([-span / 2, span / 2])
    ends = radius * np.column_stack([np.cos(t), np.sin(t)])
    mid = radius * np.array([np.cos(angle), np.sin(angle)])
    pts = np.vstack([ends, mid])
    lo, hi = pts.min(axis=0) - w, pts.max(axis=0) + w
    # arc extremes along the axes, where the arc passes them
    for k in range(4):
        a = k * np.pi / 2
        if abs(np.angle(np.exp(1j * (a - angle)))) <= span / 2:
            q = radius * np.array([np.cos(a), np.sin(a)])
            lo, hi = np.minimum(lo, q - w), np.maximum(hi, q + w)
    origin = np.floor(lo) - margin
    shape = tuple((np.ceil(hi) + margin + 1 - origin).astype(int))
    rows = np.arange(shape[0]) + origin[0]
    cols = np.arange(shape[1]) + origin[1]
    y, x = rows[:, None], cols[None, :]
    rho = np.hypot(y, x)
    off = np.angle(np.exp(1j * (np.arctan2(x, y) - angle)))  # polar angle of (row, col)
    d = np.where(np.abs(off) <= span / 2, np.abs(rho - radius), np.inf)
    for e in ends:
        d = np.minimum(d, np.hypot(y - e[0], x - e[1]))
    return d <= w


# --------------------------------------------------------------------------- benchmark set


def make_benchmark_set(
    n_per_class: int = 10,
    perturb: bool = False,
    seed: int = 0,
    size: int = 256,
    *,
    strength: float = 1.0,
) -> tuple[list[np.ndarray], np.ndarray, tuple[str, ...]]:
    """The paper's synthetic set: each base shape under random similarity transforms.

    Parameters
    ----------
    n_per_class : int
        Copies of each of the five base shapes.
    perturb : bool
        Deform each copy mildly and randomly (see :func:`perturb`) before placing it, so that
        the objects of one class are similar but not identical.
    seed : int
        Seed of the random generator: the set is a function of all arguments.
    size : int
        Masks are ``size × size``.
    strength : float
        Amplitude of the perturbation (only with ``perturb=True``).

    Returns
    -------
    masks : list of ndarray of bool
        ``5 * n_per_class`` masks, class by class.
    labels : ndarray of int, shape (5 * n_per_class,)
        Class index of each mask, into ``class_names``.
    class_names : tuple of str
        :data:`CLASS_NAMES`.
    """
    if n_per_class < 1:
        raise InputError(f"n_per_class must be at least 1, got {n_per_class}.")
    do_perturb = perturb
    rng = np.random.default_rng([int(seed), int(bool(do_perturb))])
    masks: list[np.ndarray] = []
    labels: list[int] = []
    for label, outline in enumerate(base_shapes()):
        for _ in range(n_per_class):
            shape_pts = _perturb_outline(outline, rng, strength=strength) if do_perturb else outline
            transform = random_similarity(rng, size=size, points=shape_pts)
            masks.append(rasterize(shape_pts, (size, size), transform=transform))
            labels.append(label)
    return masks, np.asarray(labels, dtype=int), CLASS_NAMES
