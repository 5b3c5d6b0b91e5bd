"""Where the widgets find the last analysis of a Labels layer.

The feature table also goes into ``labels_layer.features`` (for napari's own table and other
plugins); the full :class:`AnalysisOutput` (SDF patches, PCA, options) is kept here, keyed weakly
by the layer, and ``results_changed`` tells the plot widgets to redraw.
"""

from __future__ import annotations

import weakref

from psygnal import Signal

from ._compute import AnalysisOutput


class _Store:
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


STORE = _Store()
