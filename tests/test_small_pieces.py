"""Small pieces held to closed forms or to a second way of computing the same thing. Each test
kills a mutant that survived the mutation test of the suite (docs/testing.md):
the mutant named in the docstring passes every other test."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest
from scipy.special import gammaln, lpmv

import napari_pfsdm as P
from napari_pfsdm.analysis.interpretation import outline_measures
from napari_pfsdm.analysis.reduction import mds_coordinates
from napari_pfsdm.analysis.tracking.check import median_radius as _median_radius
from napari_pfsdm.core.boundary import _refine
from napari_pfsdm.core.descriptor import _polar_to_cartesian
from napari_pfsdm.core.medial_axis import branch_paths
from napari_pfsdm.core.pushforward import FourierMap
from napari_pfsdm.core.sph_harm import legendre_table
from napari_pfsdm.errors import InputError
from napari_pfsdm.io import read_table


def disk(radius: float, size: int = 96) -> np.ndarray:
    yy, xx = np.mgrid[:size, :size] - (size - 1) / 2
    return yy**2 + xx**2 <= radius**2


def test_the_contour_length_is_its_polygon_perimeter():
    """Mutant: the closing point appended twice (``normalized[:2]``)."""
    c = P.pfsdm(disk(30)).contour
    p = c.normalized
    assert c.length == pytest.approx(np.hypot(*(np.roll(p, -1, axis=0) - p).T).sum(), rel=1e-12)
    assert c.length == pytest.approx(2 * np.pi, rel=0.01)  # a circle of radius 1


def test_the_polar_image_samples_pixel_centres():
    """f(r, θ) = r sampled on the rings r_i = (i + ½)/n_r is drawn as ρ, the distance of each
    pixel centre ((k + ½)/size · 2 − 1) from the disk's centre. Mutant: ``(k − ½)``."""
    n_r, n_t, size = 8, 32, 40
    polar = np.repeat(((np.arange(n_r) + 0.5) / n_r)[:, None], n_t, axis=1)
    img = _polar_to_cartesian(polar, size)
    c = (np.arange(size) + 0.5) / size * 2 - 1
    rho = np.hypot(*np.meshgrid(c, c, indexing="ij"))
    inner = (rho >= 0.5 / n_r) & (rho <= 1 - 0.5 / n_r)  # between the first and last ring
    np.testing.assert_allclose(img[inner], rho[inner], atol=1e-12)
    assert np.isnan(img[rho > 1]).all() and np.isfinite(img[rho <= 1]).all()


def test_a_3d_offset_given_to_pfsdm_reaches_the_volume():
    """Mutant: pfsdm() passing (0, 0, 0) instead of a 3-D object's offset."""
    zz, yy, xx = np.mgrid[:24, :24, :24] - 11.5
    ball = zz**2 + yy**2 + xx**2 < 8**2
    at_zero = P.pfsdm(ball, n_radii=4, sh_degree=4)
    moved = P.pfsdm(ball, n_radii=4, sh_degree=4, offset=(5.0, -2.0, 7.0))
    np.testing.assert_allclose(moved.center - at_zero.center, [5.0, -2.0, 7.0], atol=1e-9)


def test_the_fourier_map_in_chunks_is_the_map_at_once():
    """Mutant: chunks one point too long (``out[i : i + chunk + 1]``)."""
    rng = np.random.default_rng(4)
    coef = rng.normal(size=16) + 1j * rng.normal(size=16)
    fm = FourierMap(coef)
    uv = rng.uniform(-0.7, 0.7, size=(11, 2))
    np.testing.assert_allclose(fm(uv, chunk=3), fm(uv, chunk=4096), rtol=1e-13)


def test_the_fourier_maps_boundary_passes_through_its_nodes():
    """X(1, θ_k) at θ_k = 2πk/M are the M outline points the coefficients were made from
    (a_n = FFT(points)/M), linear in between. Mutant: the grid one node short (``m − 1``)."""
    t = 2 * np.pi * np.arange(12) / 12
    nodes = np.cos(t) * 2 + 1j * (np.sin(t) + 0.3 * np.sin(2 * t))
    fm = FourierMap(np.fft.fft(nodes) / 12)
    got = fm.boundary(t)
    np.testing.assert_allclose(got[:, 0] + 1j * got[:, 1], nodes, atol=1e-12)
    mid = fm.boundary(t[:2].mean()[None])[0]
    np.testing.assert_allclose(mid[0] + 1j * mid[1], nodes[:2].mean(), atol=1e-12)


def test_the_outline_term_refined_in_blocks_is_refined_at_once():
    """Mutant: the start shifts of a block one pair too long (``s[p0:p1 + 1]``), which only a
    collection of more than 65,536 pairs would meet with the default block."""
    rng = np.random.default_rng(0)
    a = rng.normal(size=(5, 8)) + 1j * rng.normal(size=(5, 8))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    ii, jj = np.triu_indices(5, 1)
    s = rng.uniform(0, 2 * np.pi, len(ii))
    mirror = rng.random(len(ii)) < 0.5
    whole = _refine(a, a, ii, jj, s, mirror)
    np.testing.assert_allclose(_refine(a, a, ii, jj, s, mirror, block=3), whole, rtol=1e-12)


def test_legendre_functions_are_scipys_normalised():
    """P̄_lm = sqrt((2l + 1)/(4π) (l − m)!/(l + m)!) |P_l^m| (scipy's lpmv), every degree up to
    the top one. Mutant: the recursion stopping one degree short."""
    x = np.linspace(-0.95, 0.95, 7)
    got = legendre_table(6, x)
    for ell in range(7):
        for m in range(ell + 1):
            norm = np.sqrt((2 * ell + 1) / (4 * np.pi)
                           * np.exp(gammaln(ell - m + 1) - gammaln(ell + m + 1)))
            np.testing.assert_allclose(np.abs(got[ell, m]), norm * np.abs(lpmv(m, ell, x)),
                                       rtol=1e-10, atol=1e-14)


def test_outline_measures_of_a_regular_polygon_are_its_closed_forms():
    """A regular N-gon: circularity 4πA/P² = π / (N tan(π/N)), aspect ratio 1, solidity 1; a
    2 × 1 rectangle: circularity 4π·2/36, aspect √(1/4) = 0.5. Not measurable: NaN."""
    for n in (5, 12, 64):
        t = 2 * np.pi * np.arange(n) / n
        m = outline_measures(np.c_[np.cos(t), np.sin(t)] * 3.0)
        assert m["circularity"] == pytest.approx(np.pi / (n * np.tan(np.pi / n)), rel=1e-12)
        assert m["aspect_ratio"] == pytest.approx(1.0, rel=1e-9)
        assert m["solidity"] == pytest.approx(1.0, rel=1e-12)
    rect = outline_measures(np.array([[0.0, 0.0], [0.0, 2.0], [1.0, 2.0], [1.0, 0.0]]))
    assert rect["circularity"] == pytest.approx(8 * np.pi / 36, rel=1e-12)
    assert rect["aspect_ratio"] == pytest.approx(0.5, rel=1e-12)
    flat = outline_measures(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]))  # no area
    assert all(np.isnan(v) for v in flat.values())
    assert all(np.isnan(v) for v in outline_measures(np.zeros((4, 2))).values())


def test_table_measures_are_the_tables_regionprops_columns_and_their_axis_ratio():
    """A 20 x 10 pixel rectangle: aspect ratio = sqrt of the ratio of its pixel variances,
    (10² - 1) / (20² - 1) (each side's discrete uniform variance (n² - 1) / 12), solidity 1,
    circularity 4π·area / scikit-image's perimeter; a one-pixel object has no axis: NaN, not
    a division warning. Mutants: the ratio inverted, taken from the wrong columns, or rows
    reordered against the table."""
    from skimage.measure import perimeter

    import napari_pfsdm as pf
    from napari_pfsdm.analysis.interpretation import table_measures

    labels = np.zeros((64, 64), np.uint16)
    labels[10:30, 10:20] = 3
    labels[50, 50] = 7
    table = pf.measure(labels)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = table_measures(table)
    assert m["label"].tolist() == table["label"].tolist() == [3, 7]
    rect = m.iloc[0]
    assert rect["aspect_ratio"] == pytest.approx(np.sqrt(99 / 399), rel=1e-9)
    assert rect["solidity"] == pytest.approx(1.0)
    assert rect["circularity"] == pytest.approx(4 * np.pi * 200 / perimeter(labels == 3) ** 2)
    assert np.isnan(m.iloc[1]["aspect_ratio"])


def test_a_single_pixel_skeleton_is_one_branch():
    """Mutant: an isolated node (no neighbour) left without its branch."""
    paths = branch_paths(np.array([[3, 4]]))
    assert [p.tolist() for p in paths] == [[0, 0]]


def test_mds_of_fewer_objects_than_components_pads_with_zeros():
    """Mutant: the padding's width read from a third axis (``shape[2]``)."""
    np.testing.assert_array_equal(mds_coordinates(np.zeros((1, 1)), 2), [[0.0, 0.0]])
    xy = mds_coordinates(np.array([[0.0, 4.0], [4.0, 0.0]]), 3)
    np.testing.assert_allclose(np.abs(xy[:, 0]), [2.0, 2.0], atol=1e-12)
    np.testing.assert_allclose(xy[:, 1:], 0.0, atol=1e-7)


def test_the_linking_scale_without_areas_is_ten_pixels():
    """``_median_radius``: the radius of the median area's disk; 10 px for a table without
    areas or volumes. Mutant: ``and`` for ``or`` (it then looks for a volume column)."""
    table = pd.DataFrame({"frame": [0, 1], "label": [1, 1], "centroid_y": [1.0, 2.0],
                          "centroid_x": [1.0, 2.0]})
    assert _median_radius(table) == 10.0
    assert _median_radius(table.assign(area=[np.pi * 9, np.pi * 25])) == pytest.approx(
        np.sqrt(17))  # median area π·17: radius √17
    both = table.assign(area=[np.pi * 4, np.pi * 4], volume=[1e6, 1e6])
    assert _median_radius(both) == pytest.approx(2.0)  # the area wins over the volume


def test_a_parquet_file_given_as_a_table_is_named(tmp_path):
    """A Parquet file is recognised by its first bytes whatever its name, and a damaged one is
    named. Mutant: the magic number compared with five bytes (then it is refused as "a
    Parquet file, not a CSV table")."""
    pytest.importorskip("pyarrow", reason="telling a damaged Parquet file needs pyarrow "
                        "(the [parquet] extra)")
    (tmp_path / "t.csv").write_bytes(b"PAR1" + b"\x15\x04" * 40)
    with pytest.raises(InputError, match="is not a readable Parquet table"):
        read_table(tmp_path / "t.csv")


def test_a_character_cut_at_the_end_of_the_first_block_is_still_text(tmp_path):
    """The binary check reads 2,048 bytes; a two-byte "é" cut there is not a broken file, but
    a broken byte well before the end is. Mutant: the margin added instead of subtracted."""
    head = "movie,area\n"
    filler = "a" * (2047 - len(head) - len(",1\n"))  # "é" starts at byte 2047
    (tmp_path / "ok.csv").write_text(head + filler + ",1\né,2\n", encoding="utf-8")
    back = read_table(tmp_path / "ok.csv")
    assert back["movie"].tolist() == [filler, "é"]
    (tmp_path / "bad.csv").write_bytes(b"movie,area\n\xff\xfe,1\n" + b"x,2\n" * 600)
    with pytest.raises(InputError, match="not a UTF-8 text file"):
        read_table(tmp_path / "bad.csv")


def test_leading_singleton_axes_are_dropped_down_to_a_time_lapse(tmp_path):
    """A (1, 1, Y, X) array without axis names is a one-frame time-lapse (1, Y, X): only the
    axes beyond three go. Mutant: ``ndim + i`` (every leading singleton axis dropped)."""
    zarr = pytest.importorskip("zarr")
    from napari_pfsdm.batch import open_movie

    z = zarr.create_array(str(tmp_path / "m.zarr"), shape=(1, 1, 16, 20), dtype="uint8",
                          chunks=(1, 1, 16, 20), zarr_format=2)
    z[:] = 1
    assert open_movie(tmp_path / "m.zarr").shape == (1, 16, 20)


def test_a_short_arm_of_a_y_is_pruned_and_the_long_ones_kept():
    """A Y: a stem of 20 px, a long arm of 10 px, a short arm of 3 px meeting the stem's end
    diagonally. The short arm reaches the junction through one neighbour that has three, so
    it is a side branch (< 5 px): removed; the rest is kept. Mutant: ``and`` for ``or`` in
    the junction test (the walk then passes the junction and keeps the arm)."""
    from napari_pfsdm.core.medial_axis import prune_branches

    skel = np.zeros((40, 30), bool)
    skel[2:21, 10] = True  # stem, junction at (20, 10)
    for k in range(1, 11):
        skel[20 + k, 10 + k] = True  # long arm, down-right
    short = [(20 + k, 10 - k) for k in range(1, 4)]
    for q in short:
        skel[q] = True
    out = prune_branches(skel, min_length=5)
    assert not any(out[q] for q in short)
    assert out[2:21, 10].all() and all(out[20 + k, 10 + k] for k in range(1, 11))


# ---- survivors of the second run --------------------------------------------------------

def _ball(radius: float = 8.0, size: int = 24) -> np.ndarray:
    zz, yy, xx = np.mgrid[:size, :size, :size] - (size - 1) / 2
    return zz**2 + yy**2 + xx**2 < radius**2


def test_thousands_of_rays_in_chunks_all_meet_a_balls_surface_at_its_radius():
    """Rays from a ball's centre leave it at its radius (one exit each), for more rays than one
    chunk holds. Mutant: chunks written one ray too long."""
    from napari_pfsdm.core.descriptor3d import pfsdm3d

    res = pfsdm3d(_ball(), n_radii=4, sh_degree=4)
    rng = np.random.default_rng(2)
    dirs = rng.normal(size=(25000, 3))  # a chunk holds 400,000 samples: ~10,000 rays here
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    r, exits = res.mapping.rays(dirs)
    assert r.shape == (25000,) and (exits == 1).all()
    np.testing.assert_allclose(r, 8.0, atol=0.7)  # a raster ball: within a voxel's reach
    np.testing.assert_allclose(r.mean(), res.diagnostics["scale"], rtol=0.02)


@pytest.mark.parametrize("weight", [-1.0, float("nan"), float("inf")])
def test_a_negative_or_missing_surface_weight_is_refused(weight):
    """pfsdm3d checks its options through the record (core.params): a negative, NaN or
    infinite weight is refused in the record's words."""
    from napari_pfsdm.core.descriptor3d import pfsdm3d

    with pytest.raises(InputError, match=r"surface_weight must be a number from 0 to 1e\+12; got"):
        pfsdm3d(_ball(), n_radii=4, sh_degree=4, surface_weight=weight)


def test_shell_maps_take_radii_from_0_to_1():
    """The shell at r = 0 is the centre: one value everywhere. Mutant: 0 refused."""
    from napari_pfsdm.core.descriptor3d import pfsdm3d, shell_maps

    res = pfsdm3d(_ball(), n_radii=4, sh_degree=4)
    images, theta, phi = shell_maps(res, radii=(0.0, 1.0), n_lat=8, n_lon=16)
    assert images.shape == (2, 8, 16)
    np.testing.assert_allclose(images[0], images[0, 0, 0], atol=1e-12)
    assert images[0, 0, 0] < -0.8  # the centre of a ball: about one radius deep, normalised
    with pytest.raises(InputError, match=r"Shell radii must lie in \[0, 1\]"):
        shell_maps(res, radii=(-0.1, 0.5))


def test_the_efa_outline_keeps_every_point_counter_clockwise():
    """mask_contour is skimage's find_contours outline (the longest, without its repeated end
    point), turned counter-clockwise. Mutant: every other point kept when turning it."""
    from skimage.measure import find_contours

    from napari_pfsdm.analysis.baselines import mask_contour

    mask = np.zeros((40, 50), bool)
    mask[5:30, 8:20] = True
    mask[5:12, 8:45] = True  # an L
    ref = max(find_contours(np.pad(mask.astype(float), 1), 0.5), key=len)[:-1] - 1.0
    got = mask_contour(mask)
    assert len(got) == len(ref)
    x, y = got[:, 1], got[:, 0]
    area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)  # shoelace, (row, col)
    assert abs(abs(area) - abs(0.5 * np.sum(ref[:, 1] * np.roll(ref[:, 0], -1)
                                            - np.roll(ref[:, 1], -1) * ref[:, 0]))) < 1e-9
    assert {tuple(p) for p in got.tolist()} == {tuple(p) for p in ref.tolist()}


def test_an_object_in_pieces_is_warned_about():
    """Mutant: the number of pieces read as 1 whatever the diagnostics say."""
    lab = np.zeros((60, 60), np.uint8)
    lab[5:30, 5:30] = 1
    lab[40:50, 40:50] = 1  # a second, smaller piece of object 1
    table = P.measure(lab)
    assert table.loc[0, "warnings"] == "2 pieces, the largest kept"
    assert table.loc[0, "area"] == 725  # the label's pixels, both pieces (as regionprops)


def test_explain_components_words_the_correlations():
    """PC1 follows circularity exactly (r = +1); PC2 is unrelated to both measures given."""
    from napari_pfsdm.analysis.interpretation import explain_components

    s = pd.DataFrame({"frame": 0, "label": [1, 2, 3, 4], "PC1": [1.0, 2.0, 3.0, 4.0],
                      "PC2": [1.0, -1.0, -1.0, 1.0], "PC3": [0.0, 1.0, 0.0, 2.0]})
    m = pd.DataFrame({"frame": 0, "label": [1, 2, 3, 4],
                      "circularity": [0.2, 0.4, 0.6, 0.8], "solidity": [0.5, 0.6, 0.7, 0.8]})
    out = explain_components(s, m, ratios=[0.6], n=2)
    assert len(out) == 2  # n = 2 of the three PCs
    assert out[0].startswith("PC1 (60 %) follows circularity (4πA/P²), r = +1.00")
    assert out[1].startswith("PC2 is none of the classic measures (largest |r| = 0.00")


def test_standardized_pca_ignores_a_constant_feature():
    """A feature that never changes has no variance to scale: it is left as it is (0 after
    centring), not divided by 0. Mutant: ``sd >= 0`` (0/0 = NaN everywhere)."""
    from napari_pfsdm.analysis.reduction import pca_scores

    lab = np.zeros((60, 200), np.uint16)
    yy, xx = np.mgrid[:60, :200]
    for k, (a, b) in enumerate([(20, 10), (15, 15), (22, 8), (12, 18)]):
        lab[((yy - 30) / a) ** 2 + ((xx - 25 - 50 * k) / b) ** 2 <= 1] = k + 1
    table = P.measure(lab, n_fourier=4, n_radii=4)
    table["shape_r00_n01"] = 0.125  # constant
    scores, explained = pca_scores(table, "shape", n_components=2, standardize=True)
    assert np.isfinite(scores[["shape_PC1", "shape_PC2"]].to_numpy()).all()
    assert np.isfinite(explained).all() and 0 < explained.sum() <= 1


def test_an_empty_tracks_layer_names_no_object():
    from napari_pfsdm.analysis.tracking import track_ids_from_tracks

    table = pd.DataFrame({"frame": [0, 1], "label": [1, 1], "centroid_y": [5.0, 6.0],
                          "centroid_x": [5.0, 6.0], "area": [50.0, 50.0]})
    got = track_ids_from_tracks(np.zeros((0, 4)), table)
    assert np.asarray(got).tolist() == [-1, -1]


def test_classify_accepts_the_smallest_split_it_can_make():
    """Two objects of each group, --test-size 0.5: 2 test and 2 training objects, the least a
    split may hold (allowed); five objects at 0.2 leave 1 test object (refused in plain
    words). Mutant: ``n_train <= 2``."""
    from napari_pfsdm.analysis.prediction import make_splits

    splits = make_splits(np.array([1, 1, 0, 0]), test_size=0.5)
    assert all(len(test) == 2 and len(train) == 2 for train, test in splits)
    with pytest.raises(InputError, match="too few for a 20% test split"):
        make_splits(np.array([1, 1, 1, 0, 0]), test_size=0.2)
