"""Linked plots: clicking a point moves the viewer; the viewer's frame/label highlights points."""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.backend_bases import MouseEvent
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
from napari_pfsdm.napari._plots import (
    TrajectoryPlotWidget,
    read_groups_csv,
)

pytestmark = pytest.mark.gui

SCREENSHOT = Path(__file__).resolve().parents[2] / "docs" / "screenshot.png"


def _click(plot, index: int) -> None:
    """A real matplotlib button press at the display position of point ``index``."""
    plot.canvas.draw()
    x, y = plot.click_display_position(index)
    MouseEvent("button_press_event", plot.canvas, x, y, button=1)._process()


def _frame(viewer, labels_layer) -> int:
    return _layers.current_frame(viewer, labels_layer)


def test_trajectory_click_moves_viewer_and_selection_highlights(viewer_widget, qtbot):
    viewer, widget = viewer_widget
    labels_layer = viewer.layers["gastruloids"]
    run_and_wait(qtbot, widget)
    plot = dock(viewer, TRAJECTORIES)
    assert plot.layer_combo.currentText() == "gastruloids"
    keys = plot._keys
    assert len(keys) == len(labels_layer.features)
    target = keys.index((7, 5))
    assert (_frame(viewer, labels_layer), labels_layer.selected_label) != (7, 5)
    _click(plot, target)
    assert _frame(viewer, labels_layer) == 7
    assert labels_layer.selected_label == 5
    assert plot.highlighted_keys() == [(7, 5)]
    # moving napari's time slider and selecting another label moves the highlight
    axis = _layers.frame_axis(viewer, labels_layer)
    n_artists = len(plot._axes_points.collections) + len(plot._axes_points.lines)
    viewer.dims.set_point(axis, 2)
    labels_layer.selected_label = 3
    plot.flush()  # plots follow once the slider is still (debounced)
    assert plot.highlighted_keys() == [(2, 3)]
    # the previous highlight is gone: one star, one thick line, whatever happened before
    assert len(plot._axes_points.collections) + len(plot._axes_points.lines) == n_artists
    star = [a for a in plot._highlight_artists if hasattr(a, "get_offsets")][-1]
    np.testing.assert_allclose(star.get_offsets()[0], plot._points[keys.index((2, 3))])
    # a click far from any point does nothing
    plot.canvas.draw()
    MouseEvent("button_press_event", plot.canvas, 1, 1, button=1)._process()
    assert (_frame(viewer, labels_layer), labels_layer.selected_label) == (2, 3)


def test_trajectory_views_components_and_groups(viewer_widget, qtbot, tmp_path):
    viewer, widget = viewer_widget
    run_and_wait(qtbot, widget)
    plot = dock(viewer, TRAJECTORIES)
    out = widget.last_output
    shape_xy = plot._points.copy()
    np.testing.assert_allclose(shape_xy[:, 0], out.pca["shape"]["PC1"])
    plot.view.setCurrentText("intensity")
    np.testing.assert_allclose(plot._points[:, 1], out.pca["intensity"]["PC2"])
    plot.pc_x.setValue(3)
    np.testing.assert_allclose(plot._points[:, 0], out.pca["intensity"]["PC3"])
    csv = tmp_path / "groups.csv"
    csv.write_text("label,group\n1,single-axis\n2,multi-axes\n")
    assert read_groups_csv(csv) == {1: "single-axis", 2: "multi-axes"}
    plot.load_groups(csv)
    assert plot.color_by.currentText() == "group"
    legend = plot._axes_points.get_legend()
    assert sorted(t.get_text() for t in legend.get_texts()) == ["multi-axes", "single-axis"]
    bad = tmp_path / "bad.csv"
    bad.write_text("label,group\nfirst,x\n")
    with pytest.raises(ValueError, match="whole numbers"):
        read_groups_csv(bad)


def test_shape_comparison_follows_frame_and_click_selects(viewer_widget, qtbot):
    viewer, widget = viewer_widget
    labels_layer = viewer.layers["gastruloids"]
    run_and_wait(qtbot, widget)
    comp = dock(viewer, COMPARISON)
    axis = _layers.frame_axis(viewer, labels_layer)
    viewer.dims.set_point(axis, 4)
    wait_computed(qtbot, comp)  # the distances are computed in a worker
    n = len(np.unique(labels_layer.data[4])) - 1
    assert comp.distances.shape == (n, n)
    assert all(f == 4 for f, _ in comp._keys)
    np.testing.assert_allclose(comp.distances, comp.distances.T)
    # distances agree with the core's distance matrix on the same rows
    from napari_pfsdm import distance_matrix

    table = widget.last_output.table
    sub = table[table["frame"] == 4]
    np.testing.assert_allclose(comp.distances, distance_matrix(
        sub, intensity_weight=widget.last_output.options["intensity_weight"]))
    target = [lab for _, lab in comp._keys].index(6)
    _click(comp, target)
    assert labels_layer.selected_label == 6
    assert _frame(viewer, labels_layer) == 4
    # opt-in re-ranking through the collection: napari_pfsdm.rerank of the same distances
    from napari_pfsdm import rerank

    comp.rerank.setChecked(True)
    wait_computed(qtbot, comp)
    np.testing.assert_allclose(comp.distances, rerank(distance_matrix(
        sub, intensity_weight=widget.last_output.options["intensity_weight"]), "diffusion",
        k=min(10, len(sub) - 1)))
    comp.rerank.setChecked(False)
    # all frames: every measured object, coloured by frame, distances computed once
    comp.frame_choice.setCurrentText("all frames")
    wait_computed(qtbot, comp)
    assert comp.distances.shape == (len(table),) * 2
    cached = len(comp._cache)
    comp.redraw()
    assert len(comp._cache) == cached and not comp.computing  # from the cache, no worker
    # removing the layers with the plots open: no error, the plots say there is nothing
    for name in [layer.name for layer in viewer.layers]:
        viewer.layers.remove(name)
    comp.flush()
    comp.highlight()
    assert comp.output is None


def _two_analysed(make_napari_viewer, sample_layers, qtbot):
    """A viewer with the sample and the five shapes, "gastruloids" analysed first, then
    "five shapes" (the layer analysed last); (viewer, widget)."""
    from napari_pfsdm.napari._sample_data import benchmark_shapes

    viewer = make_napari_viewer()
    for data, kwargs, kind in sample_layers + benchmark_shapes():
        getattr(viewer, f"add_{kind}")(data, **kwargs)
    widget = dock(viewer)
    run_and_wait(qtbot, widget, labels=viewer.layers["gastruloids"])
    widget.labels_combo.setCurrentText("five shapes")
    run_and_wait(qtbot, widget)
    return viewer, widget


def test_open_plots_shows_the_layer_analysed_last(make_napari_viewer, sample_layers, qtbot):
    _viewer, widget = _two_analysed(make_napari_viewer, sample_layers, qtbot)
    open_plots(qtbot, widget)
    assert [p.layer_combo.currentText() for p in widget.plots] == ["five shapes"] * 2


def test_plots_opened_bind_only_the_layer_analysed_last_whatever_comes_between(
        make_napari_viewer, sample_layers, qtbot, monkeypatch):
    """Open plots: a layer added before a plot's first turn (the plugin's own pictures, or
    the user's) does not bind it to the first analysed layer, nor is that one drawn on the way
    to the layer analysed last: each plot binds once, to that layer."""
    from napari_pfsdm.napari._plots import _LinkedPlot
    from napari_pfsdm.napari._store import same_layer

    viewer, widget = _two_analysed(make_napari_viewer, sample_layers, qtbot)
    bound = []
    bind = _LinkedPlot._bind

    def spy(self, layer, force=False):
        if layer is not None and not same_layer(layer, self._layer):
            bound.append((type(self).__name__, layer.name))
        return bind(self, layer, force)

    monkeypatch.setattr(_LinkedPlot, "_bind", spy)
    widget.open_plots()
    viewer.add_points(np.zeros((1, 3)), name="a layer between")  # an inserted event
    assert widget.plots[0]._layer is None
    open_plots(qtbot, widget)
    assert [p.layer_combo.currentText() for p in widget.plots] == ["five shapes"] * 2
    assert sorted(bound) == [("ShapeComparisonWidget", "five shapes"),
                             ("TrajectoryPlotWidget", "five shapes")]


def test_open_plots_draws_each_plot_in_a_turn_after_its_docking(viewer_widget, qtbot):
    """napari docking a plot is one stretch of the GUI thread; the plot's first drawing
    comes in a later turn (from the Plugins menu, a plot shows the results at once)."""
    viewer, widget = viewer_widget
    run_and_wait(qtbot, widget)
    widget.open_plots()
    traj = widget.plots[0]  # docked in this call ...
    assert traj.output is None and not traj.figure.axes  # ... and not drawn in it
    plots = open_plots(qtbot, widget)
    assert [p.layer_combo.currentText() for p in plots] == ["gastruloids"] * 2
    traj.flush()
    assert traj.figure.axes and len(traj._keys) == len(viewer.layers["gastruloids"].features)
    menu = dock(viewer, TRAJECTORIES)  # already docked: the same widget, still showing it
    assert menu.output is not None


def test_one_image_is_drawn_in_a_visible_colour_without_a_ring_round_every_point(
        make_napari_viewer, sample_layers, qtbot):
    """A single image (or one frame): every point is "of this frame", so rings round them
    would cover the plot (3,000 objects: one white blob); only the selected object's star.
    Its one frame is coloured from the middle of viridis, not the darkest end (invisible on
    napari's dark theme). The time-lapse keeps its rings round the current frame's points."""
    import matplotlib

    viewer = make_napari_viewer()
    for data, kwargs, kind in sample_layers:
        getattr(viewer, f"add_{kind}")(data, **kwargs)
    widget = dock(viewer)

    def rings(plot):
        return [a for a in plot._highlight_artists if hasattr(a, "get_offsets")
                and len(a.get_offsets()) > 1]

    run_and_wait(qtbot, widget, labels=viewer.layers["gastruloids"])
    plot = dock(viewer, TRAJECTORIES)
    plot.show_layer(viewer.layers["gastruloids"])
    plot.flush()
    frame = _frame(viewer, viewer.layers["gastruloids"])
    in_frame = sum(1 for f, _ in plot._keys if f == frame)
    assert [len(r.get_offsets()) for r in rings(plot)] == [in_frame]
    one = viewer.add_labels(np.asarray(viewer.layers["gastruloids"].data[3]), name="one frame")
    reporter = [lay for lay in viewer.layers if lay.__class__.__name__ == "Image"
                and lay.ndim == 3][0]
    image = viewer.add_image(np.asarray(reporter.data[3]), name="one frame reporter")
    run_and_wait(qtbot, widget, labels=one, image=image)
    plot.show_layer(one)
    plot.color_by.setCurrentText("time")  # the sample's groups are on its own layer
    plot.flush()
    n = len(plot._points)
    assert n == len(one.features) > 1
    assert rings(plot) == []
    drawn = [c for c in plot._axes_points.collections
             if c not in plot._highlight_artists and len(c.get_offsets()) == n]
    drawn[0].update_scalarmappable()  # frames to colours (matplotlib does it at drawing)
    np.testing.assert_allclose(drawn[0].get_facecolors()[0],
                               matplotlib.colormaps["viridis"](0.5), atol=1e-6)


def _nonblank(region: np.ndarray) -> bool:
    rgb = region[..., :3].astype(float)
    return rgb.std(axis=(0, 1)).max() > 8 and len(np.unique(rgb.reshape(-1, 3), axis=0)) > 20


@pytest.mark.parametrize("window_size", [(1280, 800), (1600, 1000)])
def test_screenshot_of_the_docked_widgets_after_a_run(make_napari_viewer, sample_layers, qtbot,
                                                      tmp_path, window_size):
    """The whole window after a run, plots open, an object selected: the plot and the disk
    are drawn (non-blank) where the layout puts them. The screenshots in docs/ are made by
    benchmarks/screenshots.py (a user's session: napari.Viewer, the menu's docks)."""
    from qtpy.QtCore import QPoint

    viewer = make_napari_viewer(show=True)
    for data, kwargs, kind in sample_layers:
        getattr(viewer, f"add_{kind}")(data, **kwargs)
    window = viewer.window._qt_window
    window.resize(*window_size)
    widget = dock(viewer)
    run_and_wait(qtbot, widget)
    open_plots(qtbot, widget)
    labels_layer = viewer.layers["gastruloids"]
    viewer.dims.set_point(_layers.frame_axis(viewer, labels_layer), 9)
    labels_layer.selected_label = 5
    wait_pictures(qtbot, widget, (9, 5))
    viewer.layers["gastruloids reporter"].visible = False
    qtbot.wait(500)  # let the docks take their place before fitting the view
    viewer.reset_view()
    plot = next(w for w in window.findChildren(TrajectoryPlotWidget))
    qtbot.wait(1500)  # the docks settle (the trajectories' tab raised), the figure follows
    plot.canvas.draw()
    qtbot.wait(300)
    img = viewer.screenshot(canvas_only=False, flash=False)
    assert img.ndim == 3 and img.shape[2] in (3, 4)
    ratio = img.shape[1] / window.width()

    # the trajectory plot's canvas
    top_left = plot.canvas.mapTo(window, QPoint(0, 0))
    x0, y0 = int(top_left.x() * ratio), int(top_left.y() * ratio)
    w, h = int(plot.canvas.width() * ratio), int(plot.canvas.height() * ratio)
    assert w > 100 and h > 100
    assert _nonblank(img[y0:y0 + h, x0:x0 + w])

    # the disk layer, beside the labels on the canvas
    canvas = viewer.window._qt_viewer.canvas.native
    origin = canvas.mapTo(window, QPoint(0, 0))
    disk = viewer.layers["gastruloids PF-SDF disk"]
    size = disk.data.shape[0]  # a square disk, its colour bar on the right
    centre = np.asarray(disk.translate[-2:]) + np.asarray(disk.scale[-2:]) * size / 2
    cam = viewer.scene.camera
    offset = (centre - np.asarray(cam.center[-2:])) * cam.zoom
    cy = origin.y() + canvas.height() / 2 + offset[0]
    cx = origin.x() + canvas.width() / 2 + offset[1]
    half = 0.3 * size * disk.scale[-1] * cam.zoom
    box = img[int((cy - half) * ratio):int((cy + half) * ratio),
              int((cx - half) * ratio):int((cx + half) * ratio)]
    assert box.shape[0] > 20 and box.shape[1] > 20
    assert _nonblank(box)

    from imageio.v3 import imwrite  # napari's own dependency

    path = tmp_path / "screenshot_{}x{}.png".format(*window_size)
    path.parent.mkdir(exist_ok=True)
    imwrite(path, img[..., :3])
    assert path.stat().st_size > 10_000


def test_screenshot_of_a_3d_object(make_napari_viewer, qtbot, tmp_path):
    """A Z-stack after a run, one object selected: its shells beside the stack, non-blank.
    PFSDM_SAVE_SCREENSHOT=1 refreshes docs/screenshot_3d.png."""
    from imageio.v3 import imwrite  # napari's own dependency

    from napari_pfsdm.data.volumes import VOLUME_CLASSES, blob_volume

    names = list(VOLUME_CLASSES)
    stack = np.zeros((40, 100, 200), np.uint16)
    for i, name in enumerate([names[0], names[2], names[4], names[6]]):
        stack[:, 30:70, 5 + 48 * i:45 + 48 * i][blob_volume(name, size=40, radius=12)] = i + 1
    viewer = make_napari_viewer(show=True)
    viewer.window._qt_window.resize(1500, 900)
    labels_layer = viewer.add_labels(stack, name="objects")
    viewer.dims.axis_labels = ("z", "y", "x")
    widget = dock(viewer)
    run_and_wait(qtbot, widget)
    labels_layer.selected_label = 3
    wait_pictures(qtbot, widget, (0, 3))
    qtbot.wait(500)
    viewer.reset_view()
    qtbot.wait(800)
    img = viewer.screenshot(canvas_only=False, flash=False)
    shells = viewer.layers["objects PF-SDF shells"]
    assert shells.visible and np.isfinite(shells.data).sum() > 1000
    assert _nonblank(img[..., :3])
    path = (SCREENSHOT.with_name("screenshot_3d.png") if os.environ.get("PFSDM_SAVE_SCREENSHOT")
            else tmp_path / "screenshot_3d.png")
    imwrite(path, img[..., :3])
    assert path.stat().st_size > 10_000


def test_all_frames_beyond_the_matrix_limit_compare_by_nearest_neighbours(viewer_widget, qtbot,
                                                                          monkeypatch):
    """More objects than the matrix view holds (GRAPH_ROWS, lowered here to the sample's
    size): each object's nearest shapes, by the same distances as the full matrix, and a map
    of the neighbour graph; a click on a bar selects that neighbour in the viewer."""
    from napari_pfsdm import distance_matrix
    from napari_pfsdm.napari import _plots

    viewer, widget = viewer_widget
    labels_layer = viewer.layers["gastruloids"]
    out = run_and_wait(qtbot, widget)
    monkeypatch.setattr(_plots, "GRAPH_ROWS", 20)
    monkeypatch.setattr(_plots, "MANY_POINTS", 50)  # the map as a density image
    comp = dock(viewer, COMPARISON)
    comp.frame_choice.setCurrentText("all frames")
    wait_computed(qtbot, comp, timeout=120_000)
    assert comp.distances is None and comp._graph is not None  # no n x n matrix
    from matplotlib.image import AxesImage

    assert [type(a) for a in comp._axes_points.get_children()
            if isinstance(a, AxesImage)] == [AxesImage]
    assert len(comp._keys) == len(out.table)
    assert comp._graph.xy.shape == (len(out.table), 2)
    # drawn again (its graph kept): the figure is built over turns of the event loop, one
    # axes after the other, and drawn only once complete
    drawn_when_built = []
    comp.canvas.mpl_connect("draw_event",
                            lambda event: drawn_when_built.append(comp._building is None))
    comp.redraw()
    assert len(comp.figure.axes) == 1 and comp._graph is None  # the nearest-shapes panel
    qtbot.waitUntil(lambda: comp._graph is not None, timeout=10_000)
    assert len(comp.figure.axes) == 3  # and the map with its colour bar (frames)
    qtbot.waitUntil(lambda: len(drawn_when_built) > 0, timeout=10_000)
    assert all(drawn_when_built)
    viewer.dims.set_point(_layers.frame_axis(viewer, labels_layer), 3)
    labels_layer.selected_label = 2
    comp.flush()
    near = comp.nearest_shown()
    assert len(near) == _plots.NEAREST_SHOWN
    # the reference: the sorted row of the all-pairs matrix of the same rows
    d = distance_matrix(out.table, intensity_weight=out.options["intensity_weight"])
    me = comp._keys.index((3, 2))
    order = [j for j in np.argsort(d[me], kind="stable") if j != me][:len(near)]
    np.testing.assert_allclose([v for _, v in near], d[me, order], atol=1e-7)
    assert [k for k, _ in near] == [comp._keys[j] for j in order]
    # the bars (one collection) are as long as those distances, nearest at the top
    bars, = [a for a in comp._ax_near.collections if a in comp._highlight_artists]
    np.testing.assert_allclose([p.vertices[:, 0].max() for p in bars.get_paths()],
                               d[me, order], atol=1e-7)
    np.testing.assert_allclose([np.ptp(p.vertices[:, 1]) / 2 + p.vertices[:, 1].min()
                                for p in bars.get_paths()], np.arange(len(near)))
    # a highlight shows its markers at once and the bars' ten labels in the turns after
    # (matplotlib draws a text glyph by glyph, 4 ms a label)
    from matplotlib.text import Text

    comp.canvas.draw()
    qtbot.waitUntil(lambda: not comp._texts_left, timeout=5000)
    labels = [a for a in comp._highlight_artists if isinstance(a, Text)]
    assert len(labels) == _plots.NEAREST_SHOWN
    with_labels = np.asarray(comp.canvas.buffer_rgba()).copy()
    drawn = []
    real_draw = comp._ax_near.draw_artist
    monkeypatch.setattr(comp._ax_near, "draw_artist",
                        lambda a: drawn.append(isinstance(a, Text)) or real_draw(a))
    comp.canvas.restore_region(comp._background)
    comp._blit_highlight()
    assert drawn and not any(drawn)  # the bars, not their labels, in this turn
    assert len(comp._texts_left) == _plots.NEAREST_SHOWN
    no_labels = np.asarray(comp.canvas.buffer_rgba()).copy()
    assert (no_labels != with_labels).any()
    qtbot.waitUntil(lambda: not comp._texts_left, timeout=5000)
    assert drawn.count(True) == _plots.NEAREST_SHOWN
    np.testing.assert_array_equal(np.asarray(comp.canvas.buffer_rgba()), with_labels)
    # click the third bar: the viewer goes to that object
    target = near[2][0]
    x, y = comp._ax_near.transData.transform((0.5 * comp._ax_near.get_xlim()[1], 2))
    MouseEvent("button_press_event", comp.canvas, x, y, button=1)._process()
    assert (_frame(viewer, labels_layer), labels_layer.selected_label) == target


def test_re_ranking_the_neighbour_graph_changes_the_view_in_place(viewer_widget, qtbot,
                                                                 monkeypatch):
    """Ticking re-rank in the neighbour-graph view: the view shown stays while the re-ranked
    graph is computed, then its bars and map change in the same axes (building the view
    anew was the longest gap of re-ranking 47,700 objects)."""
    from napari_pfsdm import nearest_neighbours
    from napari_pfsdm.analysis.rerank import rerank_neighbours
    from napari_pfsdm.napari import _graph, _plots

    viewer, widget = viewer_widget
    labels_layer = viewer.layers["gastruloids"]
    out = run_and_wait(qtbot, widget)
    monkeypatch.setattr(_plots, "GRAPH_ROWS", 20)
    comp = dock(viewer, COMPARISON)
    comp.frame_choice.setCurrentText("all frames")
    wait_computed(qtbot, comp, timeout=120_000)
    viewer.dims.set_point(_layers.frame_axis(viewer, labels_layer), 3)
    labels_layer.selected_label = 2
    comp.flush()
    axes, before = list(comp.figure.axes), comp.nearest_shown()
    redraws = []
    real = comp.redraw
    monkeypatch.setattr(comp, "redraw", lambda: redraws.append(1) or real())
    comp.rerank.setChecked(True)
    assert comp.computing  # in a worker; meanwhile the view before, not a "computing" page
    assert comp.figure.axes == axes and not comp._graph.reranked
    assert comp.nearest_shown() == before
    wait_computed(qtbot, comp, timeout=120_000)
    assert redraws == [] and all(a is b for a, b in zip(comp.figure.axes, axes, strict=True))
    # the reference: the public re-ranking of the public nearest neighbours
    idx, dist = nearest_neighbours(out.table, k=_graph.GRAPH_K,
                                   intensity_weight=out.options["intensity_weight"])
    idx, dist = rerank_neighbours(idx, dist, "diffusion", k=10)[:2]
    me = comp._keys.index((3, 2))
    near = comp.nearest_shown()
    assert len(near) == _plots.NEAREST_SHOWN and near != before
    assert [k for k, _ in near] == [comp._keys[j] for j in idx[me, :len(near)]]
    np.testing.assert_allclose([v for _, v in near], dist[me, :len(near)], atol=1e-7)
    assert comp._ax_near.get_xlabel() == "re-ranked distance"
    # the map: the new coordinates only, not the old map kept beside them
    points = [c for c in comp._axes_points.collections if c not in comp._highlight_artists]
    assert len(points) == 1 and not comp._axes_points.images
    np.testing.assert_allclose(points[0].get_offsets(), comp._graph.xy)
    comp.rerank.setChecked(False)  # back: the graph computed first, kept
    assert not comp.computing and not comp._graph.reranked
    assert comp.nearest_shown() == before and redraws == []
    # a new Run (the same objects, new results): the view is drawn anew, not changed in place
    axes = list(comp.figure.axes)
    run_and_wait(qtbot, widget)
    wait_computed(qtbot, comp, timeout=120_000)
    assert redraws and comp._graph is not None
    assert not any(a is b for a in comp.figure.axes for b in axes)


def test_a_movie_beyond_the_old_3000_limit_compares_and_exports_by_neighbours(
        make_napari_viewer, qtbot, tmp_path, monkeypatch):
    """3,000+ objects (the old limit of the matrix view and export): Run measures them on
    worker processes, 'all frames' is the neighbour-graph view (no n x n matrix), and the
    export writes the edge list beside features and PCA."""
    from napari_pfsdm import nearest_neighbours
    from napari_pfsdm.analysis.features import split_failed
    from napari_pfsdm.data.moving_blobs import make_moving_blobs
    from napari_pfsdm.napari import _graph

    labels = make_moving_blobs(n_objects=250, n_frames=13, size=1024, radius=(10.0, 16.0),
                               seed=3).labels
    viewer = make_napari_viewer()
    viewer.add_labels(labels, name="blobs")
    widget = dock(viewer)
    out = run_and_wait(qtbot, widget)
    assert len(out.table) > 3000
    monkeypatch.setattr(_graph, "map_method", lambda n=0: "spectral")  # seconds, not a minute
    comp = dock(viewer, COMPARISON)
    comp.frame_choice.setCurrentText("all frames")
    wait_computed(qtbot, comp, timeout=300_000)
    graph = comp._graph
    assert graph is not None and comp.distances is None
    measured = split_failed(out.table.iloc[np.flatnonzero(out.measured())], ("shape",))[0]
    assert graph.indices.shape == (len(measured), _graph.GRAPH_K)
    rows = np.random.default_rng(0).choice(len(measured), 20, replace=False)
    idx, dist = nearest_neighbours(measured, k=_graph.GRAPH_K)
    np.testing.assert_array_equal(graph.indices[rows], idx[rows])
    widget.export_async(tmp_path)
    qtbot.waitUntil(lambda: not widget.exporting, timeout=300_000)
    names = sorted(p.name for p in tmp_path.glob("*.csv"))
    assert names == ["blobs_features.csv", "blobs_neighbours.csv", "blobs_pca_shape.csv"]
    edges = pd.read_csv(tmp_path / "blobs_neighbours.csv")
    assert len(edges) == len(measured) * _graph.GRAPH_K


def test_many_points_are_drawn_as_one_density_image_and_stay_clickable(viewer_widget, qtbot,
                                                                      monkeypatch):
    """Above MANY_POINTS the trajectory plot draws one image (its cost does not grow with
    the points), no line per object; clicking a point and the highlight work as before."""
    from matplotlib.collections import LineCollection
    from matplotlib.image import AxesImage

    from napari_pfsdm.napari import _plots

    viewer, widget = viewer_widget
    labels_layer = viewer.layers["gastruloids"]
    run_and_wait(qtbot, widget)
    monkeypatch.setattr(_plots, "MANY_POINTS", 10)  # the sample's 72 points are "many"
    plot = dock(viewer, TRAJECTORIES)
    plot.redraw()  # many points: the figure is built over turns of the event loop
    assert plot._axes_points is None and plot._building is not None
    plot.flush()  # (scripts and tests: built now)
    ax = plot._axes_points
    images = [a for a in ax.get_children() if isinstance(a, AxesImage)]
    assert len(images) == 1
    assert not [a for a in ax.collections if isinstance(a, LineCollection)]
    # every point is in a coloured pixel, and there are no more coloured pixels than points
    img = images[0]
    rgba = np.asarray(img.get_array())
    x0, x1, y0, y1 = img.get_extent()
    bins = rgba.shape[0]
    px = np.clip(((plot._points[:, 0] - x0) / (x1 - x0) * bins).astype(int), 0, bins - 1)
    py = np.clip(((plot._points[:, 1] - y0) / (y1 - y0) * bins).astype(int), 0, bins - 1)
    assert (rgba[py, px, 3] > 0).all()
    assert np.count_nonzero(rgba[..., 3]) == len({*zip(px.tolist(), py.tolist(), strict=True)})
    assert "density" in plot.info.text()
    target = plot._keys.index((7, 5))
    _click(plot, target)
    assert (_frame(viewer, labels_layer), labels_layer.selected_label) == (7, 5)
    assert plot.highlighted_keys() == [(7, 5)]
    track = [a for a in plot._highlight_artists if a in ax.lines]
    assert len(track) == 1 and len(track[0].get_xdata()) > 1  # the selected object's track
    # 12 frames: a short track, drawn bold; a long one (a movie of many frames) thin and
    # translucent, over the density image
    assert track[0].get_linewidth() == 2.2 and track[0].get_alpha() in (None, 1.0)
    monkeypatch.setattr(_plots, "LONG_TRACK", 11)
    plot.highlight()
    track = [a for a in plot._highlight_artists if a in ax.lines]
    assert len(track) == 1 and len(track[0].get_xdata()) == 12
    assert track[0].get_linewidth() == 1.0 and track[0].get_alpha() == 0.6


def test_saving_a_plot_keeps_the_picture_on_screen_and_saves_its_highlight(
        make_napari_viewer, sample_layers, qtbot, tmp_path, qtlog):
    """``figure.savefig`` (from a script or napari's console) draws the figure once more, at
    the file's size. The screen keeps its picture (matplotlib leaves the canvas holding the
    file's: the next repaint showed an empty plot), the highlight's kept background stays
    the screen's (one taken from the file's drawing was blitted with a Qt repaint outside a
    paint: "Recursive repaint detected", "QPainter::begin: Paint device returned engine ==
    0"), and the file shows the highlight as the screen does."""
    from PIL import Image

    viewer = make_napari_viewer(show=True)
    for data, kwargs, kind in sample_layers:
        getattr(viewer, f"add_{kind}")(data, **kwargs)
    viewer.window._qt_window.resize(1280, 800)
    widget = dock(viewer)
    run_and_wait(qtbot, widget)
    plot = open_plots(qtbot, widget)[0]
    wait_pictures(qtbot, widget)
    sizes: list = []

    def settled() -> bool:  # the docks laid out (the same size for 1 s), the figure drawn
        plot.flush()
        size = plot.canvas.get_width_height(physical=True)
        if not sizes or sizes[-1][1] != size:
            sizes.append((time.perf_counter(), size))
        return (time.perf_counter() - sizes[-1][0] > 1.0 and not plot.canvas.drawing
                and plot._background is not None)

    qtbot.waitUntil(settled, timeout=20_000)
    assert plot._highlight_artists  # the selected object's trajectory is highlighted
    kept = plot._background
    dpi = plot.figure.dpi * 1.5

    def save(name: str) -> np.ndarray:
        path = tmp_path / name
        plot.figure.savefig(path, dpi=dpi)
        return np.asarray(Image.open(path).convert("RGB")).astype(int)

    def on_screen(name: str) -> np.ndarray:  # what the person sees, grabbed from Qt
        path = tmp_path / name
        assert plot.canvas.grab().save(str(path))
        return np.asarray(Image.open(path).convert("RGB")).astype(int)

    shown = on_screen("before.png")
    highlighted = save("highlighted.png")
    plot.canvas.repaint()
    qtbot.wait(200)
    assert plot._background is kept
    after = on_screen("after.png")
    assert after.shape == shown.shape
    assert (np.abs(after - shown).sum(axis=2) > 30).mean() < 0.01  # the same picture
    # the file's size is the figure's at the file's dpi (not the screen picture's)
    w, h = plot.figure.get_size_inches() * dpi
    assert np.abs(np.subtract(highlighted.shape[:2], (h, w))).max() <= 1
    # without the highlight the file differs: the highlight was drawn into it
    for artist in plot._highlight_artists:
        artist.set_visible(False)
    plain = save("plain.png")
    for artist in plot._highlight_artists:
        artist.set_visible(True)
    assert (np.abs(highlighted - plain).sum(axis=2) > 30).sum() > 20
    qtbot.wait(200)
    messages = [m.message for m in qtlog.records]
    assert not [m for m in messages if "repaint" in m.lower() or "QPainter" in m], messages
