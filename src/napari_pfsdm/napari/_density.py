"""Many points as one picture: the plots' view of tens of thousands of objects.

Above :data:`~napari_pfsdm.napari._plots.MANY_POINTS` points a scatter plot costs matplotlib
a draw proportional to the points (50,000 markers: 150 ms of the GUI thread at every full
draw, on top of the ~35 ms of its axes). :func:`density_image` bins the points into a small
RGBA image instead: each pixel has the mean colour of the points in it and an opacity that
grows with their number, so dense regions stand out and the colour (frame, group) still
reads. Drawing that image costs the same for 5,000 or 50,000 points. Pure numpy; no GUI.
"""

from __future__ import annotations

import numpy as np

#: Pixels of the density image along each axis (the plot's axes are ~250-400 px wide: a
#: point is a visible dot of 2-3 screen pixels).
DENSITY_BINS = 150
#: Opacity of a pixel holding one point; pixels with the most points are opaque.
MIN_ALPHA = 0.45


def padded_extent(x: np.ndarray, y: np.ndarray, pad: float = 0.05
                  ) -> tuple[float, float, float, float]:
    """(x0, x1, y0, y1) around the finite points, ``pad`` of the range on each side (a unit
    box around a single point or none)."""
    ok = np.isfinite(x) & np.isfinite(y)
    if not ok.any():
        return -1.0, 1.0, -1.0, 1.0
    lo = np.array([x[ok].min(), y[ok].min()], float)
    hi = np.array([x[ok].max(), y[ok].max()], float)
    span = hi - lo
    span = np.where(span > 0, span, 1.0)
    lo, hi = lo - pad * span, hi + pad * span
    return float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])


def density_image(x: np.ndarray, y: np.ndarray, colors: np.ndarray,
                  extent: tuple[float, float, float, float], bins: int = DENSITY_BINS,
                  ) -> np.ndarray:
    """An RGBA image of points: mean colour per pixel, opacity by count.

    Parameters
    ----------
    x, y : ndarray, shape (n,)
        Point coordinates; non-finite points are left out.
    colors : ndarray, shape (n, 3) or (n, 4)
        Each point's colour (RGB(A) in 0..1; alpha is ignored).
    extent : (x0, x1, y0, y1)
        The data area the image covers (as for ``imshow(extent=...)``).
    bins : int
        Pixels along each axis.

    Returns
    -------
    ndarray, shape (bins, bins, 4), float
        Row 0 at ``y0`` (draw with ``origin="lower"``). Empty pixels are fully transparent;
        a pixel of ``k`` points has opacity ``MIN_ALPHA`` (one point) to 1 (the most), on a
        log scale.

    Examples
    --------
    >>> img = density_image(np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, 1.0]),
    ...                     np.array([[1, 0, 0], [0, 0, 1], [0, 1, 0]], float),
    ...                     (0.0, 1.0, 0.0, 1.0), bins=2)
    >>> img[0, 0].tolist()  # two points: mean of red and blue, the most points: opaque
    [0.5, 0.0, 0.5, 1.0]
    >>> float(img[1, 1, 3]) == MIN_ALPHA  # one point
    True
    """
    x0, x1, y0, y1 = extent
    ok = np.isfinite(x) & np.isfinite(y)
    ix = np.clip(((x[ok] - x0) / (x1 - x0) * bins).astype(np.int64), 0, bins - 1)
    iy = np.clip(((y[ok] - y0) / (y1 - y0) * bins).astype(np.int64), 0, bins - 1)
    flat = iy * bins + ix
    count = np.bincount(flat, minlength=bins * bins).astype(float)
    rgb = np.asarray(colors, float)[ok, :3]
    image = np.zeros((bins * bins, 4))
    filled = count > 0
    for ch in range(3):
        total = np.bincount(flat, weights=rgb[:, ch], minlength=bins * bins)
        image[filled, ch] = total[filled] / count[filled]
    if filled.any():
        top = np.log1p(count.max())
        scale = np.log1p(count[filled]) - np.log1p(1.0)
        span = top - np.log1p(1.0)
        image[filled, 3] = MIN_ALPHA + (1 - MIN_ALPHA) * (scale / span if span > 0 else 1.0)
    return image.reshape(bins, bins, 4)
