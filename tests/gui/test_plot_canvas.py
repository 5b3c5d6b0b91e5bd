"""The plots' canvas lays a new figure out in one step of the event loop and draws it in
the next (napari_pfsdm.napari._canvas)."""

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


def test_a_new_figure_is_laid_out_in_one_step_and_drawn_in_the_next(qtbot):
    fig = Figure(figsize=(4, 3), layout="constrained")
    canvas = PlotCanvas(fig)
    qtbot.addWidget(canvas)
    canvas.resize(420, 300)
    canvas.show()
    qtbot.waitExposed(canvas)
    drawn = []
    canvas.mpl_connect("draw_event", lambda event: drawn.append(event))
    qtbot.waitUntil(lambda: not canvas._idle_timer.isActive(), timeout=5000)

    fig.clear()
    fig.set_layout_engine("constrained")
    ax = _fill(fig)
    # what matplotlib's own constrained layout gives the same figure, drawn in one go
    ref = Figure(figsize=fig.get_size_inches(), dpi=fig.dpi, layout="constrained")
    ref_ax = _fill(ref)
    FigureCanvasAgg(ref).draw()
    drawn.clear()
    canvas.draw_idle()
    canvas.draw_idle()  # asked twice: still one layout and one drawing
    assert canvas.layout_pending and canvas._idle_timer.isActive()
    canvas._idle_timer.stop()
    canvas._idle_step()  # step 1: the layout only
    assert drawn == []
    np.testing.assert_allclose(ax.get_position().bounds, ref_ax.get_position().bounds,
                               atol=1e-9)
    assert not isinstance(fig.get_layout_engine(), ConstrainedLayoutEngine)
    assert canvas._idle_timer.isActive()  # the drawing is asked for, in the next step
    canvas._idle_timer.stop()
    canvas._idle_step()  # step 2: the drawing, with that layout
    assert len(drawn) == 1
    np.testing.assert_allclose(ax.get_position().bounds, ref_ax.get_position().bounds,
                               atol=1e-9)
    assert not canvas._idle_timer.isActive()

    # drawn in place (no new figure): no layout again
    canvas.draw_idle()
    canvas._idle_timer.stop()
    canvas._idle_step()
    assert len(drawn) == 2

    # a new size: laid out again before the next drawing, through the event loop
    old = np.array(ax.get_position().bounds)
    canvas.resize(300, 420)
    qtbot.waitUntil(lambda: len(drawn) == 3, timeout=5000)
    ref2 = Figure(figsize=fig.get_size_inches(), dpi=fig.dpi, layout="constrained")
    ref2_ax = _fill(ref2)
    FigureCanvasAgg(ref2).draw()
    want = np.array(ref2_ax.get_position().bounds)
    assert np.abs(old - want).max() > 0.02  # the old layout does not fit the new size
    # within a pixel (laid out from the old layout, not a fresh figure: sub-pixel apart)
    np.testing.assert_allclose(ax.get_position().bounds, want, atol=1 / 420)
