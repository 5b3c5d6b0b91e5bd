"""Classic measures of each object, in the same table as its PF-SDM features.

The shape measures are scikit-image's (:func:`skimage.measure.regionprops_table`'s numbers;
in 2-D computed without its per-object machinery by :func:`shape_measures_2d`, the same
perimeter and solidity exactly, the axes and eccentricity to ~1e-15, tested against it), on
**the labelled pixels** of the object in its frame (``labels == label``, every piece and hole
as segmented; not the analysed mask, which keeps the largest piece and fills holes), so that
they agree with napari-skimage-regionprops on the same layer:

- 2-D: ``perimeter``, ``eccentricity``, ``solidity``, ``axis_major_length``,
  ``axis_minor_length`` (pixels), and ``circularity`` = 4π·area / perimeter² (1 for a disk,
  smaller for elongated or ragged outlines; ``area`` is already the table's pixel count).
- 3-D (objects of Z-stacks, with the voxel size): ``solidity``, ``axis_major_length``,
  ``axis_minor_length`` (in the units of the spacing); regionprops has no perimeter or
  eccentricity in 3-D.

With a reporter image, on the labelled pixels whose intensity is finite:

- ``intensity_mean``, ``intensity_integrated`` (the sum);
- ``intensity_polarity``: how far the reporter's centre of mass lies from the object's own
  centre, in object radii (the radius of the disk, or ball, of the object's area or volume):
  0 when the reporter is spread evenly or symmetrically, towards 0.5–1 when it sits at one
  pole (a gastruloid's Brachyury at its posterior end). NaN when the object has no finite
  positive intensity.

After them, the object's own axis (:func:`midline_measures`, :mod:`napari_pfsdm.core.midline`,
2-D objects; NaN for 3-D ones and for objects without features): ``midline_length``,
``width_mean``, ``width_max`` and the width profile ``width_bXX`` (``profile_bins`` pieces of
the midline from its anterior end), in pixels; with a reporter, its profile ``reporter_bXX``
(the image's units) and the direction of its polarity, ``polarity_angle_image`` and
``polarity_angle_midline`` (degrees). Unlike the measures above they are taken on the analysed
object (the largest piece, holes filled), whose skeleton they follow.
"""

from __future__ import annotations

import numpy as np

from ..core.columns import Column, Family

__all__ = ["FORM_MEASURES_2D", "MIDLINE_COLUMNS", "REPORTER_COLUMNS", "REPORTER_MEASURES",
           "SHAPE_COLUMNS_2D", "SHAPE_COLUMNS_3D", "SHAPE_MEASURES_2D", "SHAPE_MEASURES_3D",
           "classic_measures", "convex_area", "midline_measures", "perimeter_4",
           "reporter_measures", "shape_measures", "shape_measures_2d"]

_AXES = ("axis_major_length", "major axis of the ellipse of the same second moments"), \
    ("axis_minor_length", "minor axis of the ellipse of the same second moments")
_SOLIDITY = Column("solidity", "area / area of the convex hull (1: no indentation)")
#: The columns of the 2-D shape measures (regionprops' properties, plus circularity).
SHAPE_COLUMNS_2D = (
    Column("perimeter", "perimeter (scikit-image's regionprops)", "length"),
    Column("eccentricity", "eccentricity of the ellipse of the same second moments (0: a "
                           "disk)"),
    _SOLIDITY,
    *(Column(name, words, "length") for name, words in _AXES),
    Column("circularity", "4π·area / perimeter² (1 for a disk, smaller when elongated or "
                          "ragged)"),
)
#: The columns of the 3-D shape measures.
SHAPE_COLUMNS_3D = (_SOLIDITY, *(Column(name, words, "length") for name, words in _AXES))
#: The columns of the reporter's measures (tables measured with an intensity image).
REPORTER_COLUMNS = (
    Column("intensity_mean", "mean reporter intensity on the object", "intensity"),
    Column("intensity_integrated", "summed reporter intensity on the object's pixels",
           "intensity"),
    Column("intensity_polarity", "how far the reporter's centre of mass lies from the "
                                 "object's centre, in object radii (0: even; towards 1: at one "
                                 "pole)"),
)
#: The columns of the object's own axis (``profile_bins`` > 0; 2-D objects).
MIDLINE_COLUMNS = (
    Column("midline_length", "length of the object along its own axis: the skeleton's main "
                             "path extended to the outline at both ends", "length"),
    Column("width_mean", "mean width of the object across its midline, over its length "
                         "(area / length for a straight axis)", "length"),
    Column("width_max", "largest width of the object across its midline", "length"),
    Family(r"width_b(\d+)", "width_bXX",
           lambda m: f"mean width across the midline on piece {int(m[1])} of its profile_bins "
                     "equal pieces, counted from the anterior end (0)",
           "mean width across the midline on piece XX of its `profile_bins` equal pieces, "
           "counted from the anterior end (00)", "length"),
    Family(r"reporter_b(\d+)", "reporter_bXX",
           lambda m: f"mean reporter of the object's pixels nearest piece {int(m[1])} of the "
                     "midline's profile_bins equal pieces, counted from the anterior end (0)",
           "mean reporter of the object's pixels nearest piece XX of the midline's "
           "`profile_bins` equal pieces, counted from the anterior end (00)", "intensity"),
    Column("polarity_angle_image", "direction of the reporter's centre of mass from the "
                                   "object's centre in the image (0: towards +x, the columns; "
                                   "counter-clockwise as shown, 90: up)", "degrees"),
    Column("polarity_angle_midline", "angle (0 to 180 degrees) between the reporter's "
                                     "centre-of-mass offset and the midline's anterior-to-"
                                     "posterior direction (0: towards the posterior end, 180: "
                                     "the anterior one)", "degrees"),
)

#: regionprops properties of 2-D objects (plus circularity, from area and perimeter).
SHAPE_MEASURES_2D = tuple(c.name for c in SHAPE_COLUMNS_2D)
#: regionprops properties of 3-D objects.
SHAPE_MEASURES_3D = tuple(c.name for c in SHAPE_COLUMNS_3D)
#: Size and form of a 2-D object by classic measures: what a shape space "beyond the classic
#: measures" regresses out (``ShapePCA(regress_out=FORM_MEASURES_2D)``; the plugin's PCs tab).
FORM_MEASURES_2D = ("area", "circularity", "eccentricity", "solidity", "axis_major_length",
                    "axis_minor_length")
#: The reporter's measures (tables measured with an intensity image).
REPORTER_MEASURES = tuple(c.name for c in REPORTER_COLUMNS)


def classic_measures(mask: np.ndarray, image: np.ndarray | None = None, *,
                     spacing=None) -> dict[str, float]:
    """The classic measures of one object (module docstring for what each one is): its
    :func:`shape_measures` and, with an ``image``, its :func:`reporter_measures`.

    Parameters
    ----------
    mask : ndarray of bool, 2-D or 3-D
        The object's labelled pixels (a crop with a margin is fine).
    image : ndarray, optional
        The reporter on the same crop.
    spacing : sequence of float, optional
        Voxel size (3-D).

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[:101, :101]
    >>> disk = (yy - 50) ** 2 + (xx - 50) ** 2 <= 40 ** 2
    >>> m = classic_measures(disk)
    >>> round(m["axis_major_length"] / 80, 2), round(m["eccentricity"], 2)
    (1.0, 0.0)
    """
    out = shape_measures(mask, spacing=spacing)
    if image is not None:
        out.update(reporter_measures(np.asarray(mask, bool), np.asarray(image, float)))
    return out


def shape_measures(mask: np.ndarray, *, spacing=None) -> dict[str, float]:
    """The shape measures of one object's labelled pixels: :data:`SHAPE_MEASURES_2D`
    (:func:`shape_measures_2d`) or, for a 3-D mask, :data:`SHAPE_MEASURES_3D` from
    ``regionprops_table`` with the voxel ``spacing``; NaN for an empty mask."""
    from skimage.measure import regionprops_table

    mask = np.asarray(mask, bool)
    ndim = mask.ndim
    if not mask.any():
        return dict.fromkeys(SHAPE_MEASURES_3D if ndim == 3 else SHAPE_MEASURES_2D, np.nan)
    if ndim == 2:
        return shape_measures_2d(mask)
    kwargs = {}
    if spacing is not None:
        kwargs["spacing"] = tuple(float(s) for s in spacing)
    props = regionprops_table(mask.astype(np.uint8), properties=("area", *SHAPE_MEASURES_3D),
                              **kwargs)
    return {k: float(props[k][0]) for k in SHAPE_MEASURES_3D}


def shape_measures_2d(mask: np.ndarray) -> dict[str, float]:
    """The 2-D shape measures of one object (:data:`SHAPE_MEASURES_2D`), as
    ``regionprops_table`` gives them, without its per-object machinery (a fifth of its time on
    nucleus-sized objects).

    ``perimeter`` is scikit-image's (:func:`perimeter_4`). The inertia tensor's eigenvalues
    come from the central moments in closed form (regionprops: ``moments_central`` and
    ``eigvalsh``; the same numbers to ~1e-15 relative, ~1e-7 absolute for an eigenvalue that
    is 0, as for a one-pixel-wide line). The convex area, which regionprops counts on
    ``convex_hull_image`` (the pixels whose centres lie in or on the hull of the pixels' edge
    midpoints), is counted row by row in exact integer arithmetic from the hull's edges: the
    same count (:func:`convex_area`).
    """
    r, c = np.nonzero(mask)
    n = r.size
    # the means as ndarray.mean computes them (a float sum divided by n), without its checks
    dr = r - np.add.reduce(r, dtype=float) / n
    dc = c - np.add.reduce(c, dtype=float) / n
    # regionprops' inertia tensor [[mu02, -mu11], [-mu11, mu20]] / mu00, its eigenvalues
    a, b, d = float(dc @ dc) / n, -float(dr @ dc) / n, float(dr @ dr) / n
    mid, radius = 0.5 * (a + d), float(np.hypot(0.5 * (a - d), b))
    l1, l2 = max(mid + radius, 0.0), max(mid - radius, 0.0)
    per = perimeter_4(mask)
    return {
        "perimeter": per,
        "eccentricity": float(np.sqrt(1 - l2 / l1)) if l1 != 0 else 0.0,
        "solidity": n / convex_area(mask, r, c),
        "axis_major_length": 4 * float(np.sqrt(l1)),
        "axis_minor_length": 4 * float(np.sqrt(l2)),
        "circularity": 4 * np.pi * n / per**2 if per > 0 else np.nan,
    }


#: scikit-image's perimeter weights of the codes of :func:`perimeter_4`.
_PERIMETER_WEIGHTS = np.zeros(50)
_PERIMETER_WEIGHTS[[5, 7, 15, 17, 25, 27]] = 1
_PERIMETER_WEIGHTS[[21, 33]] = np.sqrt(2)
_PERIMETER_WEIGHTS[[13, 23]] = (1 + np.sqrt(2)) / 2


def perimeter_4(mask: np.ndarray) -> float:
    """``skimage.measure.perimeter(mask, 4)``, the same number, by array slices instead of
    ``binary_erosion`` and ``convolve``: the border pixels (those with a 4-neighbour outside
    the object), each coded 1 + 2·(border 4-neighbours) + 10·(border diagonal neighbours),
    and the codes' histogram times scikit-image's weights.

    Examples
    --------
    >>> from skimage.measure import perimeter
    >>> disk = np.add.outer(np.arange(-9, 10) ** 2, np.arange(-9, 10) ** 2) <= 64
    >>> bool(perimeter_4(disk) == perimeter(disk, 4))
    True
    """
    h, w = mask.shape
    m = np.zeros((h + 2, w + 2), np.uint8)
    m[1:-1, 1:-1] = mask
    core = m[1:-1, 1:-1]
    border = np.zeros_like(m)
    inner = core & m[:-2, 1:-1]
    inner &= m[2:, 1:-1]
    inner &= m[1:-1, :-2]
    inner &= m[1:-1, 2:]
    np.subtract(core, inner, out=border[1:-1, 1:-1])
    # the border neighbours' counts from sums of pairs: across a row (left + right), then of
    # those across the rows above and below (the diagonals) and down a column
    pairs = border[:, :-2] + border[:, 2:]
    diagonal = pairs[:-2] + pairs[2:]
    diagonal *= 5
    code = border[:-2, 1:-1] + border[2:, 1:-1]
    code += pairs[1:-1]
    code += diagonal
    code *= 2
    code += border[1:-1, 1:-1]
    return float(np.bincount(code.ravel(), minlength=50) @ _PERIMETER_WEIGHTS)


def convex_area(mask: np.ndarray, rows: np.ndarray | None = None,
                cols: np.ndarray | None = None) -> int:
    """Pixels of ``skimage.morphology.convex_hull_image(mask)``: the pixel centres in or on the
    convex hull of the midpoints of the object's pixel edges, i.e. of the hull of its pixel
    centres P grown by the diamond D of radius ½ (hull(P ⊕ D) = hull(P) ⊕ D).

    That polygon is the intersection of the half-planes u · x ≤ h_P(u) + ½ max(|u_r|, |u_c|)
    over the outward normals u of hull(P)'s edges and of D's (and the columns' axis, which
    only supports it); in doubled coordinates every number is an integer, so the count of
    each row's pixels is exact. hull(P)'s sides are the convex minorant of each row's first
    pixel and the concave majorant of each row's last (:func:`_minorant`). ``rows``,
    ``cols``: the object's pixels (``np.nonzero(mask)``) if already known.

    Examples
    --------
    >>> from skimage.morphology import convex_hull_image
    >>> ell = np.zeros((9, 9), bool); ell[1:8, 1:3] = ell[6:8, 1:8] = True
    >>> convex_area(ell), int(convex_hull_image(ell).sum())
    (34, 34)
    """
    if rows is None:
        rows, cols = np.nonzero(mask)
    # each row's first and last pixel (np.nonzero goes row by row): the hull's left side is
    # the convex minorant of the first ones, its right side the concave majorant of the last
    start = np.flatnonzero(rows[1:] != rows[:-1])
    y = rows[:1].tolist() + rows[start + 1].tolist()
    left = _minorant(y, cols[:1].tolist() + cols[start + 1].tolist())
    right = _minorant(y, (-cols[start]).tolist() + [-int(cols[-1])])
    # outward normals (u_r, u_c) of hull(P)'s edges, for 2 u · x <= 2 h_P(u) + max(|u_r|, |u_c|):
    # the left side's (dc, −dr) bound each row's columns from below, the right side's
    # (−dc, dr) from above (on the right side the columns are negated: the same numbers),
    # with the diamond's and the column axis' normals
    below = [(c1 - c0, r0 - r1) for (r0, c0), (r1, c1) in zip(left, left[1:], strict=False)]
    above = [(c1 - c0, r1 - r0) for (r0, c0), (r1, c1) in zip(right, right[1:], strict=False)]
    normal = np.array(above + _ABOVE + below + _BELOW, np.int64).reshape(-1, 2)
    n_above = len(above) + len(_ABOVE)
    corners = np.array(left + [(r, -c) for r, c in right], np.int64)
    k = 2 * (normal @ corners.T).max(axis=1) + np.abs(normal).max(axis=1)
    # on each row y: 2 u_c · col <= k − 2 u_r y
    rhs = k - np.multiply.outer(np.arange(y[0], y[-1] + 1), 2 * normal[:, 0])
    twice = 2 * normal[:, 1]
    upper = (rhs[:, :n_above] // twice[:n_above]).min(axis=1)
    # col >= ceil(rhs / 2u_c) = −((−rhs) // 2u_c) where u_c < 0: the largest of these
    np.negative(rhs[:, n_above:], out=rhs[:, n_above:])
    lower = (rhs[:, n_above:] // twice[n_above:]).min(axis=1)
    upper += lower  # lower is −(the first column in the hull)
    return int(np.maximum(upper + 1, 0).sum())


def _minorant(y: list[int], x: list[int]) -> list[tuple[int, int]]:
    """The vertices (y, x) of the convex minorant of the points (y, x), y increasing (a
    monotone chain: a point on or above the chord from the vertex before it to the next
    point is dropped)."""
    chain: list[tuple[int, int]] = []
    for point in zip(y, x, strict=True):
        py, px = point
        while len(chain) > 1:
            (y0, x0), (y1, x1) = chain[-2], chain[-1]
            if (x1 - x0) * (py - y0) < (px - x0) * (y1 - y0):
                break
            chain.pop()
        chain.append(point)
    return chain


#: The outward normals of the diamond of pixel-edge midpoints around a pixel centre that bound
#: a row's columns from above (u_c > 0) and from below (u_c < 0), with the column axis' (a
#: supporting line of any convex polygon: it closes a hull one column wide). The row axis'
#: normals (u_c = 0) are left out: they bound the rows, and only the object's rows are counted.
_ABOVE = [(1, 1), (-1, 1), (0, 1)]
_BELOW = [(1, -1), (-1, -1), (0, -1)]


def reporter_measures(mask: np.ndarray, image: np.ndarray) -> dict[str, float]:
    """``intensity_mean``, ``intensity_integrated`` and ``intensity_polarity`` of one object
    (finite pixels only)."""
    values = image[mask]
    finite = np.isfinite(values)
    coords = np.transpose(np.nonzero(mask))
    if finite.all():
        v = values
        coords = coords.astype(float)
    elif finite.any():
        v = values[finite]
        coords = coords[finite].astype(float)
    else:
        return dict.fromkeys(REPORTER_MEASURES, np.nan)
    total = float(v.sum())
    out = {"intensity_mean": float(v.mean()), "intensity_integrated": total}
    weights = np.maximum(v, 0)
    weight = weights.sum()
    if weight <= 0:
        out["intensity_polarity"] = np.nan
        return out
    centre = coords.mean(axis=0)
    weighted = (coords * weights[:, None]).sum(axis=0) / weight
    n = float(mask.sum())
    radius = np.sqrt(n / np.pi) if mask.ndim == 2 else np.cbrt(3 * n / (4 * np.pi))
    out["intensity_polarity"] = float(np.linalg.norm(weighted - centre) / max(radius, 1e-12))
    return out


def midline_measures(result, image: np.ndarray | None = None, *,
                     offset: tuple[float, ...] = (0.0, 0.0), bins: int = 10,
                     anterior: str = "reporter") -> dict[str, float]:
    """The midline's columns of one object (:func:`napari_pfsdm.core.midline.midline_columns`):
    NaN for a 3-D object, an object without features (``result`` None) or a midline that
    cannot be traced (a numerical failure costs these columns, never the row).

    Parameters
    ----------
    result : PFSDMResult, PFSDM3DResult or None
    image : ndarray, optional
        The reporter, raw, over the pixels whose ``[0, 0]`` is at ``offset`` in the result's
        image coordinates (the crop :func:`~napari_pfsdm.core.descriptor.pfsdm` was given).
    bins, anterior
        The options ``profile_bins`` and ``anterior``.
    """
    from ..core.descriptor import PFSDMResult
    from ..core.midline import midline, midline_columns

    names = midline_columns(bins, image is not None)
    if not isinstance(result, PFSDMResult):
        return dict.fromkeys(names, np.nan)
    try:
        return midline(result, image, bins=bins, anterior=anterior,
                       intensity_offset=tuple(offset)).columns()
    except (ValueError, RuntimeError, ArithmeticError, IndexError):
        return dict.fromkeys(names, np.nan)
