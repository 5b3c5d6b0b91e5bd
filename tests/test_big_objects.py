"""Big objects: the skeleton and the pictures on a coarser grid, against every pixel.

A big object's skeleton is traced on a grid of at most ``SAMPLES_ACROSS`` (512) samples across
its box (:func:`napari_pfsdm.core.medial_axis.grid_step`); ``samples_across=None`` traces every
pixel, as before. Bounds pinned here, on objects of 0.4–0.7 megapixels (grid steps 2–3 px):

* the skeleton: the mean distance from each skeleton's points to the other's branches
  (polylines), both ways, ≤ 2 px; the Hausdorff distance between them ≤ 16 px (branch tips
  are where the two differ most: a tip moves by up to ~8 px at full resolution already when
  the object is shifted by half a pixel); the same number of ends and of branches;
* the pictures: the SDF picture, the disk, the reporter disk and the outline within 1e-3 of
  the object's size (they do not depend on the skeleton's grid: they agree exactly); the
  skeleton drawn on the disk within one disk-picture pixel on average;
* the features: untouched (the skeleton is computed after them, from the same result).
"""

import numpy as np
import pytest

import napari_pfsdm as P
from napari_pfsdm.analysis.pictures import object_pictures
from napari_pfsdm.core.medial_axis import SAMPLES_ACROSS, grid_step, paths_distance, skeleton
from napari_pfsdm.core.params import PFSDMParams
from napari_pfsdm.data.shapes import bent_capsule_mask, three_armed_mask

MEAN_PX = 2.0
HAUSDORFF_PX = 16.0


def _ellipse(a: float = 640.0, b: float = 330.0, turn: float = 0.4) -> np.ndarray:
    n = int(2 * a + 40)
    yy, xx = np.mgrid[:n, :n].astype(float) - n / 2 + 0.3
    c, s = np.cos(turn), np.sin(turn)
    y, x = c * yy - s * xx, s * yy + c * xx
    return (y / a) ** 2 + (x / b) ** 2 < 1


SHAPES = {
    "ellipse": _ellipse,
    "bent capsule": lambda: bent_capsule_mask(500.0, angle=0.7),
    "three arms": lambda: three_armed_mask((1100, 1100), radius=500.0, angle=0.2),
}


@pytest.fixture(scope="module", params=list(SHAPES))
def big(request):
    mask = SHAPES[request.param]()
    res = P.pfsdm(mask)
    return request.param, mask, res, skeleton(res, samples_across=None)


def test_grid_step_puts_at_most_samples_across_along_the_longer_side():
    for side in (1, 100, 511, 512, 513, 1024, 1025, 2160, 2560):
        step = grid_step((side, side // 2 + 1))
        assert len(range(0, side, step)) <= SAMPLES_ACROSS
        assert step == 1 or len(range(0, side, step - 1)) > SAMPLES_ACROSS
    assert grid_step((5000, 5000), None) == 1
    with pytest.raises(ValueError, match="samples_across"):
        grid_step((10, 10), 0)


def test_big_skeleton_lies_within_two_pixels_of_the_full_resolution_one(big):
    name, mask, res, full = big
    sk = res.skeleton  # the default grid
    assert sk.step == grid_step(res.mask_info.mask.shape) > 1, name
    mean, hausdorff = paths_distance(sk.paths("image"), full.paths("image"))
    assert mean <= MEAN_PX, (name, mean)
    assert hausdorff <= HAUSDORFF_PX, (name, hausdorff)
    assert sk.n_end_points == full.n_end_points, name
    assert len(sk.paths()) == len(full.paths()), name
    # the points are the object's pixels, the depth the distance to the outline there
    assert mask[tuple(sk.points.T)].all()
    assert abs(sk.depth.max() - full.depth.max()) <= sk.step
    # consecutive points of a branch are neighbours on the grid: one step apart
    for path in sk.paths("image"):
        assert np.abs(np.diff(path, axis=0)).max() == sk.step


def test_skeleton_of_an_object_up_to_samples_across_is_traced_at_every_pixel():
    res = P.pfsdm(bent_capsule_mask(150.0))
    assert max(res.mask_info.mask.shape) <= SAMPLES_ACROSS
    a, b = res.skeleton, skeleton(res, samples_across=None)
    assert a.step == 1
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.disk_points, b.disk_points)


def test_features_do_not_depend_on_the_skeleton_grid():
    mask = bent_capsule_mask(500.0, angle=0.7)
    res = P.pfsdm(mask)
    before = res.embedding.copy(), res.outline.copy()
    skeleton(res, samples_across=None)
    _ = res.skeleton
    np.testing.assert_array_equal(res.embedding, before[0])
    np.testing.assert_array_equal(res.outline, before[1])
    np.testing.assert_array_equal(P.pfsdm(mask).embedding, before[0])


def test_pictures_of_a_big_object_match_the_full_resolution_ones():
    mask = bent_capsule_mask(500.0, angle=0.7)
    labels = np.zeros((mask.shape[0] + 40, mask.shape[1] + 60), np.uint16)
    labels[20:-20, 30:-30][mask] = 7
    yy, xx = np.mgrid[:labels.shape[0], :labels.shape[1]]
    reporter = 100.0 + 0.1 * xx + 0.05 * yy
    kw = {"params": PFSDMParams(), "axes": "yx"}
    new = object_pictures(labels, reporter, 0, 7, **kw)
    old = object_pictures(labels, reporter, 0, 7, skeleton_samples=None, **kw)
    size = float(P.pfsdm(labels == 7).contour.scale)  # the object's size, in pixels
    assert np.nanmax(np.abs(new.sdf - old.sdf)) / size <= 1e-3
    for a, b in ((new.disk, old.disk), (new.intensity_disk, old.intensity_disk)):
        np.testing.assert_array_equal(np.isnan(a), np.isnan(b))
        assert np.nanmax(np.abs(a - b)) <= 1e-3
    assert np.abs(new.outline - old.outline).max() / size <= 1e-3
    assert (new.sdf_corner, new.sdf_step) == (old.sdf_corner, old.sdf_step)
    mean, hausdorff = paths_distance(new.skeleton_image, old.skeleton_image)
    assert mean <= MEAN_PX and hausdorff <= HAUSDORFF_PX
    assert paths_distance(new.skeleton_disk, old.skeleton_disk)[0] <= 1.0  # disk-picture pixels
    assert not new.notes
