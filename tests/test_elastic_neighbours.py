"""Nearest neighbours with the elastic term (core.elastic_neighbours) against the full matrix."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import napari_pfsdm as pf
from napari_pfsdm.analysis.neighbours import Neighbours


def _blobs(n: int, seed: int):
    """The first n described objects of a moving-blobs movie, measured with the signature."""
    from napari_pfsdm.core.table_options import carry_options
    from napari_pfsdm.data.moving_blobs import make_moving_blobs

    movie = make_moving_blobs(n_objects=60, n_frames=int(np.ceil(n / 55)), size=400,
                              radius=(10.0, 16.0), seed=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = pf.drop_failed(pf.measure(movie.labels, elastic_signature="table"))
    assert len(table) >= n
    return carry_options(table, table.iloc[:n].reset_index(drop=True))


def _sorted_rows(matrix: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    d = np.array(matrix, float)
    np.fill_diagonal(d, np.inf)
    idx = np.argsort(d, axis=1, kind="stable")[:, :k]
    return idx, d


def _agreement(found: np.ndarray, truth: np.ndarray, d: np.ndarray) -> tuple[float, np.ndarray]:
    """recall@k of ``found`` against ``truth``, and per row whether every neighbour found is
    one of the matrix's k nearest up to ties (its distance within 1e-6 of the k-th)."""
    recall = (found[:, :, None] == truth[:, None, :]).any(axis=2).mean()
    kth = np.take_along_axis(d, truth[:, -1:], 1)
    right = (np.take_along_axis(d, found, 1) <= kth + 1e-6).all(axis=1)
    return float(recall), right


@pytest.mark.slow
def test_the_elastic_neighbours_are_the_full_matrix_s_where_the_elastic_term_dominates():
    # round blobs with a large elastic weight: the default distance says little about the
    # total's order (each object's 120 nearest under it hold 0.95 of the total's 10 nearest
    # here), the term's own candidates hold them (0.99 measured)
    table = _blobs(500, seed=1)
    mu, k = 3.0, 10
    truth, d = _sorted_rows(pf.distance_matrix(table, elastic_weight=mu), k)
    found = pf.nearest_neighbours(table, k=k, elastic_weight=mu)
    recall, right = _agreement(found.indices, truth, d)
    assert recall >= 0.98
    # the distances are the matrix's entries: D computed pair by pair, as the default
    # search does (to 1e-6, but for pairs whose boundary term has two nearly equal start
    # shifts: up to 2e-3, docs/benchmarks.md), d_E the same kernel's
    err = np.abs(found.distances - np.take_along_axis(d, found.indices, 1))
    assert np.mean(err <= 1e-6) >= 0.999 and err.max() < 2e-3
    assert np.all(right[found.certified])  # a certificate never lies
    pool, cand = found.depth
    assert k <= cand <= pool <= len(table) - 1


def test_brute_is_the_sorted_rows_of_the_matrix_and_says_so():
    table = _blobs(60, seed=2)
    mu, k = 0.5, 5
    truth, d = _sorted_rows(pf.distance_matrix(table, elastic_weight=mu), k)
    found = pf.nearest_neighbours(table, k=k, elastic_weight=mu, method="brute")
    _, right = _agreement(found.indices, truth, d)
    assert right.all() and found.exact
    assert np.allclose(found.distances, np.take_along_axis(d, found.indices, 1), atol=1e-6)


def _shapes_labels(rows: int = 6) -> np.ndarray:
    """Squares, bars, ellipses and plus signs of a few sizes (8 per row of tiles): kinds far
    apart in the default distance, so that its lower bound certifies rows."""
    yy, xx = np.mgrid[:64, :64]
    tiles = []
    for i in range(8 * rows):
        s = 14 + (i % 6) * 2
        tile = np.zeros((64, 64), int)
        kind = i % 4
        if kind == 0:
            tile[32 - s // 2: 32 + s // 2, 32 - s // 2: 32 + s // 2] = 1
        elif kind == 1:
            tile[32 - s // 4: 32 + s // 4, 32 - s: 32 + s] = 1
        elif kind == 2:
            tile[((yy - 32) / s) ** 2 + ((xx - 32) / (0.6 * s)) ** 2 < 1] = 1
        else:
            tile[32 - s // 5: 32 + s // 5, 32 - s: 32 + s] = 1
            tile[32 - s: 32 + s, 32 - s // 5: 32 + s // 5] = 1
        tiles.append(tile * (i + 1))
    return np.vstack([np.hstack(tiles[r * 8:(r + 1) * 8]) for r in range(rows)])


def test_certified_rows_are_right_and_the_result_unpacks_as_before():
    table = pf.measure(_shapes_labels(25), elastic_signature="table")
    mu, k = 0.05, 3
    truth, d = _sorted_rows(pf.distance_matrix(table, elastic_weight=mu), k)
    found = pf.nearest_neighbours(table, k=k, elastic_weight=mu)
    idx, dist = found  # a pair, as without the term
    assert isinstance(found, Neighbours) and idx is found.indices and dist is found.distances
    _, right = _agreement(idx, truth, d)
    assert 0.2 < found.certified.mean() and np.all(right[found.certified])
    assert ("exact" if found.exact else "approximate") in found.describe()
    plain = pf.nearest_neighbours(table, k=k)
    assert plain.exact and plain.certified.all() and plain.depth is None


def test_the_depth_is_measured_and_follows_the_objects():
    # near-identical round blobs need a deeper pool than kinds far apart; the same seed, the
    # same depth
    from napari_pfsdm.analysis.neighbours import _signatures, neighbour_index
    from napari_pfsdm.core.elastic_neighbours import MIN_POOL, ElasticIndex, depth

    blobs = _blobs(400, seed=3)
    ei = ElasticIndex.build(neighbour_index(blobs), _signatures(blobs))
    first = depth(ei, 3.0, 10)
    assert first == depth(ei, 3.0, 10)
    shapes = pf.measure(_shapes_labels(), elastic_signature="table")
    ei2 = ElasticIndex.build(neighbour_index(shapes), _signatures(shapes))
    # 48 objects: every other object is a candidate, every row exact
    assert depth(ei2, 0.05, 3) == (47, 47)
    assert pf.nearest_neighbours(shapes, k=3, elastic_weight=0.05).exact
    assert first[0] > MIN_POOL
