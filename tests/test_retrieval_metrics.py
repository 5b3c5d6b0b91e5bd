"""Bull's-eye and leave-one-out 1-NN on hand-made matrices whose scores are known exactly."""

import numpy as np
import pytest

from napari_pfsdm.analysis.retrieval import bullseye, loo_1nn, nearest


def _points_matrix(x):
    x = np.asarray(x, dtype=float)
    return np.abs(x[:, None] - x[None, :])


def test_perfectly_separated_classes_score_100():
    # two tight clusters on a line, far apart
    D = _points_matrix([0.0, 0.1, 0.2, 10.0, 10.1, 10.2])
    labels = ["a", "a", "a", "b", "b", "b"]
    res = bullseye(D, labels, k=6)
    assert res.score == 100.0
    assert res.per_class == {"a": 100.0, "b": 100.0}
    assert loo_1nn(D, labels) == 100.0


def test_bullseye_counts_query_and_divides_by_class_size():
    # 1-D positions: a0=0, b0=1, a1=2, b1=3 ; classes of size 2, k = 2
    D = _points_matrix([0.0, 1.0, 2.0, 3.0])
    labels = np.array(["a", "b", "a", "b"])
    # query a0 (0): nearest 2 = {a0, b0} -> 1 hit / 2
    # query b0 (1): {b0, then tie a0 (idx 0) vs a1 (idx 2) -> a0} -> 1/2
    # query a1 (2): {a1, tie b0 (1) vs b1 (3) -> b0} -> 1/2
    # query b1 (3): {b1, a1} -> 1/2
    res = bullseye(D, labels, k=2)
    assert res.score == pytest.approx(50.0)
    np.testing.assert_allclose(res.per_query, [50, 50, 50, 50])
    # with k = 3: a0 -> {a0, b0, a1} 2/2; b0 -> {b0, a0, a1} 1/2;
    # a1 -> {a1, b0, b1} 1/2; b1 -> {b1, a1, b0} 2/2
    res3 = bullseye(D, labels, k=3)
    np.testing.assert_allclose(res3.per_query, [100, 50, 50, 100])
    assert res3.per_class == {"a": 75.0, "b": 75.0}
    assert res3.score == pytest.approx(75.0)


def test_query_is_included_even_when_another_item_is_at_distance_zero():
    # items 0 and 1 are duplicates of different classes: the query must still count itself
    D = np.array([[0.0, 0.0, 4.0], [0.0, 0.0, 4.0], [4.0, 4.0, 0.0]])
    labels = ["a", "b", "b"]
    res = bullseye(D, labels, k=1)
    np.testing.assert_allclose(res.per_query, [100.0, 50.0, 50.0])
    # leave-one-out: 0 -> 1 (b, miss); 1 -> 0 (a, miss); 2 -> 0 (tie 0/1 by index: a, miss)
    assert loo_1nn(D, labels) == 0.0


def test_loo_excludes_the_query_and_uses_rows_as_queries():
    # asymmetric matrix: row i ranks for query i
    D = np.array(
        [
            [0.0, 1.0, 2.0, 3.0],
            [9.0, 0.0, 1.0, 9.0],  # query 1 (a) -> 2 (b): miss
            [9.0, 9.0, 0.0, 1.0],  # query 2 (b) -> 3 (b): hit
            [1.0, 9.0, 9.0, 0.0],  # query 3 (b) -> 0 (a): miss
        ]
    )
    labels = ["a", "a", "b", "b"]
    assert loo_1nn(D, labels) == 50.0  # query 0 -> 1 (a): hit


def test_nan_distances_are_ranked_last():
    D = np.array([[0.0, np.nan, 5.0], [np.nan, 0.0, np.nan], [5.0, np.nan, 0.0]])
    labels = ["a", "a", "b"]
    # query 0: nearest other is 2 (b) since the NaN to 1 counts as infinite: miss;
    # query 1 has no finite distance: miss; query 2 -> 0 (a): miss
    assert loo_1nn(D, labels) == 0.0
    # one hit once query 1 can see item 0
    D[1, 0] = 3.0
    assert loo_1nn(D, labels) == pytest.approx(100.0 / 3.0)
    np.testing.assert_array_equal(nearest(D, 0, 2), [2, 1])
    np.testing.assert_array_equal(nearest(D, 0, 2, include_self=True), [0, 2])


def test_mpeg7_sized_random_ranking_is_near_chance():
    # 5 classes x 20, random distances: expected bull's-eye ~ (1 + 39 * 19/99) / 20
    rng = np.random.default_rng(0)
    n = 100
    A = rng.random((n, n))
    D = A + A.T
    np.fill_diagonal(D, 0.0)
    labels = np.repeat(np.arange(5), 20)
    res = bullseye(D, labels, k=40)
    expected = 100 * (1 + 39 * 19 / 99) / 20
    assert abs(res.score - expected) < 3.0
    assert set(res.per_class) == {"0", "1", "2", "3", "4"}


def test_errors_are_plain_language():
    with pytest.raises(ValueError, match="square"):
        bullseye(np.zeros((2, 3)), ["a", "b"])
    with pytest.raises(ValueError, match="one label per row"):
        loo_1nn(np.zeros((3, 3)), ["a", "b"])
    with pytest.raises(ValueError, match="k must be"):
        bullseye(np.zeros((2, 2)), ["a", "b"], k=0)
