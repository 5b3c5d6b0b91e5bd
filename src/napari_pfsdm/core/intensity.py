"""The intensity under one object, for the descriptor of 2-D and 3-D objects alike."""

from __future__ import annotations

import numpy as np

from ..errors import InputError

__all__ = ["intensity_crop"]


def intensity_crop(intensity: np.ndarray, offset: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The intensity over a prepared mask's box, divided by the object's mean intensity.

    Parameters
    ----------
    intensity : ndarray
        The whole image (2-D) or volume (3-D).
    offset : ndarray of int
        Position of ``mask[0, ...]`` in ``intensity`` (may be negative: the box may stick out
        of the image, whose edge values are then repeated).
    mask : ndarray of bool
        The object in its box.

    Raises
    ------
    ValueError
        NaN inside the object, or a mean intensity that is not positive (plain words).
    """
    intensity = np.asarray(intensity)
    lo = np.asarray(offset).astype(int)
    hi = lo + np.array(mask.shape)
    a = np.maximum(lo, 0)
    b = np.minimum(hi, intensity.shape)
    crop = np.asarray(intensity[tuple(slice(i, j) for i, j in zip(a, b, strict=True))], float)
    crop = np.pad(crop, [(int(i - j), int(k - m)) for i, j, k, m in zip(a, lo, hi, b,
                                                                         strict=True)],
                  mode="edge")
    values = crop[mask]
    n_nan = int(np.isnan(values).sum())
    if n_nan:
        what, unit = ("volume", "voxel") if mask.ndim == 3 else ("image", "pixel")
        raise InputError(
            f"The intensity {what} has {n_nan} NaN {unit}(s) inside the object. Replace them "
            "(for example with numpy.nan_to_num or an interpolation) before measuring."
        )
    mean = float(values.mean())
    if not mean > 0:
        raise InputError(
            f"The object's mean intensity is {mean:.3g}; the intensity descriptor is "
            "normalised by it and needs a positive signal (subtract less background)."
        )
    return np.nan_to_num(crop / mean)
