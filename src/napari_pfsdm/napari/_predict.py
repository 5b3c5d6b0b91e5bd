"""The prediction dock (Layers ▸ Classify): predict each object's outcome from early frames.

Groups come from the plugin's model (a groups CSV, the layer's ``metadata["groups"]``) or from
clicks: select a label in the viewer and give it a class. The model is the paper's late fusion,
:func:`napari_pfsdm.analysis.outcome.predict_outcome` (weights chosen inside each training
split), run in a napari worker with Cancel. Each object's probabilities go into the table, the
layer's ``features`` and the export (``p_<group>``).
"""

from __future__ import annotations

from collections import Counter
from functools import partial

from magicgui.widgets import ComboBox, Container, Label, LineEdit, PushButton, SpinBox
from napari.qt.threading import thread_worker
from napari.utils.notifications import show_info
from qtpy.QtWidgets import QFileDialog, QSizePolicy

from ._canvas import PlotCanvas
from ._model import REGISTRY, Analysis, current_frame
from ._results import plural
from ._widgets import PluginDock, StatusLine, analysed_layers, head_row, scrolled, stack


def read_groups_csv(path, analysis: Analysis) -> dict[int, str]:
    """Object → group from a CSV with ``label,group`` or ``track_id,group`` columns; on a
    linked time-lapse a label names the track it starts."""
    from ..analysis.groups import read_groups

    groups = read_groups(path)
    col = "track_id" if "track_id" in groups.columns else "label"
    if col not in groups.columns:
        raise ValueError("The group file needs a 'label' (or 'track_id') column and a "
                         "'group' column, e.g. 3,multi-axes.")
    given = dict(zip(groups[col].astype(int), groups["group"].astype(str), strict=True))
    table = analysis.table
    if col == "label" and "track_id" in table and not (table["track_id"] == table["label"]).all():
        first = table.sort_values("frame").drop_duplicates("track_id")
        given = {int(t): given[int(lab)] for t, lab in zip(first["track_id"], first["label"],
                                                           strict=True)
                 if int(t) >= 0 and int(lab) in given}
    return given


class _Stop(Exception):
    """Raised in the worker when Cancel was pressed."""


@thread_worker(start_thread=False)
def _predict(analysis: Analysis, table, groups, frames, object_col, stopped):
    """The prediction from ``table`` (the analysis's when the prediction started), and that
    table with its probabilities, indexed, with the layer's features made from it (the GUI
    thread only shows them)."""
    from ..analysis.outcome import predict_outcome

    def progress(done, total):
        if stopped():
            raise _Stop

    pred = predict_outcome(table, groups, frames, object_col=object_col, progress=progress)
    return pred, scored_analysis(analysis, table, pred, object_col)


def scored_analysis(analysis: Analysis, table, prediction, object_col: str) -> Analysis:
    """``analysis`` with ``table`` and its probabilities, indexed, with the layer's features."""
    scored = analysis.with_table(prediction.on_rows(table, object_col))
    scored.layer_features()  # made here, in the worker
    return scored


class PredictionWidget(PluginDock):
    """Dock: train on the frames chosen, show how well each channel predicts, write p_<group>."""

    def __init__(self, napari_viewer) -> None:
        super().__init__(napari_viewer)
        self.plot = PlotCanvas(napari_viewer)
        self.figure, self.canvas = self.plot.figure, self.plot.canvas
        self.layer_choice = ComboBox(label="Layer", choices=partial(analysed_layers, napari_viewer),
                                     tooltip="The analysed Labels layer.")
        self.class_name = LineEdit(label="Class", value="multi-axes",
                                   tooltip="Type a class, select a label, press Give class.")
        self.give = PushButton(text="Give class to the selected label")
        self.csv = PushButton(text="Groups CSV…", tooltip="label,group or track_id,group")
        self.first = SpinBox(label="First frame", min=0, max=100_000, value=0)
        self.last = SpinBox(label="Last frame", min=0, max=100_000, value=4,
                            tooltip="How early do you want to predict?")
        self.run_button = PushButton(text="Predict")
        self.cancel_button = PushButton(text="Cancel", enabled=False)
        self.classes = Label(value="No classes yet.")
        self.classes.native.setWordWrap(True)
        self.classes.native.setSizePolicy(QSizePolicy.Policy.Ignored,
                                          QSizePolicy.Policy.Preferred)
        self.status = StatusLine()
        self.form = Container(widgets=[self.class_name, self.give, self.csv, self.first,
                                       self.last, self.classes])
        self.canvas.setFixedHeight(200)
        # the layer, Predict and Cancel, and the status stay on screen; the rest scrolls
        head = head_row("Layer", self.layer_choice, self.run_button, self.cancel_button)
        stack(self, head, self.status, scrolled(self.form.native, self.plot, minimum=24,
                                                margins=True))
        # a plots dock beside gets the room this one does not need (its content scrolls)
        self.setSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Maximum)
        self.worker = None
        self._stop = False
        self.give.changed.connect(self.give_selected_class)
        self.csv.changed.connect(self._csv_dialog)
        self.run_button.changed.connect(self.run)
        self.cancel_button.changed.connect(self.cancel)
        self.layer_choice.changed.connect(self._show_classes)
        self.follow(REGISTRY.updated, self._refresh)
        self.follow(napari_viewer.layers.events.removed, self._refresh)
        self._refresh()

    def _refresh(self, *args) -> None:
        self.layer_choice.reset_choices()
        self._show_classes()

    @property
    def layer(self):
        name = self.layer_choice.value
        return self.viewer.layers[name] if name and name in self.viewer.layers else None

    @property
    def analysis(self) -> Analysis | None:
        layer = self.layer
        return REGISTRY.get(layer.unique_id) if layer is not None else None

    def object_col(self) -> str:
        a = self.analysis
        return "track_id" if a is not None and "track_id" in a.table else "label"

    def give_selected_class(self, *args) -> None:
        """The label selected in the viewer (in the frame shown) gets the class typed."""
        a, layer, name = self.analysis, self.layer, self.class_name.value.strip()
        if a is None or not name:
            self.status.value = "Run the analysis and type a class name first."
            return
        frame = current_frame(self.viewer.dims, layer, a.time_lapse)
        i = a.row_of(frame, int(layer.selected_label))
        if i is None:
            self.status.value = f"Label {layer.selected_label} is not in frame {frame}."
            return
        a.set_groups({**a.groups, int(a.table[self.object_col()].iat[i]): name})
        self._show_classes()

    def _csv_dialog(self, *args) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Groups CSV", "", "CSV (*.csv)")
        if path and self.analysis is not None:
            try:
                self.analysis.set_groups(read_groups_csv(path, self.analysis))
            except (ValueError, OSError) as err:
                self.status.value = f"Could not read the group file: {err}"
            self._show_classes()

    def _show_classes(self, *args) -> None:
        a = self.analysis
        counts = Counter(a.groups.values() if a is not None else [])
        self.classes.value = ", ".join(f"{g}: {plural(n, 'object')}"
                                       for g, n in sorted(counts.items())) \
            or "No classes yet: give classes or read a groups CSV."

    def run(self, *args):
        """Train and score in a worker; returns it (None when refused)."""
        a = self.analysis
        if a is None or self.worker is not None:
            self.status.value = "Run the PF-SDM analysis first." if a is None else ""
            return None
        frames = list(range(self.first.value, self.last.value + 1))
        self._stop = False
        col, table = self.object_col(), a.table
        self.worker = worker = _predict(a, table, dict(a.groups), frames, col,
                                        lambda: self._stop, _ignore_errors=True)

        def show(out):
            pred, scored = out
            if a.table is not table:  # new identities meanwhile: their table gets the scores
                scored = scored_analysis(a, a.table, pred, col)
            self._show(a, pred, scored)

        worker.returned.connect(show)
        worker.errored.connect(self._failed)
        worker.finished.connect(self._finished)
        self.run_button.enabled, self.cancel_button.enabled = False, True
        self.status.value = "Training on repeated splits…"
        worker.start()
        return worker

    def cancel(self, *args) -> None:
        self._stop = True

    def _failed(self, err) -> None:
        self.status.value = "Cancelled; nothing was written." if isinstance(err, _Stop) \
            else f"Prediction failed: {err}"

    def _finished(self) -> None:
        self.worker = None
        self.run_button.enabled, self.cancel_button.enabled = True, False

    def _show(self, a: Analysis, pred, scored: Analysis) -> None:
        a.set_prediction(pred, scored)  # the model writes the layer's new features
        s = pred.summary
        fused = s.loc["fused"]
        self.status.value = (
            f"Balanced accuracy {fused['mean']:.2f} ± {fused['std']:.2f} over "
            f"{int(fused['n_splits'])} splits from frames {pred.frames[0]}–{pred.frames[-1]} "
            f"(chance 0.50). {', '.join(pred.columns())} are in the layer's features and the "
            "export.")
        show_info("PF-SDM: prediction done.")
        self.figure.clear()
        ax = self.figure.add_subplot(121 if len(pred.curve) else 111)
        ax.barh(range(len(s)), s["mean"], xerr=s["std"], color="#4c72b0")
        ax.set_yticks(range(len(s)), [str(i) for i in s.index], fontsize=7)
        ax.axvline(0.5, color="grey", ls="--", lw=0.8)
        ax.set_xlim(0, 1.05)
        ax.set_xlabel("balanced accuracy", fontsize=7)
        ax.invert_yaxis()
        if len(pred.curve):
            c = pred.curve
            ax2 = self.figure.add_subplot(122)
            ax2.errorbar(c["last_frame"], c["mean"], yerr=c["std"], marker="o", ms=3)
            ax2.axhline(0.5, color="grey", ls="--", lw=0.8)
            ax2.set_ylim(0, 1.05)
            ax2.set_xlabel("last frame used", fontsize=7)
            ax2.set_title("how early?", fontsize=8)
        for axis in self.figure.axes:
            axis.tick_params(labelsize=7)
        self.plot.changed()
