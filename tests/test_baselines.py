"""EFA, mirror-aware EFA and Procrustes (GPA) baselines."""

import sys

import numpy as np
import pytest

from napari_pfsdm.analysis import baselines as B
from napari_pfsdm.core.contour import polygon_area_centroid, signed_area
from napari_pfsdm.data import shapes as S


def area_centroid(points):
    return polygon_area_centroid(points)[1]


pytest.importorskip("pyefd")


def _place(outline, angle=0.0, reflect=False, scale=45.0, center=(128.0, 128.0)):
    tr = S.Similarity(angle=angle, reflect=reflect, scale=scale, center=center)
    return S.rasterize(outline, (256, 256), transform=tr)


def test_mask_contour_is_closed_ccw_and_in_image_coordinates():
    mask = _place(S.circle(), scale=30.0, center=(100.0, 80.0))
    c = B.mask_contour(mask)
    assert signed_area(c) > 0
    assert np.allclose(c.mean(axis=0), [100.0, 80.0], atol=0.3)
    assert np.allclose(np.linalg.norm(c - [100.0, 80.0], axis=1), 30.0, atol=0.8)
    with pytest.raises(ValueError, match="empty"):
        B.mask_contour(np.zeros((8, 8), bool))


def test_efa_distance_is_invariant_to_rotating_the_raster():
    outline = S.folded()
    masks = [_place(outline, angle=a, scale=s) for a, s in ((0.0, 45), (0.9, 30), (2.5, 60))]
    masks += [_place(S.elongated()), _place(S.branched()), _place(S.rounded_square())]
    d = B.efa_distance_matrix(masks)
    within = d[:3, :3].max()
    between = d[:3, 3:].min()
    assert within < 0.1 * between
    # raw pyefd normalisation: a rotation can flip the axis direction or the start point
    raw = B.efa_descriptors(masks, canonical=False)
    d_raw = B.efa_distance_matrix(descriptors=raw, resolve_start=False)
    assert d_raw[:3, :3].max() > between


def test_efa_start_point_ambiguity_negates_even_harmonics():
    masks = [_place(S.folded(), angle=a) for a in (0.5, 2.0)]  # pyefd picks the other end
    raw = B.efa_descriptors(masks, canonical=False).reshape(2, 10, 4)
    canon = B.efa_descriptors(masks).reshape(2, 10, 4)
    assert np.allclose(canon[:, 0, 0], 1.0)
    sign = np.where(np.arange(1, 11) % 2 == 0, -1.0, 1.0)[:, None]
    flipped = np.abs(canon[0] - sign * canon[1]).max()
    assert flipped < 0.02 < np.abs(canon[0] - canon[1]).max()
    assert raw.shape == (2, 10, 4)


def test_plain_efa_sees_a_mirror_image_and_mirror_aware_efa_does_not():
    outline = S.folded()
    masks = [_place(outline), _place(outline)[:, ::-1].copy(), _place(S.elongated())]
    plain = B.efa_distance_matrix(masks)
    aware = B.efa_distance_matrix(masks, mirror_aware=True)
    assert plain[0, 1] > 0.3 * plain[0, 2]
    assert aware[0, 1] < 0.05 * aware[0, 2]
    assert np.allclose(aware, aware.T) and np.all(np.diag(aware) == 0)
    desc = B.efa_descriptors(masks)
    assert desc.shape == (3, 40)
    assert np.allclose(desc[:, :3], [1.0, 0.0, 0.0], atol=1e-9)  # normalised, canonical


def test_gpa_of_a_shape_to_its_mirrored_copy_is_zero():
    mask = _place(S.branched(), angle=0.3)
    masks = [mask, mask[:, ::-1].copy(), np.rot90(mask).copy(), _place(S.circle())]
    d = B.gpa_distance_matrix(masks)
    assert d[0, 3] > 0.3
    # what is left is the landmark sampling (100 points, start half a step apart)
    assert d[0, 1] < 0.1 * d[0, 3] and d[0, 2] < 0.1 * d[0, 3]
    no_mirror = B.gpa_distance_matrix(masks, reflection=False)
    assert no_mirror[0, 1] > 4 * d[0, 1] and no_mirror[0, 2] < 0.1 * d[0, 3]


def test_procrustes_distance_of_circle_and_ellipse_is_the_closed_form():
    # z1 = e^{it}, z2 = a cos t + i b sin t: d = |a - b| / sqrt(2 (a² + b²)), whatever the
    # start point, rotation, scale, translation and mirror image.
    t = np.linspace(0, 2 * np.pi, 128, endpoint=False)
    a, b = 1.0, 0.4
    circle = np.column_stack([np.sin(t), np.cos(t)])
    ellipse = np.column_stack([b * np.sin(t), a * np.cos(t)])
    c, s = np.cos(0.8), np.sin(0.8)
    moved = 3.0 * np.roll(ellipse, 17, axis=0) @ np.array([[c, -s], [s, c]]).T + [5.0, -2.0]
    mirrored = (moved * [1.0, -1.0])[::-1]
    d = B.procrustes_distance_matrix(np.stack([circle, ellipse, moved, mirrored]))
    expected = abs(a - b) / np.sqrt(2 * (a**2 + b**2))
    assert np.allclose(d[0, 1:], expected, atol=1e-9)
    assert np.allclose(d[1:, 1:], 0.0, atol=1e-7)
    with pytest.raises(ValueError, match="n_points"):
        B.procrustes_distance_matrix(np.zeros((3, 10)))


def test_procrustes_distance_matrix_does_not_depend_on_chunking():
    rng = np.random.default_rng(0)
    outlines = rng.normal(size=(7, 32, 2))
    assert np.allclose(B.procrustes_distance_matrix(outlines, chunk=2),
                       B.procrustes_distance_matrix(outlines))


def test_efa_outlines_are_equidistant_and_follow_the_mask():
    mask = _place(S.rounded_square(), scale=50.0, center=(120.0, 130.0))
    out = B.efa_outlines([mask], n_points=60)[0]
    steps = np.linalg.norm(np.diff(np.vstack([out, out[:1]]), axis=0), axis=1)
    assert steps.std() < 0.02 * steps.mean()
    assert signed_area(out) > 0
    assert np.allclose(area_centroid(out), [120.0, 130.0], atol=0.5)


def test_missing_pyefd_gives_a_clear_message(monkeypatch):
    monkeypatch.setitem(sys.modules, "pyefd", None)
    with pytest.raises(ImportError, match=r"napari-pfsdm\[bench\]"):
        B.efa_descriptors([np.ones((5, 5), bool)])
