"""Worker callbacks that outlive their widget (the viewer closed while work was running)."""

from __future__ import annotations

import functools
from collections import deque


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


#: Delay of :func:`next_turn` (ms): a timer, not a posted event.
NEXT_TURN_MS = 1
_QUEUE: deque = deque()
_TIMER: list = []  # the one QTimer of the queue, made on first use (in the GUI thread)


def next_turn(callback) -> None:
    """Call ``callback`` in a later turn of Qt's event loop, after what is due now, one
    queued callback per turn.

    ``QTimer.singleShot(0, ...)`` is a posted event, which Qt delivers before the timers
    already due; and Qt fires every timer that is due in one pass. Either way two heavy steps
    scheduled together freeze the viewer as one. The callbacks wait in one queue served by a
    1 ms timer that runs one callback and is started again for the next, so that what else
    is due (input, napari's drawing, other timers) runs between two heavy steps.
    """
    from qtpy.QtCore import QTimer

    _QUEUE.append(callback)
    if not _TIMER:
        timer = QTimer(singleShot=True, interval=NEXT_TURN_MS)
        timer.timeout.connect(_run_next)
        _TIMER.append(timer)
    if not _TIMER[0].isActive():
        _TIMER[0].start()


def _run_next() -> None:
    if not _QUEUE:
        return
    callback = _QUEUE.popleft()
    try:
        callback()
    except RuntimeError as err:  # its Qt object was deleted meanwhile (a closed dock or
        if "has been deleted" not in str(err):  # viewer): as Qt drops a deleted receiver's
            raise  # timer, nothing to do
    finally:
        if _QUEUE:
            _TIMER[0].start()
