"""Where the widgets of one viewer find the last analysis of a Labels layer.

The feature table also goes into ``labels_layer.features`` (for napari's own table and other
plugins); the full :class:`AnalysisOutput` (table, PCA, boxes, options) is kept in the viewer's
:class:`ResultStore`, keyed weakly by the layer, and ``results_changed`` tells that viewer's
plot widgets to redraw. Each viewer has its own store (:func:`store_for`), kept only as long as
the viewer lives: two viewers never see each other's results or signals.
"""

from __future__ import annotations

import weakref

from psygnal import Signal

from ._compute import AnalysisOutput

__all__ = ["ResultStore", "store_for"]


class ResultStore:
    """The analyses of one viewer's Labels layers."""

    results_changed = Signal(object)  # the Labels layer whose results changed

    def __init__(self) -> None:
        self._outputs: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()

    def set(self, layer, output: AnalysisOutput | None) -> None:
        if output is None:
            self._outputs.pop(layer, None)
        else:
            self._outputs[layer] = output
        self.results_changed.emit(layer)

    def get(self, layer) -> AnalysisOutput | None:
        if layer is None:
            return None
        return self._outputs.get(layer)


_STORES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def store_for(viewer) -> ResultStore:
    """The :class:`ResultStore` of ``viewer`` (made on first use, gone with the viewer)."""
    store = _STORES.get(viewer)
    if store is None:
        store = _STORES[viewer] = ResultStore()
    return store
