"""Skeleton from the SDF's singularities."""

import numpy as np

import napari_pfsdm as P


def test_skeleton_of_ellipse_lies_on_its_major_axis():
    yy, xx = np.mgrid[:200, :200]
    mask = ((yy - 100) / 70) ** 2 + ((xx - 90) / 25) ** 2 < 1
    sk = P.pfsdm(mask).skeleton
    assert len(sk.points) > 60
    assert np.abs(sk.points[:, 1] - 90).max() <= 1
    # the medial axis of an ellipse ends at the centres of curvature of its vertices: a - b²/a
    half = 70 - 25**2 / 70
    assert abs((sk.points[:, 0].max() - sk.points[:, 0].min()) / 2 - half) < 5
    assert sk.n_end_points == 2
    # depth is the local half-thickness: 25 px at the centre
    assert abs(sk.depth.max() - 25) < 1.5


def test_skeleton_of_three_armed_shape_has_three_end_points():
    yy, xx = np.mgrid[:200, :200]
    mask = np.zeros((200, 200), bool)
    for ang in (0.3, 0.3 + 2 * np.pi / 3, 0.3 + 4 * np.pi / 3):
        along = (yy - 100) * np.cos(ang) + (xx - 100) * np.sin(ang)
        across = np.abs(-(yy - 100) * np.sin(ang) + (xx - 100) * np.cos(ang))
        mask |= (along > -5) & (along < 80) & (across < 12)
    sk = P.pfsdm(mask).skeleton
    assert sk.n_end_points == 3
    assert mask[tuple(sk.points.T)].all()


def test_skeleton_is_in_image_coordinates_and_pushed_onto_the_disk():
    labels = np.zeros((120, 160), int)
    yy, xx = np.mgrid[:120, :160]
    labels[((yy - 60) / 40) ** 2 + ((xx - 110) / 15) ** 2 < 1] = 4
    obj = next(P.iter_objects(labels))
    sk = obj.result.skeleton
    assert np.abs(sk.points[:, 1] - 110).max() <= 1  # full-frame columns, not crop columns
    assert np.all(np.hypot(*sk.disk_points.T) <= 1)
    # the major axis maps to a diameter of the disk: disk points are nearly collinear
    u, s, vt = np.linalg.svd(sk.disk_points - sk.disk_points.mean(0))
    assert s[1] < 0.2 * s[0]
