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
from functools import lru_cache

import numpy as np

from ..errors import InputError
from . import fourier
from .choices import DEFAULT_MIN_AREA
from .marching_squares import _trace, outer_boundary, trace_boundary
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
    trace = _trace(crop.view(np.uint8), 0.0) if pad > 0 else trace_boundary(crop)
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
    z, length = _resample_z(_as_z(points), n)
    return _as_xy(z), length


def _as_z(points: np.ndarray) -> np.ndarray:
    """Points (K, 2) as complex numbers first axis + i·second (a view when contiguous)."""
    points = np.ascontiguousarray(points, dtype=float)
    return points.view(complex).reshape(len(points))


def _as_xy(z: np.ndarray) -> np.ndarray:
    """Complex numbers (K,) as points (K, 2) (a view)."""
    return np.ascontiguousarray(z).view(float).reshape(len(z), 2)


def _resample_z(z: np.ndarray, n: int) -> tuple[np.ndarray, float]:
    """:func:`resample_closed` of a closed polyline given as complex numbers (K,), and its
    length."""
    closed = np.concatenate((z, z[:1]))
    s = np.empty(len(closed))
    s[0] = 0.0
    np.cumsum(np.abs(closed[1:] - closed[:-1]), out=s[1:])
    return np.interp(_arange(n) * (s[-1] / n), s, closed), float(s[-1])


@lru_cache(maxsize=16)
def _arange(n: int) -> np.ndarray:
    """``np.arange(n)`` as floats (read-only)."""
    out = np.arange(n, dtype=float)
    out.flags.writeable = False
    return out


def _smooth_closed(points: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian low-pass of a uniformly sampled closed curve; ``sigma`` in samples."""
    if sigma <= 0:
        return points
    return _as_xy(_smooth_z(_as_z(points), sigma))


def _smooth_z(z: np.ndarray, sigma: float) -> np.ndarray:
    """:func:`_smooth_closed` of a curve given as complex numbers (M,)."""
    gain = np.exp(_minus_two_pi2_freq2(len(z)) * (sigma * sigma))
    spectrum = fourier.fft(z)
    spectrum *= gain
    return fourier.ifft(spectrum)


@lru_cache(maxsize=16)
def _minus_two_pi2_freq2(n: int) -> np.ndarray:
    """−2π² f² at the ``fftfreq`` frequencies f of n samples (read-only): the Gaussian's gain
    exp(−2 (π f σ)²) is exp(σ² · this)."""
    out = -2.0 * (np.pi * np.fft.fftfreq(n)) ** 2
    out.flags.writeable = False
    return out


def _area_centroid_z(z: np.ndarray) -> tuple[float, complex]:
    """:func:`polygon_area_centroid` of a closed polygon given as complex numbers (K,)."""
    zn = np.empty_like(z)
    zn[:-1] = z[1:]
    zn[-1] = z[0]
    cross = (z.conj() * zn).imag  # x·y_next − x_next·y
    area = 0.5 * cross.sum()
    zn += z
    return float(area), complex(np.dot(zn, cross) / (6.0 * area))


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
    nxt = np.concatenate([points[1:], points[:1]])
    x, y = points[:, 0], points[:, 1]
    xn, yn = nxt[:, 0], nxt[:, 1]
    cross = x * yn - xn * y
    area = 0.5 * cross.sum()
    both = points + nxt  # (x + xn, y + yn)
    cx = (both[:, 0] * cross).sum() / (6.0 * area)
    cy = (both[:, 1] * cross).sum() / (6.0 * area)
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
    z = _as_z(raw)
    # (the centroid to the last bit as ever: it decides between vertices equally far from it)
    area, raw_center = polygon_area_centroid(raw)
    if area < 0:
        z = z[::-1]
    # Start at the vertex farthest from the centroid: a canonical point, so that a raster rotated
    # by 90° or mirrored is resampled at exactly the same boundary points.
    d = z - complex(raw_center[0], raw_center[1])
    far = int(np.argmax(d.real * d.real + d.imag * d.imag))
    z = np.concatenate([z[far:], z[:far]])
    z, perimeter = _resample_z(z, n_points)
    if smooth > 0:
        z = _resample_z(_smooth_z(z, smooth * n_points / perimeter), n_points)[0]
    z += complex(info.offset[0], info.offset[1])
    area, center = _area_centroid_z(z)
    d = z - center
    scale = float(np.sqrt((d.real * d.real + d.imag * d.imag).max()))
    return Contour(points=_as_xy(z), center=np.array([center.real, center.imag]), scale=scale,
                   area=abs(area))
