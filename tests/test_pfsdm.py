"""The pipeline's pieces: maps, folding, disk rendering, distances."""

import numpy as np
import pytest

import napari_pfsdm as P
from shapes_fixture import BASE_SHAPES, raster


@pytest.mark.parametrize("mapping", ["harmonic", "bijective", "radial"])
def test_maps_send_the_circle_to_the_outline_and_the_disk_inside(mapping):
    res = P.pfsdm(raster(BASE_SHAPES["folded"], 200), mapping=mapping)
    theta = np.linspace(0, 2 * np.pi, 50, endpoint=False)
    edge = res.mapping(np.column_stack([np.cos(theta), np.sin(theta)]) * 0.9999)
    tol = 0.03 if mapping == "radial" else 0.01  # the radial fit is a degree-16 polynomial
    assert np.abs(res.sdf(edge)).max() < tol
    folded = res.diagnostics["folded_fraction"]
    assert folded == 0.0 if mapping == "bijective" else folded < 0.05
    assert (res.disk < 0).mean() > 0.95


def test_pf_sdf_of_a_disk_is_radial_and_analytic():
    yy, xx = np.mgrid[:200, :200]
    res = P.pfsdm((yy - 100) ** 2 + (xx - 100) ** 2 < 80**2)
    # a disk maps to itself: phi*(r, theta) = r - 1
    np.testing.assert_allclose(res.disk, (res.radii - 1)[:, None] * np.ones((1, 64)), atol=0.01)
    assert np.abs(res.embedding[:, 1:]).max() < 0.005


def test_harmonic_map_folds_on_a_snake_and_the_bijective_map_does_not():
    yy, xx = np.mgrid[:200, :260]
    snake = np.zeros((200, 260), bool)
    for k in range(4):  # a meander of four bars joined at alternate ends
        snake[30:170, 20 + 60 * k : 45 + 60 * k] = True
    for k in range(3):
        top = k % 2 == 0
        snake[(30 if top else 145):(55 if top else 170), 20 + 60 * k : 105 + 60 * k] = True
    harm = P.pfsdm(snake, mapping="harmonic")
    bij = P.pfsdm(snake, mapping="bijective")
    assert harm.diagnostics["folded_fraction"] > 0.5
    # linear interpolation across the crowded far ends of the bars leaves a few percent
    assert bij.diagnostics["folded_fraction"] < 0.05


def test_render_disk_shows_the_pf_sdf_and_intensity():
    yy, xx = np.mgrid[:128, :128]
    mask = ((yy - 64) / 50) ** 2 + ((xx - 64) / 20) ** 2 < 1
    res = P.pfsdm(mask, 1.0 + yy / 128.0)
    img = P.render_disk(res, 64)
    assert img.shape == (64, 64)
    assert np.isnan(img[0, 0]) and np.isfinite(img[32, 32])
    assert img[32, 32] < -0.3 and np.nanmax(img) <= 0.0
    inten = P.render_disk(res, 64, channel="intensity")
    # the reporter grows with the row; the disk keeps the image's orientation (row = u)
    assert np.nanmean(inten[48:, 28:36]) > np.nanmean(inten[:16, 28:36])
    with pytest.raises(ValueError, match="no intensity"):
        P.render_disk(P.pfsdm(mask), channel="intensity")


def test_distance_properties():
    shapes = [P.pfsdm(raster(v, 160)) for v in BASE_SHAPES.values()]
    for inv in ("magnitude", "align", "combined"):
        for bw in (None, 0.0):
            d = P.distance_matrix(shapes, invariance=inv, boundary_weight=bw)
            np.testing.assert_allclose(d, d.T, atol=1e-12)
            assert np.all(np.diag(d) == 0) and np.all(d[np.triu_indices(5, 1)] > 0)
    mag = P.distance_matrix(shapes, invariance="magnitude", boundary_weight=0)
    ali = P.distance_matrix(shapes, invariance="align", boundary_weight=0)
    assert np.all(ali >= mag - 1e-9)  # magnitudes are a lower bound of the aligned distance
    bnd = P.distance_matrix(shapes, boundary_weight=1) - mag  # d_B alone
    assert np.all((bnd >= 0) & (bnd <= 1))
    assert P.distance(shapes[0], shapes[1], invariance="magnitude", boundary_weight=0) \
        == pytest.approx(mag[0, 1])
    # the default: SDF magnitudes + 1 x the boundary term; the SDF term alone still available
    assert P.distance(shapes[0], shapes[1]) == pytest.approx(mag[0, 1] + bnd[0, 1])
    assert P.distance(shapes[0], shapes[1], boundary_weight=2.5) \
        == pytest.approx(mag[0, 1] + 2.5 * bnd[0, 1])
    assert P.distance(shapes[0], shapes[1], invariance="combined", boundary_weight=0) \
        == pytest.approx(mag[0, 1] + ali[0, 1])
    # a pair's distance does not depend on the rest of the collection
    assert P.distance(shapes[1], shapes[3]) == pytest.approx(P.distance_matrix(shapes)[1, 3],
                                                             abs=1e-12)
    with pytest.raises(ValueError, match="boundary_weight"):
        P.distance_matrix(shapes, boundary_weight=-1)


def test_viscous_sdf_stays_bounded_at_sharp_corners():
    # a perturbed branched shape whose sharp corner once sent log(w) to log(1e-300): phi = -34
    from napari_pfsdm.data.shapes import make_benchmark_set

    mask = make_benchmark_set(10, True, 0)[0][26]
    res = P.pfsdm(mask, mapping="bijective", sdf="viscous")
    exact = P.pfsdm(mask, mapping="bijective")
    assert res.disk.min() > 1.2 * exact.disk.min()
    assert np.abs(res.disk - exact.disk).max() < 0.1


def test_holes_are_filled_before_the_shape_is_described():
    """The PF-SDM describes the outer outline: a ring-shaped object is its filled disk."""
    yy, xx = np.mgrid[:80, :90]
    filled = ((yy - 40) / 22.0) ** 2 + ((xx - 45) / 30.0) ** 2 <= 1
    holed = filled & ~(((yy - 38) / 6.0) ** 2 + ((xx - 50) / 9.0) ** 2 <= 1)
    a, b = P.pfsdm(holed), P.pfsdm(filled)
    assert a.diagnostics["n_holes"] == 1 and b.diagnostics["n_holes"] == 0
    assert a.diagnostics["area"] == b.diagnostics["area"] == int(filled.sum())
    np.testing.assert_array_equal(a.embedding, b.embedding)
    table = P.measure(holed.astype(np.uint8))
    assert table.loc[0, "n_holes"] == 1 and table.loc[0, "warnings"] == "1 hole filled"


@pytest.mark.parametrize("exponent", [0.0, 0.25, 0.5])
def test_magnitude_distance_is_the_weighted_sum_the_readme_states(exponent):
    """d² = Σ_r w_r Σ_n (1 + n)^{2α} (|c_n^(1)(r)| − |c_n^(2)(r)|)², for results and tables."""
    masks = [raster(BASE_SHAPES[k], 160) for k in ("circle", "folded", "branched")]
    results = [P.pfsdm(m, mode_exponent=exponent) for m in masks]
    n = np.arange(results[0].embedding.shape[1])
    # the default rings and weights written out, not read from the results: 16 rings at
    # r_i = (i + ½)/16, each of width 1/16, "depth" weighting 1/(1 − r)²
    r = (np.arange(16) + 0.5) / 16
    w = (1 / 16) / (1 - r) ** 2
    assert results[0].embedding.shape == (16, 11)

    def by_hand(a, b):
        diff = (a.embedding - b.embedding) * (1.0 + n)[None, :] ** exponent
        return np.sqrt(np.sum(w[:, None] * diff**2))

    expected = np.array([[by_hand(a, b) for b in results] for a in results])
    got = P.distance_matrix(results, invariance="magnitude", boundary_weight=0)
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)
    labels = np.zeros((160, 480), np.uint8)
    for k, m in enumerate(masks):
        labels[:, 160 * k:160 * (k + 1)][m] = k + 1
    table = P.measure(labels, mode_exponent=exponent)
    np.testing.assert_allclose(P.distance_matrix(table, boundary_weight=0), expected,
                               rtol=1e-6, atol=1e-9)
