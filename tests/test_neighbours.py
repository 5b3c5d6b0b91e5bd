"""nearest_neighbours: the k nearest objects under the default distance, checked
against an independent reference, ``np.argsort`` of ``distance_matrix``'s rows."""

import time

import numpy as np
import pytest

import napari_pfsdm as pf
from napari_pfsdm.analysis.features import iter_objects
from napari_pfsdm.analysis.neighbours import neighbour_index
from napari_pfsdm.core import neighbours as core_nn
from napari_pfsdm.core.boundary import (
    boundary_distance_matrix,
    boundary_distance_pairs,
    boundary_lower_bound,
)
from napari_pfsdm.core.distances import Embeddings
from napari_pfsdm.data.moving_blobs import make_moving_blobs
from napari_pfsdm.errors import InputError
from unguarded_script import run_once

K = 10


@pytest.fixture(scope="module")
def blobs():
    """About 200 deforming blobs (with a reporter), their results and their table."""
    movie = make_moving_blobs(n_objects=25, n_frames=8, size=320, radius=(10.0, 16.0), seed=3)
    yy, xx = np.mgrid[: movie.labels.shape[1], : movie.labels.shape[2]]
    image = np.stack([1.0 + np.sin(xx / (7.0 + t)) ** 2 + yy / 400.0
                      for t in range(len(movie.labels))])
    objs = [o for o in iter_objects(movie.labels, image) if o.result is not None
            and o.result.intensity_embedding is not None]
    results = [o.result for o in objs]
    table = pf.drop_failed(pf.measure(movie.labels, image), intensity=True)
    keys = [(o.frame, o.label) for o in objs]
    table = table.set_index(["frame", "label"]).loc[keys].reset_index()
    table.attrs = pf.measure(movie.labels[:1]).attrs | table.attrs
    return results, table


def reference(d: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """k nearest by sorting the full matrix: self excluded, equal distances by row number."""
    d = d.copy()
    np.fill_diagonal(d, np.inf)
    order = np.argsort(d, axis=1, kind="stable")[:, :k]
    return order, np.take_along_axis(d, order, 1)


@pytest.mark.parametrize("method", ["bound", "brute"])
def test_neighbours_are_the_sorted_rows_of_the_distance_matrix(blobs, method):
    results, _ = blobs
    assert len(results) > 150
    d = pf.distance_matrix(results)
    ref_idx, ref_d = reference(d, K)
    idx, dist = pf.nearest_neighbours(results, K, method=method)
    assert idx.shape == dist.shape == (len(results), K)
    assert (idx != np.arange(len(results))[:, None]).all()  # never itself
    np.testing.assert_array_equal(idx, ref_idx)  # exact, nearest first
    np.testing.assert_allclose(dist, ref_d, rtol=0, atol=1e-7)
    assert (np.diff(dist, axis=1) >= 0).all()


def test_a_small_pool_falls_back_to_every_object(blobs, monkeypatch):
    results, _ = blobs
    d = pf.distance_matrix(results)
    monkeypatch.setattr(core_nn, "_POOL", 1)  # pools of 2k = 20: many queries need more
    ref_idx, ref_d = reference(d, K)
    idx, dist = pf.nearest_neighbours(results, K)
    np.testing.assert_array_equal(idx, ref_idx)
    np.testing.assert_allclose(dist, ref_d, rtol=0, atol=1e-7)


def test_boundary_weight_and_intensity_weight_reach_the_distance(blobs):
    results, _ = blobs
    for lam, w_i in [(0.5, 0.0), (0.0, 0.0), (1.0, 0.7)]:
        d = pf.distance_matrix(results, w_i, boundary_weight=lam)
        idx, dist = pf.nearest_neighbours(results, K, intensity_weight=w_i,
                                          boundary_weight=lam)
        ref_idx, ref_d = reference(d, K)
        np.testing.assert_array_equal(idx, ref_idx)
        np.testing.assert_allclose(dist, ref_d, rtol=0, atol=1e-7)


def test_a_table_gives_the_neighbours_of_its_results(blobs):
    results, table = blobs
    assert len(table) == len(results)
    idx_r, dist_r = pf.nearest_neighbours(results, K, intensity_weight=0.5)
    idx_t, dist_t = pf.nearest_neighbours(table, K, intensity_weight=0.5)
    np.testing.assert_array_equal(idx_t, idx_r)
    np.testing.assert_allclose(dist_t, dist_r, rtol=0, atol=1e-9)


def test_copies_tie_by_row_number_and_are_never_their_own_neighbour(blobs):
    results, _ = blobs
    items = results[:40] + results[:5]  # rows 40..44 are copies of rows 0..4
    idx, dist = pf.nearest_neighbours(items, 3)
    for i in range(5):
        assert idx[i, 0] == 40 + i and idx[40 + i, 0] == i
        assert dist[i, 0] < 1e-7
    # copies are equal to rounding only (~1e-12, in the matrix too): same distances, and
    # the same neighbours wherever the reference has no such near tie
    d = pf.distance_matrix(items)
    ref_idx, ref_d = reference(d, 3)
    np.testing.assert_allclose(dist, ref_d, atol=1e-7)
    np.testing.assert_allclose(np.take_along_axis(d, idx, 1), dist, atol=1e-7)
    gaps = np.diff(np.sort(d + np.diag(np.full(len(d), np.inf)), axis=1)[:, :4], axis=1)
    clear = (gaps[:, :3] > 1e-7) & np.hstack([np.ones((len(d), 1), bool), gaps[:, :2] > 1e-7])
    assert clear.sum() > 100
    np.testing.assert_array_equal(idx[clear], ref_idx[clear])


def test_k_must_leave_out_the_object_itself(blobs):
    results, _ = blobs
    items = results[:12]
    idx, dist = pf.nearest_neighbours(items, 11)  # everyone else
    assert all(sorted(row) == sorted(set(range(12)) - {i}) for i, row in enumerate(idx))
    for bad in (0, 12, 2.5):
        with pytest.raises(InputError):
            pf.nearest_neighbours(items, bad)


def test_rows_without_features_are_nobodys_neighbour(blobs):
    results, _ = blobs
    items = results[:60]
    f = np.stack([r.embedding for r in items])
    a = np.stack([r.outline for r in items])
    f[7] = np.nan
    a[9] = np.nan
    emb = Embeddings(shape=f, weights=items[0].weights, mode_weights=items[0].mode_weights,
                     outline=a)
    idx, dist = pf.nearest_neighbours(emb, 5)
    assert (idx[[7, 9]] == -1).all() and np.isnan(dist[[7, 9]]).all()
    assert not np.isin(idx, [7, 9]).any()
    keep = np.setdiff1d(np.arange(60), [7, 9])
    ref_idx, ref_d = reference(pf.distance_matrix([items[i] for i in keep]), 5)
    np.testing.assert_array_equal(idx[keep], keep[ref_idx])
    np.testing.assert_allclose(dist[keep], ref_d, atol=1e-7)


def test_the_lower_bound_is_below_the_distance(blobs, rng):
    results, _ = blobs
    a = np.stack([r.outline for r in results])
    # turned, mirrored and restarted copies: d_B ~ 0, the bound must not exceed it
    k = a.shape[1] // 2
    n_modes = np.concatenate([-np.arange(1, k + 1)[::-1], np.arange(1, k + 1)])
    turned = a[:20] * np.exp(1j * rng.uniform(0, 6.3, (20, 1)))
    restarted = a[:20] * np.exp(1j * n_modes * rng.uniform(0, 6.3, (20, 1)))
    mirrored = np.conj(a[:20])[:, ::-1]
    every = np.vstack([a, turned, restarted, mirrored])
    lb, d_b = boundary_lower_bound(every), boundary_distance_matrix(every)
    assert (lb <= d_b + 1e-7).all()
    assert np.median(lb[np.triu_indices(len(every), 1)]) > 0.2 * np.median(d_b)  # not trivial
    # the search's own single-precision bound of the whole distance, on random pairs
    index = neighbour_index(results)
    rows = rng.choice(len(results), 40, replace=False)
    bound = core_nn._lower_bound(index, rows).astype(float)
    d = pf.distance_matrix(results)[rows]
    off = np.isfinite(bound)
    assert (bound[off] <= d[off]).all()
    assert np.median(bound[off] / d[off]) > 0.5


def test_boundary_distance_pairs_are_the_matrix_entries(blobs, rng):
    results, _ = blobs
    a = np.stack([r.outline for r in results])
    d_b = boundary_distance_matrix(a)
    i, j = rng.integers(0, len(a), (2, 500))
    i, j = np.minimum(i, j), np.maximum(i, j)
    np.testing.assert_allclose(boundary_distance_pairs(a[i], a[j]), d_b[i, j], atol=1e-7)


def test_dask_schedulers_and_a_local_cluster_give_the_local_neighbours(blobs):
    distributed = pytest.importorskip("distributed")
    results, table = blobs
    idx, dist = pf.nearest_neighbours(table, K, n_jobs=1)
    with distributed.LocalCluster(n_workers=2, processes=False, threads_per_worker=1,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        got = pf.nearest_neighbours(table, K, client=client, block=50)  # 4 tasks
        for _ in range(100):  # the scattered index and the blocks are released (async)
            if not client.who_has():
                break
            time.sleep(0.05)
        assert not client.who_has()
        again = pf.nearest_neighbours(results, K, scheduler=cluster.scheduler_address,
                                      block=64)
    sync = pf.nearest_neighbours(table, K, scheduler="sync", block=70)
    threads = pf.nearest_neighbours(table, K, n_jobs=2, block=30)
    processes = pf.nearest_neighbours(table, K, scheduler="processes", block=100)
    for other in (got, again, sync, threads, processes):
        np.testing.assert_array_equal(other[0], idx)
        # blocks group the exact pairs differently: single-precision coarse searches may
        # differ in the last bit, the refined distances by ~1e-15
        np.testing.assert_allclose(other[1], dist, rtol=0, atol=1e-12)


def test_a_script_without_a_main_guard_finds_neighbours_once_in_processes(tmp_path):
    """The 'processes' scheduler's workers do not import the caller's script: one with no
    ``if __name__ == "__main__":`` runs once (not again in every worker, which stopped them)."""
    out = run_once(tmp_path, [
        "import napari_pfsdm as pf",
        "from napari_pfsdm.data.moving_blobs import make_moving_blobs",
        "movie = make_moving_blobs(n_objects=6, n_frames=2, size=160, entering=0, leaving=0,"
        " division=False, radius=(10.0, 14.0), seed=1)",
        "table = pf.measure(movie.labels)",
        "idx, _ = pf.nearest_neighbours(table, 3, scheduler='processes', block=4)",
        "print('rows', len(idx))"])
    assert "rows 12" in out


def test_volumes_by_shells_and_surface_term(rng):
    from napari_pfsdm.data.volumes import blob_volume, random_rotation

    vols = [blob_volume(name, size=40, radius=10, rotation=random_rotation(rng))
            for name in ("tetrahedron", "line", "tetrahedron", "line", "tetrahedron")]
    results = [pf.pfsdm(v) for v in vols]
    idx, dist = pf.nearest_neighbours(results, 2)
    ref_idx, ref_d = reference(pf.distance_matrix(results), 2)
    np.testing.assert_array_equal(idx, ref_idx)
    np.testing.assert_allclose(dist, ref_d, atol=1e-7)
    with pytest.raises(InputError, match="boundary_weight"):
        pf.nearest_neighbours(results, 2, boundary_weight=1.0)
