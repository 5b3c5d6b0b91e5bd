"""The plugin as a user meets it: docked from the Plugins menu on a public-only viewer."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from napari_helpers import (
    PLOTS,
    PREDICTION,
    dock,
    many_objects,
    run_and_wait,
    wait_pictures,
)

import napari_pfsdm as pf
from napari_pfsdm.napari._pictures import caption_texts

pytestmark = pytest.mark.gui


def _layer(viewer, suffix):
    return viewer.layers[f"gastruloids {suffix}"]


def test_run_measures_what_measure_measures_and_fills_the_layer_features(qtbot, viewer_widget):
    viewer, w = viewer_widget
    labels, reporter = viewer.layers["gastruloids"], viewer.layers["gastruloids reporter"]
    assert w.labels.value == "gastruloids" and w.reporter.value == ("gastruloids reporter", None)
    analysis = run_and_wait(qtbot, w)
    expected = pf.measure(np.asarray(labels.data), np.asarray(reporter.data))
    got = analysis.table.drop(columns=["track_id"])
    pd.testing.assert_frame_equal(got.reset_index(drop=True), expected.reset_index(drop=True),
                                  check_like=True)
    # every frame's rows with explicit frame and label columns (napari-clusters-plotter's
    # time-lapse convention), napari's index = the label
    features = labels.features
    assert features["frame"].tolist() == expected["frame"].tolist()
    assert features["label"].tolist() == features["index"].tolist() == expected["label"].tolist()
    np.testing.assert_array_equal(features["area"], expected["area"])
    assert {"shape_PC1", "circularity"} <= set(features.columns)
    assert all(pd.api.types.is_numeric_dtype(features[c]) for c in features)  # plotters' axes
    writes = []
    labels.events.features.connect(writes.append)
    for frame in (0, 4, 2):  # written once per Run, never per frame step
        viewer.dims.set_current_step(0, frame)
        labels.selected_label = 4
    assert writes == []
    # napari's status bar (one line, cut at the window's edge) shows the label's row that its
    # index finds: it says first which frame's row that is, and the numbers are that row's
    row = expected[(expected["frame"] == 2) & (expected["label"] == 4)].iloc[0]
    status = labels.get_status((2, row["centroid_y"], row["centroid_x"]), world=True)
    shown_row = status["coordinates"].split("; ", 1)[1].split(", ")
    assert shown_row[0].startswith("frame: "), shown_row
    shown = int(shown_row[0].split(": ")[1])
    want = expected[(expected["frame"] == shown) & (expected["label"] == 4)].iloc[0]
    assert f"area: {want['area']}" in shown_row, shown_row
    assert shown == expected.loc[expected["label"] == 4, "frame"].max()
    assert "72 objects" in w.status.value and "PC1" in w.status.value


def test_the_pictures_are_always_the_selected_objects_after_bursts(qtbot, viewer_widget):
    """Quick bursts of selections, frame steps and trajectory clicks: once the plugin is idle,
    the disk shown is exactly pf.render_disk of the selected object in the current frame."""
    viewer, w = viewer_widget
    run_and_wait(qtbot, w)
    plots = dock(viewer, PLOTS)
    labels = viewer.layers["gastruloids"]
    data = np.asarray(labels.data)
    rng = np.random.default_rng(1)
    n_points = len(plots.trajectories.keys)
    assert n_points == 72
    for _burst in range(6):
        for _ in range(5):
            kind = rng.integers(3)
            if kind == 0:
                labels.selected_label = int(rng.integers(1, 7))
            elif kind == 1:
                viewer.dims.set_current_step(0, int(rng.integers(0, 12)))
            else:
                plots.trajectories.select(int(rng.integers(n_points)))
            qtbot.wait(int(rng.integers(0, 30)))
        wait_pictures(qtbot, w)
        frame = int(viewer.dims.current_step[0])
        label = int(labels.selected_label)
        assert w.pictures.shown[1:] == (frame, label)
        expected = pf.render_disk(pf.pfsdm(data[frame] == label), 128)
        shown = _layer(viewer, "PF-SDF disk").data[:, :128]  # (its colour bar on the right)
        np.testing.assert_allclose(shown, np.nan_to_num(expected), atol=1e-4)
        assert f"label {label}" in " ".join(caption_texts(_layer(viewer, "captions")))


def test_while_the_pictures_are_made_the_old_ones_are_dimmed_and_say_so(qtbot, viewer_widget):
    """Between a new selection and its pictures, the pictures on screen are another object's:
    they are dimmed and the caption names the object being drawn."""
    viewer, w = viewer_widget
    run_and_wait(qtbot, w)
    labels = viewer.layers["gastruloids"]
    viewer.dims.set_current_step(0, 3)
    labels.selected_label = 1
    wait_pictures(qtbot, w)
    disk = _layer(viewer, "PF-SDF disk")
    assert disk.visible and disk.opacity == 1.0
    labels.selected_label = 4  # not made yet: no event loop has run since
    assert disk.opacity < 0.5
    captions = _layer(viewer, "captions")
    assert "making the pictures of frame 3, label 4" in " ".join(caption_texts(captions))
    wait_pictures(qtbot, w)
    assert disk.opacity == 1.0 and _layer(viewer, "outline and skeleton").opacity == 1.0
    assert "frame 3 · label 4" in " ".join(caption_texts(captions))


def test_a_step_to_the_next_or_previous_frame_shows_the_pictures_at_once(qtbot, viewer_widget):
    """Once the selected object's pictures are shown, those of the frames beside are made in
    the background: a step shows the right pictures before the event loop runs again."""
    viewer, w = viewer_widget
    run_and_wait(qtbot, w)
    labels = viewer.layers["gastruloids"]
    data = np.asarray(labels.data)
    viewer.dims.set_current_step(0, 5)
    labels.selected_label = 3
    wait_pictures(qtbot, w)
    qtbot.waitUntil(lambda: w.pictures.worker is None, timeout=10_000)
    for frame in (6, 7, 8, 7, 6, 5, 4):  # forward, back, and past where it started
        viewer.dims.set_current_step(0, frame)  # no event loop between the step and the check
        assert w.pictures.shown[1:] == (frame, 3)
        expected = pf.render_disk(pf.pfsdm(data[frame] == 3), 128)
        np.testing.assert_allclose(_layer(viewer, "PF-SDF disk").data[:, :128],
                                   np.nan_to_num(expected), atol=1e-4)
        assert _layer(viewer, "PF-SDF disk").opacity == 1.0
        qtbot.waitUntil(lambda: w.pictures.worker is None, timeout=10_000)


def test_a_trajectory_click_moves_napari_to_that_frame_and_object(qtbot, viewer_widget):
    viewer, w = viewer_widget
    run_and_wait(qtbot, w)
    plots = dock(viewer, PLOTS)
    keys = plots.trajectories.keys
    i = int(np.flatnonzero((keys[:, 0] == 7) & (keys[:, 1] == 4))[0])
    plots.trajectories.select(i)
    assert viewer.dims.current_step[0] == 7
    assert viewer.layers["gastruloids"].selected_label == 4
    assert w.bound[1].selection == (7, 4)
    # and the plot marks it: a star on that very point
    star = plots.trajectories.marks[-1]
    np.testing.assert_allclose(star.get_offsets()[0], plots.trajectories.xy[i])


def _red_pixels_near(plot, point, radius: int = 6) -> int:
    """Pixels of the star's red (#ff3c3c) within ``radius`` px of ``point`` (data
    coordinates) in what the canvas shows."""
    rgba = np.asarray(plot.canvas.buffer_rgba())
    x, y = plot.points_axes.transData.transform(point)
    row, col = int(round(rgba.shape[0] - y)), int(round(x))
    patch = rgba[max(row - radius, 0):row + radius + 1, max(col - radius, 0):col + radius + 1]
    red = (patch[..., 0] > 230) & (patch[..., 1] < 100) & (patch[..., 2] < 100)
    return int(red.sum())


def test_the_plot_shows_the_mark_of_the_selection_and_only_of_it(qtbot, shown_viewer_widget):
    """What the trajectory canvas shows (its pixels): a red star on the selected object's
    point, and none left on the object selected before."""
    viewer, w = shown_viewer_widget
    run_and_wait(qtbot, w)
    plots = dock(viewer, PLOTS)
    plot = plots.trajectories
    qtbot.waitUntil(lambda: plot.background is not None, timeout=10_000)  # drawn in full
    labels = viewer.layers["gastruloids"]
    viewer.dims.set_current_step(0, 0)
    in_frame = np.flatnonzero(plot.keys[:, 0] == 0)
    screen = plot.points_axes.transData.transform(plot.xy[in_frame])
    far = np.hypot(*(screen[:, None] - screen[None]).transpose(2, 0, 1))
    first, second = (in_frame[k] for k in np.unravel_index(far.argmax(), far.shape))
    assert far.max() > 60  # the two stars cannot overlap
    for i in (first, second):
        labels.selected_label = int(plot.keys[i, 1])
        qtbot.wait(50)
        assert _red_pixels_near(plot, plot.xy[i]) > 10
    assert _red_pixels_near(plot, plot.xy[first]) == 0  # the first star is gone
    plot.canvas.draw()  # a full drawing (zoom, resize) keeps the mark
    assert _red_pixels_near(plot, plot.xy[second]) > 10


def test_open_plots_draws_the_trajectories_once_at_the_size_shown(qtbot, shown_viewer_widget):
    """Opening the plots draws the figure once, at the canvas's size on screen (not first at
    matplotlib's default 6.4 × 4.8 inches while the dock is being laid out)."""
    viewer, w = shown_viewer_widget
    run_and_wait(qtbot, w)
    w.open_plots()  # the figure is made here; it is drawn at a later turn of the event loop
    canvas = dock(viewer, PLOTS).trajectories.canvas
    sizes: list = []
    canvas.mpl_connect("draw_event", lambda e: sizes.append(tuple(canvas.figure.bbox.size)))
    qtbot.waitUntil(lambda: len(sizes) > 0, timeout=10_000)
    qtbot.wait(1000)
    ratio = canvas.device_pixel_ratio
    assert len(sizes) == 1
    assert sizes[0] == pytest.approx((canvas.width() * ratio, canvas.height() * ratio), abs=1)


def test_an_object_without_features_says_so_where_the_pictures_would_be(qtbot,
                                                                          make_napari_viewer_proxy):
    viewer = make_napari_viewer_proxy()
    labels = np.zeros((64, 96), np.uint16)
    labels[8:40, 8:40] = 1
    labels[50:53, 60:63] = 2  # 9 px: below min_area
    layer = viewer.add_labels(labels, name="cells")
    w = dock(viewer)
    run_and_wait(qtbot, w)
    layer.selected_label = 1
    wait_pictures(qtbot, w)
    assert viewer.layers["cells PF-SDF disk"].visible
    layer.selected_label = 2
    wait_pictures(qtbot, w)
    text = " ".join(caption_texts(viewer.layers["cells captions"]))
    assert "label 2 has no features" in text and "too small" in text
    assert not viewer.layers["cells PF-SDF disk"].visible


def test_cancel_keeps_nothing(qtbot, make_napari_viewer_proxy):
    viewer = make_napari_viewer_proxy()
    layer = viewer.add_labels(np.stack([many_objects()] * 3), name="many")
    w = dock(viewer)
    worker = w.run()
    w.cancel()
    qtbot.waitUntil(lambda: w.worker is None, timeout=120_000)
    assert worker is not None and w.bound is None
    assert "Cancelled" in w.status.value and "frame" not in layer.features.columns
    from napari_pfsdm.napari._model import REGISTRY

    assert REGISTRY.get(layer.unique_id) is None


def test_a_run_shows_napari_progress_counting_its_objects(qtbot, viewer_widget, monkeypatch):
    """napari's progress bar counts a Run's objects to the last one and closes."""
    from napari_pfsdm.napari import _jobs

    bars = []

    class Recorded(_jobs.progress):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.closed_at = None
            bars.append(self)

        def close(self):
            self.closed_at = (self.n, self.total)
            super().close()

    monkeypatch.setattr(_jobs, "progress", Recorded)
    _viewer, w = viewer_widget
    n = len(run_and_wait(qtbot, w).table)
    assert n == 72 and len(bars) == 1 and bars[0].closed_at == (n, n)


def test_bad_layers_get_a_plain_message_and_no_run(qtbot, make_napari_viewer_proxy):
    viewer = make_napari_viewer_proxy()
    viewer.add_labels(np.zeros((32, 32), np.uint8), name="empty")
    w = dock(viewer)
    assert w.run() is not None  # the count happens in the worker: empty is said there
    qtbot.waitUntil(lambda: w.worker is None, timeout=60_000)
    assert "no objects" in w.status.value and w.bound is None
    w.options["n_fourier"].value = 60  # more than 64 angles can carry
    viewer.layers["empty"].data[4:20, 4:20] = 1
    assert w.run() is None and "n_fourier" in w.status.value


def test_export_writes_plain_csv_with_sidecars_equal_to_the_run(qtbot, viewer_widget, tmp_path):
    viewer, w = viewer_widget
    analysis = run_and_wait(qtbot, w)
    assert w.export(tmp_path) is not None
    qtbot.waitUntil(lambda: w.export_worker is None, timeout=120_000)
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == sorted(["gastruloids_features.csv", "gastruloids_features.csv.json",
                            "gastruloids_columns.csv", "gastruloids_columns.csv.json",
                            "gastruloids_pca_shape.csv", "gastruloids_pca_shape.csv.json",
                            "gastruloids_pca_intensity.csv", "gastruloids_pca_intensity.csv.json",
                            "gastruloids_distances.csv", "gastruloids_distances.csv.json"])
    features = pd.read_csv(tmp_path / "gastruloids_features.csv")
    np.testing.assert_allclose(features["shape_r00_n00"], analysis.table["shape_r00_n00"])
    columns = pd.read_csv(tmp_path / "gastruloids_columns.csv")  # a glossary beside it
    assert columns["column"].tolist() == list(features.columns)
    assert columns["meaning"].notna().all()
    d = pd.read_csv(tmp_path / "gastruloids_distances.csv", index_col=0)
    expected = pf.distance_matrix(pf.drop_failed(analysis.table))  # the record's weight: 0
    np.testing.assert_allclose(d.to_numpy(), expected, rtol=1e-9)
    other = tmp_path / "other"
    other.mkdir()
    (other / "gastruloids_distances.csv").write_text("someone else's table\n")
    assert w.export(other) is not None  # a name taken by a file we did not write
    qtbot.waitUntil(lambda: w.export_worker is None, timeout=60_000)
    assert "Nothing was exported" in w.status.value
    assert sorted(p.name for p in other.iterdir()) == ["gastruloids_distances.csv"]
    assert (other / "gastruloids_distances.csv").read_text() == "someone else's table\n"


def test_layer_for_plotters_has_one_id_per_object_and_frame(qtbot, viewer_widget):
    viewer, w = viewer_widget
    analysis = run_and_wait(qtbot, w)
    objects = w.add_objects_layer()
    labels = np.asarray(viewer.layers["gastruloids"].data)
    t, lab = analysis.table["frame"].to_numpy(), analysis.table["label"].to_numpy()
    for row in (0, 17, 71):
        mask = labels[t[row]] == lab[row]
        assert set(np.unique(objects.data[t[row]][mask])) == {row + 1}
    assert objects.features["index"].tolist() == list(range(1, 73))
    assert objects.features["frame"].tolist() == t.tolist()
    # the Labels layer keeps napari's index = its label, every frame's rows
    assert viewer.layers["gastruloids"].features["index"].tolist() == lab.tolist()
    assert analysis.layer_features()["index"].tolist() == lab.tolist()


def test_prediction_writes_probabilities_into_the_layer_features(qtbot, viewer_widget):
    viewer, w = viewer_widget
    run_and_wait(qtbot, w)
    p = dock(viewer, PREDICTION)
    assert "multi-axes: 2 objects" in p.classes.value  # the sample's groups
    p.last.value = 3
    assert p.run() is not None
    qtbot.waitUntil(lambda: p.worker is None, timeout=180_000)
    assert "Balanced accuracy" in p.status.value, p.status.value
    cols = [c for c in viewer.layers["gastruloids"].features.columns if c.startswith("p_")]
    assert sorted(cols) == ["p_multi-axes", "p_single-axis"]
    probs = viewer.layers["gastruloids"].features[cols].to_numpy()
    np.testing.assert_allclose(probs.sum(axis=1), 1.0)
    # identities found again while a prediction runs: the scores land on the new table
    a = w.bound[1]
    assert p.run() is not None
    relinked = a.table.drop(columns=cols).assign(note="linked again")
    a.set_table(relinked, "")
    qtbot.waitUntil(lambda: p.worker is None, timeout=180_000)
    assert (a.table["note"] == "linked again").all()
    np.testing.assert_allclose(a.table[cols].to_numpy().sum(axis=1), 1.0)


def test_every_dock_open_fits_a_laptop_screen(qtbot, make_napari_viewer, sample_layers):
    viewer = make_napari_viewer(show=True)
    window = viewer.window._qt_window  # the test measures the window; the plugin never does
    window.resize(1280, 800)
    for data, kwargs, kind in sample_layers:
        getattr(viewer, f"add_{kind}")(data, **kwargs)
    w = dock(viewer)
    run_and_wait(qtbot, w)
    w.open_plots()
    prediction = dock(viewer, PREDICTION)
    wait_pictures(qtbot, w)
    qtbot.wait(300)
    assert window.height() <= 800
    from qtpy.QtWidgets import QAbstractButton, QAbstractSpinBox, QComboBox

    plots = dock(viewer, PLOTS)
    # napari's style sheet draws spin boxes 18-20 px high (its own layer controls too): a
    # squashed control is one below that, e.g. a combo box given 0 of its 24 px
    from superqt import QCollapsible

    def squashed():
        folded = [c for c in w.findChildren(QCollapsible) if not c.isExpanded()]
        return [(type(c).__name__, c.toolTip()[:30], c.height())
                for panel in (w, plots, prediction)
                for kind in (QAbstractButton, QAbstractSpinBox, QComboBox)
                for c in panel.findChildren(kind)
                if c.isVisible() and c.height() < min(c.minimumSizeHint().height(), 18)
                and not any(f.isAncestorOf(c) for f in folded)]

    assert squashed() == []  # every control keeps its natural height (the docks scroll)
    for more in w.findChildren(QCollapsible):  # unfolding "More options" scrolls too
        more.expand(animate=False)
    qtbot.wait(200)
    assert squashed() == [] and window.height() <= 800
    from napari_pfsdm.napari._widgets import dock_of

    dock_of(w).raise_()  # the analysis tab in front
    qtbot.wait(200)
    for native in (w.labels.native, w.run_button.native, w.cancel_button.native, w.status):
        top_left = native.mapTo(window, native.rect().topLeft())
        assert native.isVisible() and 0 <= top_left.y() <= window.height() - native.height()
    shot = viewer.screenshot(canvas_only=True)[..., :3]
    assert shot.std() > 5  # the canvas shows the image and the pictures, not a blank


def test_a_z_stack_gets_shells_and_a_surface(qtbot, make_napari_viewer_proxy):
    from napari_pfsdm.data.volumes import blob_volume

    viewer = make_napari_viewer_proxy()
    blob = blob_volume("tetrahedron", size=(24, 40, 40), radius=10)
    labels = np.zeros((24, 40, 80), np.uint16)
    labels[:, :, :40][blob] = 1
    labels[6:18, 10:30, 50:70] = 2
    layer = viewer.add_labels(labels, name="stack")
    w = dock(viewer)
    w.first_axis.value = "z"  # the form says "Z (slices of 3-D objects)"
    analysis = run_and_wait(qtbot, w)
    assert analysis.axes == "zyx" and len(analysis.table) == 2
    layer.selected_label = 2
    wait_pictures(qtbot, w)
    surface = viewer.layers["stack surface"]
    verts = surface.data[0]
    assert verts.shape[1] == 3
    assert 5 <= verts[:, 0].min() and verts[:, 0].max() <= 18  # on the box of label 2, in z
    assert 49 <= verts[:, 2].min() and verts[:, 2].max() <= 70
    captions = viewer.layers["stack captions"]
    assert "label 2" in caption_texts(captions)[0]
    # 3-D captions: in napari's 3-D view the object's caption floats just above the surface
    assert captions.ndim == 3
    z, y, x = captions.data[2]  # the third caption names the object
    assert 49 <= x <= 70 and y < verts[:, 1].min() and 6 <= z <= 18


def test_a_new_run_or_pair_of_pcs_shows_its_own_points(qtbot, shown_viewer_widget):
    """The trajectory plot after another Run (one object fewer) and another pair of PCs: its
    points are the new PCA scores, coloured by their frame, inside the axes, with the star on
    the selected object's new point."""
    viewer, w = shown_viewer_widget
    run_and_wait(qtbot, w)
    plots = dock(viewer, PLOTS)
    plot = plots.trajectories
    qtbot.waitUntil(lambda: plot.background is not None, timeout=10_000)
    labels = viewer.layers["gastruloids"]
    labels.data = np.where(labels.data == 6, 0, labels.data)
    analysis = run_and_wait(qtbot, w)
    for pair in ("PC1–PC2", "PC2–PC3"):
        plot.pcs.value = pair
        scores = analysis.pca["shape"]
        i, j = pair.replace("PC", "").split("–")
        points = plot.points_axes.collections[0]
        np.testing.assert_allclose(points.get_offsets(),
                                   scores[[f"shape_PC{i}", f"shape_PC{j}"]].to_numpy())
        assert len(points.get_offsets()) == 60 and 6 not in plot.keys[:, 1]
        np.testing.assert_array_equal(points.get_array(), scores["frame"].to_numpy())
        assert points.norm.vmin == 0 and points.norm.vmax == 11
        (x0, x1), (y0, y1) = plot.points_axes.get_xlim(), plot.points_axes.get_ylim()
        x, y = points.get_offsets().T
        assert x0 < x.min() and x.max() < x1 and y0 < y.min() and y.max() < y1
        assert plot.points_axes.get_xlabel().startswith(f"PC{i} (")
        qtbot.waitUntil(lambda: plot.background is not None, timeout=10_000)
        frame, label = analysis.selection
        k = int(np.flatnonzero((plot.keys[:, 0] == frame) & (plot.keys[:, 1] == label))[0])
        assert _red_pixels_near(plot, plot.xy[k]) > 10


def test_the_plots_follow_the_model(qtbot, viewer_widget):
    viewer, w = viewer_widget
    analysis = run_and_wait(qtbot, w)
    plots = dock(viewer, PLOTS)
    traj = plots.trajectories
    assert traj.analysis is analysis and "circularity" in traj.info.value
    analysis.set_groups({1: "a", 2: "b"})
    traj.color_by.value = "group"
    legend = traj.points_axes.get_legend()
    assert [t.get_text() for t in legend.get_texts()] == ["a", "b"]
    plots.tabs.setCurrentIndex(1)
    viewer.dims.set_current_step(0, 3)
    qtbot.waitUntil(lambda: len(plots.comparison.keys) == 6, timeout=60_000)
    sub = pf.drop_failed(analysis.table[analysis.table["frame"] == 3])
    np.testing.assert_allclose(analysis.comparison[(3, 0.0, False, 0.0)]["d"],
                               pf.distance_matrix(sub), rtol=1e-9)


def test_the_form_is_the_option_record(qtbot, viewer_widget):
    """Every method option has a control with the record's default, range, choices and
    words; what the form gives reaches the run as PFSDMParams."""
    from napari_pfsdm.core.params import OPTIONS, PFSDMParams, option

    _viewer, w = viewer_widget
    for o in OPTIONS:
        control = w.options[o.name]
        assert control.value == o.default and control.tooltip == o.help
        if o.choices:
            assert tuple(control.choices) == tuple(o.choices)
        elif o.high is not None:
            assert control.max == o.high
    assert w.params() == PFSDMParams()
    # the distance's weight and the "only with" rules come from the record too
    weight = option("intensity_weight")
    assert (w.intensity_weight.value, w.intensity_weight.tooltip) == (weight.default, weight.help)
    assert not w.relevant(option("viscosity"))
    w.options["sdf"].value = "viscous"
    assert w.relevant(option("viscosity"))
    w.options["sdf"].value = "exact"
    w.options["n_fourier"].value = 6
    w.options["mapping"].value = "bijective"
    w.options["sh_degree"].value = 12  # a 3-D option: not for this 2-D time-lapse
    assert w.params() == PFSDMParams(n_fourier=6, mapping="bijective")
    w.options["n_fourier"].value = 40  # more than 64 angles carry: the record's own words
    assert w.run() is None
    assert "n_fourier=40 needs more than 80 angles" in w.status.value


def test_clusters_plotter_selects_exactly_the_rows_of_each_frame(qtbot, viewer_widget):
    """napari-clusters-plotter, docked beside the plugin, reads the objects layer's features:
    a selection in its plot marks exactly the selected rows' objects, frame by frame."""
    pytest.importorskip("napari_clusters_plotter")
    viewer, w = viewer_widget
    analysis = run_and_wait(qtbot, w)
    objects = w.add_objects_layer()
    _dock, plotter = viewer.window.add_plugin_dock_widget("napari-clusters-plotter",
                                                          "Plot & select features")
    viewer.layers.selection.active = objects
    qtbot.wait(200)
    plotter.x_axis, plotter.y_axis = "shape_PC1", "area"
    pc1 = objects.features["shape_PC1"].to_numpy()
    frames = objects.features["frame"].to_numpy()
    chosen = np.zeros(len(pc1), int)
    for f in np.unique(frames):  # the right half of shape_PC1 within each frame
        rows = np.flatnonzero(frames == f)
        chosen[rows] = pc1[rows] > np.median(pc1[rows])
    plotter.plotting_widget.show_color_overlay = True  # as drawing a selection does
    selector = next(iter(plotter.plotting_widget.selectors.values()))
    selector.selection_applied_signal.emit(chosen)
    qtbot.wait(300)
    table = analysis.table
    for f in (0, int(table["frame"].max())):
        rows = np.flatnonzero(table["frame"].to_numpy() == f)
        colours = {int(r): tuple(np.round(objects.colormap.map(np.array([r + 1]))[0], 3))
                   for r in rows}
        picked = {colours[r] for r in rows if chosen[r]}
        others = {colours[r] for r in rows if not chosen[r]}
        assert picked and others and not (picked & others), f


def test_removing_the_analysed_layer_forgets_its_results(qtbot, viewer_widget):
    from napari_pfsdm.napari._model import REGISTRY

    viewer, w = viewer_widget
    run_and_wait(qtbot, w)
    plots = dock(viewer, PLOTS)
    layer_id = viewer.layers["gastruloids"].unique_id
    viewer.layers.remove("gastruloids")
    assert REGISTRY.get(layer_id) is None and w.bound is None
    assert plots.analysis is None and plots.layer_choice.choices == ()
    assert "gastruloids" not in w.labels.choices


def test_the_components_tab_shows_the_loadings_and_the_real_objects_along_the_pc(
        qtbot, viewer_widget):
    from skimage.measure import regionprops

    from napari_pfsdm.analysis.shape_space import ShapePCA, shape_modes

    viewer, w = viewer_widget
    analysis = run_and_wait(qtbot, w)
    plots = dock(viewer, PLOTS)
    plots.tabs.setCurrentIndex(2)
    comp = plots.components
    comp.component.value = 2
    qtbot.waitUntil(lambda: len(comp.figure.axes) > 2 and "PC2" in comp.info.value,
                    timeout=60_000)
    space = ShapePCA(5).fit(analysis.table)
    loadings = comp.figure.axes[0].get_images()[0].get_array()
    np.testing.assert_allclose(loadings, space.loadings(2), rtol=1e-9)
    modes = shape_modes(space.transform(analysis.table), 2)
    objects = [ax for ax in comp.figure.axes if ax.get_xlabel().startswith("f")]
    assert [ax.get_xlabel() for ax in objects] == [
        f"f{int(r.frame)} l{int(r.label)}" for r in modes.itertuples()]
    for ax, r in zip(objects, modes.itertuples(), strict=True):
        x, y = ax.get_lines()[0].get_data()
        area = 0.5 * abs(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1)))  # shoelace
        mask = np.asarray(analysis.labels[int(r.frame)]) == int(r.label)
        pixels, perimeter = mask.sum(), regionprops(mask.astype(int))[0].perimeter
        assert abs(area - pixels) < perimeter  # the outline of that object, closed
        assert abs(np.mean(x)) < 2 and abs(np.mean(y)) < 2  # centred


def test_cancelled_distances_say_so_and_a_new_request_computes_them(qtbot, shown_viewer_widget):
    viewer, w = shown_viewer_widget
    analysis = run_and_wait(qtbot, w)
    plots = dock(viewer, PLOTS)
    plots.tabs.setCurrentIndex(1)
    comp = plots.comparison
    qtbot.waitUntil(lambda: comp.worker is None, timeout=60_000)
    comp.which.value = "all frames"  # 72 objects, in a worker
    assert comp.cancel_button.visible
    comp.cancel()
    qtbot.waitUntil(lambda: comp.worker is None, timeout=60_000)
    assert "Cancelled" in comp.info.value and not comp.cancel_button.visible
    assert (None, 0.0, False, 0.0) not in analysis.comparison
    comp.rerank.value = True  # something else asked: computed
    qtbot.waitUntil(lambda: len(comp.keys) == 72, timeout=60_000)
    assert not comp.cancel_button.visible and "72 objects" in comp.info.value


def test_words_count_right_and_the_first_selection_is_away_from_the_border(
        qtbot, make_napari_viewer_proxy, monkeypatch):
    """"1 object", not "1 objects"; the object selected after a Run does not touch the border;
    the background of a still image selects no object (no word of tracks)."""
    from napari_pfsdm.napari import _jobs

    said = []
    monkeypatch.setattr(_jobs, "show_info", said.append)
    labels = np.zeros((64, 96), np.uint16)
    labels[0:20, 0:24] = 1  # on the border: napari's selected label at first
    labels[30:52, 40:70] = 2
    viewer = make_napari_viewer_proxy()
    layer = viewer.add_labels(labels, name="cells")
    assert layer.selected_label == 1
    w = dock(viewer)
    analysis = run_and_wait(qtbot, w)
    assert w.status.value.startswith("2 objects measured in ") and said == [
        "PF-SDM: 2 objects measured."]
    assert layer.selected_label == 2 and analysis.selection == (0, 2)
    wait_pictures(qtbot, w)
    layer.selected_label = 0  # a click on the background
    wait_pictures(qtbot, w)
    text = " ".join(caption_texts(viewer.layers["cells captions"]))
    assert "no object selected" in text and "track" not in text
    assert w.hover.value == "Selected: no object (the background)."
    layer.data = np.where(labels == 2, 2, 0).astype(np.uint16)  # one object
    run_and_wait(qtbot, w)
    assert w.status.value.startswith("1 object measured in ")
    assert said[-1] == "PF-SDM: 1 object measured."
