"""Classic measures of each object, in the same table as its PF-SDM features.

The shape measures are scikit-image's (:func:`skimage.measure.regionprops_table`, called, not
rewritten), on **the labelled pixels** of the object in its frame (``labels == label``, every
piece and hole as segmented; not the analysed mask, which keeps the largest piece and fills
holes), so that they agree with napari-skimage-regionprops on the same layer:

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
"""

from __future__ import annotations

import numpy as np

__all__ = ["SHAPE_MEASURES_2D", "SHAPE_MEASURES_3D", "REPORTER_MEASURES", "classic_columns",
           "classic_measures"]

#: regionprops properties of 2-D objects (plus circularity, from area and perimeter).
SHAPE_MEASURES_2D = ("perimeter", "eccentricity", "solidity", "axis_major_length",
                     "axis_minor_length", "circularity")
#: regionprops properties of 3-D objects.
SHAPE_MEASURES_3D = ("solidity", "axis_major_length", "axis_minor_length")
#: The reporter's measures (tables measured with an intensity image).
REPORTER_MEASURES = ("intensity_mean", "intensity_integrated", "intensity_polarity")


def classic_columns(ndim: int = 2, with_intensity: bool = False) -> list[str]:
    """The classic-measure columns of a table, in order."""
    cols = list(SHAPE_MEASURES_3D if ndim == 3 else SHAPE_MEASURES_2D)
    return cols + (list(REPORTER_MEASURES) if with_intensity else [])


def classic_measures(mask: np.ndarray, image: np.ndarray | None = None, *,
                     spacing=None) -> dict[str, float]:
    """The classic measures of one object (module docstring for what each one is).

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
    from skimage.measure import regionprops_table

    mask = np.asarray(mask, bool)
    ndim = mask.ndim
    names = SHAPE_MEASURES_3D if ndim == 3 else SHAPE_MEASURES_2D[:-1]
    kwargs = {}
    if spacing is not None and ndim == 3:
        kwargs["spacing"] = tuple(float(s) for s in spacing)
    out: dict[str, float] = {}
    if mask.any():
        props = regionprops_table(mask.astype(np.uint8), properties=("area", *names), **kwargs)
        out = {k: float(props[k][0]) for k in names}
        if ndim == 2:
            area, perimeter = float(props["area"][0]), out["perimeter"]
            out["circularity"] = 4 * np.pi * area / perimeter**2 if perimeter > 0 else np.nan
    else:
        out = dict.fromkeys(SHAPE_MEASURES_3D if ndim == 3 else SHAPE_MEASURES_2D, np.nan)
    if image is not None:
        out.update(reporter_measures(mask, np.asarray(image, float)))
    return out


def reporter_measures(mask: np.ndarray, image: np.ndarray) -> dict[str, float]:
    """``intensity_mean``, ``intensity_integrated`` and ``intensity_polarity`` of one object
    (finite pixels only)."""
    values = image[mask]
    finite = np.isfinite(values)
    if not finite.any():
        return dict.fromkeys(REPORTER_MEASURES, np.nan)
    coords = np.argwhere(mask)[finite].astype(float)
    v = values[finite]
    total = float(v.sum())
    out = {"intensity_mean": float(v.mean()), "intensity_integrated": total}
    weights = np.clip(v, 0, None)
    if weights.sum() <= 0:
        out["intensity_polarity"] = np.nan
        return out
    centre = coords.mean(axis=0)
    weighted = (coords * weights[:, None]).sum(axis=0) / weights.sum()
    n = float(mask.sum())
    radius = np.sqrt(n / np.pi) if mask.ndim == 2 else np.cbrt(3 * n / (4 * np.pi))
    out["intensity_polarity"] = float(np.linalg.norm(weighted - centre) / max(radius, 1e-12))
    return out
