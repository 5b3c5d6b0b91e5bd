"""Worker callbacks that outlive their widget (the viewer closed while work was running)."""

from __future__ import annotations

import functools


def while_alive(method):
    """Run the widget method unless its Qt object is gone: a worker that finishes after the
    viewer was closed calls it on a deleted widget, which would print a traceback for nothing
    the user can act on."""

    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        try:
            return method(self, *args, **kwargs)
        except RuntimeError as err:
            if "has been deleted" in str(err):
                return None
            raise

    return wrapper


def offer(combo, names: list[str]) -> None:
    """Put ``names`` in a combo box when they differ from what it offers, keeping the current
    choice when it is still there, without emitting its change signals."""
    if names == [combo.itemText(i) for i in range(combo.count())]:
        return
    current = combo.currentText()
    combo.blockSignals(True)
    combo.clear()
    combo.addItems(names)
    if current in names:
        combo.setCurrentText(current)
    combo.blockSignals(False)


#: Delay of :func:`next_turn` (ms): any timer, not a posted event.
NEXT_TURN_MS = 1


def next_turn(callback) -> None:
    """Call ``callback`` in a later turn of Qt's event loop, after what is due now.

    ``QTimer.singleShot(0, ...)`` is a posted event, which Qt delivers before the timers
    already due (napari's, the canvas's): two heavy steps chained that way freeze the viewer
    as one. A 1 ms timer is ordered by time with the others, so what was due runs between.
    """
    from qtpy.QtCore import QTimer

    QTimer.singleShot(NEXT_TURN_MS, callback)
