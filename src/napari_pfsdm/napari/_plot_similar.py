"""The plots dock's "Similar" tab: the objects most like the selected one, as a gallery.

For the selected object, its nearest shapes under the PF-SDM distance, with the elastic outline
term when "elastic" is ticked (:class:`napari_pfsdm.analysis.neighbours.NeighbourSearch`: one
object against all, never an n × n matrix), each drawn as its outline with its frame, label and
distance: by default other objects, each once, in its frame nearest the selected shape
(:func:`pick`; the object itself in other frames is what a time-lapse's nearest rows mostly
are); its own frames, or any object and frame, are choices. Computed in a worker (the search
of the run kept for the next selections); a click on a thumbnail moves napari to that object
and frame.
"""

from __future__ import annotations

import numpy as np
from magicgui.widgets import ComboBox, SpinBox
from napari.qt.threading import thread_worker

from ._elastic import elastic_box, notice, weight_of
from ._model import REGISTRY, Analysis
from ._plot_base import Plot, outline_of

#: Thumbnails shown by default (the selected object first).
SHOWN = 8
#: Which objects the gallery shows, in the form's words → :func:`pick`'s.
WHICH = {"other objects": "others", "its own frames": "own", "any object and frame": "any"}


def pick(order: np.ndarray, objects: np.ndarray, me: int, which: str, k: int) -> np.ndarray:
    """Positions in ``order`` (rows nearest first, the selected one left out) of the ``k``
    shown: ``"others"`` the nearest row of each other object (its best frame), ``"own"`` the
    selected object's own rows (object ``me``), ``"any"`` the nearest rows. An object below 0
    (no track) is its row alone.

    >>> objects = np.array([5, 5, 7, 7, 9, -1, -1])
    >>> order = np.array([1, 2, 3, 0, 4, 5, 6])  # rows nearest first; row 0 is another frame
    >>> pick(order, objects, 5, "others", 4).tolist(), pick(order, objects, 5, "own", 4).tolist()
    ([1, 4, 5, 6], [0, 3])
    """
    obj = objects[order]
    if which == "own":
        keep = obj == me
    elif which == "others":
        key = np.where(obj >= 0, obj, -1 - np.arange(len(obj)))  # no track: each row alone
        first = np.zeros(len(obj), bool)
        first[np.unique(key, return_index=True)[1]] = True
        keep = first & (obj != me)
    else:
        keep = np.ones(len(obj), bool)
    return np.flatnonzero(keep)[:k]


@thread_worker(start_thread=False)
def _similar(analysis: Analysis, index, row: int, k: int, which: str = "others",
             elastic: float = 0.0, say=None):
    """The ``k`` nearest objects of the measured row ``row`` (the search of the analysis's
    measured rows made when missing; ``which``: :func:`pick`'s; ``elastic``: μ of the elastic
    term), with their outlines."""
    from ..analysis.neighbours import NeighbourSearch
    from ..core.compiled import compile_notice

    rows = np.flatnonzero(analysis.measured)
    table = analysis.table.iloc[rows]
    weight = float(analysis.options.get("intensity_weight", 0.0)) if "intensity" in \
        analysis.pca else 0.0
    at = int(np.searchsorted(rows, row))
    with compile_notice(say or (lambda _message: None)):
        if index is None:
            index = NeighbourSearch(table, intensity_weight=weight, elastic_weight=elastic)
        idx, dist = index.rows([at], len(rows) - 1)  # all, nearest first
    valid = idx[0] >= 0
    order, dist = rows[idx[0][valid]], dist[0][valid]
    chosen = pick(order, analysis.objects(), int(analysis.objects()[row]), which, k)
    found = np.concatenate([[row], order[chosen]])
    distances = np.concatenate([[0.0], dist[chosen]])
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
        self.which = ComboBox(choices=list(WHICH.items()), value="others",
                              tooltip="Other objects, each in its frame nearest this shape; "
                                      "this object in its other frames; or any object and "
                                      "frame.")
        self.elastic = elastic_box()
        super().__init__(viewer, [self.count, self.which, self.elastic])
        self.index = None  # ((analysis key, elastic weight), search) of the last run searched
        self.result = None  # (selection, k, frames, labels, distances, outlines)
        self.worker = None
        self.thumbs: list = []
        self.asked = None  # (run, selection, count, which) of the last drawing

    def draw(self) -> None:
        a = self.analysis
        self.asked = self._wanted(a)  # what this drawing is of
        if a.ndim == 3:
            raise ValueError("The gallery is drawn for 2-D objects.")
        if a.selection is None or a.row_of(*a.selection) is None \
                or not a.measured[a.row_of(*a.selection)]:
            raise ValueError("Select an object with features to see the objects like it.")
        want = self._wanted(a)
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
        what = {"others": "other objects nearest in shape to the selected one, each in its "
                          "nearest frame",
                "own": "frames of the selected object nearest its shape here",
                "any": "objects and frames nearest in shape to the selected one"}
        term = " with the elastic term" if weight_of(self.elastic) else ""
        self.info.value = (f"The {n - 1} {what[self.which.value]} (PF-SDM distance{term}). "
                           "Click one to go there.")

    def _wanted(self, a: Analysis) -> tuple:
        """What a gallery shows: (run, selection, count, which, elastic weight)."""
        return a.key, a.selection, self.count.value, self.which.value, weight_of(self.elastic)

    def highlight(self) -> None:
        """A new selection: its own gallery (the selected object is what the tab shows)."""
        a = self.analysis
        if a is not None and self._wanted(a) != self.asked:
            self.redraw()

    def _compute(self, a: Analysis, want) -> None:
        if self.worker is not None:  # the one running ends, then this one starts
            return
        mu = want[4]
        index = self.index[1] if self.index is not None and self.index[0] == (a.key, mu) \
            else None
        self.worker = worker = _similar(a, index, a.row_of(*a.selection), self.count.value,
                                        self.which.value, mu, notice(self.info),
                                        _ignore_errors=True)

        def done(result):
            index, *rest = result
            self.index = ((a.key, mu), index)
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
