"""The plugin beside napari-clusters-plotter, both docked as the Plugins menu docks them: the
plotter sees every frame's rows, raises nothing, and is not made to plot again by frame steps,
selections or plot clicks."""

from __future__ import annotations

import numpy as np
import pytest
from napari_helpers import PLOTS, dock, run_and_wait, wait_pictures

pytestmark = pytest.mark.gui
pytest.importorskip("napari_clusters_plotter")


def _plotter(viewer):
    _dock, plotter = viewer.window.add_plugin_dock_widget("napari-clusters-plotter",
                                                          "Plot & select features")
    return plotter


def test_the_clusters_plotter_plots_every_frame_and_is_left_alone_by_steps(
        qtbot, make_napari_viewer_proxy, sample_layers):
    viewer = make_napari_viewer_proxy()
    for data, kwargs, kind in sample_layers:
        getattr(viewer, f"add_{kind}")(data, **kwargs)
    labels = viewer.layers["gastruloids"]
    plotter = _plotter(viewer)
    viewer.layers.selection.active = labels  # the plotter plots the Labels layer
    w = dock(viewer)
    analysis = run_and_wait(qtbot, w)
    wait_pictures(qtbot, w)
    plots = dock(viewer, PLOTS)
    qtbot.wait(300)
    # the plotter's table is every frame's rows (its time-lapse convention) with numbers only
    assert [lay.name for lay in plotter.layers] == ["gastruloids"]
    plotter.x_axis, plotter.y_axis = "shape_PC1", "area"
    points = plotter.plotting_widget.active_artist.data
    np.testing.assert_allclose(points[:, 1], analysis.table["area"])
    np.testing.assert_allclose(points[:, 0], labels.features["shape_PC1"])
    assert len(points) == 72
    # the picture layers never became the plotter's (it would plot the captions' words)
    assert [lay.name for lay in viewer.layers.selection] == ["gastruloids"]
    assert "text" not in viewer.layers["gastruloids captions"].features
    writers = []

    def writer(event) -> None:  # who set the features: the code that called napari's setter
        import traceback

        stack = traceback.extract_stack()
        at = max(i for i, f in enumerate(stack) if f.name == "features"
                 and f.filename.endswith("labels.py"))
        writers.append(stack[at - 1].filename)

    labels.events.features.connect(writer)
    for frame in (3, 4, 7, 2):
        viewer.dims.set_current_step(0, frame)
        wait_pictures(qtbot, w)
        labels.selected_label = int(analysis.labels_in(frame)[1])
        wait_pictures(qtbot, w)
        traj = plots.trajectories
        traj.select(int(np.flatnonzero(traj.keys[:, 0] == frame)[0]))  # a plot click
        wait_pictures(qtbot, w)
        # the plotter fades the other frames' points, as it does for any time-lapse table
        alpha = np.asarray(plotter.plotting_widget.active_artist.alpha)
        np.testing.assert_array_equal(alpha == 1, analysis.table["frame"].to_numpy() == frame)
    # the plugin never wrote the features: only the plotter, marking a selected label (as it
    # does with napari alone)
    assert writers and all("napari_clusters_plotter" in f for f in writers), set(writers)
    assert len(labels.features) == 72


def _whole(widget) -> bool:
    """Whether all of ``widget`` is on screen: shown, not clipped by a scroll area or the dock,
    and not narrower than it asks to be."""
    seen = widget.visibleRegion().boundingRect()
    return (widget.isVisible() and seen.width() == widget.width()
            and seen.height() == widget.height()
            and widget.width() >= widget.minimumSizeHint().width()
            and widget.height() >= min(widget.minimumSizeHint().height(), 18))


def _cut_at_the_right(panel) -> list:
    """The visible controls of ``panel`` that reach past the right edge of what shows them
    (the dock, or the scroll area they are in), or are narrower than they ask to be."""
    from qtpy.QtCore import QPoint
    from qtpy.QtWidgets import (
        QAbstractButton,
        QAbstractScrollArea,
        QAbstractSpinBox,
        QComboBox,
        QLabel,
        QLineEdit,
    )

    out = []
    for kind in (QAbstractButton, QComboBox, QAbstractSpinBox, QLineEdit, QLabel):
        for c in panel.findChildren(kind):
            if not c.isVisible() or c.width() == 0:
                continue
            frame = c.parentWidget()
            while frame is not panel and not isinstance(frame, QAbstractScrollArea):
                frame = frame.parentWidget()
            box = frame.viewport() if isinstance(frame, QAbstractScrollArea) else panel
            right = c.mapTo(box, QPoint(c.width(), 0)).x()
            if right > box.width() + 1 or (not isinstance(c, (QLabel, QComboBox))
                                           and c.width() < c.minimumSizeHint().width()):
                out.append((type(c).__name__, getattr(c, "text", lambda: "")()[:30], right,
                            box.width(), type(c.parentWidget()).__name__, c.width(),
                            c.minimumSizeHint().width()))
    return out


@pytest.mark.parametrize("plotter_first", [False, True])
def test_at_1280_by_800_beside_the_plotter_the_layer_run_cancel_and_status_are_whole(
        qtbot, make_napari_viewer, sample_layers, plotter_first):
    """Every dock of the plugin and napari-clusters-plotter docked, in either order: the window
    fits 1280 × 800, the plotter keeps a plot of ≥ 200 px, and in the analysis and prediction
    docks the layer, Run (Predict), Cancel and the status show whole, without scrolling;
    nothing is cut at the right; the status is at most 3 lines with the rest a click away;
    a docked plot too small to read says so."""
    from napari_helpers import PREDICTION

    from napari_pfsdm.napari._plot_base import FLOAT
    from napari_pfsdm.napari._widgets import dock_of

    viewer = make_napari_viewer(show=True)
    window = viewer.window._qt_window  # the test measures the window; the plugin never does
    window.resize(1280, 800)
    for data, kwargs, kind in sample_layers:
        getattr(viewer, f"add_{kind}")(data, **kwargs)
    plotter = _plotter(viewer) if plotter_first else None
    w = dock(viewer)
    run_and_wait(qtbot, w)
    w.open_plots()
    prediction = dock(viewer, PREDICTION)
    plots = dock(viewer, PLOTS)
    plotter = plotter or _plotter(viewer)
    viewer.layers.selection.active = viewer.layers["gastruloids"]
    qtbot.wait(500)
    # the plugin's tab group asks for ~150 px (the layer, Run, three lines of status and a
    # scroll strip): the plotter, above or below it, keeps a plot of 190 px or more
    canvas = plotter.plotting_widget.canvas
    assert window.height() <= 800 and canvas.height() >= 190, (window.height(), canvas.height())
    for panel, key in ((w, [w.labels, w.run_button, w.cancel_button]),
                       (prediction, [prediction.layer_choice, prediction.run_button,
                                     prediction.cancel_button])):
        dock_of(panel).raise_()
        qtbot.wait(300)
        for control in [*(c.native for c in key), panel.status]:
            assert _whole(control), (type(panel).__name__, control)
        assert _cut_at_the_right(panel) == []
    dock_of(w).raise_()
    qtbot.wait(200)
    long = " ".join(f"Sentence {k} of what the Run found, long enough to wrap." for k in range(12))
    w.say(long)
    qtbot.wait(100)
    status = w.status
    assert status.shown_lines() == 3 and status.label.text().endswith("…")
    assert _whole(status) and status.toggle.isVisible() and long in status.toolTip()
    status.toggle.click()  # the whole text, a click away
    qtbot.wait(100)
    assert status.shown_lines() > 3 and status.label.text().replace("\n", " ") == long
    status.toggle.click()
    assert status.shown_lines() == 3
    w.say("72 objects measured.")
    assert status.shown_lines() == 1 and not status.toggle.isVisible()
    # a docked plot too small to read says so instead of drawing itself squashed
    dock_of(plots).raise_()
    for i in range(len(plots.kinds)):
        plots.tabs.setCurrentIndex(i)
        plot = plots.plot(i)
        # the layout settles (a loaded machine takes longer than 0.3 s)
        qtbot.waitUntil(lambda p=plot: p.small or p.canvas.height() >= p.READABLE[1],
                        timeout=5_000)
        if plot.small:
            assert FLOAT in plot.info.value and not plot.canvas.isVisible()
            assert _whole(plot.info.native) and _whole(plots.float_button.native)
        else:
            assert plot.canvas.height() >= plot.READABLE[1]
    assert _cut_at_the_right(plots) == []
    plots.tabs.setCurrentIndex(0)
    plots.toggle_floating()  # Float: large enough, the plot drawn
    qtbot.waitUntil(lambda: not plots.plot(0).small and plots.plot(0).canvas.isVisible(),
                    timeout=5_000)
    plots.tabs.setCurrentIndex(0)
    qtbot.waitUntil(lambda: len(plots.trajectories.keys) == 72, timeout=5_000)
