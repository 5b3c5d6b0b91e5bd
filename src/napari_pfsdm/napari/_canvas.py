"""A napari-matplotlib canvas that lays its figure out once per new content or size, and draws
the selection's marks over a saved background (matplotlib's blitting).

A figure is drawn only on screen: new content while the canvas is hidden (a dock being made,
a tab not shown) is drawn when the canvas is shown, at its real size.

Constrained layout measures every tick label, and a full Agg drawing renders every artist:
both are paid when the figure's content or size changes, never for a new selection. The layout
runs inside the next drawing (coalescing a burst of resizes into one), and is then switched off
until the content or the size changes again.
"""

from __future__ import annotations

from matplotlib.layout_engine import ConstrainedLayoutEngine
from matplotlib.ticker import MaxNLocator
from napari_matplotlib.base import BaseNapariMPLWidget
from qtpy.QtWidgets import QSizePolicy

#: At most this many numbered ticks on an axis: enough in a dock, and each tick label is
#: measured by the layout and drawn.
TICKS = 4


class PlotCanvas(BaseNapariMPLWidget):
    """napari-matplotlib's themed canvas and toolbar, with :meth:`changed` (new content: laid
    out and drawn in full at the next turn of the event loop) and :meth:`set_marks` (artists
    drawn over the last full drawing)."""

    def __init__(self, napari_viewer, parent=None) -> None:
        super().__init__(napari_viewer, parent=parent)
        # the figure's own size (6.4 × 4.8 in) is no request for room: the dock decides
        self.canvas.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Ignored)
        self.marks: list = []
        self.background = None
        self.stale = False  # content changed while the canvas was not on screen
        self.canvas.mpl_connect("resize_event", self._on_resize)
        self.canvas.mpl_connect("draw_event", self._on_draw)

    def changed(self) -> None:
        """The figure's content changed: lay it out and draw it in full (once, later)."""
        for axes in self.figure.axes:
            for axis in (axes.xaxis, axes.yaxis):
                if isinstance(axis.get_major_locator(), MaxNLocator):  # numbers, not names
                    axis.get_major_locator().set_params(nbins=TICKS)
        self.background = None
        self.figure.set_layout_engine("constrained")
        self._draw_when_shown()

    def _draw_when_shown(self) -> None:
        """Draw in full at the next turn of the event loop, or, while the canvas is not on
        screen (a dock being made, a hidden tab), once it is shown: at its real size, once."""
        self.stale = not self.canvas.isVisible()
        if not self.stale:
            self.canvas.draw_idle()

    def showEvent(self, event) -> None:  # noqa: N802 - Qt's name
        super().showEvent(event)
        if self.stale:
            self.stale = False
            self.canvas.draw_idle()

    def _on_resize(self, event=None) -> None:
        self.background = None
        self.figure.set_layout_engine("constrained")  # the canvas draws after a resize

    def _on_draw(self, event=None) -> None:
        if isinstance(self.figure.get_layout_engine(), ConstrainedLayoutEngine):
            self.figure.set_layout_engine("none")  # placed: a new selection needs no layout
        self.background = self.canvas.copy_from_bbox(self.figure.bbox)
        for artist in self.marks:
            artist.axes.draw_artist(artist)

    def set_marks(self, artists: list) -> None:
        """Show ``artists`` (marks of the axes, made once and given new data for each
        selection) over the last full drawing, without drawing the figure again; the
        previous marks that are not among them are hidden."""
        for artist in self.marks:
            if not any(artist is a for a in artists):
                artist.set_visible(False)
        self.marks = list(artists)
        for artist in self.marks:
            artist.set_animated(True)  # drawn only here, over the saved background
            artist.set_visible(True)
        if self.background is None:
            self._draw_when_shown()
            return
        self.canvas.restore_region(self.background)
        for artist in self.marks:
            artist.axes.draw_artist(artist)
        self.canvas.update()  # painted with napari's next repaint
