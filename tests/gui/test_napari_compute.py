"""The widget's array side (no Qt): objects, disk pixels, SDF patches, PCA, MDS, export."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from napari_pfsdm.io_csv import read_table_csv
from napari_pfsdm.napari._compute import (
    PictureCache,
    classical_mds,
    count_objects,
    disk_pixels,
    layer_features,
    object_pictures,
    pca_scores,
    run_analysis,
    status_line,
    validate_layers_data,
)
from napari_pfsdm.napari._export import export_results, read_csv


def _run(labels, intensity=None, **options):
    gen = run_analysis(labels, intensity, options)
    progress = []
    try:
        while True:
            progress.append(next(gen))
    except StopIteration as stop:
        return stop.value, progress


@pytest.fixture(scope="module")
def two_frames():
    labels = np.zeros((2, 80, 120), np.uint16)
    yy, xx = np.mgrid[:80, :120]
    labels[0][(yy - 40) ** 2 / 400 + (xx - 30) ** 2 / 100 <= 1] = 3  # ellipse, long along y
    labels[1][(yy - 40) ** 2 / 100 + (xx - 30) ** 2 / 400 <= 1] = 3  # the same, turned
    labels[1][(yy - 40) ** 2 + (xx - 90) ** 2 <= 15**2] = 7  # a disk, only in frame 1
    intensity = (xx / 120.0).astype(np.float32)[None].repeat(2, axis=0)
    return labels, intensity


def test_run_keeps_rows_and_pictures_are_made_on_demand(two_frames):
    labels, intensity = two_frames
    out, progress = _run(labels, intensity)
    assert [p[:2] for p in progress] == [(1, 3), (2, 3), (3, 3)]
    assert count_objects(labels) == 3
    table = out.table
    assert list(zip(table["frame"], table["label"], strict=True)) == [(0, 3), (1, 3), (1, 7)]
    assert table.attrs["pfsdm"]["n_fourier"] == 10
    assert sorted(out.boxes) == [(0, 3), (1, 3), (1, 7)]
    assert list(out.labels_in(1)) == [3, 7] and list(out.frames_of(7)) == [1]
    assert out.row_index(0, 7) is None and out.row_index(1, 7) == 2
    # pictures of one object, made from the run's own arrays and options
    a = object_pictures(labels, intensity, out, 0, 3, size=48)
    b = object_pictures(labels, intensity, out, 1, 3, size=48)
    assert a.disk.shape == a.intensity_disk.shape == (48, 48)
    assert np.isnan(a.disk[0, 0]) and np.nanmin(a.disk) < -0.3 and np.nanmax(a.disk) <= 1e-6
    # rotation invariance: the disk of the turned ellipse has the same values, turned
    assert abs(np.nanmean(a.disk) - np.nanmean(b.disk)) < 0.02
    # the skeleton of the ellipse runs along its long axis (rows in frame 0), as lines
    pts = np.vstack(a.skeleton_image)
    assert np.ptp(pts[:, 0]) > 3 * max(np.ptp(pts[:, 1]), 1)
    for path in a.skeleton_image:  # consecutive points of a line are neighbours
        assert np.abs(np.diff(path, axis=0)).max() <= 1.0
    # SDF: negative inside (about -radius at the centre), 0 at the outline, positive out
    c = object_pictures(labels, intensity, out, 1, 7, size=48)
    r0, c0 = c.sdf_corner

    def at(r, col):  # the SDF sample nearest to frame position (r, col)
        return c.sdf[int(round((r - r0) / c.sdf_step)), int(round((col - c0) / c.sdf_step))]

    # 31 px box: (31 * 1.5 + 4) px on 48 samples
    assert c.sdf.shape == (48, 48) and c.sdf_step == pytest.approx((31 * 1.5 + 4) / 48)
    assert at(40, 90) == pytest.approx(-15, abs=1.0)
    assert abs(at(40, 105)) < 1.0 and at(40, 110) > 3
    assert np.hypot(*(c.outline - (40, 90)).T).mean() == pytest.approx(15, abs=0.7)
    with pytest.raises(KeyError):
        object_pictures(labels, intensity, out, 0, 7)
    # pictures made ahead give way: asked to stop, the work ends between two steps
    from napari_pfsdm.napari._compute import PicturesCancelled

    with pytest.raises(PicturesCancelled):
        object_pictures(labels, intensity, out, 1, 7, stop=lambda: True)


def test_picture_cache_is_bounded_and_least_recently_used_goes_first():
    cache = PictureCache(maxsize=2)
    cache.put((0, 1), "a")
    cache.put((0, 2), "b")
    assert cache.get((0, 1)) == "a"  # now the most recent
    cache.put((0, 3), "c")
    assert (0, 2) not in cache and (0, 1) in cache and len(cache) == 2


def test_layer_features_are_numbers_with_pc_scores_and_status_is_short(two_frames):
    labels, intensity = two_frames
    out, _ = _run(labels, intensity)
    feats = layer_features(out)
    assert list(feats.columns[:3]) == ["index", "frame", "label"]
    assert all(pd.api.types.is_numeric_dtype(feats[c]) for c in feats.columns)
    assert {"shape_PC1", "intensity_PC1", "failed"} <= set(feats.columns)
    np.testing.assert_allclose(feats["shape_PC1"], out.pca["shape"]["PC1"])
    raw = ("shape_r", "intensity_r", "outline_")  # raw vectors: export and API, not features
    num = [c for c in out.table.columns if c not in ("error", "warnings", "touches_border")
           and not c.startswith(raw)]
    assert "perimeter" in num and not [c for c in feats.columns if c.startswith(raw)]
    np.testing.assert_array_equal(feats[num].to_numpy(float), out.table[num].to_numpy(float))
    # the one classic measure the table lacks: regionprops' minor / major axis, row by row
    np.testing.assert_allclose(feats["aspect_ratio"], out.table["axis_minor_length"]
                               / out.table["axis_major_length"], rtol=1e-12)
    line = status_line(out, 1, 7)
    assert line.startswith("frame 1 · label 7 · area ") and "PC1" in line and len(line) < 100
    assert status_line(out, 0, 7) == "label 7: not present in frame 0"


def test_table_matches_measure(two_frames):
    from napari_pfsdm import measure

    labels, intensity = two_frames
    out, _ = _run(labels, intensity, n_fourier=6)
    ref = measure(labels, intensity, n_fourier=6)
    assert list(out.table.columns) == list(ref.columns)
    num = [c for c in ref.columns if c not in ("error", "warnings")]
    np.testing.assert_allclose(out.table[num].to_numpy(float), ref[num].to_numpy(float))


def test_widgets_pca_is_scikit_learns_pca_of_the_weighted_features(two_frames):
    """The widget's PCA against an independent one: scikit-learn's PCA of the weighted
    features (signs are a convention: aligned per component)."""
    from sklearn.decomposition import PCA

    from napari_pfsdm.analysis.tables import weighted_features

    labels, intensity = two_frames
    out, _ = _run(labels, intensity)
    mine = pca_scores(out.table, "shape", n_components=3)
    x = weighted_features(out.table)
    sk = PCA(n_components=3).fit(x)
    ref = sk.transform(x)
    got = mine[["PC1", "PC2", "PC3"]].to_numpy()
    signs = np.sign(np.sum(got * ref, axis=0))
    np.testing.assert_allclose(got, ref * signs, atol=1e-9)
    # the ratio of the total variance (not of the kept components' variance)
    np.testing.assert_allclose(mine.attrs["explained_variance_ratio"],
                               sk.explained_variance_ratio_, rtol=1e-9)


def test_classical_mds_recovers_planar_points():
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(12, 2))
    d = np.hypot(*(pts[:, None] - pts[None]).transpose(2, 0, 1))
    xy = classical_mds(d)
    d2 = np.hypot(*(xy[:, None] - xy[None]).transpose(2, 0, 1))
    np.testing.assert_allclose(d2, d, atol=1e-9)


def test_disk_pixels_centre_and_axes():
    np.testing.assert_allclose(disk_pixels([[0, 0], [-1, 1]], 48), [[23.5, 23.5], [-0.5, 47.5]])


def test_validation_messages():
    with pytest.raises(ValueError, match="a time-lapse of Z-stacks"):
        validate_layers_data(np.zeros((2, 2, 2, 2, 2), int), None)
    assert validate_layers_data(np.zeros((2, 2, 2, 2), int), None) == "tzyx"
    with pytest.raises(ValueError, match="integer"):
        validate_layers_data(np.zeros((4, 4)), None)
    with pytest.raises(ValueError, match="does not match"):
        validate_layers_data(np.zeros((4, 4), int), np.zeros((4, 5)))
    with pytest.raises(ValueError, match="no objects"):
        _run(np.zeros((10, 10), int))
    assert validate_layers_data(np.zeros((3, 4, 4), int), None, first_axis="z") == "zyx"
    assert validate_layers_data(np.zeros((3, 4, 4), int), None, first_axis="time") == "tyx"


def test_export_is_atomic_and_roundtrips(two_frames, tmp_path, monkeypatch):
    from napari_pfsdm.napari import _export

    labels, intensity = two_frames
    out, _ = _run(labels, intensity)
    out.options["intensity_weight"] = 0.5
    paths = export_results(out, tmp_path, "cells")
    feats = read_csv(paths[0])
    num = [c for c in out.table.columns if c not in ("error", "warnings")]
    np.testing.assert_array_equal(feats[num].to_numpy(float), out.table[num].to_numpy(float))
    assert feats.attrs["pfsdm"]["intensity_weight"] == 0.5
    dist = read_table_csv(tmp_path / "cells_distances.csv", index_col=0)  # the CLI's layout
    from napari_pfsdm import distance_matrix

    np.testing.assert_array_equal(dist.to_numpy(float),
                                  distance_matrix(out.table, intensity_weight=0.5))
    # an error while writing leaves the previous file untouched and no temporary file
    before = paths[0].read_bytes()

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr("pandas.DataFrame.to_csv", boom)
    with pytest.raises(OSError, match="disk full"):
        _export.export_results(out, tmp_path, "cells")
    assert paths[0].read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [p.name for p in paths] + [p.name + ".json" for p in paths])
    monkeypatch.undo()
    # a file of the same name that napari-pfsdm did not write is never replaced
    (tmp_path / "mine_distances.csv").write_text("my own numbers\n")
    with pytest.raises(ValueError, match="mine_distances.csv already exists and was not written"):
        _export.export_results(out, tmp_path, "mine")
    assert not (tmp_path / "mine_features.csv").exists()  # all or nothing
    assert (tmp_path / "mine_distances.csv").read_text() == "my own numbers\n"


def test_cli_and_widget_give_the_same_pca_mds_and_distance_table(tmp_path):
    """One reduction module: the widget's export and the command line on that export agree."""
    from napari_pfsdm.cli import main
    from napari_pfsdm.data.gastruloids import make_timelapse_montage

    labels, intensity, _ = make_timelapse_montage(n_objects=4, n_frames=3, size=128, seed=2)
    out, _ = _run(labels, intensity, n_fourier=6)
    out.options["intensity_weight"] = 0.5  # as the widget sets it
    export_results(out, tmp_path, "w")
    assert main(["trajectories", str(tmp_path / "w_features.csv"), "-o", str(tmp_path / "p.csv"),
                 "--channel", "shape", "--components", "5", "-q"]) == 0
    cli = pd.read_csv(tmp_path / "p.csv")
    widget = pd.read_csv(tmp_path / "w_pca_shape.csv")
    k = sum(c.startswith("PC") for c in widget.columns)
    np.testing.assert_allclose(cli[[f"shape_PC{i}" for i in range(1, k + 1)]].to_numpy(),
                               widget[[f"PC{i}" for i in range(1, k + 1)]].to_numpy(),
                               rtol=1e-10, atol=1e-12)
    assert main(["compare", str(tmp_path / "w_features.csv"), "-o", str(tmp_path / "d.csv"),
                 "--intensity-weight", "0.5", "-q"]) == 0
    d_cli = pd.read_csv(tmp_path / "d.csv", index_col=0)
    d_widget = pd.read_csv(tmp_path / "w_distances.csv", index_col=0)
    pd.testing.assert_frame_equal(d_cli, d_widget)
    # the MDS map keeps the distances of the points it places (an MDS of the map's own
    # Euclidean distances gives the same map up to a rotation: compare distances, by scipy)
    from scipy.spatial.distance import pdist

    xy = classical_mds(d_widget.to_numpy())
    d = d_widget.to_numpy()
    r = np.corrcoef(pdist(xy), d[np.triu_indices(len(d), 1)])[0, 1]
    assert r > 0.9


def test_each_viewer_has_its_own_result_store():
    import weakref

    from napari.components import ViewerModel
    from napari.layers import Labels

    from napari_pfsdm.napari._store import _STORES, store_for

    a, b = ViewerModel(), ViewerModel()
    assert store_for(a) is store_for(a) and store_for(a) is not store_for(b)
    layer = Labels(np.zeros((8, 8), np.uint8))
    heard = []
    store_for(b).results_changed.connect(heard.append)
    store_for(a).set(layer, "output of a")
    assert store_for(a).get(layer) == "output of a" and store_for(b).get(layer) is None
    assert heard == []  # b's plots are not told about a's results
    assert isinstance(_STORES, weakref.WeakKeyDictionary)  # kept only while the viewer lives


def test_neighbour_export_rows_are_rows_of_the_features_file_with_an_intensity_weight():
    """The edge list's ``row`` and ``neighbour`` name rows of the features file even when
    rows without intensity features are left out (they were renumbered from 0 before)."""
    from napari_pfsdm.core.table_schema import table_feature_columns
    from napari_pfsdm.data.gastruloids import make_timelapse_montage
    from napari_pfsdm.napari._export import neighbour_export_steps

    labels, intensity, _ = make_timelapse_montage(n_objects=4, n_frames=3, size=128, seed=2)
    out, _ = _run(labels, intensity, n_fourier=6)
    out.options["intensity_weight"] = 0.5
    cols = table_feature_columns(out.table.attrs["pfsdm"], "intensity")
    out.table.loc[out.table.index[1], cols] = np.nan  # the second object's reporter: NaN
    out.reindex()
    steps = neighbour_export_steps(out)
    try:
        while True:
            next(steps)
    except StopIteration as done:
        edges = done.value["neighbours"]
    table = out.table
    assert 1 not in set(edges["row"]) | set(edges["neighbour"])
    assert set(edges["row"]) == set(range(len(table))) - {1}
    for end, prefix in (("row", ""), ("neighbour", "neighbour_")):
        for key in ("frame", "label"):
            np.testing.assert_array_equal(table[key].to_numpy()[edges[end].to_numpy()],
                                          edges[prefix + key].to_numpy())
