"""Predict each object's outcome from its early frames, in the viewer.

Groups come from a CSV (``label,group`` or ``track_id,group``, as the trajectory plot reads),
from a numeric column of the features (split at a threshold), or from the user: select a label
in the viewer and give it a class (as napari-feature-classifier does). The model is
:func:`napari_pfsdm.analysis.prediction.predict_outcome` (shape, reporter and classic measures
fused late, weights chosen inside each training split), run in a worker with progress and
Cancel. The result: balanced accuracy with its spread next to each channel alone and chance,
the accuracy against the last frame used, and each object's probability of each group written
into the Labels layer's ``features`` and the exported table (``p_<group>``).
"""

from __future__ import annotations

import napari
import numpy as np
import pandas as pd
from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from napari.layers import Labels
from napari.qt.threading import thread_worker
from napari.utils.notifications import show_error
from qtpy.QtCore import QSize
from qtpy.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QProgressBar,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from ..analysis.reduction import read_groups
from . import _layers
from ._alive import offer, while_alive
from ._store import store_for

SOURCES = ("clicked classes", "groups CSV", "numeric column")


class _Stop(Exception):
    """Raised inside the worker when the user pressed Cancel."""


class PredictionWidget(QWidget):
    """Train the nested late-fusion classifier on the frames chosen; show how well it predicts
    and write each object's probabilities into the layer's features."""

    def __init__(self, napari_viewer: napari.viewer.Viewer) -> None:
        super().__init__()
        self.viewer = napari_viewer
        self._store = store_for(napari_viewer)
        self.classes: dict[int, str] = {}  # object id -> group (clicked or read)
        self.result = None
        self.worker = None
        self._stop = False
        self.layer_combo = QComboBox(toolTip="The analysed Labels layer.")
        self.source = QComboBox(toolTip="Where the groups come from.")
        self.source.addItems(SOURCES)
        self.class_name = QLineEdit("multi-axes", toolTip="The class given to the selected "
                                    "label (type a name, then press Give class).")
        self.give_button = QPushButton("Give class to the selected label")
        self.csv_button = QPushButton("Groups CSV…", toolTip="A CSV with columns label,group "
                                      "(or track_id,group).")
        self.column = QComboBox(toolTip="A numeric column of the features: objects above the "
                                "threshold (in the last frame chosen) form one group.")
        self.threshold = QDoubleSpinBox(minimum=-1e12, maximum=1e12, decimals=3,
                                        toolTip="Objects above this value form the group "
                                        "'high', the others 'low'.")
        self.first = QSpinBox(minimum=0, maximum=10_000, toolTip="First frame used.")
        self.last = QSpinBox(minimum=0, maximum=10_000, toolTip="Last frame used: how early "
                             "do you want to predict?")
        self.run_button = QPushButton("Predict")
        self.cancel_button = QPushButton("Cancel", enabled=False)
        self.progress = QProgressBar(minimum=0, maximum=1, value=0)
        self.classes_label = QLabel("No classes yet.", wordWrap=True)
        self.status = QLabel("", wordWrap=True)
        self.figure = Figure(figsize=(3.6, 2.6), constrained_layout=True)
        self.canvas = FigureCanvasQTAgg(self.figure)
        self.canvas.setMinimumSize(260, 170)

        form = self.form = QFormLayout()
        form.addRow("Layer", self.layer_combo)
        form.addRow("Groups from", self.source)
        form.addRow("Class", self.class_name)
        form.addRow("", self.give_button)
        form.addRow("", self.csv_button)
        form.addRow("Column", self.column)
        form.addRow("Threshold", self.threshold)
        frames = QHBoxLayout()
        frames.addWidget(self.first)
        frames.addWidget(QLabel("to"))
        frames.addWidget(self.last)
        form.addRow("Frames", frames)
        buttons = QHBoxLayout()
        buttons.addWidget(self.run_button)
        buttons.addWidget(self.cancel_button)
        layout = QVBoxLayout(self)
        layout.addLayout(form)
        layout.addWidget(self.classes_label)
        layout.addLayout(buttons)
        layout.addWidget(self.progress)
        layout.addWidget(self.canvas, 1)
        layout.addWidget(self.status)

        self.give_button.clicked.connect(self.give_selected_class)
        self.csv_button.clicked.connect(self._csv_dialog)
        self.run_button.clicked.connect(self.run)
        self.cancel_button.clicked.connect(self.cancel)
        self.source.currentTextChanged.connect(self._show_source)
        self.layer_combo.currentTextChanged.connect(self._on_layer)
        self._store.results_changed.connect(self._refresh)
        for event in (napari_viewer.layers.events.inserted, napari_viewer.layers.events.removed):
            event.connect(self._refresh)
        self._refresh()
        self._show_source(self.source.currentText())

    def sizeHint(self) -> QSize:  # noqa: N802 - Qt's name
        return QSize(380, 520)

    # ------------------------------------------------------------------ inputs
    @property
    def layer(self) -> Labels | None:
        name = self.layer_combo.currentText()
        return self.viewer.layers[name] if name in self.viewer.layers else None

    @property
    def output(self):
        return self._store.get(self.layer)

    @while_alive
    def _refresh(self, *args) -> None:
        names = [lay.name for lay in self.viewer.layers
                 if isinstance(lay, Labels) and self._store.get(lay) is not None]
        offer(self.layer_combo, names)
        self._on_layer()

    def _on_layer(self, *args) -> None:
        output = self.output
        if output is None:
            return
        n = int(output.table["frame"].max()) if len(output.table) else 0
        for box in (self.first, self.last):
            box.setMaximum(n)
        if self.last.value() == 0 and n:
            self.last.setValue(n)
        numeric = [c for c in output.table.columns
                   if c not in ("frame", "label", "track_id") and not str(c).startswith(
                       ("shape_r", "intensity_r", "outline_", "surface_", "p_"))
                   and pd.api.types.is_numeric_dtype(output.table[c])
                   and not pd.api.types.is_bool_dtype(output.table[c])]
        if numeric != [self.column.itemText(i) for i in range(self.column.count())]:
            self.column.clear()
            self.column.addItems(numeric)

    def _show_source(self, text: str) -> None:
        """Only the rows of the chosen source (labels included)."""
        clicked, csv, column = (text == s for s in SOURCES)
        for w, shown in ((self.class_name, clicked), (self.give_button, clicked),
                         (self.csv_button, csv), (self.column, column),
                         (self.threshold, column)):
            self.form.setRowVisible(w, shown)

    def object_col(self) -> str:
        out = self.output
        return "track_id" if out is not None and "track_id" in out.table.columns else "label"

    def give_selected_class(self) -> None:
        """Give the label selected in the viewer (in the frame shown) the class typed."""
        layer, output = self.layer, self.output
        name = self.class_name.text().strip()
        if output is None or not name:
            self.status.setText("Run the analysis and type a class name first.")
            return
        frame = _layers.current_frame(self.viewer, layer)
        i = output.row_index(frame, int(layer.selected_label))
        if i is None:
            self.status.setText(f"Label {layer.selected_label} is not in frame {frame}.")
            return
        obj = int(output.table[self.object_col()].iat[i])
        self.classes[obj] = name
        self._show_classes()

    def load_groups(self, path) -> None:
        """Read the groups of a CSV (``label,group`` or ``track_id,group``)."""
        groups = read_groups(path)
        col = "track_id" if "track_id" in groups.columns else "label"
        given = dict(zip(groups[col].astype(int), groups["group"].astype(str), strict=True))
        if col == "label" and self.object_col() == "track_id":
            # a track takes the group of the label it has in its first frame
            table = self.output.table.sort_values("frame")
            first = table.drop_duplicates("track_id")
            given = {int(t): given[int(lab)] for t, lab in
                     zip(first["track_id"], first["label"], strict=True)
                     if int(t) >= 0 and int(lab) in given}
        self.classes = given
        self.source.setCurrentText("groups CSV")
        self._show_classes()

    def _csv_dialog(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Groups CSV", "", "CSV (*.csv)")
        if path:
            try:
                self.load_groups(path)
            except (ValueError, OSError) as err:
                show_error(f"Could not read the group file: {err}")

    def _show_classes(self) -> None:
        counts: dict[str, int] = {}
        for g in self.classes.values():
            counts[g] = counts.get(g, 0) + 1
        self.classes_label.setText(", ".join(f"{g}: {n} objects" for g, n in
                                             sorted(counts.items())) or "No classes yet.")

    def groups(self) -> dict:
        """Object id → group, from the chosen source."""
        if self.source.currentText() != "numeric column":
            return dict(self.classes)
        output, col = self.output, self.column.currentText()
        table = output.table[output.table["frame"] == self.last.value()]
        values = table[col].to_numpy(float)
        ids = table[self.object_col()].to_numpy()
        return {int(o): ("high" if v > self.threshold.value() else "low")
                for o, v in zip(ids, values, strict=True) if np.isfinite(v)}

    # --------------------------------------------------------------------- run
    def run(self):
        """Train and score in a worker; returns it (None when refused)."""
        output = self.output
        if output is None or self.worker is not None:
            self.status.setText("Run the PF-SDM analysis first." if output is None else "")
            return None
        groups = self.groups()
        frames = list(range(self.first.value(), self.last.value() + 1))
        table = output.table
        self._stop = False
        self.run_button.setEnabled(False)
        self.cancel_button.setEnabled(True)
        self.progress.setRange(0, 0)
        self.status.setText("Training on repeated splits…")
        worker = _predict_worker(table, groups, frames, self.object_col(), lambda: self._stop,
                                 _ignore_errors=True)
        worker.yielded.connect(self._on_progress)
        worker.returned.connect(self._on_result)
        worker.errored.connect(self._on_error)
        worker.finished.connect(self._on_finished)
        self.worker = worker
        worker.start()
        return worker

    def cancel(self) -> None:
        self._stop = True

    @while_alive
    def _on_progress(self, value) -> None:
        done, total = value
        self.progress.setRange(0, total)
        self.progress.setValue(done)

    @while_alive
    def _on_error(self, err) -> None:
        if isinstance(err, _Stop):
            self.status.setText("Cancelled; nothing was written.")
            return
        self.status.setText(f"Prediction failed: {err}")
        self.status.setStyleSheet("color: #e05050;")

    @while_alive
    def _on_finished(self) -> None:
        self.worker = None
        self.run_button.setEnabled(True)
        self.cancel_button.setEnabled(False)
        self.progress.setRange(0, 1)

    @while_alive
    def _on_result(self, pred) -> None:
        self.status.setStyleSheet("")
        self.result = pred
        self._write(pred)
        self._draw(pred)
        s = pred.summary
        fused, classic = s.loc["fused"], s.loc["classic alone"] if "classic alone" in s.index \
            else None
        text = (f"Balanced accuracy {fused['mean']:.2f} ± {fused['std']:.2f} over "
                f"{int(fused['n_splits'])} splits from frames {pred.frames[0]}–"
                f"{pred.frames[-1]} (chance 0.50")
        if classic is not None:
            text += f"; classic measures alone {classic['mean']:.2f} ± {classic['std']:.2f}"
        self.status.setText(text + f"). {', '.join(pred.columns())} are in the layer's "
                            "features and the export.")

    def _write(self, pred) -> None:
        """``p_<group>`` for every row of each object, in the table (export) and features."""
        layer, output = self.layer, self.output
        col = self.object_col()
        probs = pred.probabilities.set_index(col)
        ids = output.table[col].to_numpy()
        for name in pred.columns():
            output.table[name] = probs[name].reindex(ids).to_numpy()
        output.derived.pop("layer_features", None)
        features = layer.features
        for name in pred.columns():
            features[name] = output.table[name].to_numpy()
        layer.features = features

    def _draw(self, pred) -> None:
        self.figure.clear()
        ax = self.figure.add_subplot(121 if len(pred.curve) else 111)
        s = pred.summary
        ax.barh(range(len(s)), s["mean"], xerr=s["std"], color="#4c72b0")
        ax.set_yticks(range(len(s)), [str(i) for i in s.index], fontsize=7)
        ax.axvline(0.5, color="k", ls="--", lw=0.8)
        ax.set_xlim(0, 1.05)
        ax.set_xlabel("balanced accuracy", fontsize=7)
        ax.invert_yaxis()
        ax.tick_params(labelsize=7)
        if len(pred.curve):
            ax2 = self.figure.add_subplot(122)
            c = pred.curve
            ax2.errorbar(c["last_frame"], c["mean"], yerr=c["std"], marker="o", ms=3)
            ax2.axhline(0.5, color="k", ls="--", lw=0.8)
            ax2.set_ylim(0, 1.05)
            ax2.set_xlabel("last frame used", fontsize=7)
            ax2.set_title("how early?", fontsize=8)
            ax2.tick_params(labelsize=7)
        self.canvas.draw_idle()


@thread_worker(start_thread=False)
def _predict_worker(table, groups, frames, object_col, stopped):
    """Worker: :func:`predict_outcome`, yielding progress; stops when ``stopped()``."""
    from ..analysis.prediction import predict_outcome

    steps = []

    def progress(done, total):
        if stopped():
            raise _Stop
        steps.append((done, total))

    result = predict_outcome(table, groups, frames, object_col=object_col, progress=progress)
    yield steps[-1] if steps else (1, 1)
    return result
