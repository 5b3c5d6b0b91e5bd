"""The object's own axis: its midline, the widths and the reporter along it (2-D objects).

The midline is the skeleton's main axis (:mod:`~napari_pfsdm.core.medial_axis`): its longest
path, smoothed over a few grid steps (the pixel staircase would lengthen it), then extended
straight along its end tangents to the outline, because the medial axis of a smooth outline
stops short of it (at the centres of the end caps; the skeleton's threshold stops it earlier
still). Its length is therefore the object's length along its own axis: 2a for an ellipse of
half-axes a, b; arc length + 2 × half-width for a bent capsule.

Along the midline, resampled uniformly by arc length:

A round or roundish object, whose skeleton is no longer than its median half-width, takes the
major axis of its pixels through their centre instead.

- **width**: the chord of the object across the midline, along the local normal, from outline
  to outline (rays cast to the sub-pixel outline polygon); 2b·√(1 − s²) at s = x/a on an
  ellipse's axis, 0 at both ends. ``width_mean`` is its mean over the length (area / length for
  a straight axis), ``width_max`` its largest value, ``width_bXX`` its mean in ``bins`` equal
  pieces of the length, anterior first.
- **reporter** (with an intensity image): every pixel of the object goes to its nearest
  midline point; ``reporter_bXX`` is the mean reporter of the pixels of each piece, in the
  image's own units (NaN for a piece with no finite pixel).
- **anterior**: which end the profiles start from, by a stated rule (:data:`ANTERIOR_RULES`):
  ``"reporter"`` (default) the end whose half of the object has the higher mean reporter,
  ``"reporter_low"`` the lower one (e.g. Brachyury marks the *posterior* pole of a
  gastruloid), ``"first"`` the end nearer the image's top (the left one when the ends lie more
  left-right than up-down), ``"last"`` the other. The reporter rules fall back to ``"first"``
  without a reporter (or with equal halves); :attr:`Midline.anterior` says which rule applied.
- **polarity direction**: the reporter's centre of mass minus the object's centre, as an angle
  in the image (degrees, 0 = +x i.e. along the columns, counter-clockwise as the image is
  shown, rows growing downwards: 90 = up) and as the angle (0–180°) to the midline's
  anterior→posterior chord (0: the reporter lies towards the posterior end).

Lengths are in pixels, or in the units of ``pixel_size`` when given; points stay in image
``(row, col)`` pixels. The skeleton is traced on a grid of at most
:data:`MIDLINE_SAMPLES_ACROSS` samples across the object (every ``step`` pixels,
:func:`~napari_pfsdm.core.medial_axis.grid_step`); the reporter is read at every pixel of
objects up to 512 pixels across, and on the grid of 512 samples across bigger ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage as ndi
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from ..errors import InputError
from .choices import ANTERIOR_RULES
from .medial_axis import SAMPLES_ACROSS, Skeleton, grid_step, skeleton

__all__ = ["ANTERIOR_RULES", "MIDLINE_SAMPLES_ACROSS", "Midline", "main_path", "midline",
           "midline_columns", "SAMPLES_PER_BIN"]

#: Midline points per profile bin (the profiles' resolution along the length).
SAMPLES_PER_BIN = 10
#: Default grid of the midline's skeleton: at most this many samples along the longer side of
#: the object's box (:func:`~napari_pfsdm.core.medial_axis.grid_step`). Coarser than the
#: pictures' skeleton (512) for objects over 256 px: the midline is smoothed over two grid
#: steps anyway. On bent capsules and ellipses 184 to 1,440 px long the length stays within
#: 1 px and the widths within 1 px of the closed forms (128 samples: 2.9 px and 2 px).
MIDLINE_SAMPLES_ACROSS = 256


@dataclass(frozen=True)
class Midline:
    """The midline of one 2-D object and what was measured along it (module docstring).

    Attributes
    ----------
    points : ndarray, shape (M + 1, 2)
        The midline in image ``(row, col)`` pixels, anterior end first, uniform in arc length;
        the first and last points lie on the outline.
    arc : ndarray, shape (M + 1,)
        Arc length of each point from the anterior end (pixels, or units of ``pixel_size``).
    width : ndarray, shape (M + 1,)
        The object's width across the midline at each point (same units; 0 at both ends).
    normals : ndarray, shape (M + 1, 2)
        Unit normals of the midline at its points (``(row, col)``), along which the widths run.
    width_bins : ndarray, shape (bins,)
        Mean width in each of ``bins`` equal pieces of the length, anterior first.
    reporter_bins : ndarray, shape (bins,) or None
        Mean reporter of the pixels nearest each piece (None without a reporter).
    anterior : str
        The rule that chose the anterior end (one of :data:`ANTERIOR_RULES`; ``"first"`` when a
        reporter rule had no reporter to go by).
    polarity_angle_image, polarity_angle_midline : float
        Direction of the reporter's centre of mass from the object's centre, degrees (module
        docstring); NaN without a reporter.
    pixel_size : float
    sides : ndarray, shape (M + 1, 2)
        Pixels from each point to the outline along ``+normals`` and ``-normals`` (their sum is
        the width in pixels); for drawing the cross-sections (:meth:`cross_sections`).
    """

    points: np.ndarray
    arc: np.ndarray
    width: np.ndarray
    normals: np.ndarray
    width_bins: np.ndarray
    reporter_bins: np.ndarray | None
    anterior: str
    polarity_angle_image: float = np.nan
    polarity_angle_midline: float = np.nan
    pixel_size: float = 1.0
    sides: np.ndarray | None = None

    def cross_sections(self) -> np.ndarray:
        """The cross-section at the middle of each bin, outline to outline along the normal:
        segments ``(bins, 2, 2)`` in image ``(row, col)`` pixels, anterior bin first (for
        drawing, e.g. as a napari Shapes layer of lines).

        Examples
        --------
        >>> from napari_pfsdm.core.descriptor import pfsdm
        >>> yy, xx = np.mgrid[:61, :101]
        >>> m = midline(pfsdm(((yy - 30) / 20) ** 2 + ((xx - 50) / 40) ** 2 <= 1), bins=2)
        >>> np.round(m.cross_sections()[:, :, 1]).tolist()  # columns of the two sections' ends
        [[30.0, 30.0], [70.0, 70.0]]
        """
        if self.sides is None:
            return np.zeros((0, 2, 2))
        at = SAMPLES_PER_BIN * np.arange(len(self.width_bins)) + SAMPLES_PER_BIN // 2
        p, n, s = self.points[at], self.normals[at], self.sides[at]
        return np.stack([p + s[:, :1] * n, p - s[:, 1:] * n], axis=1)

    @property
    def length(self) -> float:
        """Length of the midline, outline to outline."""
        return float(self.arc[-1])

    @property
    def width_mean(self) -> float:
        """Mean width over the length (trapezoid rule)."""
        return float(_trapezoid(self.width, self.arc) / self.length) if self.length > 0 \
            else np.nan

    @property
    def width_max(self) -> float:
        """Largest width."""
        return float(self.width.max())

    @property
    def bin_edges(self) -> np.ndarray:
        """Arc lengths of the bins' edges (``bins + 1``), anterior first."""
        return np.linspace(0.0, self.length, len(self.width_bins) + 1)

    def columns(self) -> dict[str, float]:
        """The table's columns of this midline (:func:`midline_columns`' names)."""
        out = {"midline_length": self.length, "width_mean": self.width_mean,
               "width_max": self.width_max}
        out.update({f"width_b{k:02d}": float(w) for k, w in enumerate(self.width_bins)})
        if self.reporter_bins is not None:
            out.update({f"reporter_b{k:02d}": float(v)
                        for k, v in enumerate(self.reporter_bins)})
            out["polarity_angle_image"] = self.polarity_angle_image
            out["polarity_angle_midline"] = self.polarity_angle_midline
        return out


def midline_columns(bins: int, with_intensity: bool = False) -> list[str]:
    """The midline's column names of a table, in order.

    Examples
    --------
    >>> midline_columns(2, with_intensity=True)  # doctest: +NORMALIZE_WHITESPACE
    ['midline_length', 'width_mean', 'width_max', 'width_b00', 'width_b01', 'reporter_b00',
     'reporter_b01', 'polarity_angle_image', 'polarity_angle_midline']
    """
    cols = ["midline_length", "width_mean", "width_max"]
    cols += [f"width_b{k:02d}" for k in range(bins)]
    if with_intensity:
        cols += [f"reporter_b{k:02d}" for k in range(bins)]
        cols += ["polarity_angle_image", "polarity_angle_midline"]
    return cols


def _trapezoid(y: np.ndarray, x: np.ndarray) -> float:
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(x)))


def main_path(sk: Skeleton) -> np.ndarray:
    """The skeleton's longest path (its main axis), image ``(row, col)`` points (k, 2), float.

    The points are joined as 8-neighbours on the skeleton's grid (steps of 1 or √2 cells);
    the path runs between the two points farthest apart along the skeleton (two sweeps of
    Dijkstra's shortest paths, exact on a tree).

    Examples
    --------
    >>> pts = np.array([[0, 0], [0, 1], [0, 2], [1, 1], [2, 1], [3, 1]])  # a T, long leg down
    >>> path = main_path(Skeleton(pts, np.zeros((6, 2)), np.ones(6)))
    >>> path[0].tolist(), path[-1].tolist(), len(path)
    ([0.0, 0.0], [3.0, 1.0], 4)
    """
    pts = np.asarray(sk.points, float).reshape(-1, 2)
    if len(pts) < 2:
        return pts
    cells = sk.cells
    lo = cells.min(axis=0)
    grid = np.full(tuple(cells.max(axis=0) - lo + 3), -1, np.intp)
    local = cells - lo + 1
    grid[tuple(local.T)] = np.arange(len(cells))
    rows, cols, weights = [], [], []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        other = grid[local[:, 0] + dr, local[:, 1] + dc]
        ok = np.flatnonzero(other >= 0)
        rows += [ok, other[ok]]
        cols += [other[ok], ok]
        weights.append(np.full(2 * len(ok), np.hypot(dr, dc)))
    r, c = np.concatenate(rows), np.concatenate(cols)
    order = np.argsort(r, kind="stable")
    indptr = np.searchsorted(r[order], np.arange(len(cells) + 1))
    w = np.concatenate(weights)  # each edge both ways
    graph = csr_matrix((w[order], c[order], indptr), shape=(len(cells), len(cells)))
    first = dijkstra(graph, directed=True, indices=0)
    a = int(np.argmax(np.where(np.isfinite(first), first, -1)))
    dist, pred = dijkstra(graph, directed=True, indices=a, return_predecessors=True)
    b = int(np.argmax(np.where(np.isfinite(dist), dist, -1)))
    order = [b]
    while order[-1] != a:
        order.append(int(pred[order[-1]]))
    return pts[order]


def _resample(poly: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points of a polyline uniform in arc length, and their arc lengths."""
    seg = np.linalg.norm(np.diff(poly, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    t = np.linspace(0.0, s[-1], n)
    return np.column_stack([np.interp(t, s, poly[:, k]) for k in range(2)]), t


def _smooth(path: np.ndarray, sigma_px: float, spacing: float) -> np.ndarray:
    """The path resampled every ``spacing`` pixels and smoothed by a Gaussian of ``sigma_px``
    along it; the ends are padded by point reflection, which keeps a straight end straight."""
    length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
    n = max(int(np.ceil(length / spacing)) + 1, 2)
    pts, _ = _resample(path, n)
    sigma = min(sigma_px / spacing, (n - 1) / 4)
    if sigma <= 0.3 or n < 4:
        return pts
    pad = min(int(np.ceil(3 * sigma)), n - 1)
    head = 2 * pts[0] - pts[1:pad + 1][::-1]
    tail = 2 * pts[-1] - pts[-pad - 1:-1][::-1]
    full = np.vstack([head, pts, tail])
    return ndi.gaussian_filter1d(full, sigma, axis=0, mode="nearest")[pad:pad + n]


def _crossings(origins: np.ndarray, directions: np.ndarray,
               polygon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where the line through each origin along its unit direction first crosses the closed
    ``polygon`` (K, 2) ahead of the origin and behind it: distances ``(ahead, behind)``, both
    positive, NaN where there is none.

    Each vertex's side of the line (``side``) and position along it (``along``): an edge whose
    ends lie on opposite sides crosses the line where the side is 0.
    """
    rel0 = polygon[None, :, 0] - origins[:, None, 0]
    rel1 = polygon[None, :, 1] - origins[:, None, 1]
    d0, d1 = directions[:, 0:1], directions[:, 1:2]
    side = d0 * rel1 - d1 * rel0
    along = d0 * rel0 + d1 * rel1
    side_next = np.concatenate([side[:, 1:], side[:, :1]], axis=1)
    along_next = np.concatenate([along[:, 1:], along[:, :1]], axis=1)
    crossing = (side > 0) != (side_next > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = along + (along_next - along) * side / (side - side_next)
    t = np.where(crossing, t, np.nan)
    ahead = np.where(t > 1e-9, t, np.inf).min(axis=1)
    behind = np.where(t < -1e-9, -t, np.inf).min(axis=1)
    ahead[~np.isfinite(ahead)] = np.nan
    behind[~np.isfinite(behind)] = np.nan
    return ahead, behind


def _trim(path: np.ndarray, cut: float) -> np.ndarray:
    """The path without its first and last ``cut`` pixels (of arc length)."""
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    keep = (s >= cut) & (s <= s[-1] - cut)
    return path[keep] if keep.sum() >= 2 else path


def _end_tangent(pts: np.ndarray, reach: float) -> np.ndarray:
    """The unit direction out of the path's last point: the straight line fitted (principal
    direction) to its last ``reach`` pixels."""
    seg = np.linalg.norm(np.diff(pts[::-1], axis=0), axis=1)
    back = np.concatenate([[0.0], np.cumsum(seg)])[::-1]  # distance to the end, per point
    window = pts[back <= reach]
    if len(window) < 2:
        window = pts[-2:]
    d = _principal_direction(window)
    return -d if d @ (pts[-1] - window[0]) < 0 else d


def _principal_direction(pixels: np.ndarray) -> np.ndarray:
    """The unit major axis of a set of points (a round object's midline direction)."""
    centred = pixels - pixels.mean(axis=0)
    _, vecs = np.linalg.eigh(centred.T @ centred)
    return vecs[:, -1]


def _first_is_anterior(points: np.ndarray) -> bool:
    """Whether the midline's first point is the ``"first"`` rule's end: the end nearer the
    top, or the left one when the ends lie more left-right than up-down."""
    d = points[-1] - points[0]
    return bool(d[0] > 0) if abs(d[0]) >= abs(d[1]) else bool(d[1] > 0)


def _nearest_points(points: np.ndarray, cells: np.ndarray, shape: tuple[int, int],
                    origin: np.ndarray, every: int) -> np.ndarray:
    """For each grid cell (``cells``, indices into a grid of ``shape`` whose cell (i, j) is
    the image pixel ``origin + every · (i, j)``), the index of the nearest of ``points``
    rounded to the grid: one Euclidean distance transform (its feature transform) instead of
    a nearest-neighbour query per pixel, a tenth of the cost on a 40,000-pixel object."""
    local = np.rint((points - origin) / every).astype(int)
    local = np.clip(local, 0, np.array(shape) - 1)
    index = np.full(shape, -1, np.intp)
    index[local[:, 0], local[:, 1]] = np.arange(len(points))
    _, (rows, cols) = ndi.distance_transform_edt(index < 0, return_indices=True)
    return index[rows[cells[:, 0], cells[:, 1]], cols[cells[:, 0], cells[:, 1]]]


def _anterior_first(points: np.ndarray, rule: str, first_half: float,
                    second_half: float) -> tuple[str, bool]:
    """The rule applied and whether the midline's first point is its anterior end, given the
    mean reporter over its first and second half (NaN: no reporter)."""
    if rule in ("reporter", "reporter_low"):
        if np.isfinite(first_half) and np.isfinite(second_half) and first_half != second_half:
            return rule, (first_half > second_half) == (rule == "reporter")
        rule = "first"  # nothing to go by
    return rule, _first_is_anterior(points) == (rule == "first")


def _reporter_profile(points: np.ndarray, arc: np.ndarray, pixels: np.ndarray,
                      values: np.ndarray, bins: int,
                      nearest: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Mean reporter in ``bins`` pieces of the midline (each pixel to its ``nearest`` midline
    point), and the mean over the first and the second half of the length (NaN: no finite
    pixel there)."""
    ok = np.isfinite(values)
    if not ok.any():
        return np.full(bins, np.nan), np.nan, np.nan
    pixels, nearest = pixels[ok], nearest[ok]
    # the pixel's own position along the midline: its nearest point's, plus its offset along
    # the midline there (exact on a straight midline; the points are a tenth of a bin apart)
    tangent = np.gradient(points, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    along = arc[nearest] + np.einsum("ij,ij->i", pixels - points[nearest], tangent[nearest])
    where = np.clip(along / max(float(arc[-1]), 1e-12), 0.0, 1.0)
    piece = np.minimum((where * bins).astype(int), bins - 1)
    v = values[ok]
    counts = np.bincount(piece, minlength=bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        profile = np.bincount(piece, v, minlength=bins) / counts
    first, last = v[where < 0.5], v[where >= 0.5]
    return (profile, float(first.mean()) if len(first) else np.nan,
            float(last.mean()) if len(last) else np.nan)


def midline(result, intensity: np.ndarray | None = None, *, bins: int = 10,
            anterior: str = "reporter", pixel_size: float = 1.0,
            intensity_offset: tuple[float, float] = (0.0, 0.0),
            samples_across: int | None = MIDLINE_SAMPLES_ACROSS) -> Midline:
    """The midline of a 2-D object and the widths and reporter along it (module docstring).

    Parameters
    ----------
    result : PFSDMResult
        The object (:func:`~napari_pfsdm.core.descriptor.pfsdm`). Its skeleton is traced
        here, on the midline's own grid (``samples_across``), without its disk points: the
        table and the pictures then give the same midline.
    intensity : ndarray (Y, X), optional
        The reporter, raw (its own units), over pixels whose ``[0, 0]`` sits at
        ``intensity_offset`` in the result's image coordinates.
    bins : int
        Pieces of the length for the width and reporter profiles.
    anterior : {"reporter", "reporter_low", "first", "last"}
        Which end comes first (module docstring).
    pixel_size : float
        Size of a pixel; lengths and widths are multiplied by it.
    intensity_offset : (float, float)
        Image coordinates of ``intensity[0, 0]``: the ``offset`` given to ``pfsdm`` when the
        intensity covers the same pixels as its mask (default: the origin).
    samples_across : int or None
        At most this many skeleton samples along the longer side of the object's box
        (:data:`MIDLINE_SAMPLES_ACROSS`; None: every pixel).

    Returns
    -------
    Midline

    Examples
    --------
    >>> from napari_pfsdm.core.descriptor import pfsdm
    >>> yy, xx = np.mgrid[:81, :141]
    >>> ellipse = ((yy - 40) / 25) ** 2 + ((xx - 70) / 60) ** 2 <= 1
    >>> m = midline(pfsdm(ellipse), bins=4)
    >>> round(m.length), round(m.width_max), m.anterior
    (120, 50, 'first')
    """
    if anterior not in ANTERIOR_RULES:
        raise InputError(f"anterior must be one of {', '.join(ANTERIOR_RULES)}; got "
                         f"{anterior!r}.")
    bins = int(bins)
    if bins < 1:
        raise InputError(f"bins must be a whole number of at least 1; got {bins}.")
    info = result.mask_info
    sk = skeleton(result, samples_across=samples_across, disk=False)
    step = int(sk.step)
    polygon = np.asarray(result.contour.points, float)
    # the smooth outline's vertices at most ~a grid step apart are enough for the rays (the
    # chord of a vertex pair then strays < 0.01 px from an outline 14 px in radius)
    spacing = float(np.linalg.norm(np.diff(polygon, axis=0), axis=1).mean())
    polygon = polygon[::max(1, int(step / max(spacing, 1e-12)))]
    # the object's pixels: every one up to 512 across, as the pictures' skeleton samples them
    every = grid_step(info.mask.shape, SAMPLES_ACROSS)
    sampled = info.mask[::every, ::every]
    cells = np.argwhere(sampled)
    pixels = cells * every + np.asarray(info.offset, float)

    full = _axis(sk, pixels, polygon)
    points, arc = _resample(full, SAMPLES_PER_BIN * bins + 1)
    normals, sides, width = _widths(points, polygon)
    values = None if intensity is None else _pixel_values(intensity, pixels, intensity_offset)

    # which end is anterior; the profiles then run from it
    reporter_bins, halves = None, (np.nan, np.nan)
    if values is not None:
        nearest = _nearest_points(points, cells, sampled.shape,
                                  np.asarray(info.offset, float), every)
        reporter_bins, *halves = _reporter_profile(points, arc, pixels, values, bins, nearest)
    rule, keep = _anterior_first(points, anterior, *halves)
    if not keep:
        points, normals, width, sides = points[::-1], normals[::-1], width[::-1], sides[::-1]
        arc = arc[-1] - arc[::-1]
        if reporter_bins is not None:
            reporter_bins = reporter_bins[::-1]

    scale = float(pixel_size)
    arc, width = arc * scale, width * scale
    per_bin = width.reshape(-1)[:-1].reshape(bins, SAMPLES_PER_BIN)
    nxt = np.append(per_bin[1:, 0], width[-1])
    width_bins = (per_bin.sum(axis=1) - 0.5 * per_bin[:, 0] + 0.5 * nxt) / SAMPLES_PER_BIN
    angle_image, angle_midline = (np.nan, np.nan) if values is None else \
        _polarity_angles(pixels, values, points)
    return Midline(points=points, arc=arc, width=width, normals=normals, width_bins=width_bins,
                   reporter_bins=reporter_bins, anterior=rule,
                   polarity_angle_image=angle_image, polarity_angle_midline=angle_midline,
                   pixel_size=scale, sides=sides)


def _axis(sk: Skeleton, pixels: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """The object's axis as points in image (row, col): the skeleton's main path, its hooked
    ends cut, smoothed, and extended straight along its end tangents to the outline
    ``polygon``; a roundish object's (skeleton no longer than its half-width) the pixels'
    major axis through their centre."""
    step = int(sk.step)
    depth = float(np.median(sk.depth)) if len(sk.depth) else 1.0
    path = main_path(sk)
    plen = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum()) if len(path) > 1 else 0.0
    if plen < max(2.0 * step, depth):
        centre = pixels.mean(axis=0)
        d = _principal_direction(pixels)
        path = np.vstack([centre - 1e-3 * d, centre + 1e-3 * d])
        head_dir, tail_dir = -d, d
    else:
        # the last pixels of a raster skeleton often hook to one side (a pruned fork, a grid
        # step): cut them before smoothing, the straight extension replaces them
        path = _trim(path, min(1.0 * step, plen / 4))
        path = _smooth(path, sigma_px=2.0 * step, spacing=0.5 * step)
        plen = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
        reach = float(np.clip(depth, 3.0 * step, plen / 3))
        tail_dir = _end_tangent(path, reach)
        head_dir = _end_tangent(path[::-1], reach)
    ends = np.vstack([path[0], path[-1]])
    t, _ = _crossings(ends, np.vstack([head_dir, tail_dir]), polygon)
    t = np.where(np.isfinite(t), t, 0.0)
    return np.vstack([path[0] + t[0] * head_dir, path, path[-1] + t[1] * tail_dir])


def _widths(points: np.ndarray, polygon: np.ndarray) -> tuple[np.ndarray, ...]:
    """(normals, the distances to the outline on either side, the widths) at the axis'
    ``points``: chords along the normal, 0 at the two ends."""
    tangent = np.gradient(points, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    normals = np.column_stack([tangent[:, 1], -tangent[:, 0]])
    ahead, behind = _crossings(points, normals, polygon)
    sides = np.column_stack([ahead, behind])
    sides[[0, -1]] = 0.0
    sides = np.where(np.isfinite(sides), sides, 0.0)
    return normals, sides, sides.sum(axis=1)


def _pixel_values(intensity: np.ndarray, pixels: np.ndarray,
                  offset: tuple[float, float]) -> np.ndarray:
    """The reporter at the object's ``pixels`` (image coordinates; ``intensity[0, 0]`` at
    ``offset``): NaN outside the image and where it is not finite."""
    image = np.asarray(intensity, float)
    idx = np.rint(pixels - np.asarray(offset, float)).astype(int)
    inside = np.all((idx >= 0) & (idx < image.shape), axis=1)
    values = np.full(len(pixels), np.nan)
    values[inside] = image[idx[inside, 0], idx[inside, 1]]
    values[~np.isfinite(values)] = np.nan
    return values


def _polarity_angles(pixels: np.ndarray, values: np.ndarray,
                     points: np.ndarray) -> tuple[float, float]:
    """The direction of the reporter's centre of mass from the object's centre: in the image
    (degrees, 0 towards +x, counter-clockwise as shown) and against the axis from its first
    to its last point (0–180 degrees); NaN without positive reporter or offset."""
    ok = np.isfinite(values)
    w = np.clip(values[ok], 0, None)
    if w.sum() <= 0:
        return np.nan, np.nan
    offset = (pixels[ok] * w[:, None]).sum(axis=0) / w.sum() - pixels.mean(axis=0)
    if np.linalg.norm(offset) <= 1e-12:
        return np.nan, np.nan
    angle_image = float(np.degrees(np.arctan2(-offset[0], offset[1])))
    chord = points[-1] - points[0]
    cos = offset @ chord / (np.linalg.norm(offset) * np.linalg.norm(chord))
    return angle_image, float(np.degrees(np.arccos(np.clip(cos, -1, 1))))
