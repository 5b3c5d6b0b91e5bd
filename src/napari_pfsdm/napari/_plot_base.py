"""What every plot of the plots dock shares: a napari-matplotlib canvas showing one view of an
analysis, its controls and words, the selection's marks, and a click that moves napari there."""

from __future__ import annotations

import matplotlib.style as mplstyle
import numpy as np
from magicgui.widgets import Container, Label, PushButton
from qtpy.QtCore import QTimer
from qtpy.QtWidgets import QSizePolicy

from ._canvas import PlotCanvas
from ._model import REGISTRY, Analysis

#: What a plot says before a Run.
EMPTY = "Run the PF-SDM analysis to fill this plot."
#: A plot's least height on the canvas (px).
MIN_CANVAS = 120
#: What a plot too small to read says instead of drawing itself squashed.
FLOAT = "Float for a larger view"
#: Height (px) kept for the plot's words under the canvas.
INFO_ROOM = 36


class Plot(PlotCanvas):
    """A napari-matplotlib canvas showing one view of an analysis; click a point to go there.

    Below :attr:`READABLE` (width, height in pixels) of canvas the plot is not drawn squashed
    (text over its axes, thumbnails cut): it says :data:`FLOAT` until the canvas grows (the
    dock floated or given more room)."""

    #: The least canvas (width, height) in pixels at which the plot is readable.
    READABLE = (260, 170)

    def __init__(self, viewer, controls: list) -> None:
        super().__init__(viewer)
        self.layer = None
        self.analysis: Analysis | None = None
        self.keys = np.zeros((0, 2), np.int64)  # (frame, label) of each point
        self.xy = np.zeros((0, 2))
        self.points_axes = None
        self.mark_artists: dict = {}  # name → artist of points_axes, made at first use
        self.info = Label(value=EMPTY)
        self.info.native.setWordWrap(True)
        self.info.native.setSizePolicy(QSizePolicy.Policy.Expanding,  # the dock's width,
                                       QSizePolicy.Policy.Maximum)  # the words' height
        self.controls = Container(widgets=controls, layout="horizontal", labels=False)
        self.controls.margins = (0, 0, 0, 0)
        for w in controls:
            if not isinstance(w, PushButton):
                w.changed.connect(self.redraw)
        self.layout().insertWidget(0, self.controls.native)
        self.layout().addWidget(self.info.native)
        self.layout().setStretchFactor(self.canvas, 1)  # spare height goes to the plot
        self.canvas.setMinimumHeight(MIN_CANVAS)
        self.canvas.setToolTip("Click a point to go to that object (and frame) in napari.")
        self.layout().setContentsMargins(2, 2, 2, 2)
        self.canvas.mpl_connect("button_press_event", self._on_click)
        self.small = False  # the drawing on show says FLOAT
        self._checking = False  # a check of the room is due

    def too_small(self) -> bool:
        """Whether the room on screen leaves the canvas below :attr:`READABLE` (False while
        hidden: the room is known when it is shown)."""
        if not self.isVisible():
            return False
        others = self.controls.native.sizeHint().height() + \
            self.toolbar.sizeHint().height() + INFO_ROOM
        return self.width() < self.READABLE[0] or \
            self.height() - others < self.READABLE[1]

    def redraw(self, *args) -> None:
        """Draw the figure again: new data or options (a selection only :meth:`highlight`)."""
        self.small = self.too_small()
        self.info.tooltip = ""
        for part in (self.controls.native, self.toolbar, self.canvas):  # the words instead
            part.setVisible(not self.small)
        if self.small:
            self._say_float()
        elif self.analysis is None or not self.refresh():  # else new data in the same artists
            self.figure.clear()
            self.marks, self.points_axes, self.mark_artists = [], None, {}
            self.keys = np.zeros((0, 2), np.int64)
            try:
                if self.analysis is None:
                    raise ValueError(EMPTY)
                with mplstyle.context(self.napari_theme_style_sheet):  # napari's colours
                    self.draw()
            except ValueError as err:
                self.figure.clear()
                self.info.value = str(err)
        self.changed()
        self.highlight()

    def _say_float(self) -> None:
        self.figure.clear()
        self.marks, self.points_axes, self.mark_artists = [], None, {}
        self.keys = np.zeros((0, 2), np.int64)
        w, h = self.READABLE
        self.info.value = f"Too small to read here: {FLOAT} (Float, above)."
        self.info.tooltip = (f"The plot needs {w} × {h} px: press Float for a window of its "
                             "own, or give this dock more room.")

    def resizeEvent(self, event) -> None:  # noqa: N802 - Qt's name
        super().resizeEvent(event)
        self._check_room_later()

    def showEvent(self, event) -> None:  # noqa: N802 - Qt's name
        super().showEvent(event)
        self._check_room_later()

    def _check_room_later(self) -> None:
        """Once the layout has settled (a burst of resizes while a dock is placed is one
        check), draw again if the plot became readable or stopped being so."""
        if not self._checking:
            self._checking = True
            QTimer.singleShot(0, self._check_room)

    def _check_room(self) -> None:
        self._checking = False
        if self.too_small() != self.small:
            self.redraw()

    def draw(self) -> None:  # pragma: no cover - each plot draws its own
        raise NotImplementedError

    def refresh(self) -> bool:
        """Give the figure's artists new data in place, when the figure keeps its kind of
        content (True); else False, and :meth:`redraw` draws the figure from scratch."""
        return False

    def highlight(self) -> None:
        """Mark the selected object (and its frame's points) on the plot."""
        a = self.analysis
        if a is not None and a.selection is not None and self.points_axes is not None \
                and len(self.keys):
            self.set_marks(self.mark(self.points_axes, *a.selection))
        else:
            self.set_marks([])

    def mark_artist(self, name: str, make):
        """The mark ``name`` of the plotted axes: ``make()`` at first use after a drawing,
        then the same artist, given the new selection's data by :meth:`mark`."""
        if name not in self.mark_artists:
            self.mark_artists[name] = make()
        return self.mark_artists[name]

    def mark(self, ax, frame: int, label: int) -> list:
        hit = (self.keys[:, 0] == frame) & (self.keys[:, 1] == label)
        if not hit.any():
            return []
        star = self.mark_artist("star", lambda: ax.scatter(
            [], [], s=150, marker="*", color="#ff3c3c", edgecolors="white", zorder=5))
        star.set_offsets(self.xy[hit])
        return [star]

    def _on_click(self, event) -> None:
        if event.inaxes is not self.points_axes or not len(self.keys) or event.button != 1:
            return
        if self.toolbar.mode:  # zooming or panning
            return
        screen = self.points_axes.transData.transform(self.xy)
        i = int(np.argmin(np.hypot(*(screen - (event.x, event.y)).T)))
        self.select(i)

    def select(self, i: int) -> None:
        """Go to the object of point ``i``: napari moves to its frame and selects it."""
        frame, label = (int(v) for v in self.keys[i])
        link = REGISTRY.link(self.analysis.layer_id)
        if link is not None:
            link.go_to(frame, label)


def outline_of(plane: np.ndarray, box, label: int) -> np.ndarray:
    """The object's closed outline (row, col), centred."""
    from ..analysis.baselines import mask_contour

    line = mask_contour(plane[box] == label if box is not None else plane == label)
    return np.vstack([line, line[:1]]) - line.mean(axis=0)
