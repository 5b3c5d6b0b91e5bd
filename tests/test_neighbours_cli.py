"""``pfsdm compare --neighbours K``: the edge list, its round trip through a plain
``pandas.read_csv``, re-ranking on the graph, and the map drawn from the graph above
``FULL_MATRIX_LIMIT``. Expected neighbours come from ``np.argsort`` of the full matrix."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import tifffile

import napari_pfsdm as P
from napari_pfsdm.analysis.rerank import rerank
from napari_pfsdm.cli import compare as compare_command
from napari_pfsdm.cli import main
from napari_pfsdm.io import read_table
from test_cli_options import three_objects

FAST = ["--n-fourier", "6", "--n-radii", "8", "--scheduler", "sync", "-q"]


def _exact_neighbours(items, k=10, *, intensity_weight=0.0, boundary_weight=None, **_):
    d = P.distance_matrix(items, intensity_weight, boundary_weight=boundary_weight)
    order = np.argsort(d + np.diag(np.full(len(d), np.inf)), axis=1, kind="stable")[:, :k]
    return order, np.take_along_axis(d, order, axis=1)


@pytest.fixture(autouse=True)
def neighbours_available(monkeypatch):
    """Until napari_pfsdm.nearest_neighbours exists (branch issue23-nn), the exact one."""
    try:
        P.nearest_neighbours  # noqa: B018
    except AttributeError:
        monkeypatch.setattr(P, "nearest_neighbours", _exact_neighbours, raising=False)


def _objects(n_frames=4):
    """Three objects per frame that change shape over time: 12 rows."""
    return three_objects(n_frames)[0]  # the CLI tests' movie (tests/test_cli_options.py)


@pytest.fixture(scope="module")
def features(tmp_path_factory):
    folder = tmp_path_factory.mktemp("nn")
    tifffile.imwrite(folder / "m.tif", _objects(), photometric="minisblack")
    out = folder / "features.csv"
    assert main(["measure", str(folder / "m.tif"), "-o", str(out), "--link", "labels",
                 *FAST]) == 0
    return out


def _full(features):
    table = read_table(features)
    return table, P.distance_matrix(table)


def test_edge_list_is_the_k_nearest_and_reads_back_with_plain_read_csv(features, tmp_path):
    out = tmp_path / "edges.csv"
    assert main(["compare", str(features), "--neighbours", "3", "-o", str(out), "-q"]) == 0
    edges = pd.read_csv(out)  # no arguments
    assert list(edges.columns) == ["row", "neighbour", "rank", "distance", "movie", "frame",
                                   "label", "neighbour_movie", "neighbour_frame",
                                   "neighbour_label"]
    assert pd.api.types.is_string_dtype(edges["movie"]) and set(edges["movie"]) == {"m"}
    for c in ("row", "neighbour", "rank", "frame", "label", "neighbour_frame",
              "neighbour_label"):
        assert edges[c].dtype == np.int64, c
    assert edges["distance"].dtype == np.float64
    table, d = _full(features)
    n = len(table)
    assert len(edges) == 3 * n
    order = np.argsort(d + np.diag(np.full(n, np.inf)), axis=1)[:, :3]
    np.testing.assert_array_equal(edges["neighbour"].to_numpy().reshape(n, 3), order)
    np.testing.assert_array_equal(edges["row"].to_numpy(), np.repeat(np.arange(n), 3))
    np.testing.assert_array_equal(edges["rank"].to_numpy(), np.tile([1, 2, 3], n))
    np.testing.assert_allclose(edges["distance"].to_numpy().reshape(n, 3),
                               np.take_along_axis(d, order, 1), rtol=1e-12)
    # the keys of both ends are those rows of the feature table
    for end, prefix in (("row", ""), ("neighbour", "neighbour_")):
        rows = table.iloc[edges[end].to_numpy()]
        np.testing.assert_array_equal(edges[prefix + "frame"], rows["frame"])
        np.testing.assert_array_equal(edges[prefix + "label"], rows["label"])
    side = json.loads((tmp_path / "edges.csv.json").read_text())
    assert side["table"] == "neighbours" and side["options"]["neighbours"] == 3
    assert side["options"]["rerank"] == "none"


def test_rows_are_rows_of_the_feature_file_after_frames(features, tmp_path):
    """--frames 2-3: 'row' and 'neighbour' still number the rows of the feature file."""
    out = tmp_path / "edges.csv"
    assert main(["compare", str(features), "--neighbours", "2", "--frames", "2-3",
                 "-o", str(out), "-q"]) == 0
    edges = pd.read_csv(out)
    table, d = _full(features)
    keep = np.flatnonzero(table["frame"].isin([2, 3]).to_numpy())
    sub = d[np.ix_(keep, keep)]
    order = keep[np.argsort(sub + np.diag(np.full(len(keep), np.inf)), axis=1)[:, :2]]
    np.testing.assert_array_equal(edges["neighbour"].to_numpy().reshape(len(keep), 2), order)
    np.testing.assert_array_equal(table["frame"].to_numpy()[edges["neighbour"]],
                                  edges["neighbour_frame"])


def test_edge_list_as_parquet_is_the_csv_one(features, tmp_path):
    pytest.importorskip("pyarrow")
    assert main(["compare", str(features), "--neighbours", "4", "-o",
                 str(tmp_path / "e.csv"), "-q"]) == 0
    assert main(["compare", str(features), "--neighbours", "4", "-o",
                 str(tmp_path / "e.parquet"), "-q"]) == 0
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "e.parquet"),
                                  pd.read_csv(tmp_path / "e.csv"))
    side = json.loads((tmp_path / "e.parquet.json").read_text())
    assert side["format"] == "parquet" and side["table"] == "neighbours"


def test_rerank_on_the_graph_is_the_full_matrix_re_ranking(features, tmp_path):
    """12 objects, --rerank-k 3: the graph holds 3 k = 9 neighbours; every object's 3
    re-ranked neighbours are the argsort of rerank(full matrix) and their distances its
    values (the tie-break's median from all 12 objects, as in the full route)."""
    out = tmp_path / "edges.csv"
    assert main(["compare", str(features), "--neighbours", "3", "--rerank", "--rerank-k", "3",
                 "-o", str(out), "-q"]) == 0
    edges = pd.read_csv(out)
    table, d = _full(features)
    n = len(table)
    r = rerank(d, "diffusion", k=3)
    order = np.argsort(r + np.diag(np.full(n, np.inf)), axis=1)[:, :3]
    side = json.loads((tmp_path / "edges.csv.json").read_text())
    assert side["rerank_graph_neighbours"] == 9
    certified = side["rerank_certified_share"]
    got = edges["neighbour"].to_numpy().reshape(n, 3)
    assert certified >= 0.5
    assert (got == order).all(axis=1).mean() >= certified
    np.testing.assert_allclose(edges["distance"].to_numpy().reshape(n, 3),
                               np.take_along_axis(r, got, 1), rtol=1e-9)
    assert side["options"]["rerank"] == "diffusion" and side["options"]["rerank_k"] == 3


def test_neighbours_refuses_what_it_cannot_do(features, tmp_path, capsys):
    out = str(tmp_path / "e.csv")
    assert main(["compare", str(features), "--neighbours", "12", "-o", out]) == 2
    assert "at most 11 neighbours" in capsys.readouterr().err
    for dense in ("transduction", "tpg"):
        assert main(["compare", str(features), "--neighbours", "3", "--rerank", dense,
                     "-o", out]) == 2
        assert "full matrix" in capsys.readouterr().err
    assert not (tmp_path / "e.csv").exists()


def test_the_map_comes_from_the_graph_above_the_limit(features, tmp_path, capsys,
                                                      monkeypatch):
    monkeypatch.setattr(compare_command, "FULL_MATRIX_LIMIT", 5)
    monkeypatch.setattr(compare_command, "TSNE_SLOW", 10)  # 12 objects: "slow", suggest UMAP
    png = tmp_path / "map.png"
    assert main(["compare", str(features), "--neighbours", "3", "-o",
                 str(tmp_path / "e.csv"), "--mds", str(png)]) == 0
    said = capsys.readouterr()
    assert "t-SNE map of the 11-nearest-neighbour graph, not MDS" in said.out
    assert "--map umap" in said.err
    assert png.stat().st_size > 1000
    # without --neighbours too: the map of the full matrix's graph
    assert main(["compare", str(features), "-o", str(tmp_path / "d.csv"), "--mds",
                 str(tmp_path / "m2.png"), "--map", "spectral"]) == 0
    said = capsys.readouterr()
    assert "spectral embedding map of the 11-nearest-neighbour graph, not MDS" in said.out
    assert "--map umap" not in said.err
    monkeypatch.setattr(compare_command, "FULL_MATRIX_LIMIT", 2000)
    assert main(["compare", str(features), "--neighbours", "3", "-o",
                 str(tmp_path / "e2.csv"), "--mds", str(tmp_path / "m3.png")]) == 0
    assert "classical MDS of the full matrix" in capsys.readouterr().out


@pytest.mark.parametrize("method", ["tsne", "spectral", "umap"])
def test_graph_map_keeps_separate_kinds_apart(method):
    """Four blobs of 40 points in 12-D: in the 2-D map drawn from the 10-neighbour graph
    alone, a point's nearest point is of its blob for ≥ 95 % of the points."""
    from napari_pfsdm.analysis.reduction import graph_coordinates

    if method == "umap":
        pytest.importorskip("umap")
    rng = np.random.default_rng(0)
    pts = np.vstack([rng.normal(size=(40, 12)) + 6 * np.eye(12)[c] for c in range(4)])
    labels = np.repeat(np.arange(4), 40)
    d = ((pts[:, None] - pts[None]) ** 2).sum(-1)  # squared, as the PF-SDM distance
    order = np.argsort(d + np.diag(np.full(160, np.inf)), axis=1)[:, :10]
    xy = graph_coordinates(order, np.take_along_axis(d, order, 1), method)
    assert xy.shape == (160, 2) and np.isfinite(xy).all()
    d2 = ((xy[:, None] - xy[None]) ** 2).sum(-1) + np.diag(np.full(160, np.inf))
    assert (labels[d2.argmin(axis=1)] == labels).mean() >= 0.95


def test_umap_map_without_umap_learn_says_what_to_install(monkeypatch, features, tmp_path,
                                                          capsys):
    import sys

    monkeypatch.setitem(sys.modules, "umap", None)
    monkeypatch.setattr(compare_command, "FULL_MATRIX_LIMIT", 5)
    assert main(["compare", str(features), "--neighbours", "3", "-o", str(tmp_path / "e.csv"),
                 "--mds", str(tmp_path / "m.png"), "--map", "umap"]) == 2
    assert 'pip install "napari-pfsdm[umap]"' in capsys.readouterr().err
