"""The matplotlib canvas of the plots: a full redraw in three turns of the event loop.

A redraw of a plot (``figure.clear()`` and new artists) is followed by matplotlib's
constrained layout (~45 ms for two axes and a colour bar here, measured with the stack
sampler of ``benchmarks/plugin.py``) and the drawing itself (~35-65 ms). In one turn they froze
the viewer for longer than a person notices (100 ms); :class:`PlotCanvas` lays the figure out
in one turn and draws it in the next, each after what else is due (:func:`._alive.next_turn`).
"""

from __future__ import annotations

import traceback
import warnings

from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.layout_engine import ConstrainedLayoutEngine

from ._alive import next_turn


class PlotCanvas(FigureCanvasQTAgg):
    """:class:`FigureCanvasQTAgg` whose idle draw lays out first, then draws a turn later.

    The figure keeps the layout of its last full draw (its engine is set to ``"none"`` once
    laid out): drawing in place (new data in the same axes) costs no layout. A new figure
    structure (``figure.set_layout_engine("constrained")``, as after ``figure.clear()``) or a
    new canvas size is laid out again.
    """

    def __init__(self, figure) -> None:
        super().__init__(figure)
        self.step_queued = False  # an idle step waits in :func:`._alive.next_turn`'s queue

    def draw_idle(self) -> None:
        """Draw soon (once however often asked), in a turn of its own."""
        if not self.step_queued:
            self.step_queued = True
            next_turn(self._idle_step)

    @property
    def layout_pending(self) -> bool:
        """True when the next idle step lays the figure out (and draws in the turn after)."""
        return isinstance(self.figure.get_layout_engine(), ConstrainedLayoutEngine)

    def _idle_step(self) -> None:
        try:
            self.step_queued = False
            if self.width() <= 0 or self.height() <= 0:
                return
        except RuntimeError:  # the Qt widget is gone (its dock was closed)
            return
        try:
            if self.layout_pending and self.figure.axes:
                with warnings.catch_warnings():  # a dock squeezed for a moment (napari
                    # laying its window out again): the last layout is kept, and the next
                    # size is laid out again; not a warning for the user
                    warnings.filterwarnings("ignore", "constrained_layout not applied")
                    self.figure.get_layout_engine().execute(self.figure)
                self.figure.set_layout_engine("none")
                self.draw_idle()  # the drawing in a later turn
                return
            self.draw()
        except Exception:  # noqa: BLE001 - as matplotlib's own idle draw: print, go on
            traceback.print_exc()

    def resizeEvent(self, event) -> None:  # noqa: N802 - Qt's name
        """A new size: lay the figure out again before the next draw."""
        if self.figure.get_layout_engine() is not None and not self.layout_pending:
            self.figure.set_layout_engine("constrained")
        super().resizeEvent(event)
