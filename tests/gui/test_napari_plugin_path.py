"""The plugin as a biologist meets it: docked from the Plugins menu (napari hands the widgets a
public-only proxy of the viewer), next to the tools they already use, on awkward input."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pandas as pd
import pytest
from napari_helpers import (
    COMPARISON,
    TRAJECTORIES,
    dock,
    open_plots,
    run_and_wait,
    wait_computed,
    wait_pictures,
)

from napari_pfsdm.napari import _layers

pytestmark = pytest.mark.gui


def _result_layers(viewer, source: str) -> dict:
    names = set(_layers.layer_names(source).values())
    return {layer.name: layer for layer in viewer.layers if layer.name in names}


def test_the_docked_widget_gets_naparis_proxy_and_still_updates_layers_in_place(
        viewer_widget, qtbot):
    viewer, widget = viewer_widget
    # docked from the menu, the widget holds napari's public-only stand-in, not the viewer
    assert widget.viewer is not viewer and widget.viewer.layers is not viewer.layers
    labels = viewer.layers["gastruloids"]
    run_and_wait(qtbot, widget)
    wait_pictures(qtbot, widget)
    before = _result_layers(viewer, "gastruloids")
    assert len(before) == 5
    events = []
    viewer.layers.events.inserted.connect(lambda e: events.append(("inserted", e.value.name)))
    viewer.layers.events.removed.connect(lambda e: events.append(("removed", e.value.name)))
    viewer.layers.selection.events.active.connect(
        lambda e: events.append(("active", getattr(e.value, "name", None))))
    frame = _layers.current_frame(viewer, labels)
    for label in (2, 4, 3):
        labels.selected_label = label
        wait_pictures(qtbot, widget, (frame, label))
    viewer.dims.set_point(0, frame + 1)
    wait_pictures(qtbot, widget, (frame + 1, 3))
    after = _result_layers(viewer, "gastruloids")
    # the same five layer objects, their data swapped: nothing removed, added or selected
    assert all(after[name] is before[name] for name in before)
    assert events == []
    assert viewer.layers.selection.active is labels


def test_result_layers_never_become_the_active_layer(make_napari_viewer, sample_layers, qtbot):
    viewer = make_napari_viewer()
    for data, kwargs, kind in sample_layers:
        getattr(viewer, f"add_{kind}")(data, **kwargs)
    reporter = viewer.layers["gastruloids reporter"]
    viewer.layers.selection.active = reporter  # the user looks at the reporter
    widget = dock(viewer)
    actives = []
    viewer.layers.selection.events.active.connect(lambda e: actives.append(e.value))
    run_and_wait(qtbot, widget, labels=viewer.layers["gastruloids"])
    wait_pictures(qtbot, widget)
    names = set(_layers.layer_names("gastruloids").values())
    # the first pictures add five layers: none of them was ever made the active layer
    assert not [a for a in actives if a is not None and a.name in names]
    assert all(layer.name not in names for layer in viewer.layers.selection)


def test_first_pictures_add_one_layer_per_event_loop_slot(viewer_widget, qtbot):
    """napari needs about 0.1 s per new layer under software OpenGL: the five result layers
    of the first pictures are added in five slots of Qt's event loop, not in one."""
    from qtpy.QtCore import QTimer

    viewer, widget = viewer_widget
    turns = [0]
    ticker = QTimer(interval=0)
    ticker.timeout.connect(lambda: turns.__setitem__(0, turns[0] + 1))
    names = set(_layers.layer_names("gastruloids").values())
    added = []
    viewer.layers.events.inserted.connect(
        lambda e: added.append(turns[0]) if e.value.name in names else None)
    ticker.start()
    run_and_wait(qtbot, widget)
    wait_pictures(qtbot, widget)
    ticker.stop()
    assert len(added) == 5
    assert len(set(added)) == 5, added  # one slot each: the loop turned between them


def test_a_run_of_many_objects_uses_worker_processes_and_gives_measures_table(
        viewer_widget, qtbot, monkeypatch):
    import napari_pfsdm as pf
    from napari_pfsdm.analysis import parallel

    viewer, widget = viewer_widget
    monkeypatch.setattr(parallel, "MIN_OBJECTS", 1)  # the sample, as if it were large
    parallel.shutdown_pool()
    out = run_and_wait(qtbot, widget)
    assert parallel._POOL["pool"] is not None  # the run went through the process pool
    labels = viewer.layers["gastruloids"].data
    reporter = viewer.layers["gastruloids reporter"].data
    expected = pf.measure(labels, reporter)
    table = out.table.drop(columns=["track_id"], errors="ignore")
    pd.testing.assert_frame_equal(table[expected.columns], expected)
    assert widget.progress.value() == widget.progress.maximum() == len(expected)


def test_docking_starts_the_processes_so_a_small_run_uses_them(viewer_widget, qtbot,
                                                               monkeypatch):
    """The widget warms the process pool when docked: the 72-object sample, far below
    MIN_OBJECTS, is then measured in the processes too, with measure's table."""
    import napari_pfsdm as pf
    from napari_pfsdm.analysis import parallel

    if parallel.available_cores() < 2:
        pytest.skip("one core: no process pool")
    viewer, widget = viewer_widget
    qtbot.waitUntil(parallel.pool_ready, timeout=120_000)
    routes = []
    real = parallel._iter_blocks_pool
    monkeypatch.setattr(parallel, "_iter_blocks_pool",
                        lambda *a, **k: routes.append("pool") or real(*a, **k))
    out = run_and_wait(qtbot, widget)
    assert routes == ["pool"]
    labels = viewer.layers["gastruloids"].data
    reporter = viewer.layers["gastruloids reporter"].data
    expected = pf.measure(labels, reporter)
    pd.testing.assert_frame_equal(out.table[expected.columns], expected)


def test_plots_redraw_only_when_their_data_change(viewer_widget, qtbot):
    viewer, widget = viewer_widget
    labels = viewer.layers["gastruloids"]
    run_and_wait(qtbot, widget)
    wait_pictures(qtbot, widget)
    traj, comp = dock(viewer, TRAJECTORIES), dock(viewer, COMPARISON)
    wait_computed(qtbot, comp)
    counts = {"traj": 0, "comp": 0}

    def counting(plot, key):
        redraw = plot.redraw

        def wrapped():
            counts[key] += 1
            redraw()
        return wrapped

    traj.redraw, comp.redraw = counting(traj, "traj"), counting(comp, "comp")
    # unrelated layer events (a new image, the plugin's own pictures): no redraw
    viewer.add_image(np.zeros((8, 8)), name="unrelated")
    viewer.layers.remove("unrelated")
    frame = _layers.current_frame(viewer, labels)
    labels.selected_label = 2
    wait_pictures(qtbot, widget, (frame, 2))
    traj.flush()
    comp.flush()
    assert counts == {"traj": 0, "comp": 0}
    assert traj.highlighted_keys() == [(frame, 2)]
    # a new frame: the trajectories only move their highlight; the comparison shows the new
    # frame's distances in its axes (same number of objects: drawn in place)
    n = len(widget.last_output.labels_in(frame))
    assert len(widget.last_output.labels_in(frame + 1)) == n
    viewer.dims.set_point(0, frame + 1)
    wait_computed(qtbot, comp)
    traj.flush()
    assert counts["traj"] == 0 and counts["comp"] == 0
    assert all(f == frame + 1 for f, _ in comp._keys)
    assert traj.highlighted_keys() == [(frame + 1, 2)]
    from napari_pfsdm import distance_matrix

    table = widget.last_output.table
    np.testing.assert_allclose(comp.distances, distance_matrix(
        table[table["frame"] == frame + 1],
        intensity_weight=widget.last_output.options["intensity_weight"]))


def test_comparison_is_computed_in_a_worker_and_can_be_cancelled(viewer_widget, qtbot,
                                                                 monkeypatch):
    import threading

    from napari_pfsdm.napari import _plots

    viewer, widget = viewer_widget
    run_and_wait(qtbot, widget)
    release = threading.Event()
    real = _plots._comparison_worker

    @_plots.thread_worker(start_thread=False)
    def held(table, rows, w, reranked):
        while not release.is_set():  # a computation that waits: only Cancel ends it
            release.wait(0.005)
            yield "waiting"
        return None

    monkeypatch.setattr(_plots, "_comparison_worker", held)
    comp = dock(viewer, COMPARISON)
    comp.flush()
    assert comp.computing and comp.cancel_button.isVisibleTo(comp)
    texts = [t.get_text() for ax in comp.figure.axes for t in ax.texts]
    assert any("computing" in t for t in texts)
    comp.cancel()
    qtbot.waitUntil(lambda: not comp.computing, timeout=30_000)
    assert not comp.cancel_button.isVisibleTo(comp)
    assert not comp._cache  # nothing kept from a cancelled computation
    comp.redraw()  # the same frame and options: not asked for again
    assert not comp.computing and "Cancelled" in comp.info.text()
    monkeypatch.setattr(_plots, "_comparison_worker", real)
    comp.frame_choice.setCurrentText("all frames")  # something else: computed
    wait_computed(qtbot, comp)
    assert comp.distances.shape[0] == len(comp._keys) > 1


def test_export_runs_in_a_worker_and_always_writes_features_and_pca(viewer_widget, qtbot,
                                                                    tmp_path, monkeypatch):
    from napari_pfsdm.napari import _export

    viewer, widget = viewer_widget
    out = run_and_wait(qtbot, widget)
    worker = widget.export_async(tmp_path / "small")
    assert worker is not None and widget.exporting
    qtbot.waitUntil(lambda: not widget.exporting, timeout=60_000)
    assert sorted(p.name for p in widget.last_export) == sorted([
        "gastruloids_features.csv", "gastruloids_pca_shape.csv",
        "gastruloids_pca_intensity.csv", "gastruloids_distances.csv"])
    # a collection too large for the all-pairs matrix: features and PCA still written, the
    # matrix left out with a sentence in the sidecar and in the status line, and each
    # object's nearest neighbours written instead
    monkeypatch.setattr(_export, "MAX_DISTANCE_ROWS", len(out.table) - 1)
    widget.export_async(tmp_path / "large")
    qtbot.waitUntil(lambda: not widget.exporting, timeout=60_000)
    written = sorted(p.name for p in (tmp_path / "large").glob("*.csv"))
    assert written == sorted(["gastruloids_features.csv", "gastruloids_pca_shape.csv",
                              "gastruloids_pca_intensity.csv", "gastruloids_neighbours.csv"])
    side = json.loads((tmp_path / "large" / "gastruloids_features.csv.json").read_text())
    assert f"{len(out.table)} objects are more than the" in side["distances"]
    assert "gastruloids_neighbours.csv" in side["distances"]
    assert "distance matrix was left out" in widget.status.text()
    features = pd.read_csv(tmp_path / "large" / "gastruloids_features.csv")
    assert len(features) == len(out.table)
    # the edge list against the small export's all-pairs matrix (another computation):
    # each object's nearest, in order, by the matrix's own distances
    matrix = pd.read_csv(tmp_path / "small" / "gastruloids_distances.csv", index_col=0)
    edges = pd.read_csv(tmp_path / "large" / "gastruloids_neighbours.csv")
    assert {"row", "neighbour", "rank", "distance", "frame", "label",
            "neighbour_frame", "neighbour_label"} <= set(edges.columns)
    for row, group in edges.groupby("row"):
        me = f"t{features['frame'][row]}/l{features['label'][row]}"
        assert (group["frame"] == features["frame"][row]).all()
        d = matrix.loc[me].drop(me).sort_values(kind="stable")
        names = [f"t{f}/l{lb}" for f, lb in zip(group["neighbour_frame"],
                                                  group["neighbour_label"], strict=True)]
        assert names == list(d.index[:len(group)]) or np.allclose(
            d.to_numpy()[:len(group)], group["distance"], atol=1e-9)  # ties may swap
        np.testing.assert_allclose(group["distance"], matrix.loc[me, names], atol=1e-7)


def test_cancelled_export_writes_nothing(viewer_widget, qtbot, tmp_path, monkeypatch):
    import threading

    from napari_pfsdm.napari import _export

    viewer, widget = viewer_widget
    run_and_wait(qtbot, widget)
    release = threading.Event()
    real = _export.prepare_export

    def slow(output):
        release.wait(30)  # the distances take long; Cancel is pressed meanwhile
        return real(output)

    monkeypatch.setattr(_export, "prepare_export", slow)
    widget.export_async(tmp_path)
    assert widget.cancel_button.isEnabled()
    widget.cancel()
    release.set()
    qtbot.waitUntil(lambda: not widget.exporting, timeout=60_000)
    assert list(tmp_path.iterdir()) == []
    assert "nothing was written" in widget.status.text()
    assert widget.export_button.isEnabled()


def _squeezed(widget) -> list:
    """Visible controls shown lower than their natural height."""
    from qtpy.QtWidgets import QAbstractButton, QAbstractSpinBox, QComboBox

    out = []
    for kind in (QComboBox, QAbstractSpinBox, QAbstractButton):
        for control in widget.findChildren(kind):
            if control.isVisible() and control.height() < control.sizeHint().height():
                out.append((control.objectName() or type(control).__name__, control.height()))
    return out


@pytest.mark.parametrize("size", [(1280, 800), (1600, 1000)])
def test_panel_is_readable_on_a_laptop_screen_with_the_plots_open(make_napari_viewer,
                                                                  sample_layers, qtbot, size):
    viewer = make_napari_viewer(show=True)
    for data, kwargs, kind in sample_layers:
        getattr(viewer, f"add_{kind}")(data, **kwargs)
    window = viewer.window._qt_window
    window.resize(*size)
    widget = dock(viewer)
    run_and_wait(qtbot, widget)
    open_plots(qtbot, widget)
    wait_pictures(qtbot, widget)
    qtbot.wait(300)
    # the window still fits the screen: the docks do not force it taller
    assert window.minimumSizeHint().height() <= size[1]
    assert window.height() <= size[1]
    widget.method_options.expand(animate=False)
    # once Qt has laid the docks out again (on a loaded machine that took longer than the
    # 100 ms waited before: a combo box was once caught squeezed half-way; a control that
    # stays squeezed fails here after 3 s)
    def readable() -> None:  # retried until it holds (pytest-qt), its last failure raised
        for part in (widget, *widget.plots):
            assert _squeezed(part) == [], type(part).__name__

    qtbot.waitUntil(readable, timeout=3000)
    # the pictures and their texts: scaled with the zoom, values as people write them
    legend = viewer.layers["gastruloids legend"]
    assert legend.text.scaling
    texts = list(legend.features["text"])
    assert not [t for t in texts if "e+" in t or "e-0" in t]
    assert any(t.startswith("\u2212") for t in texts)  # a true minus sign


def test_clusters_plotter_selects_exactly_the_rows_of_each_frame(viewer_widget, qtbot):
    """napari-clusters-plotter colours label values; on a time-lapse the plugin's objects
    layer (one id per frame and label) lets a selection in its plot mark exactly the selected
    rows' objects in every frame."""
    pytest.importorskip("napari_clusters_plotter")
    viewer, widget = viewer_widget
    out = run_and_wait(qtbot, widget)
    objects = widget.add_objects_layer()
    assert objects is not None and objects.name == "gastruloids objects"
    labels = viewer.layers["gastruloids"]
    # one id per row, the row's own object in its own frame
    table = out.table
    for i in (0, len(table) // 2, len(table) - 1):
        f, lab = int(table["frame"].iat[i]), int(table["label"].iat[i])
        assert np.array_equal(objects.data[f] == i + 1, labels.data[f] == lab)
    assert (objects.features["index"].to_numpy() == np.arange(1, len(table) + 1)).all()
    _dock, plotter = viewer.window.add_plugin_dock_widget("napari-clusters-plotter",
                                                          "Plot & select features")
    viewer.layers.selection.active = objects
    qtbot.wait(200)
    plotter.x_axis, plotter.y_axis = "shape_PC1", "area"
    pc1 = objects.features["shape_PC1"].to_numpy()
    # a cluster that splits every frame: the right half of shape_PC1 within each frame
    frames = objects.features["frame"].to_numpy()
    chosen = np.zeros(len(pc1), int)
    for f in np.unique(frames):
        rows = np.flatnonzero(frames == f)
        chosen[rows] = pc1[rows] > np.median(pc1[rows])
    plotter.plotting_widget.show_color_overlay = True  # as drawing a selection does
    selector = next(iter(plotter.plotting_widget.selectors.values()))
    selector.selection_applied_signal.emit(chosen)
    qtbot.wait(300)
    colormap = objects.colormap
    for f in (0, int(table["frame"].max())):
        rows = np.flatnonzero(table["frame"].to_numpy() == f)
        colours = {int(r): tuple(np.round(colormap.map(np.array([r + 1]))[0], 3)) for r in rows}
        picked = {colours[r] for r in rows if chosen[r]}
        others = {colours[r] for r in rows if not chosen[r]}
        assert picked and others and not (picked & others), f


def test_restores_its_features_after_another_plugin_replaced_them(viewer_widget, qtbot):
    viewer, widget = viewer_widget
    labels = viewer.layers["gastruloids"]
    run_and_wait(qtbot, widget)
    n_cols = labels.features.shape[1]
    try:  # the real thing: napari-skimage-regionprops on the same layer
        from napari_skimage_regionprops import regionprops_table

        frame = np.asarray(viewer.layers["gastruloids reporter"].data)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            regionprops_table(frame, labels.data, napari_viewer=viewer)
    except ImportError:
        labels.features = pd.DataFrame({"label": [1, 2], "area": [3, 4]})
    assert labels.features.shape[1] < n_cols
    assert widget.restore_button.isVisibleTo(widget)
    assert "Restore features" in widget.status.text()
    widget.restore_features()
    assert labels.features.shape[1] == n_cols
    assert not widget.restore_button.isVisibleTo(widget)


def test_an_rgb_mask_opened_as_labels_is_refused_in_plain_words(make_napari_viewer, qtbot,
                                                                monkeypatch):
    from napari_pfsdm.napari import _widget

    shown = []
    monkeypatch.setattr(_widget, "show_error", shown.append)
    viewer = make_napari_viewer()
    rgb = np.zeros((303, 384, 3), np.uint8)
    rgb[100:200, 100:200] = (255, 0, 0)
    viewer.add_labels(rgb, name="mask.png")
    widget = dock(viewer)
    assert widget.run() is None
    assert "colour picture" in widget.status.text() and "3 colour channels" in shown[-1]
    assert [layer.name for layer in viewer.layers] == ["mask.png"]


def test_the_reporter_never_defaults_to_the_labels_own_pixels(make_napari_viewer,
                                                               sample_layers):
    viewer = make_napari_viewer()
    (image, image_kw, _), (labels, labels_kw, _) = sample_layers
    viewer.add_labels(labels, **labels_kw)
    viewer.add_image(labels.copy(), name="mask as image")  # a .tif opened twice
    widget = dock(viewer)
    assert widget.image_combo.currentText() == "(none)"
    viewer.add_image(image, **image_kw)
    widget.labels_combo.setCurrentIndex(0)
    widget.image_combo.clear()
    widget._refresh_images()
    assert widget.image_combo.currentText() == image_kw["name"]


def test_closing_the_viewer_while_pictures_are_made_is_quiet(make_napari_viewer, sample_layers,
                                                             qtbot, capfd):
    from superqt.utils._qthreading import WorkerBase

    viewer = make_napari_viewer(show=True)
    for data, kwargs, kind in sample_layers:
        getattr(viewer, f"add_{kind}")(data, **kwargs)
    widget = dock(viewer)
    comp = dock(viewer, COMPARISON)
    run_and_wait(qtbot, widget)
    labels = viewer.layers["gastruloids"]
    for label in (2, 3, 4, 5):
        labels.selected_label = label
    comp.frame_choice.setCurrentText("all frames")
    assert widget._picture_worker is not None or comp.computing
    viewer.close()
    WorkerBase.await_workers(msecs=30_000)
    qtbot.wait(200)
    err = capfd.readouterr().err
    assert "Traceback" not in err and "has been deleted" not in err


def test_a_run_uses_no_private_napari_attribute(viewer_widget, qtbot):
    viewer, widget = viewer_widget
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run_and_wait(qtbot, widget)
        wait_pictures(qtbot, widget)
        open_plots(qtbot, widget)
        for plot in widget.plots:
            plot.flush()
    private = [str(w.message) for w in caught if "Private attribute" in str(w.message)]
    assert private == []


def test_prediction_from_the_widget_writes_p_group_into_every_row(viewer_widget, qtbot,
                                                                   tmp_path):
    """Point 4 of issue 22: train on the sample's groups from the prediction dock (docked from
    the menu), read the accuracy, find the probabilities in the features and the export."""
    from napari_helpers import PREDICTION

    viewer, widget = viewer_widget
    out = run_and_wait(qtbot, widget)
    labels = viewer.layers["gastruloids"]
    groups = labels.metadata["groups"]
    csv = tmp_path / "groups.csv"
    csv.write_text("label,group\n" + "".join(f"{k},{v}\n" for k, v in groups.items()))
    predict = dock(viewer, PREDICTION)
    assert predict.layer_combo.currentText() == "gastruloids"
    predict.load_groups(csv)
    predict.first.setValue(0)
    predict.last.setValue(3)
    worker = predict.run()
    assert worker is not None and not predict.run_button.isEnabled()
    qtbot.waitUntil(lambda: predict.worker is None, timeout=120_000)
    assert "Balanced accuracy" in predict.status.text(), predict.status.text()
    assert "chance 0.50" in predict.status.text()
    names = sorted({f"p_{g}" for g in groups.values()})
    feats = labels.features
    for name in names:
        assert name in feats.columns and np.isfinite(feats[name]).all()
    np.testing.assert_allclose(feats[names[0]] + feats[names[1]], 1.0)
    assert predict.result.frames == [0, 1, 2, 3] and len(predict.result.curve) == 4
    # the export carries them too
    paths = widget.export(tmp_path / "export")
    table = pd.read_csv(next(p for p in paths if p.name.endswith("_features.csv")))
    assert set(names) <= set(table.columns) and len(table) == len(out.table)
    # a class given by clicking: the selected label of the frame shown
    predict.source.setCurrentText("clicked classes")
    predict.classes = {}
    predict.class_name.setText("odd")
    labels.selected_label = 3
    predict.give_selected_class()
    assert predict.classes == {int(out.table.loc[out.table["label"] == 3, "track_id"].iat[0])
                               if "track_id" in out.table else 3: "odd"}


def test_reading_a_component_loadings_and_shape_modes(viewer_widget, qtbot):
    """Point 3 of issue 22: the loadings of the chosen PC as rings x harmonics, the real objects
    at -2 ... +2 sigma, and the PCA beyond the classic measures (uncorrelated with them)."""
    from napari_helpers import COMPONENTS

    viewer, widget = viewer_widget
    out = run_and_wait(qtbot, widget)
    comp = dock(viewer, COMPONENTS)
    qtbot.waitUntil(lambda: comp.worker is None and comp.result is not None, timeout=60_000)
    space, scores, modes, outlines = comp.result
    opts = out.table.attrs["pfsdm"]
    heat = comp.figure.axes[0].images[0].get_array()
    assert heat.shape == (opts["n_radii"], opts["n_fourier"] + 1)
    words = comp.figure.axes[0].get_xlabel()
    assert "0 thickness, 1 off-centre, 2 elongation, 3 triangularity" in words
    assert "weighted" in comp.figure.axes[0].get_title()
    assert len(outlines) == 5 and modes["sigma"].tolist() == [-2, -1, 0, 1, 2]
    v = scores["shape_PC1"].to_numpy()
    assert modes["score"].iat[0] <= modes["score"].iat[2] <= modes["score"].iat[4]
    assert modes["score"].iat[2] == pytest.approx(v[np.argmin(np.abs(v - v.mean()))])
    comp.kind.setCurrentText("beyond the classic measures")

    def beyond_shown():  # says what the panel says if it never comes (a flake seen once)
        assert comp.worker is None and "beyond" in comp.figure.axes[0].get_title(), \
            f"panel says: {comp.info.text()!r}, worker {comp.worker}"

    qtbot.waitUntil(beyond_shown, timeout=60_000)
    scores = comp.result[1]
    merged = scores.merge(out.table[["frame", "label", "circularity"]], on=["frame", "label"])
    assert abs(np.corrcoef(merged["shape_PC1"], merged["circularity"])[0, 1]) < 1e-6


def test_the_component_reading_last_asked_for_wins_whatever_finishes_first(
        viewer_widget, qtbot, monkeypatch):
    """Three readings asked for in a row, finishing out of order: the panel ends on the last
    one, and ``worker`` is None only when none runs. (Before: the first reading's end cleared
    ``worker`` while the second ran; the second was then never stopped and, finishing after
    the third, replaced it: the once-seen flake of the test above.)"""
    import threading

    from napari_helpers import COMPONENTS
    from qtpy.QtCore import QThreadPool

    from napari_pfsdm.napari import _components

    viewer, widget = viewer_widget
    run_and_wait(qtbot, widget)
    comp = dock(viewer, COMPONENTS)
    qtbot.waitUntil(lambda: comp.worker is None and comp.result is not None, timeout=60_000)
    gates = {k: threading.Event() for k in (2, 3, 4)}
    real = _components.reading

    def gated(output, kind, component):
        assert gates[component].wait(60), f"PC{component} was never let through"
        return real(output, kind, component)

    monkeypatch.setattr(_components, "reading", gated)
    pool = QThreadPool.globalInstance()
    threads = pool.maxThreadCount()
    pool.setMaxThreadCount(max(threads, 6))  # the held readings must not starve the others
    try:
        workers = {}
        for k in (2, 3):
            comp.component.setValue(k)
            workers[k] = comp.worker
        with qtbot.waitSignal(workers[2].finished, timeout=30_000):
            gates[2].set()
        assert comp.worker is workers[3]  # PC3 still runs
        comp.component.setValue(4)
        workers[4] = comp.worker
        with qtbot.waitSignal(workers[4].finished, timeout=60_000):
            gates[4].set()
        with qtbot.waitSignal(workers[3].finished, timeout=60_000):
            gates[3].set()
        qtbot.wait(50)  # anything PC3 queued is delivered
    finally:
        for gate in gates.values():
            gate.set()
        pool.setMaxThreadCount(threads)
    assert comp.worker is None
    assert comp.figure.axes[0].get_title().startswith("PC4 ")
    assert comp.result[2]["sigma"].tolist() == [-2, -1, 0, 1, 2]


def test_trajectories_in_the_pc_space_of_another_layer_or_a_saved_reference(
        make_napari_viewer, qtbot, tmp_path):
    """Point 5 of issue 22: the plot's axes from a control layer; a saved table too; a
    reference measured otherwise is refused in words."""
    from napari_pfsdm.analysis.shape_space import ShapePCA
    from napari_pfsdm.data.gastruloids import make_timelapse_montage
    from napari_pfsdm.io_csv import write_table_csv

    viewer = make_napari_viewer()
    control, _, _ = make_timelapse_montage(n_objects=4, n_frames=3, size=192, seed=1)
    treated, _, _ = make_timelapse_montage(n_objects=4, n_frames=3, size=192, seed=2)
    viewer.add_labels(control, name="control")
    viewer.add_labels(treated, name="treated")
    widget = dock(viewer)
    ref = run_and_wait(qtbot, widget, labels=viewer.layers["control"])
    out = run_and_wait(qtbot, widget, labels=viewer.layers["treated"])
    plot = dock(viewer, TRAJECTORIES)
    plot.show_layer(viewer.layers["treated"])
    assert [plot.space.itemText(i) for i in range(plot.space.count())] == ["this layer",
                                                                           "control"]
    plot.space.setCurrentText("control")
    expected = ShapePCA(n_components=5).fit(ref.table).transform(out.table)
    np.testing.assert_allclose(plot._points[:, 0], expected["shape_PC1"], atol=1e-9)
    assert "PC space of layer 'control'" in plot._axes_points.get_title()
    # a saved reference measured with other options: refused, said in the plot
    from napari_pfsdm import measure

    coarse = measure(control, n_fourier=6)
    write_table_csv(coarse, tmp_path / "coarse.csv", coarse.attrs["pfsdm"],
                    table_type="features")
    plot.load_reference(tmp_path / "coarse.csv")
    assert plot.space.currentText() == "saved reference"
    assert "n_fourier" in plot.info.text()


def _font_glyphs(viewer) -> dict:
    """The characters napari has drawn in this viewer (its one font cache, private)."""
    qt_viewer = viewer.window._qt_viewer
    return qt_viewer._font_manager.get_font(qt_viewer.canvas.font_info().face)._glyphs


def test_the_legends_characters_are_drawn_ahead_in_the_put_back_overlay(
        make_napari_viewer, sample_layers, qtbot, monkeypatch):
    """napari draws each new character on the GUI thread (~6 ms each): the legend's are drawn
    a few per turn soon after docking (and during a Run that lasts, when some are left), in
    the text overlay, which is then put back."""
    from napari_pfsdm.napari import _widget
    from napari_pfsdm.napari._glyphs import LEGEND_CHARACTERS

    viewer = make_napari_viewer(show=True)  # napari draws texts only on a shown canvas
    for data, kwargs, kind in sample_layers:
        getattr(viewer, f"add_{kind}")(data, **kwargs)
    overlay = viewer.canvas.overlays.text
    before = (overlay.visible, overlay.text, tuple(np.asarray(overlay.color).ravel()))
    seen = []
    overlay.events.text.connect(lambda text: seen.append((text, overlay.visible)))
    widget = dock(viewer)
    assert not set(LEGEND_CHARACTERS) <= set(_font_glyphs(viewer))
    qtbot.waitUntil(lambda: bool(seen) and not widget._glyphs.active, timeout=90_000)
    assert set(LEGEND_CHARACTERS) <= set(_font_glyphs(viewer))
    # drawn in chunks of a few characters while the overlay was shown (transparent), two
    # first, then as many as the repaints allow
    chunks = [text for text, visible in seen if visible and text]
    assert "".join(chunks) == LEGEND_CHARACTERS and max(map(len, chunks)) <= 12
    assert len(chunks[0]) == 2
    assert (overlay.visible, overlay.text, tuple(np.asarray(overlay.color).ravel())) == before
    # a Run then draws no new character, and its legend uses only characters drawn ahead
    n = len(_font_glyphs(viewer))
    run_and_wait(qtbot, widget)
    wait_pictures(qtbot, widget)
    legend = viewer.layers[_layers.layer_names("gastruloids")["legend"]]
    used = set("".join(legend.features["text"])) - set(" \n")
    assert used <= set(LEGEND_CHARACTERS), used - set(LEGEND_CHARACTERS)
    qtbot.wait(300)
    assert len(_font_glyphs(viewer)) == n
    # characters left to draw: a Run that lasts draws them while its worker computes
    widget._glyphs.drawn.clear()
    monkeypatch.setattr(_widget, "GLYPHS_AFTER_RUN_START_MS", 0)
    shown = len(seen)
    with qtbot.waitSignal(widget.finished, timeout=60_000):
        widget.run()
    assert any(visible and text for text, visible in seen[shown:])
    qtbot.waitUntil(lambda: widget.worker is None, timeout=5000)
    assert not widget._glyphs.active
    assert (overlay.visible, overlay.text, tuple(np.asarray(overlay.color).ravel())) == before


@pytest.fixture
def imports_held_open(make_napari_viewer, sample_layers, monkeypatch):
    """A viewer with the sample's layers, the characters due at once after docking, and
    docking's background imports a thread that lives until ``release`` is set. Yields
    (viewer, the overlay texts seen, release, the thread)."""
    import threading

    from napari_pfsdm.napari import _widget

    release = threading.Event()
    importing = threading.Thread(target=release.wait, daemon=True)
    importing.start()
    monkeypatch.setattr(_widget, "_BACKGROUND_IMPORT", [importing])
    monkeypatch.setattr(_widget, "GLYPHS_AFTER_DOCK_MS", 0)
    viewer = make_napari_viewer(show=True)
    for data, kwargs, kind in sample_layers:
        getattr(viewer, f"add_{kind}")(data, **kwargs)
    seen = []
    viewer.canvas.overlays.text.events.text.connect(lambda text: seen.append(text))
    try:
        yield viewer, seen, release, importing
    finally:
        release.set()
        importing.join()


def test_the_characters_wait_for_the_background_imports_to_finish(imports_held_open, qtbot):
    """The imports after docking end with a full garbage collection (200-460 ms): the
    characters (the first cost 180-300 ms, napari's first text) are drawn after them, not in
    the same seconds; drawn all the same once the imports are done."""
    viewer, seen, release, importing = imports_held_open
    widget = dock(viewer)
    qtbot.wait(600)  # several polls (READY_POLL_MS) later
    assert not widget._glyphs.active and not seen
    release.set()
    importing.join()
    qtbot.waitUntil(lambda: bool(seen), timeout=5000)
    qtbot.waitUntil(lambda: not widget._glyphs.active, timeout=90_000)


def test_the_characters_wait_for_the_imports_only_so_long(imports_held_open, qtbot,
                                                          monkeypatch):
    """Imports that never end (a hung network drive) do not keep the characters from being
    drawn: they start READY_WAIT_MS later all the same."""
    from napari_pfsdm.napari import _glyphs

    monkeypatch.setattr(_glyphs, "READY_WAIT_MS", 300)
    viewer, seen, _release, importing = imports_held_open
    widget = dock(viewer)
    qtbot.waitUntil(lambda: bool(seen), timeout=5000)
    assert importing.is_alive()
    qtbot.waitUntil(lambda: not widget._glyphs.active, timeout=90_000)


def test_characters_per_turn_fit_the_repaints_of_the_last_turn():
    """70 ms a turn: 4 characters that stalled the viewer 40 ms (10 ms each, as if the whole
    stall were theirs) leave room for 7; 12 in 300 ms (25 ms each) for 2; a turn under the
    budget draws one more the next turn at least (2 in 60 ms: 30 ms each would say 2, but
    the canvas' repaint does not grow with them: 3), one at the budget as many again; a
    character slower than the budget alone still goes, one a turn; a stall that cost nothing
    allows the most, 12."""
    from napari_pfsdm.napari._glyphs import characters_per_turn

    assert characters_per_turn(40.0, 4) == 7
    assert characters_per_turn(300.0, 12) == 2
    assert characters_per_turn(60.0, 2) == 3
    assert characters_per_turn(69.0, 1) == 2
    assert characters_per_turn(70.0, 5) == 5
    assert characters_per_turn(400.0, 1) == 1
    assert characters_per_turn(0.0, 2) == 12
    assert characters_per_turn(-5.0, 2) == 12  # the next turn came before its interval


def test_a_repaint_that_fits_in_the_pause_still_counts(qtbot, monkeypatch):
    """Each turn sizes itself by the event loop's longest stall since the last turn (a 10 ms
    clock), not by how late the turn came: a 100 ms repaint inside a 210 ms pause is 100 ms."""
    from types import SimpleNamespace

    from napari_pfsdm.napari import _glyphs

    overlay = SimpleNamespace(text="", color="white", visible=False)
    viewer = SimpleNamespace(canvas=SimpleNamespace(overlays=SimpleNamespace(text=overlay)))
    now = [0.0]
    monkeypatch.setattr(_glyphs.time, "perf_counter", lambda: now[0])
    warmer = _glyphs.GlyphWarmer(viewer, set())

    def ticks_then_turn(*times: float) -> None:
        for t in times:
            now[0] = t
            warmer._tick()
        warmer._turn()

    warmer.start()
    assert overlay.visible and overlay.color == "transparent"
    ticks_then_turn()
    assert len(warmer._shown) == 2  # the first turn: two
    # the two characters' repaint stalls the loop 210 ms (220 between ticks, less the 10 ms
    # clock), over the 70 ms budget: one a turn, and a pause as long as the stall
    ticks_then_turn(0.01, 0.23)
    assert len(warmer._shown) == 1 and warmer._timer.interval() == 210
    # the next turn comes on time, 210 ms later, its character's repaint (100 ms) inside
    # the pause: still one a turn (the turn's lateness, the old measure, saw almost none)
    ticks_then_turn(0.24, 0.35, 0.36, 0.37, 0.38, 0.39, 0.40, 0.41, 0.42, 0.43, 0.44)
    assert len(warmer._shown) == 1 and warmer._timer.interval() == 100
    # a repaint that costs nothing: the loop ticked every 10 ms; twelve, the most
    ticks_then_turn(0.45, 0.46, 0.47, 0.48, 0.49, 0.50, 0.51, 0.52, 0.53, 0.54)
    assert len(warmer._shown) == 12
    warmer.stop()
    assert not overlay.visible and overlay.color == "white" and overlay.text == ""


def test_an_overlay_the_user_shows_is_left_alone(viewer_widget, qtbot):
    viewer, widget = viewer_widget
    overlay = viewer.canvas.overlays.text
    overlay.text = "embryo 3, 48 h"
    overlay.visible = True
    run_and_wait(qtbot, widget)
    assert not widget._glyphs.active
    assert overlay.text == "embryo 3, 48 h" and overlay.visible


def test_a_run_that_shows_no_pictures_adds_their_layers_hidden_one_per_turn(
        make_napari_viewer, sample_layers, qtbot):
    """The frame shown has no object: no pictures, but their four layers are added empty and
    hidden, one per event-loop turn, so that the first object selected only fills them."""
    from qtpy.QtCore import QTimer

    viewer = make_napari_viewer()
    for data, kwargs, kind in sample_layers:
        data = data.copy()
        if kind == "labels":
            data[0] = 0  # frame 0: no object
        getattr(viewer, f"add_{kind}")(data, **kwargs)
    widget = dock(viewer)
    labels = viewer.layers["gastruloids"]
    viewer.dims.set_point(0, 0)
    names = _layers.layer_names("gastruloids")
    pictures = {names[k] for k in ("sdf", "disk", "intensity_disk", "skeleton")}
    turns = [0]
    ticker = QTimer(interval=0)
    ticker.timeout.connect(lambda: turns.__setitem__(0, turns[0] + 1))
    added = []
    viewer.layers.events.inserted.connect(
        lambda e: added.append(turns[0]) if e.value.name in pictures else None)
    ticker.start()
    run_and_wait(qtbot, widget, labels=labels)
    qtbot.waitUntil(lambda: len(added) == 4, timeout=10_000)
    ticker.stop()
    assert len(set(added)) == 4, added  # one turn each
    assert widget.shown_key == (0, int(labels.selected_label))
    assert not any(viewer.layers[n].visible for n in pictures)
    assert "not in this frame" in viewer.layers[names["legend"]].features["text"].iloc[-2]
    before = {n: viewer.layers[n] for n in pictures}
    inserted = []
    viewer.layers.events.inserted.connect(lambda e: inserted.append(e.value.name))
    viewer.dims.set_point(0, 1)
    label = int(widget.last_output.labels_in(1)[0])
    labels.selected_label = label
    shown = wait_pictures(qtbot, widget, (1, label))
    # the same layers, now shown with the object's pictures: none added
    assert inserted == []
    assert all(viewer.layers[n] is before[n] and viewer.layers[n].visible for n in pictures)
    sdf = viewer.layers[names["sdf"]].data
    assert sdf.shape[0] == shown.sdf.shape[0] and sdf.shape[1] > shown.sdf.shape[1]


def test_a_text_the_user_writes_while_characters_are_drawn_is_kept_in_their_colour(
        viewer_widget, qtbot):
    viewer, widget = viewer_widget
    overlay = viewer.canvas.overlays.text
    colour = overlay.color
    widget._glyphs.drawn.clear()
    widget._glyphs.start()
    assert widget._glyphs.active and overlay.visible
    overlay.text = "embryo 3, 48 h"  # the user, meanwhile
    qtbot.waitUntil(lambda: not widget._glyphs.active, timeout=10_000)
    assert overlay.text == "embryo 3, 48 h" and overlay.visible
    assert overlay.color == colour


def test_a_hidden_text_of_the_users_stays_hidden_and_comes_back(viewer_widget, qtbot):
    viewer, widget = viewer_widget
    overlay = viewer.canvas.overlays.text
    overlay.text = "for later"  # written, not shown
    widget._glyphs.drawn.clear()
    widget._glyphs.start()
    qtbot.waitUntil(lambda: not widget._glyphs.active, timeout=10_000)
    assert overlay.text == "for later" and not overlay.visible



def test_pictures_of_a_new_object_update_their_layers_one_per_turn(viewer_widget, qtbot,
                                                                   monkeypatch):
    """Once the picture layers exist, another object's pictures still go in one layer per
    event-loop turn: the five updates and their redraws in one go froze the viewer for
    110-150 ms on each time-slider step (``benchmarks/plugin.py --stacks time-slider``)."""
    from qtpy.QtCore import QTimer

    viewer, widget = viewer_widget
    labels = viewer.layers["gastruloids"]
    run_and_wait(qtbot, widget, labels=labels)
    first = wait_pictures(qtbot, widget)
    names = _layers.layer_names("gastruloids")
    keys = ("sdf", "disk", "intensity_disk", "skeleton", "legend")
    layers = {k: viewer.layers[names[k]] for k in keys}
    turns = [0]
    ticker = QTimer(interval=0)
    ticker.timeout.connect(lambda: turns.__setitem__(0, turns[0] + 1))
    updated: list = []  # (layer name, turn) of each layer the pictures were put in

    def spy_on(real):
        def spy(*args, **kwargs):
            out = real(*args, **kwargs)
            layer = out[0] if isinstance(out, tuple) else out
            updated.append((layer.name, turns[0]))
            return out
        return spy

    for fn in ("_place_picture", "_replace_lines", "_legend"):
        monkeypatch.setattr(_layers, fn, spy_on(getattr(_layers, fn)))
    other = next(int(v) for v in widget.last_output.labels_in(first.frame)
                 if int(v) != first.label)
    ticker.start()
    labels.selected_label = other
    assert updated == []  # nothing in the selection's own turn: napari's drawing first
    shown = wait_pictures(qtbot, widget, (first.frame, other))
    ticker.stop()
    assert [n for n, _t in updated] == [names[k] for k in keys], updated
    assert len({t for _n, t in updated}) == len(keys), updated  # one turn each
    assert all(viewer.layers[names[k]] is layers[k] for k in keys)  # updated in place
    assert layers["sdf"].data.shape[0] == shown.sdf.shape[0]


_FIRST_OPEN = r"""
import gc
import sys
import threading
import time

import napari
import numpy as np
from qtpy.QtWidgets import QApplication

assert "matplotlib" not in sys.modules, "imported before docking: nothing to measure"
viewer = napari.Viewer(show=True)
viewer.add_labels(np.zeros((2, 64, 64), "uint16"), name="empty")
full = []  # (thread, the function running then) of each collection of generation 2


def on_gc(phase, info):  # an explicit gc.collect(): its caller; else what allocated
    if phase == "start" and info["generation"] == 2:
        try:
            caller = sys._getframe(1).f_code.co_name
        except ValueError:  # no Python frame (set off by a thread's C code)
            caller = "?"
        full.append((threading.current_thread().name, caller))


gc.callbacks.append(on_gc)
_dock, widget = viewer.window.add_plugin_dock_widget("napari-pfsdm", "PF-SDM analysis")
from napari_pfsdm.napari import _widget

thread = _widget._BACKGROUND_IMPORT[0]
print("thread", thread.name, thread is not threading.main_thread())
end = time.perf_counter() + 60
while thread.is_alive() and time.perf_counter() < end:
    QApplication.processEvents()
    time.sleep(0.002)
print("imported", "matplotlib" in sys.modules, "napari_pfsdm.napari._plots" in sys.modules,
      "napari_pfsdm.core.descriptor" in sys.modules)
print("full collections", [f for f in full if f[0] == "pfsdm-imports"], gc.isenabled())
viewer.close()
"""


def test_docking_imports_the_plots_in_a_background_thread(tmp_path):
    """matplotlib's import (~0.8 s) froze the viewer at the first Open plots (850 ms gap,
    156 ms once imported; a probe on the sample): docking the analysis widget imports the
    plots' modules, and the measuring code, in a daemon thread, in a fresh interpreter as a
    person's session is.

    The thread ends with the one full collection of Python's garbage collector the imports
    lead to (none half-way through them, the collector enabled again after): left to
    Python, it came later in the session, 200-460 ms in opening the plots or the
    all-frames view (``_widget.import_in_background``)."""
    import os
    import subprocess
    import sys

    script = tmp_path / "first_open.py"
    script.write_text(_FIRST_OPEN)
    env = {**os.environ, "NAPARI_CONFIG": str(tmp_path / "settings.yaml")}
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         timeout=300, env=env)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "thread pfsdm-imports True" in out.stdout, out.stdout
    assert "imported True True True" in out.stdout, out.stdout
    assert "full collections [('pfsdm-imports', 'load')] True" in out.stdout, out.stdout


#: Modules of the measuring code (and what they load) that napari's docking, which imports
#: the panel's module on the GUI thread, must not import (~0.6 s of freeze in all).
_MEASURING = ("napari_pfsdm.core.descriptor", "napari_pfsdm.core.pushforward",
              "napari_pfsdm.analysis.features", "napari_pfsdm.analysis.parallel",
              "scipy.interpolate", "scipy.spatial", "skimage.morphology", "matplotlib")


def test_the_panels_module_imports_no_measuring_code():
    """Docking from the menu froze the viewer for 0.7 s while napari imported the panel's
    module, which imported the measuring code (``core/__init__`` loaded the whole method;
    ``python -X importtime``). In a fresh interpreter, importing the module napari imports
    loads none of it, although napari has been imported."""
    import subprocess
    import sys

    code = ("import sys, napari, napari.layers\n"
            f"before = {{m for m in {_MEASURING!r} if m in sys.modules}}\n"
            "import napari_pfsdm.napari._widget\n"
            f"print(sorted({{m for m in {_MEASURING!r} if m in sys.modules}} - before))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.strip().splitlines()[-1] == "[]", out.stdout
