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

from magicgui.widgets import ComboBox, Container, FileEdit, Label, LineEdit, PushButton, Select
from napari.qt.threading import thread_worker
from napari.utils import progress
from napari.utils.notifications import show_error, show_info, show_warning
from qtpy.QtWidgets import QFileDialog, QSizePolicy, QTabWidget, QVBoxLayout, QWidget

from ..core.units import LENGTHS, TIMES
from ..errors import InputError
from ._jobs import layer_data
from ._study_model import (
    NAME_RULES,
    Study,
    StudyInput,
    pixel_size_of,
    reporter_for,
    reporter_words,
    run_study,
)
from ._study_plots import OverTimeTab, PredictionTab, SimilarTab, TrajectoryTab
from ._widgets import PluginDock, StatusLine, shrinkable

#: The result tabs.
TABS = ("Trajectories", "Over time", "Similar", "Prediction")
#: The movie list's height in rows (it scrolls beyond).
LIST_ROWS = 4
#: "No time unit" in the form.
FRAMES = "(none)"


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
        self._labels_followed: list = []  # (layer, callback) of napari's selected label
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
        self.group_column.native.setMaximumWidth(90)  # a column's name; the file gets the room
        for row, share in ((time_row, 2), (group_row, 1)):  # the text and the file: the room
            row.native.layout().setStretch(0, 3)
            row.native.layout().setStretch(1, share)
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
        self._forget_renames()
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
        self._unfollow_labels()
        self._forget_renames()

    def _forget_renames(self) -> None:
        """Stop following the layers' names (the list of layers changed, or the dock closed)."""
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
        self.reporters.value = reporter_words(found)
        self.reporters.tooltip = ("Each movie's reporter: an Image layer named like the movie "
                                  "(e.g. 'org01 reporter') with its shape; never another "
                                  "movie's.\n" + "\n".join(f"{m} ← {r or 'none'}"
                                                            for m, r in found.items()))
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
        from ..io.times_file import read_times_file
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
            if ending["words"] or self.worker is not worker:  # a count after the Run ended
                return
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
        """A finished Run: its results shown, each movie's rows in its layer's features (once),
        napari's selected label of each movie followed."""
        self._unfollow_labels()
        self.study, self.layer_ids, self.selection = study, dict(ids), None
        for movie, layer in self._study_layers().items():
            layer.features = study.layer_features(movie)

            def picked(event=None, _movie=movie, _layer=layer) -> None:
                self._on_label(_movie, _layer)

            layer.events.selected_label.connect(picked)
            self._labels_followed.append((layer, picked))
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

    def _unfollow_labels(self) -> None:
        for layer, cb in self._labels_followed:
            try:
                layer.events.selected_label.disconnect(cb)
            except (RuntimeError, ValueError, TypeError):
                pass
        self._labels_followed = []

    def _on_label(self, movie: str, layer) -> None:
        """napari's selected label of a study layer changed: it becomes the selection (the
        Similar tab shows the shapes nearest it)."""
        from ._model import current_frame

        frame = current_frame(self.viewer.dims, layer, layer.ndim == 3)
        key = (movie, frame, int(layer.selected_label))
        if self.study is None or key == self.selection or self.study.row_of(*key) is None:
            return
        self.selection = key
        current = self.plots[self.tabs.currentIndex()]
        current.redraw() if isinstance(current, SimilarTab) else current.highlight()

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
        from ..io import write_table

        if self.study is None:
            return None
        try:
            out = write_table(self.study.with_scores(), path)
        except (OSError, InputError) as err:
            self.status.set_text(f"The table could not be written: {err}", True)
            show_error(f"PF-SDM study: the table could not be written: {err}")
            return None
        self.status.set_text(f"Wrote {out}.")
        return out
