"""The plots' canvas lays a new figure out in steps of the event loop and draws it in the
steps after (napari_pfsdm.napari._canvas)."""

from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.layout_engine import ConstrainedLayoutEngine

from napari_pfsdm.napari._canvas import PlotCanvas


def _fill(fig: Figure):
    ax = fig.add_subplot(111)
    im = ax.imshow(np.arange(12.0).reshape(3, 4))
    fig.colorbar(im, ax=ax, label="a colour bar")
    ax.set_ylabel("a long label\non two lines")
    ax.set_title("a title")
    return ax


def _refilled(fig: Figure, fill):
    """``fig`` cleared and filled again by ``fill`` (to be laid out anew), and the same
    figure as matplotlib's own constrained layout places it, drawn in one go: what ``fill``
    returned for each."""
    fig.clear()
    fig.set_layout_engine("constrained")
    shown = fill(fig)
    ref = Figure(figsize=fig.get_size_inches(), dpi=fig.dpi, layout="constrained")
    want = fill(ref)
    FigureCanvasAgg(ref).draw()
    return shown, want


def test_callbacks_of_next_turn_run_one_per_turn(qtbot):
    """Two heavy steps queued together: what the first one schedules (here a posted event)
    runs before the second; with timers (or posted events) of their own both would run in
    one pass and freeze the viewer as one."""
    from qtpy.QtCore import QTimer

    from napari_pfsdm.napari._alive import next_turn

    order = []

    def first():
        order.append("first")
        QTimer.singleShot(0, lambda: order.append("what else was due"))

    from qtpy.QtWidgets import QWidget

    gone = QWidget()
    next_turn(first)
    next_turn(gone.show)  # a widget deleted before its turn: skipped, as Qt would
    next_turn(lambda: order.append("second"))
    gone.deleteLater()
    qtbot.waitUntil(lambda: len(order) == 3, timeout=5000)
    assert order == ["first", "what else was due", "second"]


def test_a_new_figure_is_laid_out_in_one_step_and_drawn_in_the_next(qtbot, monkeypatch):
    from napari_pfsdm.napari import _canvas

    queued = []  # the turns, one callback each, run by hand below
    monkeypatch.setattr(_canvas, "next_turn", queued.append)
    monkeypatch.setattr(_canvas, "DRAW_BUDGET_S", 10.0)  # each drawing in one turn
    fig = Figure(figsize=(4, 3), layout="constrained")
    canvas = PlotCanvas(fig)
    qtbot.addWidget(canvas)
    canvas.resize(420, 300)
    canvas.show()
    qtbot.waitExposed(canvas)
    drawn = []
    canvas.mpl_connect("draw_event", lambda event: drawn.append(event))
    while queued:  # whatever showing it asked for
        queued.pop(0)()

    ax, ref_ax = _refilled(fig, _fill)
    drawn.clear()
    canvas.draw_idle()
    canvas.draw_idle()  # asked twice: still one layout and one drawing
    assert canvas.layout_pending and len(queued) == 1
    queued.pop(0)()  # turn 1: the layout only
    assert drawn == []
    # matplotlib's own layout to a quarter of a pixel (the decorations measured apart from
    # the layout engine; matplotlib's layout run once more moves its own axes by 0.07 px)
    np.testing.assert_allclose(ax.get_position().bounds, ref_ax.get_position().bounds,
                               atol=0.25 / 420)
    assert not isinstance(fig.get_layout_engine(), ConstrainedLayoutEngine)
    assert len(queued) == 1  # the drawing is asked for, in a later turn
    queued.pop(0)()  # turn 2: the drawing, with that layout
    assert len(drawn) == 1 and not queued
    np.testing.assert_allclose(ax.get_position().bounds, ref_ax.get_position().bounds,
                               atol=0.25 / 420)

    # drawn in place (no new figure): no layout again, one turn
    canvas.draw_idle()
    queued.pop(0)()
    assert len(drawn) == 2 and not queued

    # a new size: laid out again before the next drawing
    old = np.array(ax.get_position().bounds)
    canvas.resize(300, 420)
    qtbot.waitUntil(lambda: len(queued) == 1, timeout=5000)
    queued.pop(0)()
    assert len(drawn) == 2 and len(queued) == 1
    queued.pop(0)()
    assert len(drawn) == 3
    ref2 = Figure(figsize=fig.get_size_inches(), dpi=fig.dpi, layout="constrained")
    ref2_ax = _fill(ref2)
    FigureCanvasAgg(ref2).draw()
    want = np.array(ref2_ax.get_position().bounds)
    assert np.abs(old - want).max() > 0.02  # the old layout does not fit the new size
    # within a pixel (laid out from the old layout, not a fresh figure: sub-pixel apart)
    np.testing.assert_allclose(ax.get_position().bounds, want, atol=1 / 420)

    # a canvas closed with a step still queued: the step does nothing
    gone = PlotCanvas(Figure())
    gone.draw_idle()
    gone.deleteLater()
    qtbot.waitUntil(lambda: _deleted(gone), timeout=5000)
    queued.pop(0)()


def test_a_layout_is_measured_an_axes_part_at_a_time(qtbot, monkeypatch):
    """The layout of a new figure in steps: each axes' decorations measured in three parts
    (x axis, y axis, the whole), the layout engine in one more, twice; nothing drawn
    meanwhile, and the result is matplotlib's own layout."""
    from napari_pfsdm.napari import _canvas

    queued = []
    monkeypatch.setattr(_canvas, "next_turn", queued.append)
    monkeypatch.setattr(_canvas, "DRAW_BUDGET_S", 0.0)  # one part per turn
    fig = Figure(figsize=(4.2, 3.0), dpi=100, layout="constrained")
    canvas = PlotCanvas(fig)
    qtbot.addWidget(canvas)
    canvas.resize(420, 300)
    canvas.show()
    qtbot.waitExposed(canvas)
    while queued:
        queued.pop(0)()
    canvas.draw()
    before = np.array(canvas.buffer_rgba())
    drawn = []
    canvas.mpl_connect("draw_event", lambda event: drawn.append(event))

    def two_plots(f: Figure):
        a = f.add_subplot(121)
        im = a.imshow(np.arange(12.0).reshape(3, 4))  # aspect kept: drawn smaller than placed
        f.colorbar(im, ax=a, label="value")
        a.set_title("a picture")
        b = f.add_subplot(122)
        b.plot([0, 1000, 2000], [-3.5, 0.25, 7.0])
        b.set_xlabel("frame")
        b.set_ylabel("distance")
        return a, b

    shown, ref_axes = _refilled(fig, two_plots)
    canvas.draw_idle()
    turns = 0
    while isinstance(fig.get_layout_engine(), ConstrainedLayoutEngine):
        assert len(queued) == 1
        queued.pop(0)()
        turns += 1
        assert not drawn
        np.testing.assert_array_equal(np.array(canvas.buffer_rgba()), before)
    assert len(fig.axes) == 3  # two plots and a colour bar
    assert turns == 2 * (3 * 3 + 1)
    for a, want in zip(shown, ref_axes, strict=True):
        np.testing.assert_allclose(a.get_position().bounds, want.get_position().bounds,
                                   atol=0.25 / 420)
    while queued:
        queued.pop(0)()
    assert len(drawn) == 1
    for a in fig.axes:  # measured, not replaced: each axes measures itself again
        assert "get_tightbbox" not in vars(a)


def _deleted(widget) -> bool:
    try:
        widget.width()
    except RuntimeError:
        return True
    return False


def test_a_squeezed_canvas_lays_out_without_a_warning(qtbot, monkeypatch):
    """napari laying its window out again can squeeze a dock for a moment: matplotlib then
    warns that the layout was not applied, which napari shows the user as a notification."""
    import warnings

    from napari_pfsdm.napari import _canvas

    queued = []
    monkeypatch.setattr(_canvas, "next_turn", queued.append)
    fig = Figure(figsize=(4, 3), layout="constrained")
    canvas = PlotCanvas(fig)
    qtbot.addWidget(canvas)
    _fill(fig)
    canvas.resize(40, 30)
    canvas.show()
    qtbot.waitExposed(canvas)
    fig.set_layout_engine("constrained")
    canvas.draw_idle()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any warning fails the test
        while queued:
            queued.pop(0)()
    # the same figure laid out by matplotlib itself does warn (what the test guards against)
    ref = Figure(figsize=fig.get_size_inches(), dpi=fig.dpi, layout="constrained")
    _fill(ref)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        FigureCanvasAgg(ref).draw()
    assert any("constrained_layout not applied" in str(w.message) for w in seen)


def _three_panels(fig: Figure, cmap: str) -> None:
    """Two pictures (one with a colour bar) in fixed places and a title: four artists."""
    data = np.arange(30.0).reshape(5, 6)
    a = fig.add_axes((0.08, 0.1, 0.35, 0.75))
    im = a.imshow(data, cmap=cmap)  # aspect "equal": placed when drawn (apply_aspect)
    fig.colorbar(im, cax=fig.add_axes((0.45, 0.1, 0.03, 0.75)), label="value")
    b = fig.add_axes((0.6, 0.1, 0.35, 0.75))
    b.imshow(data.T, cmap=cmap)
    b.set_title("transposed")
    fig.suptitle("three panels")


def test_a_full_drawing_is_spread_over_turns_and_shown_only_when_complete(qtbot, monkeypatch):
    from napari_pfsdm.napari import _canvas

    queued = []
    monkeypatch.setattr(_canvas, "next_turn", queued.append)
    monkeypatch.setattr(_canvas, "DRAW_BUDGET_S", 0.0)  # one part per turn
    fig = Figure(figsize=(4.2, 3.0), dpi=100)
    canvas = PlotCanvas(fig)
    qtbot.addWidget(canvas)
    canvas.resize(420, 300)
    canvas.show()
    qtbot.waitExposed(canvas)
    _three_panels(fig, "viridis")
    while queued:  # whatever showing it asked for
        queued.pop(0)()
    canvas.draw()  # the picture shown before: state A
    before = np.array(canvas.buffer_rgba())
    own = canvas.get_renderer()  # its measures of texts are kept (the layout made them)
    drawn = []
    canvas.mpl_connect("draw_event", lambda event: drawn.append(event))

    fig.clear()  # state B: other colours
    _three_panels(fig, "magma")
    ref = Figure(figsize=fig.get_size_inches(), dpi=fig.dpi)
    _three_panels(ref, "magma")
    ref_canvas = FigureCanvasAgg(ref)
    ref_canvas.draw()  # matplotlib's own drawing of B, in one go
    want = np.array(ref_canvas.buffer_rgba())
    assert not np.array_equal(want, before)

    canvas.draw_idle()
    turns = 0
    while queued:
        queued.pop(0)()
        turns += 1
        if queued:  # under way: the last full drawing is what is shown
            assert canvas.drawing and not drawn
            np.testing.assert_array_equal(np.array(canvas.buffer_rgba()), before)
        if turns == 2:  # the figure changes meanwhile: the drawing starts again
            canvas.draw_idle()
            assert len(queued) == 1
    # an axes is drawn a part at a time: its background, then each artist it holds (its
    # picture, spines, axes lines, titles: matplotlib's own list); the figure's title is one
    parts = sum(1 + len([a for a in ax.get_children() if a is not ax.patch])
                for ax in fig.axes) + 1
    assert parts > 3 * 10  # many more than the four artists of the figure itself
    # (and the picture shown, with what draw_event draws on it, in a turn of its own)
    assert turns == 2 + parts + 1
    assert len(drawn) == 1 and not canvas.drawing
    np.testing.assert_array_equal(np.array(canvas.buffer_rgba()), want)
    assert canvas.get_renderer() is own  # drawn into the canvas's own picture

    # a direct drawing drops one under way
    canvas.draw_idle()
    queued.pop(0)()
    assert canvas.drawing
    canvas.draw()
    assert not canvas.drawing and len(drawn) == 2 and canvas.get_renderer() is own
    np.testing.assert_array_equal(np.array(canvas.buffer_rgba()), want)
    while queued:
        queued.pop(0)()
    assert len(drawn) == 2
