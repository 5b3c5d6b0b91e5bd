"""The synthetic shape set: outlines, rasterisation, transforms, determinism."""

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from napari_pfsdm.core.contour import polygon_area_centroid, signed_area
from napari_pfsdm.data import shapes as S


def area_centroid(points):
    return polygon_area_centroid(points)[1]



def _area(points):
    return signed_area(points)


def _radius(points):
    return np.linalg.norm(points - area_centroid(points), axis=1)


def test_base_outlines_are_normalised_and_counter_clockwise():
    for name, outline in zip(S.CLASS_NAMES, S.base_shapes(), strict=True):
        assert _area(outline) > 0, name
        assert np.allclose(area_centroid(outline), 0.0, atol=1e-9), name
        assert _radius(outline).max() == pytest.approx(1.0), name


def test_base_shapes_have_their_defining_geometry():
    circle, elongated, folded, square, branched = S.base_shapes()
    r = _radius(circle)
    assert r.min() == pytest.approx(1.0, abs=1e-9)
    # elongated: area of an ellipse with semi-axes 1 and 0.45
    assert _area(elongated) == pytest.approx(np.pi * 0.45, rel=1e-3)
    # folded: clearly non-convex and without a mirror symmetry (its radius profile is not
    # equal to any reversed, shifted copy of itself)
    assert _area(folded) < 0.97 * ConvexHull(folded).volume
    rf = _radius(folded)
    assert rf.min() < 0.5  # the fold reaches deep towards the centre
    mirrored = min(np.abs(np.roll(rf[::-1], k) - rf).max() for k in range(len(rf)))
    assert mirrored > 0.05
    # rounded square: between the inscribed circle and the square of the same diagonal
    side = 2 / np.sqrt(2) * np.sqrt(2) ** (1 - 2 / 5)  # superellipse p=5 scaled to r_max = 1
    assert np.pi * (_radius(square).min()) ** 2 < _area(square) < side**2 * 1.01
    assert _area(square) > 0.9 * ConvexHull(square).volume
    # branched: three radius maxima (arm tips) at radius ~1, body in between much thinner
    rb = _radius(branched)
    peaks = np.flatnonzero((rb > np.roll(rb, 1)) & (rb >= np.roll(rb, -1)) & (rb > 0.8))
    assert len(peaks) == 3
    assert rb.min() < 0.5


def test_base_shapes_differ_from_each_other():
    outlines = S.base_shapes()
    areas = [_area(o) for o in outlines]
    assert min(np.diff(sorted(areas))) > 0.1


def test_rasterize_matches_area_and_is_sub_pixel_accurate():
    t = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
    for r in (7.3, 20.0, 55.5):
        disk = S.rasterize(np.column_stack([64.2 + r * np.cos(t), 63.7 + r * np.sin(t)]),
                           (128, 128))
        assert abs(disk.sum() - np.pi * r**2) < 0.6 * 2 * np.pi * r * 0.1 + 2
    # a half-pixel shift of an axis-aligned square moves whole columns only when it should
    square = np.array([[10.0, 10.0], [10.0, 20.0], [20.0, 20.0], [20.0, 10.0]]) - 0.5
    m = S.rasterize(square, (32, 32), oversample=4)
    assert m.sum() == 100 and m[10:20, 10:20].all()
    # shifted by 0.7 px: column 10 keeps 1/4 of its sub-samples (dropped), column 20 3/4 (kept)
    m = S.rasterize(square + [0.0, 0.7], (32, 32), oversample=4)
    assert m.sum() == 100 and m[10:20, 20].all() and not m[10:20, 10].any()


def test_rasterize_rejects_bad_outlines():
    with pytest.raises(ValueError, match="vertices"):
        S.rasterize(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="oversample"):
        S.rasterize(S.circle(), oversample=0)


def test_similarity_transform_reflects_rotates_scales_and_translates():
    outline = S.folded()
    tr = S.Similarity(angle=0.7, reflect=True, scale=30.0, center=(100.0, 90.0))
    p = tr.apply(outline)
    assert _area(p) == pytest.approx(-(30.0**2) * _area(outline))  # mirror flips orientation
    assert np.allclose(area_centroid(p), [100.0, 90.0])
    q = S.Similarity(angle=0.7, reflect=False, scale=30.0, center=(100.0, 90.0)).apply(outline)
    assert _area(q) == pytest.approx(30.0**2 * _area(outline))
    assert np.allclose(np.sort(np.linalg.norm(p - [100, 90], axis=1)),
                       np.sort(np.linalg.norm(q - [100, 90], axis=1)))


def test_random_similarity_keeps_the_shape_inside_and_covers_the_ranges():
    rng = np.random.default_rng(3)
    outline = S.branched()
    scales, reflects = [], []
    for _ in range(200):
        tr = S.random_similarity(rng, size=128, points=outline, margin=3)
        p = tr.apply(outline)
        assert p.min() >= 2.5 - 1e-9 and p.max() <= 127 - 2.5 + 1e-9
        scales.append(tr.scale / (0.21 * 128))
        reflects.append(tr.reflect)
    assert 0.5 <= min(scales) < 0.6 and 1.8 < max(scales) <= 2.0
    assert 0.35 < np.mean(reflects) < 0.65
    with pytest.raises(ValueError, match="does not fit"):
        S.random_similarity(rng, size=32, base_scale=40.0)


def test_perturb_is_mild_smooth_and_random():
    rng = np.random.default_rng(0)
    base = S.rounded_square()
    a, b = S.perturb(base, rng), S.perturb(base, rng)
    assert not np.allclose(a, b)
    for p in (a, b):
        assert _area(p) > 0
        assert abs(_area(p) / _area(base) - 1) < 0.25
        # same vertex order: the deformation is a small displacement of each point
        assert np.abs(p - base).max() < 0.3
    assert np.allclose(S.perturb(base, rng, strength=0.0), base, atol=1e-9)


def test_benchmark_set_is_deterministic_and_labelled():
    masks, labels, names = S.make_benchmark_set(n_per_class=2, seed=5, size=96)
    again, _, _ = S.make_benchmark_set(n_per_class=2, seed=5, size=96)
    other, _, _ = S.make_benchmark_set(n_per_class=2, seed=6, size=96)
    pert, _, _ = S.make_benchmark_set(n_per_class=2, seed=5, size=96, perturb=True)
    assert names == S.CLASS_NAMES
    assert labels.tolist() == [0, 0, 1, 1, 2, 2, 3, 3, 4, 4]
    assert all(m.shape == (96, 96) and m.dtype == bool for m in masks)
    assert all(np.array_equal(x, y) for x, y in zip(masks, again, strict=True))
    assert not any(np.array_equal(x, y) for x, y in zip(masks, other, strict=True))
    assert not any(np.array_equal(x, y) for x, y in zip(masks, pert, strict=True))
    for m in masks + pert:  # never touching the border, one piece of a sensible size
        assert not (m[0].any() or m[-1].any() or m[:, 0].any() or m[:, -1].any())
        assert m.sum() > 50


def test_benchmark_set_copies_have_the_area_of_their_scaled_base():
    masks, labels, _ = S.make_benchmark_set(n_per_class=3, seed=0, size=256)
    outlines = S.base_shapes()
    # recompute the transforms with the same random stream
    rng = np.random.default_rng([0, 0])
    for i, mask in enumerate(masks):
        tr = S.random_similarity(rng, size=256, points=outlines[labels[i]])
        expected = tr.scale**2 * _area(outlines[labels[i]])
        assert abs(mask.sum() - expected) < 0.02 * expected + 10


def test_skeleton_helpers():
    e = S.ellipse_mask((100, 120), axes=(40, 15), angle=np.pi / 2)
    rows, cols = np.nonzero(e)
    assert np.ptp(cols) > 2 * np.ptp(rows)  # the major axis along columns
    assert abs(e.sum() - np.pi * 40 * 15) < 0.02 * np.pi * 40 * 15
    t = S.three_armed_mask((128, 128), radius=50)
    assert t.sum() > 500 and not t[0].any()
    dist = np.hypot(*(np.argwhere(t) - 63.5).T)
    assert dist.max() == pytest.approx(50, abs=1.5)


def test_unknown_base_shape():
    with pytest.raises(ValueError, match="circle"):
        S.base_shape("triangle")
