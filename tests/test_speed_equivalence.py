"""The fast paths of issue 44 compute what the straightforward code computed.

- Embeddings and outline coefficients of a fixed set of masks equal those stored from the
  code before the speed work (commit aca1214) to 1e-10 (measured: 1.1e-13).
- The exact SDF equals a plain re-statement of its rule (nearest vertex by a single-precision
  brute force, closest point on its two edges, sign by the pseudo-normal) on random polygons.
- The classic 2-D measures equal scikit-image's regionprops (perimeter and solidity exactly).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage as ndi
from skimage import draw
from skimage.measure import perimeter, regionprops_table
from skimage.morphology import convex_hull_image

from napari_pfsdm import pfsdm
from napari_pfsdm.analysis.classic import convex_area, perimeter_4, shape_measures_2d
from napari_pfsdm.core.sdf import ExactSDF
from shapes_fixture import BASE_SHAPES, raster

REFERENCE = Path(__file__).parent / "data" / "pfsdm_embeddings_aca1214.npz"


def _blob(radius: float, rng: np.random.Generator) -> np.ndarray:
    n = int(3.4 * radius + 8)
    yy, xx = np.mgrid[:n, :n] - n / 2 + rng.uniform(-0.5, 0.5, 2)[:, None, None]
    theta = np.arctan2(yy, xx)
    r = np.ones_like(theta)
    for k in range(2, 6):
        r += rng.uniform(0, 0.24 / k) * np.cos(k * theta + rng.uniform(0, 2 * np.pi))
    return np.hypot(xx / 1.1, yy * 1.1) < radius * r


def reference_masks() -> list[np.ndarray]:
    """Five shapes at two sizes and turns, small blobs, and pixel-symmetric disks and squares
    (whose farthest boundary vertices tie: the start point must not move)."""
    masks = [raster(outline, size, angle=0.3 * i)
             for i, outline in enumerate(BASE_SHAPES.values()) for size in (64, 160)]
    rng = np.random.default_rng(44)
    masks += [_blob(radius, rng) for radius in (10, 12, 12, 16, 20)]
    yy, xx = np.mgrid[:64, :64]
    for r in (5.5, 9.0, 14.5):
        masks.append((yy - 32) ** 2 + (xx - 32) ** 2 <= r * r)
        masks.append((abs(yy - 32) <= r) & (abs(xx - 31.5) <= r))
    return masks


def test_embeddings_equal_those_before_the_speed_work():
    ref = np.load(REFERENCE)
    masks = reference_masks()
    assert len(masks) == len(ref["embedding"])
    for i, mask in enumerate(masks):
        res = pfsdm(mask)
        np.testing.assert_allclose(res.embedding, ref["embedding"][i], rtol=0, atol=1e-10)
        np.testing.assert_allclose(res.outline, ref["outline"][i], rtol=0, atol=1e-10)
        # the first outline points: the same canonical start, the same resampling
        np.testing.assert_allclose(res.contour.points[:8], ref["contour"][i], rtol=0, atol=1e-9)
        assert res.diagnostics["folded_fraction"] == ref["folded"][i]


def _reference_sdf(poly: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """The exact SDF's rule, stated plainly (as core/sdf.py had it before the speed work)."""
    m = len(poly)
    nxt, prv = np.roll(np.arange(m), -1), np.roll(np.arange(m), 1)
    origin = poly.mean(axis=0)
    p32, q32 = (poly - origin).astype(np.float32), (pts - origin).astype(np.float32)
    k = np.argmin((p32**2).sum(axis=1) - q32 @ (2.0 * p32.T), axis=1)
    edge = poly[nxt] - poly
    edge_sq = (edge**2).sum(axis=1)
    normal = np.column_stack([edge[:, 1], -edge[:, 0]]) / np.sqrt(edge_sq)[:, None]
    vertex = normal + normal[prv]
    vertex /= np.maximum(np.linalg.norm(vertex, axis=1), 1e-12)[:, None]
    found = []
    for a in (prv[k], k):
        t = np.clip(((pts - poly[a]) * edge[a]).sum(axis=1) / edge_sq[a], 0, 1)
        c = poly[a] + t[:, None] * edge[a]
        found.append((a, t, c, np.linalg.norm(pts - c, axis=1)))
    (a0, t0, c0, d0), (a1, t1, c1, d1) = found
    pick = d1 < d0
    a, t, c, d = (np.where(pick, x1, x0) for x0, x1 in ((a0, a1), (t0, t1), (d0, d1), (d0, d1)))
    c = np.where(pick[:, None], c1, c0)
    n = np.where(((t > 0) & (t < 1))[:, None], normal[a],
                 np.where((t <= 0)[:, None], vertex[a], vertex[nxt[a]]))
    area = 0.5 * np.sum(poly[:, 0] * np.roll(poly[:, 1], -1) - np.roll(poly[:, 0], -1) * poly[:, 1])
    side = ((pts - c) * n).sum(axis=1) * np.sign(area)
    return np.where(side < 0, -1.0, 1.0) * d


def test_exact_sdf_equals_its_plain_rule_on_random_polygons():
    rng = np.random.default_rng(0)
    for i in range(40):
        m = int(rng.integers(8, 300))
        t = np.sort(rng.uniform(0, 2 * np.pi, m))
        r = 1 + 0.3 * np.sin(rng.integers(1, 6) * t + rng.uniform(0, 6)) + 0.02 * rng.normal(size=m)
        poly = np.column_stack([r * np.cos(t), r * np.sin(t)])[:: 1 if i % 2 else -1]
        pts = rng.uniform(-1.6, 1.6, (400, 2))
        ours, ref = ExactSDF(poly)(pts), _reference_sdf(poly, pts)
        assert np.array_equal(np.sign(ours), np.sign(ref))
        np.testing.assert_allclose(ours, ref, rtol=0, atol=1e-12)


def _classic_masks() -> list[np.ndarray]:
    rng = np.random.default_rng(1)
    masks = [_blob(radius, rng) for radius in (3, 8, 12, 20, 40)]
    for i in range(60):
        noise = ndi.gaussian_filter(rng.random((30, 36)), 0.5 + (i % 4))
        masks.append(noise > np.quantile(noise, rng.uniform(0.2, 0.9)))
    for i in range(40):  # lines, triangles, single pixels, scattered pixels
        m = np.zeros((24, 24), bool)
        if i % 4 == 0:
            m[draw.line(*rng.integers(0, 24, 4))] = True
        elif i % 4 == 1:
            m[draw.polygon(rng.uniform(0, 24, 3), rng.uniform(0, 24, 3), m.shape)] = True
        elif i % 4 == 2:
            m[rng.integers(0, 24), rng.integers(0, 24)] = True
        else:
            m[rng.integers(0, 24, 5), rng.integers(0, 24, 5)] = True
        masks.append(m)
    return [m for m in masks if m.any()]


@pytest.mark.parametrize("which", ["perimeter", "convex area"])
def test_perimeter_and_convex_area_are_scikit_images(which):
    for mask in _classic_masks():
        if which == "perimeter":
            assert perimeter_4(mask) == perimeter(mask, 4)
        else:
            assert convex_area(mask) == np.count_nonzero(convex_hull_image(mask))


def test_classic_measures_equal_regionprops():
    names = ("perimeter", "eccentricity", "solidity", "axis_major_length", "axis_minor_length")
    for mask in _classic_masks():
        ref = regionprops_table(mask.astype(np.uint8), properties=names)
        ours = shape_measures_2d(mask)
        assert ours["perimeter"] == ref["perimeter"][0]
        assert ours["solidity"] == ref["solidity"][0]
        for name in ("eccentricity", "axis_major_length", "axis_minor_length"):
            # an eigenvalue that is 0 (a one-pixel line) comes out as ±1e-15 either way
            np.testing.assert_allclose(ours[name], ref[name][0], rtol=1e-12, atol=1e-6,
                                       err_msg=name)
