"""Numbers held to references computed independently of the package: scikit-learn's PCA,
classical MDS of a known configuration, scikit-image's regionprops, closed forms of the ring
weights (none reads its expected value from the code under test; several kill a mutant that
no other test sees)."""

from __future__ import annotations

import re

import numpy as np
import pytest
from scipy.spatial.distance import pdist, squareform
from skimage.measure import regionprops
from sklearn.decomposition import PCA

import napari_pfsdm as P
from napari_pfsdm.analysis.reduction import mds_coordinates, pca_scores


def ellipses() -> np.ndarray:
    """Eight objects of different shapes in one frame (ellipses, rectangles, an L)."""
    yy, xx = np.mgrid[:120, :480]
    lab = np.zeros((120, 480), np.uint16)
    for k, (a, b) in enumerate([(20, 20), (25, 12), (30, 8), (18, 14)]):
        lab[((yy - 30) / a) ** 2 + ((xx - 40 - 110 * k) / b) ** 2 <= 1] = k + 1
    lab[70:110, 20:40] = 5
    lab[70:90, 120:190] = 6
    lab[70:110, 240:255] = 7
    lab[95:110, 240:290] = 7  # an L
    lab[65:115, 360:372] = 8
    return lab


@pytest.fixture(scope="module")
def table():
    return P.measure(ellipses(), n_fourier=6, n_radii=8)


def by_hand_features(table) -> np.ndarray:
    """The shape features scaled as docs/design.md §2.6 says, with the weights written out:
    rings r_i = (i + ½)/8, cell width 1/8, ring weight (1/8)/(1 − r_i)² ("depth", the default),
    mode weight (1 + n)^0.25 (the default exponent)."""
    cols = [c for c in table.columns if re.fullmatch(r"shape_r\d\d_n\d\d", c)]
    assert len(cols) == 8 * 7
    x = table[cols].to_numpy(float).reshape(len(table), 8, 7)
    r = (np.arange(8) + 0.5) / 8
    w = (1 / 8) / (1 - r) ** 2
    return (x * np.sqrt(w)[None, :, None] * (1.0 + np.arange(7))[None, None, :] ** 0.25
            ).reshape(len(table), -1)


def aligned(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a`` with each column's sign flipped to match ``b`` (components are up to sign)."""
    return a * np.sign(np.sum(a * b, axis=0))[None, :]


def test_pca_explained_variance_and_scores_are_scikit_learns(table):
    x = by_hand_features(table)
    ref = PCA(n_components=3, svd_solver="full").fit(x)
    scores, explained = pca_scores(table, "shape", n_components=3)
    # the share of the *total* variance: with 3 of 8 components kept they sum to less than 1
    np.testing.assert_allclose(explained, ref.explained_variance_ratio_, rtol=1e-9)
    assert explained.sum() < 0.9999
    got = scores[["shape_PC1", "shape_PC2", "shape_PC3"]].to_numpy()
    want = ref.transform(x)
    np.testing.assert_allclose(aligned(got, want), want, rtol=1e-8, atol=1e-10)


def test_standardized_pca_is_scikit_learns_on_unit_variance_features(table):
    cols = [c for c in table.columns if re.fullmatch(r"shape_r\d\d_n\d\d", c)]
    x = table[cols].to_numpy(float)
    sd = x.std(axis=0)
    z = (x - x.mean(axis=0)) / np.where(sd > 0, sd, 1.0)
    ref = PCA(n_components=2, svd_solver="full").fit(z)
    scores, explained = pca_scores(table, "shape", n_components=2, standardize=True)
    np.testing.assert_allclose(explained, ref.explained_variance_ratio_, rtol=1e-9)
    got = scores[["shape_PC1", "shape_PC2"]].to_numpy()
    np.testing.assert_allclose(aligned(got, ref.transform(z)), ref.transform(z), atol=1e-9)


def test_weighted_features_are_the_weights_written_out(table):
    np.testing.assert_allclose(P.weighted_features(table), by_hand_features(table),
                               rtol=1e-12, atol=1e-15)


def test_classical_mds_of_a_known_configuration_is_its_principal_axes():
    # six points in 3-D with clearly different spreads along three axes: classical MDS of
    # their Euclidean distances is their PCA (Torgerson), so scikit-learn's PCA is the answer
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(6, 3)) * np.array([5.0, 2.0, 0.3])
    d = squareform(pdist(pts))
    xy = mds_coordinates(d, 2)
    want = PCA(n_components=2, svd_solver="full").fit_transform(pts)
    np.testing.assert_allclose(aligned(xy, want), want, atol=1e-9)
    # and the exact square: 4 corners of a unit square, distances 1 and sqrt(2)
    sq = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    xy = mds_coordinates(squareform(pdist(sq)), 2)
    np.testing.assert_allclose(squareform(pdist(xy)), squareform(pdist(sq)), atol=1e-12)
    np.testing.assert_allclose(np.abs(xy).max(), np.sqrt(0.5), atol=1e-12)  # on a circle


def test_a_rank_one_configuration_gets_zero_second_coordinates():
    line = np.array([[0.0], [1.0], [3.0], [7.0]])
    xy = mds_coordinates(squareform(pdist(line)), 2)
    np.testing.assert_allclose(np.abs(xy[:, 0]), np.abs(line[:, 0] - 2.75), atol=1e-12)
    np.testing.assert_allclose(xy[:, 1], 0.0, atol=1e-7)


def test_area_and_centroid_are_regionprops(table):
    lab = ellipses()
    props = {p.label: p for p in regionprops(lab)}
    assert table["label"].tolist() == sorted(props)
    for _, row in table.iterrows():
        p = props[int(row["label"])]
        assert row["area"] == p.area
        assert row["centroid_y"] == pytest.approx(p.centroid[0], abs=1e-9)
        assert row["centroid_x"] == pytest.approx(p.centroid[1], abs=1e-9)
        assert row["touches_border"] == (p.bbox[0] == 0 or p.bbox[1] == 0
                                         or p.bbox[2] == lab.shape[0]
                                         or p.bbox[3] == lab.shape[1])
