"""The boundary term of the default distance (core/boundary.py) and the tables that carry it."""

import numpy as np
import pytest
from scipy import ndimage as ndi

import napari_pfsdm as P
from napari_pfsdm.core.boundary import (
    boundary_distance_matrix,
    outline_coefficients,
    outline_modes,
)
from napari_pfsdm.core.distances import boundary_term
from shapes_fixture import BASE_SHAPES, raster


@pytest.fixture(scope="module")
def masks():
    return {k: raster(v, 160) for k, v in BASE_SHAPES.items()}


def _d_b(results):
    return boundary_term(results)


def test_outline_coefficients_are_normalised_and_ordered():
    t = 2 * np.pi * np.arange(128) / 128
    circle = np.column_stack([5 + 2 * np.cos(t), 3 + 2 * np.sin(t)])
    a = outline_coefficients(circle, 4)
    assert np.linalg.norm(a) == pytest.approx(1.0)
    # a circle traced counter-clockwise in (row, col) is the single mode n = +1
    assert abs(a[list(outline_modes(4)).index(1)]) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="no extent"):
        outline_coefficients(np.ones((64, 2)))
    with pytest.raises(ValueError, match="M > 32"):
        outline_coefficients(circle[:20], 16)


def test_rotations_by_90_degrees_and_mirrors_give_identical_boundary_terms(masks):
    base = masks["folded"]
    variants = [base, np.rot90(base), np.rot90(base, 2), np.rot90(base, 3), base[::-1],
                base[:, ::-1], base.T]
    others = [masks["branched"], masks["elongated"]]
    results = [P.pfsdm(m) for m in variants + others]
    d = _d_b(results)
    n = len(variants)
    assert np.abs(d[:n, :n]).max() < 1e-6  # every copy is the same outline
    # ... and every copy is at the same distance from the other shapes
    for j in range(n, len(results)):
        assert np.ptp(d[:n, j]) < 1e-9
        assert d[0, j] > 0.05


def test_start_points_do_not_change_the_boundary_term(masks):
    pts = [P.pfsdm(masks[k]).contour.normalized for k in ("folded", "branched", "rounded_square")]
    a = np.stack([outline_coefficients(p) for p in pts])
    rolled = np.stack([outline_coefficients(np.roll(p, s, axis=0))
                       for p, s in zip(pts, (7, 101, 33), strict=True)])
    d = boundary_distance_matrix(a)
    d_rolled = boundary_distance_matrix(np.vstack([a, rolled]))
    # d(x, roll(x)) = 0 and d(x, roll(y)) = d(x, y): to 1e-7 for the copies; to 2e-4 between
    # different outlines (here d ≈ 0.3), whose correlation over start points and mirror can
    # have two nearly equal peaks (the coarse search may then refine the other one)
    assert np.abs(np.diag(d_rolled[:3, 3:])).max() < 1e-7
    np.testing.assert_allclose(d_rolled[:3, 3:], d, atol=2e-4)
    np.testing.assert_allclose(d_rolled[3:, 3:], d, atol=2e-4)
    # mirrored outline traced counter-clockwise again, from another start: conj(a_n) e^{ins}
    mirrored = np.stack([outline_coefficients(np.roll(p[::-1] * [1, -1], 50, axis=0))
                         for p in pts])
    np.testing.assert_allclose(boundary_distance_matrix(a, mirrored), d, atol=2e-4)
    assert np.abs(np.diag(boundary_distance_matrix(a, mirrored))).max() < 1e-7


@pytest.mark.parametrize("angle", [17.0, 30.0, 45.0, 71.0])
def test_arbitrary_rotations_change_the_boundary_term_little(masks, angle):
    """Rasterising a rotated object changes its outline by up to a pixel: the boundary term
    between an object and its rotated raster stays below 0.02 (objects ~130 px across), a
    tenth of the distance between the closest different base shapes."""
    names = list(BASE_SHAPES)
    results = [P.pfsdm(masks[k]) for k in names]
    turned = [P.pfsdm(ndi.rotate(masks[k].astype(float), angle, order=1) > 0.5) for k in names]
    d = _d_b(results + turned)
    k = len(names)
    same = np.diag(d[:k, k:])
    assert same.max() < 0.02
    between = d[:k, :k][~np.eye(k, dtype=bool)]
    assert same.max() < 0.1 * between.min()


def test_nan_rows_give_nan_distances():
    a = np.stack([outline_coefficients(np.column_stack([np.cos(t), 2 * np.sin(t)]))
                  for t in [2 * np.pi * np.arange(64) / 64] * 3])
    a[1] = np.nan
    d = boundary_distance_matrix(a)
    assert np.isnan(d[1]).all() and np.isnan(d[:, 1]).all()
    assert d[0, 2] == pytest.approx(0.0, abs=1e-7) and d[0, 0] == 0


def _labels(masks, names):
    labels = np.zeros((160, 160 * len(names)), np.uint16)
    for k, name in enumerate(names):
        labels[:, 160 * k:160 * (k + 1)][masks[name]] = k + 1
    return labels


def test_table_distance_equals_results_distance(masks, tmp_path):
    """The default distance of a table (and of its CSV, and of 'pfsdm compare') is the one of
    the results it was measured from."""
    names = ["circle", "folded", "branched", "rounded_square"]
    labels = _labels(masks, names)
    table = P.measure(labels)
    results = [o.result for o in P.iter_objects(labels)]
    ref = P.distance_matrix(results)
    np.testing.assert_allclose(P.distance_matrix(table), ref, rtol=0, atol=1e-9)
    path = tmp_path / "features.csv"
    P.write_table(table, path)
    np.testing.assert_allclose(P.distance_matrix(P.read_table(path)), ref, rtol=0, atol=1e-9)
    from napari_pfsdm.cli import main

    out = tmp_path / "d.csv"
    assert main(["compare", str(path), "-o", str(out), "-q"]) == 0
    import pandas as pd

    written = pd.read_csv(out, index_col=0).to_numpy(float)
    np.testing.assert_allclose(written, ref, rtol=0, atol=1e-9)
    # the boundary term is there: the SDF term alone is smaller
    sdf_only = P.distance_matrix(table, boundary_weight=0)
    assert np.all(sdf_only[np.triu_indices(4, 1)] < ref[np.triu_indices(4, 1)])


def test_a_table_without_outline_columns_falls_back_with_a_warning(masks):
    table = P.measure(_labels(masks, ["circle", "folded", "branched"]))
    old = table[[c for c in table.columns if not c.startswith("outline_")]].copy()
    old.attrs = table.attrs
    with pytest.warns(UserWarning, match="no outline_"):
        d = P.distance_matrix(old)
    np.testing.assert_allclose(d, P.distance_matrix(table, boundary_weight=0), atol=1e-12)
    from napari_pfsdm.analysis.tables import embeddings
    from napari_pfsdm.core.distances import distance_matrix as core_matrix

    with pytest.raises(ValueError, match="boundary_weight=0"):
        core_matrix(embeddings(old))
