"""Classic measures in measure's table: scikit-image's regionprops on the labelled pixels, and
the reporter's mean, sum and polarity against hand-worked cases."""

import numpy as np
import pytest
from skimage import data, filters, morphology
from skimage import measure as skm

from napari_pfsdm import measure
from napari_pfsdm.analysis.classic import REPORTER_MEASURES, SHAPE_MEASURES_2D


@pytest.fixture(scope="module")
def coins():
    """skimage's coins, thresholded and labelled: real objects nobody here drew."""
    image = data.coins()
    mask = image > filters.threshold_otsu(image)
    mask = morphology.remove_small_objects(morphology.binary_opening(mask, morphology.disk(2)),
                                           200)
    return skm.label(mask).astype(np.int32), image.astype(float)


def test_shape_measures_agree_with_regionprops_on_the_same_label_image(coins):
    labels, image = coins
    table = measure(labels, image)
    ref = skm.regionprops_table(labels, properties=(
        "label", "area", "perimeter", "eccentricity", "solidity", "axis_major_length",
        "axis_minor_length"))
    by_label = {int(lab): i for i, lab in enumerate(ref["label"])}
    rows = [by_label[int(lab)] for lab in table["label"]]
    assert len(rows) == len(ref["label"]) > 10
    np.testing.assert_array_equal(table["area"], ref["area"][rows])
    for col in ("eccentricity", "solidity", "axis_major_length", "axis_minor_length"):
        np.testing.assert_allclose(table[col], ref[col][rows], rtol=0.03, err_msg=col)
    np.testing.assert_allclose(table["perimeter"], ref["perimeter"][rows], rtol=0.06)
    np.testing.assert_allclose(table["circularity"],
                               4 * np.pi * ref["area"][rows] / ref["perimeter"][rows] ** 2,
                               rtol=0.06)
    # the reporter on the labelled pixels: mean and sum by hand
    for i in (0, len(table) // 2):
        lab = int(table["label"].iat[i])
        pixels = image[labels == lab]
        assert table["intensity_mean"].iat[i] == pytest.approx(pixels.mean())
        assert table["intensity_integrated"].iat[i] == pytest.approx(pixels.sum())
    # the columns sit between the base columns and the features, in the documented order
    cols = list(table.columns)
    start = cols.index("perimeter")
    assert cols[start:start + 9] == [*SHAPE_MEASURES_2D, *REPORTER_MEASURES]
    assert cols.index("warnings") < start < cols.index("shape_r00_n00")


def test_polarity_of_a_reporter_on_half_a_disk_is_4_over_3_pi():
    yy, xx = np.mgrid[:201, :201] - 100.0
    r = 80.0
    labels = (yy**2 + xx**2 <= r**2).astype(np.uint8)
    even = np.ones(labels.shape)
    half = (xx > 0).astype(float)  # all the reporter on one side
    t_even = measure(labels, even)
    t_half = measure(labels, half)
    assert t_even["intensity_polarity"].iat[0] == pytest.approx(0.0, abs=1e-9)
    # closed form: the centroid of a half-disk lies 4r/(3π) from the centre; in radii
    assert t_half["intensity_polarity"].iat[0] == pytest.approx(4 / (3 * np.pi), rel=0.02)


def test_reporter_measures_skip_nan_pixels_and_shapes_have_no_reporter_columns():
    labels = np.zeros((64, 64), np.uint8)
    labels[10:40, 10:40] = 1
    image = np.full(labels.shape, 2.0)
    image[10:15, 10:40] = np.nan  # a stripe of missing pixels
    table = measure(labels, image)
    assert table["intensity_mean"].iat[0] == pytest.approx(2.0)
    assert table["intensity_integrated"].iat[0] == pytest.approx(2.0 * 25 * 30)
    assert "intensity_mean" not in measure(labels).columns


def test_objects_of_a_z_stack_get_the_3d_measures_with_the_voxel_size():
    zz, yy, xx = np.mgrid[:40, :40, :40] - 19.5
    ball = (zz**2 + yy**2 + xx**2 <= 15**2).astype(np.uint8)
    table = measure(ball, axes="zyx", spacing=(2.0, 1.0, 1.0))
    ref = skm.regionprops_table(ball, properties=("axis_major_length", "axis_minor_length",
                                                  "solidity"), spacing=(2.0, 1.0, 1.0))
    for col in ("axis_major_length", "axis_minor_length", "solidity"):
        assert table[col].iat[0] == pytest.approx(ref[col][0], rel=0.03), col
    # stretched twice along z by the voxel size: the major axis is about twice the minor
    assert table["axis_major_length"].iat[0] / table["axis_minor_length"].iat[0] == \
        pytest.approx(2.0, rel=0.05)
    assert "perimeter" not in table.columns
