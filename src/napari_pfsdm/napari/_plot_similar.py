"""The plots dock's "Similar" tab: the objects most like the selected one, as a gallery.

For the selected object, its nearest shapes among every measured object of every frame under
the PF-SDM distance (:func:`napari_pfsdm.analysis.neighbours.neighbour_index` and
:func:`napari_pfsdm.core.neighbours.search_rows`: one object against all, never an n × n
matrix), each drawn as its outline with its frame, label and distance. Computed in a worker
(the index of the run kept for the next selections); a click on a thumbnail moves napari to
that object and frame.
"""

from __future__ import annotations

import numpy as np
from magicgui.widgets import SpinBox
from napari.qt.threading import thread_worker

from ._model import REGISTRY, Analysis
from ._plot_base import Plot, outline_of

#: Thumbnails shown by default (the selected object first).
SHOWN = 8


@thread_worker(start_thread=False)
def _similar(analysis: Analysis, index, row: int, k: int):
    """The ``k`` nearest objects of the measured row ``row`` (the index of the analysis's
    measured rows made when missing), with their outlines."""
    from ..analysis.neighbours import neighbour_index
    from ..core.neighbours import search_rows

    rows = np.flatnonzero(analysis.measured)
    table = analysis.table.iloc[rows]
    weight = float(analysis.options.get("intensity_weight", 0.0)) if "intensity" in \
        analysis.pca else 0.0
    if index is None:
        index = neighbour_index(table, intensity_weight=weight)
    at = int(np.searchsorted(rows, row))
    idx, dist = search_rows(index, np.array([at]), min(k, len(rows) - 1))
    keep = idx[0] >= 0
    found = np.concatenate([[row], rows[idx[0][keep]]])
    distances = np.concatenate([[0.0], dist[0][keep]])
    frames = analysis.table["frame"].to_numpy()[found].astype(int)
    labels = analysis.table["label"].to_numpy()[found].astype(int)
    outlines = []
    for t, lab in zip(frames, labels, strict=True):
        plane = np.asarray(analysis.labels[t] if analysis.time_lapse else analysis.labels)
        outlines.append(outline_of(plane, analysis.boxes.get((int(t), int(lab))), int(lab)))
    return index, frames, labels, distances, outlines


class SimilarPlot(Plot):
    """The selected object and the objects nearest it in shape, as outlines."""

    READABLE = (280, 200)

    def __init__(self, viewer) -> None:
        self.count = SpinBox(value=SHOWN - 1, min=1, max=24,
                             tooltip="How many of the nearest objects are shown.")
        super().__init__(viewer, [self.count])
        self.index = None  # (analysis key, neighbour index) of the last run searched
        self.result = None  # (selection, k, frames, labels, distances, outlines)
        self.worker = None
        self.thumbs: list = []
        self.asked = None  # (run, selection, count) of the last drawing

    def draw(self) -> None:
        a = self.analysis
        self.asked = (a.key, a.selection, self.count.value)  # what this drawing is of
        if a.ndim == 3:
            raise ValueError("The gallery is drawn for 2-D objects.")
        if a.selection is None or a.row_of(*a.selection) is None \
                or not a.measured[a.row_of(*a.selection)]:
            raise ValueError("Select an object with features to see the objects like it.")
        want = (a.key, a.selection, self.count.value)
        if self.result is None or self.result[0] != want:
            self._compute(a, want)
            self.info.value = "Finding the nearest shapes in the background…"
            return
        _want, frames, labels, distances, outlines = self.result
        n = len(outlines)
        cols = min(4, n)
        rows = -(-n // cols)
        self.thumbs = []
        for i, (t, lab, d, line) in enumerate(zip(frames, labels, distances, outlines,
                                                  strict=True)):
            ax = self.figure.add_subplot(rows, cols, i + 1)
            ax.plot(line[:, 1], -line[:, 0], lw=1.4, color="#ff3c3c" if i == 0 else None)
            ax.set(aspect="equal", xticks=[], yticks=[])
            where = f"f{t} " if a.time_lapse else ""
            ax.set_title(f"{where}l{lab}" + ("  (this one)" if i == 0 else f"  d={d:.3g}"),
                         fontsize=7)
            self.thumbs.append((ax, int(t), int(lab)))
        self.info.value = (f"The {n - 1} objects nearest in shape to the selected one (PF-SDM "
                           "distance, every frame). Click one to go there.")

    def highlight(self) -> None:
        """A new selection: its own gallery (the selected object is what the tab shows)."""
        a = self.analysis
        if a is not None and (a.key, a.selection, self.count.value) != self.asked:
            self.redraw()

    def _compute(self, a: Analysis, want) -> None:
        if self.worker is not None:  # the one running ends, then this one starts
            return
        index = self.index[1] if self.index is not None and self.index[0] == a.key else None
        self.worker = worker = _similar(a, index, a.row_of(*a.selection), self.count.value,
                                        _ignore_errors=True)

        def done(result):
            index, *rest = result
            self.index = (a.key, index)
            self.result = (want, *rest)

        def failed(err):
            self.info.value = f"The nearest shapes failed: {err}"

        def finished():
            self.worker = None
            if self.analysis is not None and self.result is not None:
                self.redraw()  # the gallery, or the one asked for meanwhile

        worker.returned.connect(done)
        worker.errored.connect(failed)
        worker.finished.connect(finished)
        worker.start()

    def _on_click(self, event) -> None:
        for ax, frame, label in self.thumbs:
            if event.inaxes is ax and event.button == 1 and not self.toolbar.mode:
                link = REGISTRY.link(self.analysis.layer_id)
                if link is not None:
                    link.go_to(frame, label)
                return
