"""Invariance is a promise: similarity transforms of the raster change the PF-SDM by no more than
the rasterisation error."""

import numpy as np
import pytest

import napari_pfsdm as P
from shapes_fixture import BASE_SHAPES, raster

SIZE = 320
# 56 px radius at scale 1, so 0.5x-2x gives 28-112 px. Measured with the defaults, the worst
# within-class distance is 4-5 % of the median between-class distance here; for objects of
# 20 px radius it grows to ~8 % (the outer ring sits within a pixel of the outline).
BASE = 56 / (0.3 * SIZE)


@pytest.mark.parametrize(
    "options",
    [{}, {"mapping": "bijective"}, {"mapping": "radial"}, {"sdf": "viscous"},
     {"radii": "boundary", "ring_weighting": "boundary"},
     {"ring_weighting": "none", "mode_exponent": 0}],
    ids=["default", "bijective", "radial", "viscous", "boundary-rings", "paper-weights"],
)
def test_similarity_transforms_change_embedding_less_than_5_percent(options, rng):
    names = list(BASE_SHAPES)
    base = [P.pfsdm(raster(BASE_SHAPES[k], SIZE, scale=BASE), **options) for k in names]
    between = P.distance_matrix(base, invariance="magnitude")[np.triu_indices(len(names), 1)]
    within, nearest = [], []
    for i, name in enumerate(names):
        for _ in range(4):
            mask = raster(BASE_SHAPES[name], SIZE, angle=rng.uniform(0, 2 * np.pi),
                          scale=BASE * rng.uniform(0.5, 2.0), mirror=bool(rng.random() < 0.5),
                          shift=rng.uniform(-20, 20, 2))
            res = P.pfsdm(mask, **options)
            d = [P.distance(res, b, invariance="magnitude") for b in base]
            within.append(d[i])
            nearest.append(int(np.argmin(d)) == i)
    assert max(within) < 0.05 * np.median(between)
    assert all(nearest)


def test_rotation_by_90_degrees_and_mirror_keep_the_aligned_distance(rng):
    mask = raster(BASE_SHAPES["folded"], SIZE, scale=BASE, angle=0.4)
    other = P.pfsdm(raster(BASE_SHAPES["branched"], SIZE, scale=BASE))
    ref = P.pfsdm(mask)
    scale = P.distance(ref, other, invariance="align")
    for variant in (np.rot90(mask), np.rot90(mask, 2), mask[:, ::-1], mask.T):
        res = P.pfsdm(np.ascontiguousarray(variant))
        # the outline starts at a canonical point: the same boundary samples, the same numbers
        np.testing.assert_allclose(res.embedding, ref.embedding, atol=1e-9)
        assert P.distance(ref, res, invariance="align") < 0.02 * scale
        assert P.distance(ref, res) < 0.02 * scale
    arbitrary = P.pfsdm(raster(BASE_SHAPES["folded"], SIZE, scale=BASE, angle=1.234))
    assert P.distance(ref, arbitrary, invariance="align") < 0.05 * scale


def test_intensity_embedding_ignores_brightness_and_rotates_with_the_object():
    yy, xx = np.mgrid[:128, :128]
    mask = ((yy - 64) / 40) ** 2 + ((xx - 60) / 20) ** 2 < 1
    ramp = 1.0 + (yy - 24) / 40.0
    a = P.pfsdm(mask, ramp)
    b = P.pfsdm(mask, 7.5 * ramp)
    np.testing.assert_allclose(a.intensity_embedding, b.intensity_embedding, atol=1e-9)
    c = P.pfsdm(mask[::-1], ramp[::-1])  # mirrored object and reporter
    assert np.abs(c.intensity_embedding - a.intensity_embedding).max() < 0.02
    flat = P.pfsdm(mask, np.ones_like(ramp))
    assert np.abs(flat.intensity_embedding[:, 1:]).max() < 1e-9
    assert np.abs(a.intensity_embedding[:, 1]).max() > 0.05  # the ramp shows in mode 1
