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
        NaN or ±inf inside the object, or a mean intensity that is not positive (plain
        words). Non-finite pixels around the object, in its box, count as 0.
    """
    intensity = np.asarray(intensity)
    lo = np.asarray(offset).astype(int)
    hi = lo + np.array(mask.shape)
    a = np.maximum(lo, 0)
    b = np.minimum(hi, intensity.shape)
    crop = np.asarray(intensity[tuple(slice(i, j) for i, j in zip(a, b, strict=True))], float)
    widths = [(int(i - j), int(k - m)) for i, j, k, m in zip(a, lo, hi, b, strict=True)]
    if any(before or after for before, after in widths):  # (np.pad costs ~20 µs even for none)
        crop = np.pad(crop, widths, mode="edge")
    _refuse_non_finite(crop[mask], mask.ndim)
    mean = float(crop[mask].mean())
    if not mean > 0:
        raise InputError(
            f"The object's mean intensity is {mean:.3g}; the intensity descriptor is "
            "normalised by it and needs a positive signal (subtract less background)."
        )
    # pixels around the object (its box, reached by the interpolation at the outline) that
    # are not finite count as no signal
    return np.where(np.isfinite(crop), crop / mean, 0.0)


def _refuse_non_finite(values: np.ndarray, ndim: int) -> None:
    """Raise, in plain words, when the intensity under an object holds NaN or ±inf pixels.

    Such an object's intensity features would be meaningless (a mean of inf makes every
    relative intensity 0 or NaN): the caller leaves them empty (NaN) and says why in the
    row's ``warnings``; the shape features do not depend on the reporter and are kept.
    """
    bad = ~np.isfinite(values)
    if not bad.any():
        return
    kinds = [(int(np.isnan(values).sum()), "NaN"), (int(np.isposinf(values).sum()), "+inf"),
             (int(np.isneginf(values).sum()), "-inf")]
    counts = ", ".join(f"{n} {word}" for n, word in kinds if n)
    what, unit = ("volume", "voxel") if ndim == 3 else ("image", "pixel")
    raise InputError(
        f"The intensity {what} has non-finite {unit}s inside the object ({counts}). Replace "
        "them (for example with numpy.nan_to_num or an interpolation) before measuring."
    )
