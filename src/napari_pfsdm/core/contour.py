"""Sub-pixel boundary contour of one object, resampled in arc length and normalised.

Step 1 of the method (docs/design.md §2.1): marching squares on the object's bounding box, the
outer boundary oriented counter-clockwise, resampled uniformly in arc length, lightly smoothed
against the pixel staircase, then centred on the area centroid and scaled so that the farthest
boundary point lies on the unit circle.

Coordinates are image coordinates ``(row, col)`` in pixels; "normalised" coordinates are the
same axes after ``(p - center) / scale``. Counter-clockwise means a positive shoelace area in
``(row, col)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from .choices import DEFAULT_MIN_AREA
from .marching_squares import outer_boundary, trace_boundary
from .pieces import fill_holes, largest_piece

__all__ = ["Contour", "MaskInfo", "extract_contour", "polygon_area_centroid", "prepare_mask",
           "resample_closed", "signed_area"]


@dataclass(frozen=True)
class MaskInfo:
    """What :func:`prepare_mask` found and changed in a mask.

    Attributes
    ----------
    mask : ndarray of bool
        The cleaned mask cropped to the object's bounding box plus ``pad`` pixels.
    offset : ndarray, shape (2,)
        Image coordinates ``(row, col)`` of ``mask[0, 0]``.
    area : int
        Pixels of the cleaned object (holes filled).
    n_components : int
        Connected components (8-connectivity) of the input mask.
    n_holes : int
        Enclosed holes that were filled.
    touches_border : bool
        Whether the object touches the edge of the input image (its outline there is the
        image edge, not the object's true edge).
    outline : ndarray, shape (K, 2), optional
        The marching-squares loop of ``mask`` (crop coordinates, :func:`~napari_pfsdm.core.
        marching_squares.outer_boundary`) when :func:`prepare_mask` already traced it.
    """

    mask: np.ndarray
    offset: np.ndarray
    area: int
    n_components: int
    n_holes: int
    touches_border: bool
    outline: np.ndarray | None = field(default=None, repr=False)


@dataclass(frozen=True)
class Contour:
    """A closed boundary, uniformly resampled in arc length.

    Attributes
    ----------
    points : ndarray, shape (M, 2)
        Boundary in image ``(row, col)`` pixel coordinates, counter-clockwise, without the
        closing point.
    center : ndarray, shape (2,)
        Area centroid in image coordinates.
    scale : float
        Pixels per normalised unit: the largest centroid-to-boundary distance.
    area : float
        Area enclosed by the polygon, in pixels².
    """

    points: np.ndarray
    center: np.ndarray
    scale: float
    area: float
    normalized: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "normalized", (self.points - self.center) / self.scale)

    @property
    def length(self) -> float:
        """Perimeter in normalised units."""
        return float(np.linalg.norm(np.diff(self.normalized, axis=0, append=self.normalized[:1]),
                                    axis=1).sum())

    def to_image(self, points: np.ndarray) -> np.ndarray:
        """Convert normalised ``(row, col)`` points to image pixel coordinates."""
        return np.asarray(points) * self.scale + self.center


def prepare_mask(
    mask: np.ndarray,
    *,
    components: str = "largest",
    min_area: int = DEFAULT_MIN_AREA,
    pad: int = 2,
) -> MaskInfo:
    """Validate a 2-D object mask, crop it and clean it for contour extraction.

    Parameters
    ----------
    mask : array_like of bool, shape (Y, X)
        The object (``labels == id``).
    components : {"largest", "raise"}
        What to do when the object has several disconnected pieces: keep the largest and warn
        (default), or raise a ``ValueError``.
    min_area : int
        Objects with fewer pixels raise a ``ValueError``.
    pad : int
        Background pixels added around the bounding box.

    Returns
    -------
    MaskInfo

    Raises
    ------
    ValueError
        For an array that is not 2-D, an empty mask, a too small object or, with
        ``components="raise"``, several components.

    Notes
    -----
    Holes are filled: the PF-SDM describes the outer outline (``n_holes`` records how many were
    filled). An object touching the image edge is accepted (the edge becomes its outline) and
    flagged by ``touches_border``.
    """
    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise InputError(
            f"Expected a 2-D mask (Y, X) or a 3-D volume (Z, Y, X) of one object, got an array "
            f"with {mask.ndim} dimensions {mask.shape}. For a time-lapse or a label image use "
            "`measure` (with axes='tyx', 'zyx' or 'tzyx'), which goes through the frames and "
            "labels for you."
        )
    mask = mask.astype(bool, copy=False)
    rows = np.flatnonzero(mask.any(axis=1))
    if rows.size == 0:
        raise InputError("The mask is empty: no pixel belongs to the object.")
    cols = np.flatnonzero(mask.any(axis=0))
    r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    touches = bool(r0 == 0 or c0 == 0 or r1 == mask.shape[0] or c1 == mask.shape[1])
    crop = np.zeros((r1 - r0 + 2 * pad, c1 - c0 + 2 * pad), bool)
    crop[pad:pad + r1 - r0, pad:pad + c1 - c0] = mask[r0:r1, c0:c1]
    trace = trace_boundary(crop)
    if trace.single_loop and not trace.n_saddles:
        # one piece without holes, with 4- and 8-connectivity alike: nothing to label or fill
        return _mask_info(crop, r0 - pad, c0 - pad, 1, 0, touches, min_area, trace.points)
    crop, n_comp = largest_piece(crop, components, "pixels")
    filled, n_holes = fill_holes(crop)
    unchanged = n_comp == 1 and n_holes == 0  # the traced loop is still the mask's
    return _mask_info(filled, r0 - pad, c0 - pad, n_comp, n_holes, touches, min_area,
                      trace.points if unchanged else None)


def _mask_info(filled: np.ndarray, row: int, col: int, n_components: int, n_holes: int,
               touches: bool, min_area: int, outline: np.ndarray | None) -> MaskInfo:
    """The :class:`MaskInfo` of a cleaned crop whose ``[0, 0]`` is image pixel (row, col),
    after the size check."""
    area = int(np.count_nonzero(filled))
    if area < min_area:
        raise InputError(
            f"The object is too small to describe its shape: {area} pixels, the minimum is "
            f"{min_area}. Remove tiny objects from the segmentation (or lower min_area)."
        )
    return MaskInfo(mask=filled, offset=np.array([row, col], float), area=area,
                    n_components=n_components, n_holes=n_holes, touches_border=touches,
                    outline=outline)


def resample_closed(points: np.ndarray, n: int) -> np.ndarray:
    """Resample a closed polyline at ``n`` points equally spaced in arc length.

    Parameters
    ----------
    points : ndarray, shape (K, 2)
        Vertices, without repeating the first one at the end.
    n : int
        Number of output points.

    Returns
    -------
    ndarray, shape (n, 2)
        The first output point is ``points[0]``.
    """
    return _resample(points, n)[0]


def _resample(points: np.ndarray, n: int) -> tuple[np.ndarray, float]:
    """:func:`resample_closed` and the polyline's length."""
    closed = np.concatenate([points, points[:1]])
    step = np.diff(closed, axis=0)
    s = np.empty(len(closed))
    s[0] = 0.0
    np.cumsum(np.sqrt(step[:, 0] ** 2 + step[:, 1] ** 2), out=s[1:])
    t = np.arange(n) * (s[-1] / n)
    out = np.empty((n, 2))
    out[:, 0] = np.interp(t, s, closed[:, 0])
    out[:, 1] = np.interp(t, s, closed[:, 1])
    return out, float(s[-1])


def _smooth_closed(points: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian low-pass of a uniformly sampled closed curve; ``sigma`` in samples."""
    if sigma <= 0:
        return points
    n = len(points)
    freq = np.fft.fftfreq(n)
    gain = np.exp(-2.0 * (np.pi * freq * sigma) ** 2)
    return np.real(np.fft.ifft(np.fft.fft(points, axis=0) * gain[:, None], axis=0))


def signed_area(points: np.ndarray) -> float:
    """Shoelace area of a closed polygon (k, 2): positive when its vertices turn from the first
    axis towards the second (counter-clockwise in (x, y); clockwise on screen in (row, col)).
    The package's one polygon area.

    Examples
    --------
    >>> signed_area(np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]]))
    2.0
    """
    x, y = points[:, 0], points[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def polygon_area_centroid(points: np.ndarray) -> tuple[float, np.ndarray]:
    """Signed shoelace area (as :func:`signed_area`) and area centroid of a closed polygon
    (k, 2), in the points' own axis order."""
    x, y = points[:, 0], points[:, 1]
    xn, yn = np.concatenate([x[1:], x[:1]]), np.concatenate([y[1:], y[:1]])
    cross = x * yn - xn * y
    area = 0.5 * cross.sum()
    cx = ((x + xn) * cross).sum() / (6.0 * area)
    cy = ((y + yn) * cross).sum() / (6.0 * area)
    return float(area), np.array([cx, cy])


def extract_contour(info: MaskInfo, n_points: int = 256, smooth: float = 1.0) -> Contour:
    """Outer boundary of a prepared mask as a normalised, arc-length resampled contour.

    Parameters
    ----------
    info : MaskInfo
        From :func:`prepare_mask`.
    n_points : int
        Points of the resampled contour.
    smooth : float
        Width (standard deviation, in pixels of arc length) of the Gaussian that removes the
        marching-squares staircase. 0 keeps the raw polygon.

    Returns
    -------
    Contour

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[:64, :64]
    >>> c = extract_contour(prepare_mask((yy - 32) ** 2 + (xx - 30) ** 2 < 20 ** 2))
    >>> bool(np.allclose(c.center, [32, 30], atol=0.1)), round(c.scale)
    (True, 20)
    """
    # the longest loop of skimage's find_contours(mask, 0.5), traced once
    raw = info.outline if info.outline is not None else outer_boundary(info.mask)
    area, raw_center = polygon_area_centroid(raw)
    if area < 0:
        raw = raw[::-1]
    # Start at the vertex farthest from the centroid: a canonical point, so that a raster rotated
    # by 90° or mirrored is resampled at exactly the same boundary points.
    far = int(np.argmax((raw[:, 0] - raw_center[0]) ** 2 + (raw[:, 1] - raw_center[1]) ** 2))
    raw = np.concatenate([raw[far:], raw[:far]])
    pts, perimeter = _resample(raw, n_points)
    if smooth > 0:
        pts = resample_closed(_smooth_closed(pts, smooth * n_points / perimeter), n_points)
    pts += info.offset
    area, center = polygon_area_centroid(pts)
    scale = float(np.sqrt(((pts - center) ** 2).sum(axis=1).max()))
    return Contour(points=pts, center=center, scale=scale, area=abs(area))
