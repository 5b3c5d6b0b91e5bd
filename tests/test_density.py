"""The plots' density image of many points (napari_pfsdm.napari._density): pure numpy, so it
is tested without a display. Expected pixels are worked out by hand."""

from __future__ import annotations

import numpy as np

from napari_pfsdm.napari._density import MIN_ALPHA, density_image, padded_extent


def test_each_point_lands_in_its_pixel_with_the_mean_colour_and_an_opacity_by_count():
    # 4 x 4 pixels over [0, 4) x [0, 8): pixel (row, col) = (y // 2, x // 1)
    x = np.array([0.5, 0.5, 0.5, 3.9, 2.2, np.nan])
    y = np.array([1.0, 1.5, 0.2, 7.9, 4.1, 1.0])
    colors = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1], [0.2, 0.4, 0.6],
                       [0, 0, 0]], float)
    img = density_image(x, y, colors, (0.0, 4.0, 0.0, 8.0), bins=4)
    assert img.shape == (4, 4, 4)
    np.testing.assert_allclose(img[0, 0], [1 / 3, 1 / 3, 1 / 3, 1.0])  # 3 points: opaque
    np.testing.assert_allclose(img[3, 3], [1, 1, 1, MIN_ALPHA])  # one point
    np.testing.assert_allclose(img[2, 2], [0.2, 0.4, 0.6, MIN_ALPHA])
    assert np.count_nonzero(img[..., 3]) == 3  # the NaN point is left out; the rest empty
    # two points in a pixel: between one (MIN_ALPHA) and three (1) on a log scale
    two = density_image(np.array([0.5, 0.5, 0.5, 2.5, 2.5]), np.zeros(5), np.ones((5, 3)),
                        (0.0, 4.0, 0.0, 8.0), bins=4)[0, 2, 3]
    expected = MIN_ALPHA + (1 - MIN_ALPHA) * (np.log(3) - np.log(2)) / (np.log(4) - np.log(2))
    np.testing.assert_allclose(two, expected)


def test_points_on_the_far_edge_stay_in_the_image_and_the_extent_pads_the_range():
    x, y = np.array([0.0, 10.0]), np.array([-1.0, 1.0])
    x0, x1, y0, y1 = padded_extent(x, y, pad=0.1)
    np.testing.assert_allclose([x0, x1, y0, y1], [-1.0, 11.0, -1.2, 1.2])
    img = density_image(x, y, np.ones((2, 3)), (0.0, 10.0, -1.0, 1.0), bins=5)
    assert img[0, 0, 3] > 0 and img[4, 4, 3] > 0  # the maximum falls in the last pixel
    assert padded_extent(np.array([np.nan]), np.array([1.0])) == (-1.0, 1.0, -1.0, 1.0)
    np.testing.assert_allclose(padded_extent(np.array([2.0]), np.array([3.0]), pad=0.5),
                               [1.5, 2.5, 2.5, 3.5])  # one point: a unit range around it
