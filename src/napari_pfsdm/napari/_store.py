"""Where the widgets of one viewer find the last analysis of a Labels layer.

The feature table also goes into ``labels_layer.features`` (for napari's own table and other
plugins); the full :class:`AnalysisOutput` (table, PCA, boxes, options) is kept in the viewer's
:class:`ResultStore`, and ``results_changed`` tells that viewer's plot widgets to redraw. Each
viewer has its own store (:func:`store_for`), kept only as long as the viewer lives: two viewers
never see each other's results or signals.

Docked from the Plugins menu, a widget gets a public-only proxy of the viewer, and every layer
it reads from it is a new proxy object: identity (``is``) and weak references to those proxies
mean nothing. The store therefore keys results by the layer's ``unique_id`` (napari's public,
stable identity of a layer) and forgets them when the layer leaves the viewer.
"""

from __future__ import annotations

import weakref

from psygnal import Signal

from ._compute import AnalysisOutput

__all__ = ["ResultStore", "same_layer", "store_for"]


def same_layer(a, b) -> bool:
    """True when ``a`` and ``b`` are the same napari layer (proxies of it included)."""
    if a is None or b is None:
        return False
    return a.unique_id == b.unique_id


class ResultStore:
    """The analyses of one viewer's Labels layers, by layer identity."""

    results_changed = Signal(object)  # the Labels layer whose results changed

    def __init__(self) -> None:
        self._outputs: dict = {}
        #: the characters napari has drawn in this viewer's texts (:mod:`._glyphs`)
        self.glyphs_drawn: set[str] = set()

    def set(self, layer, output: AnalysisOutput | None) -> None:
        if output is None:
            self._outputs.pop(layer.unique_id, None)
        else:
            self._outputs[layer.unique_id] = output
        self.results_changed.emit(layer)

    def get(self, layer) -> AnalysisOutput | None:
        if layer is None:
            return None
        return self._outputs.get(layer.unique_id)

    def forget(self, layer) -> None:
        """Drop the results of a layer that left the viewer (no signal: nothing to show)."""
        self._outputs.pop(layer.unique_id, None)

    def __contains__(self, layer) -> bool:
        return layer is not None and layer.unique_id in self._outputs


_STORES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _viewer_key(viewer):
    """The viewer a proxy stands for (a store per viewer, not per proxy object)."""
    return getattr(viewer, "__wrapped__", viewer)


def store_for(viewer) -> ResultStore:
    """The :class:`ResultStore` of ``viewer`` (made on first use, gone with the viewer)."""
    key = _viewer_key(viewer)
    store = _STORES.get(key)
    if store is None:
        store = _STORES[key] = ResultStore()

        def _forget(event) -> None:
            store.forget(event.value)

        viewer.layers.events.removed.connect(_forget)
    return store
