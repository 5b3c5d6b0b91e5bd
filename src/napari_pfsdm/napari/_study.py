"""The PF-SDM study dock: several Labels layers (movies) measured as one analysis.

A form (the movies, each one's reporter when an Image layer of its name and shape is there,
the times, the pixel size from each layer's ``scale``, the groups from a file or from the
layers' names), Run and Cancel (a napari worker, napari's progress bar counting the objects
of every movie), then four tabs over the one table keyed by (movie, frame, label):
Trajectories (one shape space), Over time (a measure per group, with the group statistics),
Similar (the nearest shapes across movies) and Prediction (the groups from the features).

A click on a point or a thumbnail shows that object: its Labels layer made visible and active
(the study's other Labels layers hidden: the movies share the canvas), the time slider at its
frame and napari's ``selected_label`` set. Each Run writes each movie's rows into its layer's
``features`` (every frame, with a ``frame`` column), once. The state and the computations are
in :mod:`._study_model` (no Qt).
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
from magicgui.widgets import ComboBox, Container, FileEdit, Label, LineEdit, PushButton, Select
from napari.qt.threading import thread_worker
from napari.utils import progress
from napari.utils.notifications import show_error, show_info, show_warning
from qtpy.QtWidgets import QFileDialog, QSizePolicy, QTabWidget, QVBoxLayout, QWidget

from ..core.units import LENGTHS, TIMES
from ..errors import InputError
from ._canvas import PlotCanvas
from ._jobs import layer_data
from ._study_model import (
    NAME_RULES,
    STAT_CHOICES,
    Study,
    StudyInput,
    pixel_size_of,
    reporter_for,
    run_study,
)
from ._widgets import PluginDock, StatusLine, shrinkable

#: The result tabs.
TABS = ("Trajectories", "Over time", "Similar", "Prediction")
#: The movie list's height in rows (it scrolls beyond).
LIST_ROWS = 4
#: What a plot says before a Run.
EMPTY = "Choose the movies and press Run."
#: "No time unit" in the form.
FRAMES = "(none)"
#: The colours of the groups (matplotlib's tab10, in the order of the sorted groups).
PALETTE = "tab10"


class _Stopped(Exception):
    """The Run was cancelled (raised from the progress callback inside the measuring)."""


@thread_worker(start_thread=False)
def _study_worker(given: StudyInput):
    """Measure the study in a thread of its own, yielding (done, total) every 0.2 s (napari's
    progress bar from the first second); stopped by the worker's quit (the measuring raises
    at its next object)."""
    state = {"done": 0, "total": 0, "stop": False}
    box: dict = {}

    def tick(done: int, total: int, _movie: str) -> None:
        if state["stop"]:
            raise _Stopped
        state["done"], state["total"] = done, total

    def go() -> None:
        try:
            box["result"] = run_study(given, progress=tick)
        except BaseException as err:  # noqa: BLE001 - handed to the worker's thread
            box["error"] = err

    inner = threading.Thread(target=go, daemon=True, name="pfsdm-study")
    inner.start()
    try:
        while inner.is_alive():
            yield state["done"], state["total"]
            inner.join(0.2)
    finally:
        state["stop"] = True  # the worker quit (Cancel): the measuring stops at its next object
    if "error" in box:
        raise box["error"]
    return box["result"]


@thread_worker(start_thread=False)
def _predict_worker(study: Study, frames):
    return study.predict(frames)


@thread_worker(start_thread=False)
def _similar_worker(study: Study, key, k: int):
    return key, study.similar(*key, k=k)


# --------------------------------------------------------------------------- plots
class StudyPlot(PlotCanvas):
    """A napari-matplotlib canvas of the study: its controls, the figure, its words; a click
    on a point (``self.xy``, keyed by ``self.keys``: movie, frame, label) shows that object."""

    def __init__(self, dock: StudyWidget, controls: list) -> None:
        super().__init__(dock.viewer)
        self.dock = dock
        self.keys: list[tuple[str, int, int]] = []
        self.xy = np.zeros((0, 2))
        self.points_axes = None
        self.info = Label(value=EMPTY)
        self.info.native.setWordWrap(True)
        self.info.native.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Maximum)
        self.controls = Container(widgets=controls, layout="horizontal", labels=False)
        self.controls.margins = (0, 0, 0, 0)
        for w in controls:
            if isinstance(w, ComboBox):
                shrinkable(w.native, 8)
        self.layout().insertWidget(0, self.controls.native)
        self.layout().addWidget(self.info.native)
        self.layout().setStretchFactor(self.canvas, 1)
        self.layout().setContentsMargins(2, 2, 2, 2)
        self.canvas.setMinimumHeight(140)
        self.canvas.mpl_connect("button_press_event", self._on_click)

    @property
    def study(self) -> Study | None:
        return self.dock.study

    def redraw(self, *args) -> None:
        """Draw the figure again (new results or choices)."""
        import matplotlib.style as mplstyle

        self.figure.clear()
        self.keys, self.xy, self.points_axes = [], np.zeros((0, 2)), None
        self.marks = []
        try:
            if self.study is None:
                raise InputError(EMPTY)
            with mplstyle.context(self.napari_theme_style_sheet):
                self.draw()
        except (InputError, ValueError) as err:
            self.figure.clear()
            self.info.value = str(err)
        self.changed()
        self.highlight()

    def draw(self) -> None:  # pragma: no cover - each plot draws its own
        raise NotImplementedError

    def highlight(self) -> None:
        """Star the selected object's point."""
        sel = self.dock.selection
        if self.points_axes is None or sel is None or not self.keys:
            self.set_marks([])
            return
        hit = [i for i, k in enumerate(self.keys) if k == sel]
        if not hit:
            self.set_marks([])
            return
        if not hasattr(self, "_star") or self._star.axes is not self.points_axes:
            self._star = self.points_axes.scatter([], [], s=150, marker="*", color="#ff3c3c",
                                                  edgecolors="white", zorder=5)
        self._star.set_offsets(self.xy[hit])
        self.set_marks([self._star])

    def _on_click(self, event) -> None:
        if event.inaxes is None or event.inaxes is not self.points_axes or not self.keys \
                or event.button != 1 or self.toolbar.mode:
            return
        screen = self.points_axes.transData.transform(self.xy)
        i = int(np.argmin(np.hypot(*(screen - (event.x, event.y)).T)))
        self.dock.show_object(*self.keys[i])


def _group_colours(groups) -> dict[str, tuple]:
    import matplotlib

    tab = matplotlib.colormaps[PALETTE]
    names = sorted(set(groups) - {""})
    colours = {g: tab(i % 10) for i, g in enumerate(names)}
    colours[""] = (0.6, 0.6, 0.6, 1.0)
    return colours


class TrajectoryTab(StudyPlot):
    """Each object's path through one shape space (PCA of every movie's rows), coloured by
    group."""

    def __init__(self, dock: StudyWidget) -> None:
        super().__init__(dock, [])

    def draw(self) -> None:
        s = self.study
        paths = s.trajectories()
        ax = self.figure.add_subplot(111)
        colours = _group_colours(paths["group"])
        for _obj, rows in paths.groupby("object", sort=False):
            c = colours[rows["group"].iloc[0]]
            ax.plot(rows["PC1"], rows["PC2"], "-", color=c, lw=0.8, alpha=0.6)
        ax.scatter(paths["PC1"], paths["PC2"], s=12, c=[colours[g] for g in paths["group"]],
                   zorder=3)
        for g, c in colours.items():
            if g and (paths["group"] == g).any():
                ax.plot([], [], "o", color=c, label=g)
        if s.has_groups:
            ax.legend(fontsize=7, loc="best", title="group", title_fontsize=7)
        ratios = s.explained
        pct = [f" ({100 * r:.0f} %)" for r in ratios] + ["", ""]
        ax.set_xlabel(f"shape PC1{pct[0]} (unitless)", fontsize=8)
        ax.set_ylabel(f"shape PC2{pct[1]} (unitless)", fontsize=8)
        ax.tick_params(labelsize=7)
        self.points_axes = ax
        self.xy = paths[["PC1", "PC2"]].to_numpy(float)
        self.keys = [(str(m), int(f), int(lab)) for m, f, lab in
                     paths[["movie", "frame", "label"]].itertuples(index=False)]
        self.info.value = (f"{paths['object'].nunique()} objects of {paths['movie'].nunique()} "
                           "movies in one shape space (PCA of every movie's rows). Click a "
                           "point to show that object.")


class OverTimeTab(StudyPlot):
    """A measure against time: each object's line, each group's mean ± sd, and the group
    statistics of the measure at the last time or of its slope."""

    def __init__(self, dock: StudyWidget) -> None:
        self.measure = ComboBox(choices=[], tooltip="The measure drawn against time.")
        self.stat = ComboBox(choices=list(STAT_CHOICES), value=STAT_CHOICES[0],
                             tooltip="The groups are compared on each object's value at the "
                                     "last time, or on its slope (change per time unit).")
        super().__init__(dock, [self.measure, self.stat])
        self.measure.changed.connect(self.redraw)
        self.stat.changed.connect(self.redraw)
        self.sentences: list[str] = []

    def draw(self) -> None:
        from ..analysis.over_time import plot_over_time
        from ..analysis.physical import column_label, time_label

        s = self.study
        table = s.with_scores()
        with self.measure.changed.blocked():
            chosen = self.measure.value
            self.measure.choices = s.measures()
            if chosen in self.measure.choices:
                self.measure.value = chosen
        column = self.measure.value
        if column is None:
            raise InputError("No measure to draw against time.")
        ax = self.figure.add_subplot(111)
        lines = plot_over_time(ax, table, column)
        ax.set_xlabel(time_label(table), fontsize=8)
        ax.set_ylabel(column_label(table, column), fontsize=8)
        ax.tick_params(labelsize=7)
        self.points_axes = ax
        self.xy = lines[["time", "value"]].to_numpy(float)
        movie_of = dict(zip(s.objects, s.table["movie"].astype(str), strict=True))
        movies = [movie_of[o] for o in lines["object"]]
        self.keys = [(m, int(f), int(lab)) for m, f, lab in
                     zip(movies, lines["frame"], lines["label"], strict=True)]
        try:
            self.sentences = s.group_sentences(column, self.stat.value)
        except InputError as err:
            self.sentences = [str(err)]
        self.info.value = " ".join(self.sentences)
        self.info.tooltip = self.info.value


class SimilarTab(StudyPlot):
    """The selected object's nearest shapes across every movie, as outlines."""

    def __init__(self, dock: StudyWidget) -> None:
        from magicgui.widgets import SpinBox

        self.count = SpinBox(value=7, min=1, max=24, label="shown",
                             tooltip="How many of the nearest other objects are shown.")
        super().__init__(dock, [self.count])
        self.count.changed.connect(self.redraw)
        self.result = None  # ((key, k), [(movie, frame, label, distance, outline)…])
        self.thumbs: list = []
        self.worker = None

    def draw(self) -> None:
        sel = self.dock.selection
        self.thumbs = []
        if sel is None:
            raise InputError("Click an object in Trajectories or Over time (or select a label "
                             "of a study layer) to see the shapes nearest it.")
        want = (sel, int(self.count.value))
        if self.result is None or self.result[0] != want:
            self._compute(*want)
            self.info.value = "Finding the nearest shapes in the background…"
            return
        found = self.result[1]
        n = len(found)
        cols = min(4, n)
        rows = -(-n // cols)
        for i, (movie, t, lab, d, line) in enumerate(found):
            ax = self.figure.add_subplot(rows, cols, i + 1)
            ax.plot(line[:, 1], -line[:, 0], lw=1.4, color="#ff3c3c" if i == 0 else None)
            ax.set(aspect="equal", xticks=[], yticks=[])
            ax.set_title(f"{movie} f{t} l{lab}\n" + ("(this one)" if i == 0 else f"d={d:.3g}"),
                         fontsize=6)
            self.thumbs.append((ax, (movie, int(t), int(lab))))
        self.info.value = (f"The {n - 1} other objects nearest in shape to {sel[0]} frame "
                           f"{sel[1]} label {sel[2]}, from every movie, each in its nearest "
                           "frame (PF-SDM distance, unitless). Click one to show it.")

    def _compute(self, key, k: int) -> None:
        if self.worker is not None:
            return
        self.worker = _similar_worker(self.study, key, k, _ignore_errors=True)

        def done(result):
            key_, found = result
            self.result = ((key_, k), found)

        def failed(err):
            self.result = ((key, k), [])
            self.info.value = f"The nearest shapes could not be found: {err}"

        def finished():
            self.worker = None
            if self.isVisible():
                self.redraw()

        self.worker.returned.connect(done)
        self.worker.errored.connect(failed)
        self.worker.finished.connect(finished)
        self.worker.start()

    def _on_click(self, event) -> None:
        if event.button != 1 or self.toolbar.mode:
            return
        for ax, key in self.thumbs:
            if event.inaxes is ax:
                self.dock.show_object(*key)
                return


class PredictionTab(StudyPlot):
    """Each object's group predicted from its features at the chosen frames: balanced
    accuracy per family and fused, and the confusion matrix."""

    def __init__(self, dock: StudyWidget) -> None:
        self.frames = Select(choices=[], tooltip="The frames whose features are used "
                             "(none chosen: every frame).")
        self.frames.native.setMaximumHeight(52)
        self.go = PushButton(text="Predict", tooltip="Predict each object's group "
                             "(cross-validated: all frames of an object on one side).")
        self.go.changed.connect(self.start)
        super().__init__(dock, [self.frames, self.go])
        self.prediction = None
        self.worker = None

    def set_frames(self, frames: list[int]) -> None:
        self.frames.choices = [(f"frame {f}", f) for f in frames]
        self.prediction = None

    def start(self, *args):
        if self.study is None or self.worker is not None:
            return None
        self.worker = _predict_worker(self.study, list(self.frames.value) or None,
                                      _ignore_errors=True)
        self.info.value = "Predicting the groups in the background…"

        def done(result):
            self.prediction = result

        def failed(err):
            self.prediction = None
            show_error(f"PF-SDM study: the prediction stopped: {err}")
            self.info.value = f"The prediction stopped: {err}"

        def finished():
            self.worker = None
            if self.prediction is not None:
                self.redraw()

        self.worker.returned.connect(done)
        self.worker.errored.connect(failed)
        self.worker.finished.connect(finished)
        self.worker.start()
        return self.worker

    def draw(self) -> None:
        from ..analysis.outcome import FAMILY_WORDS

        p = self.prediction
        if p is None:
            raise InputError("Choose frames (none: every frame) and press Predict: each "
                             "object's group from its features, cross-validated.")
        summary = p.summary
        methods = [m for m in summary.index if m != "chance"]
        ax = self.figure.add_subplot(1, 2, 1)
        names = [m.replace(" alone", "") for m in methods]
        names = [FAMILY_WORDS.get(n, n) for n in names]
        ax.barh(names, summary.loc[methods, "mean"], xerr=summary.loc[methods, "std"],
                color="#4c9be8")
        chance = float(summary.loc["chance", "mean"]) if "chance" in summary.index else None
        if chance is not None:
            ax.axvline(chance, color="#ff3c3c", ls="--", lw=1)
        ax.set_xlim(0, 1)
        ax.set_xlabel("balanced accuracy (0–1)", fontsize=8)
        ax.tick_params(labelsize=7)
        cm = self.figure.add_subplot(1, 2, 2)
        m = p.confusion.to_numpy(float)
        cm.imshow(m, cmap="Blues")
        cm.set_xticks(range(m.shape[1]), [str(c) for c in p.confusion.columns], fontsize=7,
                      rotation=45)
        cm.set_yticks(range(m.shape[0]), [str(r) for r in p.confusion.index], fontsize=7)
        for (i, j), v in np.ndenumerate(m):
            cm.text(j, i, f"{v:.0f}", ha="center", va="center", fontsize=7,
                    color="white" if v > m.max() / 2 else "black")
        cm.set_xlabel("predicted group", fontsize=8)
        cm.set_ylabel("true group", fontsize=8)
        fused = summary.loc["fused", "mean"] if "fused" in summary.index else float("nan")
        self.info.value = (f"{p.n_scored} objects with a group scored: fused balanced accuracy "
                           f"{fused:.2f} (chance {chance:.2f}, red line); confusion matrix of "
                           "the fused model over the test splits (object counts).")


# --------------------------------------------------------------------------- the dock
class StudyWidget(PluginDock):
    """Dock: several Labels layers as one PF-SDM study."""

    def __init__(self, napari_viewer) -> None:
        super().__init__(napari_viewer)
        self.study: Study | None = None
        self.selection: tuple[str, int, int] | None = None
        self.worker = None
        self.layer_ids: dict[str, str] = {}  # movie → its Labels layer's unique id (the Run's)
        self._make_form()
        self.status = StatusLine("Choose two or more Labels layers (one movie each) and Run.")
        self.tabs = QTabWidget()
        self.plots = [TrajectoryTab(self), OverTimeTab(self), SimilarTab(self),
                      PredictionTab(self)]
        for name, plot in zip(TABS, self.plots, strict=True):
            page = QWidget()
            lay = QVBoxLayout(page)
            lay.setContentsMargins(0, 0, 0, 0)
            lay.addWidget(plot)
            self.tabs.addTab(page, name)
        outer = QVBoxLayout(self)
        outer.setContentsMargins(0, 0, 0, 0)
        outer.setSpacing(2)
        outer.addWidget(self.form.native)
        outer.addWidget(self.status)
        outer.addWidget(self.tabs, 1)
        self.setSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Expanding)
        self.tabs.currentChanged.connect(lambda i: self.plots[i].redraw())
        for emitter in (napari_viewer.layers.events.inserted, napari_viewer.layers.events.removed,
                        napari_viewer.layers.events.moved):
            self.follow(emitter, self._on_layers)
        self._renames: list = []
        self._on_layers()

    # ------------------------------------------------------------------ the form
    def _make_form(self) -> None:
        self.movies = Select(choices=[], label="Movies", tooltip="The Labels layers of the "
                             "study: one movie (T × Y × X) each; Ctrl/Shift-click for several.")
        self.reporters = Label(value="", label="Reporters")
        self.reporters.native.setWordWrap(True)
        self.reporters.native.setSizePolicy(QSizePolicy.Policy.Ignored,
                                            QSizePolicy.Policy.Preferred)
        self.times = LineEdit(value="", label="Times", tooltip="The frames' times, the same "
                              "for every movie: 2,5,8,10,… (blank: the frame numbers, or the "
                              "times file).")
        self.time_unit = ComboBox(choices=[FRAMES, *TIMES], value=FRAMES, label="unit",
                                  tooltip="The times' unit.")
        self.times_file = FileEdit(mode="r", filter="*.csv", label="Times file", value="",
                                   tooltip="A CSV with the columns movie, frame, time (instead "
                                           "of the times above).")
        self.space_unit = ComboBox(choices=list(LENGTHS), value="µm", label="Pixel unit",
                                   tooltip="The unit of the layers' scale (the pixel size), "
                                           "when napari gives none.")
        self.pixel_words = Label(value="")
        self.groups_file = FileEdit(mode="r", filter="*.csv", label="Groups file", value="",
                                    tooltip="A CSV naming each movie's group (movie,clone,…).")
        self.group_column = ComboBox(choices=[], label="column",
                                     tooltip="The groups file's column that holds the groups.")
        self.name_rule = ComboBox(choices=list(NAME_RULES.items()), value="prefix",
                                  label="Groups from names",
                                  tooltip="Without a groups file: each movie's group from its "
                                          "layer's name (e.g. 'c1_org03' → 'c1').")
        self.run_button = PushButton(text="Run", tooltip="Measure every chosen movie.")
        self.cancel_button = PushButton(text="Cancel", enabled=False)
        self.export_button = PushButton(text="Export CSV…", enabled=False,
                                        tooltip="Write the study's table (CSV and its JSON "
                                                "sidecar).")
        time_row = Container(widgets=[self.times, self.time_unit], layout="horizontal",
                             label="Times", labels=False)
        group_row = Container(widgets=[self.groups_file, self.group_column],
                              layout="horizontal", label="Groups file", labels=False)
        space_row = Container(widgets=[self.space_unit, self.pixel_words], layout="horizontal",
                              label="Pixel unit", labels=False)
        buttons = Container(widgets=[self.run_button, self.cancel_button, self.export_button],
                            layout="horizontal", labels=False)
        for row in (time_row, group_row, space_row, buttons):
            row.margins = (0, 0, 0, 0)
        self.form = Container(widgets=[self.movies, self.reporters, time_row, self.times_file,
                                       space_row, group_row, self.name_rule, buttons])
        self.form.margins = (4, 2, 4, 0)
        self.movies.native.setMaximumHeight(LIST_ROWS * 18 + 6)
        for combo in (self.time_unit, self.space_unit, self.group_column, self.name_rule):
            shrinkable(combo.native, 5)
        self.movies.changed.connect(self._on_movies)
        self.groups_file.changed.connect(self._on_groups_file)
        self.run_button.changed.connect(self.run)
        self.cancel_button.changed.connect(self.cancel)
        self.export_button.changed.connect(self._ask_export)

    def _labels(self) -> dict:
        from napari.layers import Labels

        return {lay.name: lay for lay in self.viewer.layers if isinstance(lay, Labels)}

    def _images(self) -> list:
        from napari.layers import Image

        return [lay for lay in self.viewer.layers if isinstance(lay, Image)]

    def _on_layers(self, event=None) -> None:
        """Layers added, removed, moved or renamed: the movie list follows."""
        for layer, cb in self._renames:
            try:
                layer.events.name.disconnect(cb)
            except (RuntimeError, ValueError, TypeError):
                pass
        self._renames = []
        for layer in self.viewer.layers:
            layer.events.name.connect(self._on_layers)
            self._renames.append((layer, self._on_layers))
        chosen = list(self.movies.value)
        names = list(self._labels())
        with self.movies.changed.blocked():
            self.movies.choices = names
            self.movies.value = [n for n in chosen if n in names]
        self._on_movies()

    def release(self) -> None:
        super().release()
        for layer, cb in self._renames:
            try:
                layer.events.name.disconnect(cb)
            except (RuntimeError, ValueError, TypeError):
                pass
        self._renames = []

    def reporter_names(self) -> dict[str, str | None]:
        """Each chosen movie's reporter layer (None: no Image layer of its name and shape)."""
        labels = self._labels()
        images = [(im.name, layer_data(im).shape) for im in self._images()]
        chosen = list(self.movies.value)
        return {m: reporter_for(m, layer_data(labels[m]).shape, images, list(labels))
                for m in chosen if m in labels}

    def _on_movies(self, *args) -> None:
        found = self.reporter_names()
        if not found:
            self.reporters.value = "(choose movies)"
        else:
            self.reporters.value = "; ".join(f"{m} ← {r}" if r else f"{m}: none"
                                             for m, r in found.items())
        self.reporters.tooltip = ("Each movie's reporter: an Image layer named like the movie "
                                  "(e.g. 'org01 reporter') with its shape; never another "
                                  "movie's.\n" + self.reporters.value)
        self.pixel_words.value = self._pixel_words()

    def _pixel_words(self) -> str:
        labels = self._labels()
        sizes = []
        for m in self.movies.value:
            if m in labels:
                try:
                    sizes.append(f"{pixel_size_of(labels[m].scale):g}")
                except InputError:
                    sizes.append("?")
        return ("px " + ", ".join(dict.fromkeys(sizes))) if sizes else ""

    def _on_groups_file(self, *args) -> None:
        import pandas as pd

        from ..analysis.groups import KEY_COLUMNS

        path = self._path(self.groups_file)
        columns: list[str] = []
        if path is not None:
            try:
                header = pd.read_csv(path, nrows=0, dtype=str, encoding="utf-8-sig")
                columns = [str(c).strip() for c in header.columns
                           if str(c).strip().lower() not in KEY_COLUMNS]
            except (OSError, ValueError) as err:
                self.status.set_text(f"The groups file could not be read: {err}", True)
        self.group_column.choices = columns
        if "group" in columns:
            self.group_column.value = "group"

    @staticmethod
    def _path(edit: FileEdit) -> Path | None:
        value = edit.value
        if value is None or str(value) in ("", "."):
            return None
        return Path(value)

    def _space_unit(self, layers) -> str:
        """The pixel size's unit: napari's ``layer.units`` when it has one that is not
        'pixel', else the form's."""
        for layer in layers:
            units = getattr(layer, "units", None)
            if units:
                unit = str(units[-1])
                if unit not in ("pixel", "px", "pixels"):
                    from ..core.units import space_unit

                    try:
                        return space_unit(unit.replace("micrometer", "µm"))[0]
                    except InputError:
                        pass
        return self.space_unit.value

    def gather(self) -> StudyInput:
        """What a Run measures, read from the form and the layers (refused in words)."""
        from ..analysis.groups import read_groups
        from ..batch.calibration import read_times_file
        from ._study_model import name_groups, parse_times, times_per_movie

        labels = self._labels()
        chosen = [m for m in self.movies.value if m in labels]
        if not chosen:
            raise InputError("choose one or more Labels layers (the movies) in the list")
        layers = [labels[m] for m in chosen]
        movies = {m: layer_data(labels[m]) for m in chosen}
        names = {im.name: im for im in self._images()}
        reporters = {m: layer_data(names[r]) for m, r in self.reporter_names().items()
                     if r is not None}
        times_file = self._path(self.times_file)
        times = None
        if times_file is not None:
            frames = {m: (a.shape[0] if a.ndim == 3 else 1) for m, a in movies.items()}
            times = times_per_movie(read_times_file(times_file), frames)
        elif self.times.value.strip():
            times = parse_times(self.times.value)
        unit = self.time_unit.value if self.time_unit.value != FRAMES else None
        if times is not None and unit is None:
            raise InputError("choose the times' unit (e.g. day) beside the times")
        sizes = {m: pixel_size_of(lay.scale) for m, lay in zip(chosen, layers, strict=True)}
        if all(s == 1.0 for s in sizes.values()) and not any(
                getattr(lay, "units", None) and str(lay.units[-1]) not in ("pixel", "px")
                for lay in layers):
            sizes = None  # no scale set: sizes in pixels
        groups_path = self._path(self.groups_file)
        groups = read_groups(groups_path, self.group_column.value or None) \
            if groups_path is not None else None
        by_name = name_groups(chosen, self.name_rule.value) if groups is None else {}
        return StudyInput(movies=movies, reporters=reporters, times=times, time_unit=unit,
                          pixel_sizes=sizes, space_unit=self._space_unit(layers)
                          if sizes else None, groups=groups, name_groups=by_name)

    # ------------------------------------------------------------------ Run
    def run(self, *args):
        """Start a Run (returns its worker; None when the form is refused)."""
        if self.worker is not None:
            return None
        try:
            given = self.gather()
        except InputError as err:
            self.status.set_text(str(err), True)
            show_error(f"PF-SDM study: {err}")
            return None
        labels = self._labels()
        ids = {m: labels[m].unique_id for m in given.movies}
        worker = _study_worker(given, _ignore_errors=True)
        bar = progress(total=0, desc="PF-SDM study")
        ending = {"words": None}

        def count(value):
            done, total = value
            if total:
                bar.total = total
                bar.update(done - bar.n)
                self.status.set_text(f"Measuring {len(ids)} movies: {done:,} of {total:,} "
                                     "objects (napari's activity panel, bottom right).")

        def removed(event):
            if getattr(event.value, "unique_id", None) in ids.values():
                ending["words"] = (f"The Labels layer '{event.value.name}' was removed during "
                                   "the Run: nothing was kept.")
                worker.quit()

        def done(study):
            missing = [m for m, i in ids.items() if not any(
                lay.unique_id == i for lay in self.viewer.layers)]
            if missing:
                ending["words"] = (f"The Labels layer '{missing[0]}' was removed during the "
                                   "Run: nothing was kept.")
                return
            self.take(study, ids)

        def failed(err):
            words = f"The study stopped: {err}"
            self.status.set_text(words, True)
            show_error(f"PF-SDM study: {words}")

        def finished():
            bar.close()
            try:
                self.viewer.layers.events.removed.disconnect(removed)
            except (RuntimeError, ValueError, TypeError):
                pass
            self.worker = None
            self.run_button.enabled, self.cancel_button.enabled = True, False
            if ending["words"]:
                self.status.set_text(ending["words"], True)
                show_warning(f"PF-SDM study: {ending['words']}")

        def aborted():
            if not ending["words"]:
                ending["words"] = "Cancelled: nothing was kept."

        worker.yielded.connect(count)
        worker.returned.connect(done)
        worker.errored.connect(failed)
        worker.aborted.connect(aborted)
        worker.finished.connect(finished)
        self.viewer.layers.events.removed.connect(removed)
        self.worker = worker
        self.run_button.enabled, self.cancel_button.enabled = False, True
        self.status.set_text(f"Counting the objects of {len(ids)} movies…")
        worker.start()
        return worker

    def cancel(self, *args) -> None:
        if self.worker is not None:
            self.worker.quit()

    def take(self, study: Study, ids: dict[str, str]) -> None:
        """A finished Run: its results shown, each movie's rows in its layer's features."""
        self.study, self.layer_ids, self.selection = study, dict(ids), None
        for movie, layer in self._study_layers().items():
            layer.features = study.layer_features(movie)
        self.plots[3].set_frames(study.frames())
        self.plots[2].result = None
        self.export_button.enabled = True
        self.status.set_text(study.summary() + ". Click a point to show that object.")
        show_info(f"PF-SDM study: {len(study.table)} object-frames of "
                  f"{study.table['movie'].nunique()} movies measured.")
        self.plots[self.tabs.currentIndex()].redraw()

    def _study_layers(self) -> dict:
        """Movie → its Labels layer (those still in the viewer)."""
        by_id = {lay.unique_id: lay for lay in self.viewer.layers}
        return {m: by_id[i] for m, i in self.layer_ids.items() if i in by_id}

    # ------------------------------------------------------------------ a click
    def show_object(self, movie: str, frame: int, label: int) -> None:
        """Show (movie, frame, label): its layer visible and active (the study's other Labels
        layers hidden), the time slider at its frame, napari's selected label set."""
        layers = self._study_layers()
        layer = layers.get(movie)
        if layer is None:
            self.status.set_text(f"The Labels layer of {movie} is no longer in the viewer.",
                                 True)
            return
        for other_movie, other in layers.items():
            if other_movie != movie:
                other.visible = False
        layer.visible = True
        self.viewer.layers.selection.active = layer
        if layer.ndim == 3:
            axis = self.viewer.dims.ndim - layer.ndim
            self.viewer.dims.set_point(axis, layer.translate[0] + frame * layer.scale[0])
        layer.selected_label = int(label)
        self.selection = (movie, int(frame), int(label))
        current = self.plots[self.tabs.currentIndex()]
        if isinstance(current, SimilarTab):
            current.redraw()
        else:
            current.highlight()
        self.status.set_text(f"Shown: {movie}, frame {frame}, label {label}.")

    # ------------------------------------------------------------------ export
    def _ask_export(self, *args) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "Export the study's table",
                                              "study.csv", "CSV (*.csv)")
        if path:
            self.export(path)

    def export(self, path) -> Path | None:
        """Write the study's table (with its shape PC scores) as CSV with its sidecar."""
        from ..io import write_table_csv

        if self.study is None:
            return None
        try:
            out = write_table_csv(self.study.with_scores(), path)
        except (OSError, InputError) as err:
            self.status.set_text(f"The table could not be written: {err}", True)
            show_error(f"PF-SDM study: the table could not be written: {err}")
            return None
        self.status.set_text(f"Wrote {out}.")
        return out
