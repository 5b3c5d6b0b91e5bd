"""The vectorised marching squares against skimage, and prepare_mask's shortcut for masks that
need no labelling (core/marching_squares.py, core/contour.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage as ndi
from skimage.measure import find_contours

from napari_pfsdm.core.contour import prepare_mask
from napari_pfsdm.core.marching_squares import outer_boundary, trace_boundary


def _same_loop(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two closed polygons have the same vertices in the same cyclic order (either
    direction, any start)."""
    if a.shape != b.shape:
        return False
    start = np.flatnonzero((b == a[0]).all(axis=1))
    if start.size != 1:
        return False
    b = np.roll(b, -start[0], axis=0)
    return np.array_equal(a, b) or np.array_equal(a, np.roll(b[::-1], 1, axis=0))


def _skimage_longest(mask: np.ndarray) -> np.ndarray:
    padded = np.pad(mask.astype(float), 1)
    return max(find_contours(padded, 0.5), key=len)[:-1] - 1.0


def _random_masks(n: int, seed: int = 0):
    """Noisy blobs full of saddles, holes, pieces, some touching the array's edge."""
    rng = np.random.default_rng(seed)
    for i in range(n):
        noise = ndi.gaussian_filter(rng.random((40, 48)), 1.0 + (i % 3))
        mask = noise > np.quantile(noise, rng.uniform(0.3, 0.7))
        if i % 4 == 0:
            mask |= rng.random(mask.shape) < 0.05  # salt: isolated pixels, corner contacts
        if mask.any():
            yield mask


def test_outer_boundary_is_skimages_longest_contour():
    n_saddle_masks = 0
    for mask in _random_masks(120):
        ours = outer_boundary(mask)
        assert _same_loop(ours, _skimage_longest(mask))
        n_saddle_masks += trace_boundary(mask).n_saddles > 0
    assert n_saddle_masks > 20  # the comparison did cover saddles


def test_trace_reports_loops_and_saddles():
    square = np.zeros((8, 8), bool)
    square[2:6, 2:6] = True
    trace = trace_boundary(square)
    assert trace.single_loop and trace.n_saddles == 0 and len(trace.points) == 16
    ring = square.copy()
    ring[3:5, 3:5] = False
    assert not trace_boundary(ring).single_loop  # the hole is a second loop
    corner = square.copy()
    corner[6, 6] = True  # touches the square at a corner only
    trace = trace_boundary(corner)
    assert trace.n_saddles == 1 and not trace.single_loop
    assert len(trace.points) == 16  # the square's loop is the longest
    with pytest.raises(ValueError, match="empty"):
        outer_boundary(np.zeros((5, 5), bool))


def _labelled_reference(mask: np.ndarray):
    """prepare_mask's cleaning done the long way: 8-connected pieces, the largest kept, holes
    (4-connected background) filled."""
    lab, n = ndi.label(mask, structure=np.ones((3, 3), bool))
    sizes = np.bincount(lab.ravel())[1:]
    piece = lab == np.argmax(sizes) + 1
    background, n_bg = ndi.label(~np.pad(piece, 1))
    filled = (background != background[0, 0])[1:-1, 1:-1]
    return filled, int(n), int(n_bg) - 1


@pytest.mark.filterwarnings("ignore:The object has")
def test_prepare_mask_shortcut_agrees_with_labelling():
    yy, xx = np.mgrid[:40, :48]
    smooth = [((yy - 20) / a) ** 2 + ((xx - 24) / b) ** 2 < 1 for a, b in ((9, 15), (14, 6))]
    fast = 0
    for mask in [*smooth, *_random_masks(80, seed=1)]:
        if np.count_nonzero(mask) < 20:
            continue
        info = prepare_mask(mask)
        filled, n_comp, n_holes = _labelled_reference(mask)
        r0, c0 = info.offset.astype(int)
        full = np.zeros((mask.shape[0] + 4, mask.shape[1] + 4), bool)
        full[r0 + 2:r0 + 2 + info.mask.shape[0], c0 + 2:c0 + 2 + info.mask.shape[1]] = info.mask
        assert np.array_equal(full[2:-2, 2:-2], filled)
        assert (info.n_components, info.n_holes, info.area) == (n_comp, n_holes,
                                                                int(filled.sum()))
        if info.outline is not None:  # the traced loop is the cleaned mask's own
            assert _same_loop(info.outline, outer_boundary(info.mask))
            fast += 1
    assert fast >= 2
