"""Cleaning a cropped object mask, in 2-D or 3-D: the largest piece, holes filled
(docs/design.md §2.1; 3-D: §6). Shared by :func:`~napari_pfsdm.core.contour.prepare_mask` and
:func:`~napari_pfsdm.core.volume_sdf.prepare_volume`.

The object's pieces are fully connected (8 neighbours in 2-D, 26 in 3-D); the background is
face-connected (4 or 6), its dual, so that a hole is a background region the object encloses.
"""

from __future__ import annotations

import contextlib
import contextvars
import warnings
from collections.abc import Iterator

import numpy as np
from scipy import ndimage as ndi

from ..errors import InputError

__all__ = ["fill_holes", "largest_piece", "quietly"]

# per thread (each thread has its own context): ``warnings.catch_warnings`` changes the filters
# of every thread, so a measurement in a worker thread would hide or swallow the main thread's
# warnings while it runs
_QUIET: contextvars.ContextVar[bool] = contextvars.ContextVar("pfsdm_quiet_pieces",
                                                              default=False)


@contextlib.contextmanager
def quietly() -> Iterator[None]:
    """Within this block, in this thread only, :func:`largest_piece` keeps the largest piece
    without warning (the callers record the number of pieces in the table instead)."""
    token = _QUIET.set(True)
    try:
        yield
    finally:
        _QUIET.reset(token)


def largest_piece(crop: np.ndarray, components: str = "largest",
                  unit: str = "pixels") -> tuple[np.ndarray, int]:
    """The largest fully connected piece of a boolean mask, and how many pieces it had.

    Parameters
    ----------
    crop : ndarray of bool
        The object (2-D or 3-D).
    components : {"largest", "raise"}
        With several pieces: keep the largest and warn, or raise ``ValueError``.
    unit : str
        "pixels" or "voxels", for the messages.

    Returns
    -------
    piece : ndarray of bool
        ``crop`` itself when it is one piece.
    n_pieces : int
    """
    lab, n_pieces = ndi.label(crop, structure=np.ones((3,) * crop.ndim, bool))
    if n_pieces <= 1:
        return crop, int(n_pieces)
    sizes = np.bincount(lab.ravel())[1:]
    if components == "raise":
        raise InputError(
            f"The object has {n_pieces} separate pieces (sizes {sorted(sizes.tolist())[::-1]} "
            f"{unit}). Give each piece its own label, or use components='largest'."
        )
    if components != "largest":
        raise InputError(f"components must be 'largest' or 'raise', got {components!r}.")
    if _QUIET.get():
        return lab == (np.argmax(sizes) + 1), int(n_pieces)
    # stacklevel as before the move: from prepare_mask, the caller of pfsdm (2-D); from
    # prepare_volume, pfsdm (3-D, through pfsdm3d)
    warnings.warn(f"The object has {n_pieces} separate pieces; only the largest "
                  f"({sizes.max()} of {sizes.sum()} {unit}) is described.", stacklevel=4)
    return lab == (np.argmax(sizes) + 1), int(n_pieces)


def fill_holes(crop: np.ndarray) -> tuple[np.ndarray, int]:
    """The mask with its holes filled, and how many there were. ``crop`` must have background
    all around (a padded crop): the background piece at ``crop[0, 0(, 0)]`` is the outside."""
    background, n_background = ndi.label(~crop)  # face-connected: the dual of full
    return background != background[(0,) * crop.ndim], int(n_background) - 1
