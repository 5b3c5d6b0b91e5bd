"""Reading a principal component: its loadings as a ring × harmonic map, and the real objects
that sit at -2σ … +2σ along it (a shape-space strip), for the PCA the user picks.

The PCA is :class:`napari_pfsdm.analysis.shape_space.ShapePCA` on the layer's last run:
weighted (the PF-SDM distances), standardised (every feature unit variance, the paper's plots),
or "beyond the classic measures" (area, circularity, eccentricity, solidity and the axis
lengths regressed out first, so that its first component is not circularity again). The
figure says which. Computed in a worker; the outlines come from the measured labels.
"""

from __future__ import annotations

import napari
import numpy as np
from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from napari.layers import Labels
from napari.qt.threading import thread_worker
from qtpy.QtCore import QSize
from qtpy.QtWidgets import QComboBox, QHBoxLayout, QLabel, QSpinBox, QVBoxLayout, QWidget

from ..analysis.shape_space import HARMONIC_WORDS
from ._alive import offer, while_alive
from ._store import store_for

#: The PCAs offered, and how each is fitted.
KINDS = {
    "weighted (PF-SDM distances)": {},
    "standardised (each feature)": {"standardize": True},
    "beyond the classic measures": {"regress_out": ("area", "circularity", "eccentricity",
                                                    "solidity", "axis_major_length",
                                                    "axis_minor_length")},
}
SIGMAS = (-2, -1, 0, 1, 2)


def object_outline(labels, output, frame: int, label: int) -> np.ndarray:
    """The outline (row, col) of one measured object, centred on its centroid."""
    from skimage.measure import find_contours

    box = output.boxes.get((int(frame), int(label)))
    plane = np.asarray(labels[frame] if output.time_lapse else labels)
    if box is None:
        where = np.argwhere(plane == label)
        box = tuple(slice(int(a), int(b) + 1) for a, b in zip(where.min(0), where.max(0),
                                                                strict=True))
    crop = np.pad(plane[box] == label, 1)
    contours = find_contours(crop.astype(float), 0.5)
    line = max(contours, key=len) if contours else np.zeros((1, 2))
    return line - line.mean(axis=0)


def reading(output, kind: str, component: int):
    """(fitted ShapePCA, scores, shape modes, outlines of the modes): the worker's job."""
    from ..analysis.shape_space import ShapePCA, shape_modes

    space = ShapePCA(n_components=max(5, component), **KINDS[kind]).fit(output.table)
    scores = space.transform(output.table)
    modes = shape_modes(scores, component)
    outlines = [object_outline(output.labels, output, int(getattr(r, "frame", 0)),
                               int(r.label)) for r in modes.itertuples()]
    return space, scores, modes, outlines


class ComponentsWidget(QWidget):
    """Loadings and shape modes of one principal component of the last run."""

    def __init__(self, napari_viewer: napari.viewer.Viewer) -> None:
        super().__init__()
        self.viewer = napari_viewer
        self._store = store_for(napari_viewer)
        self.worker = None
        self.result = None
        self.layer_combo = QComboBox(toolTip="The analysed Labels layer.")
        self.kind = QComboBox(toolTip="Which PCA: weighted as PF-SDM compares shapes, every "
                              "feature standardised, or after removing what the classic "
                              "measures (area, circularity, …) already say.")
        self.kind.addItems(list(KINDS))
        self.component = QSpinBox(minimum=1, maximum=10, value=1, toolTip="The component.")
        self.figure = Figure(figsize=(3.6, 4.2), constrained_layout=True)
        self.canvas = FigureCanvasQTAgg(self.figure)
        self.canvas.setMinimumSize(260, 220)
        self.info = QLabel("Run the PF-SDM analysis first.", wordWrap=True)
        top = QHBoxLayout()
        top.addWidget(QLabel("Layer"))
        top.addWidget(self.layer_combo, 1)
        row = QHBoxLayout()
        row.addWidget(self.kind, 1)
        row.addWidget(QLabel("PC"))
        row.addWidget(self.component)
        layout = QVBoxLayout(self)
        layout.addLayout(top)
        layout.addLayout(row)
        layout.addWidget(self.canvas, 1)
        layout.addWidget(self.info)
        for box in (self.layer_combo, self.kind):
            box.currentTextChanged.connect(lambda *a: self.update_reading())
        self.component.valueChanged.connect(lambda *a: self.update_reading())
        self._store.results_changed.connect(self._refresh)
        for event in (napari_viewer.layers.events.inserted, napari_viewer.layers.events.removed):
            event.connect(self._refresh)
        self._refresh()

    def sizeHint(self) -> QSize:  # noqa: N802 - Qt's name
        return QSize(380, 520)

    @property
    def output(self):
        name = self.layer_combo.currentText()
        return self._store.get(self.viewer.layers[name]) if name in self.viewer.layers else None

    @while_alive
    def _refresh(self, *args) -> None:
        names = [lay.name for lay in self.viewer.layers
                 if isinstance(lay, Labels) and self._store.get(lay) is not None]
        offer(self.layer_combo, names)
        if args and not isinstance(args[0], Labels) and self.result is not None:
            return  # a layer came or went: nothing to recompute
        self.update_reading()

    def update_reading(self):
        """Compute the chosen component's reading in a worker; returns it (None: nothing)."""
        output = self.output
        if output is None or output.ndim == 3:
            self.info.setText("Run the PF-SDM analysis on 2-D objects first."
                              if output is None else "Loadings are shown for 2-D objects.")
            return None
        if self.worker is not None:
            self.worker.quit()
        kind, k = self.kind.currentText(), self.component.value()
        self.info.setText("Computing…")
        worker = _reading_worker(output, kind, k, _ignore_errors=True)
        # the last asked wins: a reading that finishes after a newer one was asked for is
        # dropped, and it does not clear ``worker`` while the newer one runs
        worker.returned.connect(lambda res: self._show(res, kind, k, worker))
        worker.errored.connect(lambda err: self._failed(err, worker))
        worker.finished.connect(lambda: self._done(worker))
        self.worker = worker
        worker.start()
        return worker

    @while_alive
    def _done(self, worker) -> None:
        if self.worker is worker:
            self.worker = None

    @while_alive
    def _failed(self, err, worker) -> None:
        if self.worker is worker:
            self.info.setText(f"No reading: {err}")

    @while_alive
    def _show(self, res, kind: str, k: int, worker) -> None:
        if self.worker is not worker:
            return  # a newer reading was asked for meanwhile
        space, scores, modes, outlines = res
        self.result = res
        maps = space.loadings(k)
        ratio = space.explained_variance_ratio_[k - 1]
        self.figure.clear()
        grid = self.figure.add_gridspec(2, len(SIGMAS), height_ratios=(1.6, 1))
        ax = self.figure.add_subplot(grid[0, :])
        lim = float(np.abs(maps).max()) or 1.0
        im = ax.imshow(maps, cmap="RdBu_r", vmin=-lim, vmax=lim, aspect="auto")
        n_h = maps.shape[1]
        ax.set_xticks(range(n_h), [str(h) for h in range(n_h)], fontsize=6)
        ax.set_xlabel("harmonic: " + ", ".join(f"{h} {w}" for h, w in
                                               enumerate(HARMONIC_WORDS[:4])) + ", …",
                      fontsize=6)
        ax.set_yticks([0, maps.shape[0] - 1], ["centre", "outline"], fontsize=7)
        ax.set_ylabel("ring", fontsize=7)
        ax.set_title(f"PC{k} ({100 * ratio:.0f} %) loadings · {kind}", fontsize=8)
        self.figure.colorbar(im, ax=ax, fraction=0.05, pad=0.02).ax.tick_params(labelsize=6)
        for i, (row, line) in enumerate(zip(modes.itertuples(), outlines, strict=True)):
            a = self.figure.add_subplot(grid[1, i])
            a.plot(line[:, 1], -line[:, 0], lw=1.2)
            a.set_aspect("equal")
            a.set_xticks([])
            a.set_yticks([])
            where = f"f{int(row.frame)} l{int(row.label)}" if "frame" in modes else \
                f"l{int(row.label)}"
            a.set_title(f"{row.sigma:+.0f}σ", fontsize=7)
            a.set_xlabel(where, fontsize=6)
        self.canvas.draw_idle()
        self.info.setText(f"Top: how much each ring (centre to outline) and harmonic weighs in "
                          f"PC{k} ({kind}). Bottom: the real objects nearest −2σ … +2σ "
                          "along it.")


@thread_worker(start_thread=False)
def _reading_worker(output, kind, component):
    return reading(output, kind, component)
