"""The study dock's tabs: Trajectories (one shape space of every movie), Over time (a measure
per group with the group statistics), Similar (the nearest shapes across movies) and Prediction
(the groups from the features). Each is a napari-matplotlib canvas over the dock's
:class:`~._study_model.Study`, its points keyed by (movie, frame, label); a click on a point or
a thumbnail asks the dock to show that object (:meth:`._study.StudyWidget.show_object`)."""

from __future__ import annotations

import numpy as np
from magicgui.widgets import ComboBox, Container, Label, PushButton, Select, SpinBox
from napari.qt.threading import thread_worker
from napari.utils.notifications import show_error
from qtpy.QtWidgets import QSizePolicy

from ..errors import InputError
from ._canvas import PlotCanvas
from ._study_model import STAT_CHOICES, Study
from ._widgets import shrinkable

#: What a plot says before a Run.
EMPTY = "Choose the movies and press Run."
#: The colours of the groups (matplotlib's tab10, in the order of the sorted groups).
PALETTE = "tab10"


@thread_worker(start_thread=False)
def _predict_worker(study: Study, frames):
    return study.predict(frames)


@thread_worker(start_thread=False)
def _similar_worker(study: Study, key, k: int):
    return key, study.similar(*key, k=k)


# --------------------------------------------------------------------------- plots
class StudyPlot(PlotCanvas):
    """A napari-matplotlib canvas of the study: its controls, the figure, its words; a click
    on a point (``self.xy``, keyed by ``self.keys``: movie, frame, label) shows that object.
    ``dock`` is the :class:`~._study.StudyWidget` (its ``study``, ``selection`` and
    ``show_object``)."""

    def __init__(self, dock, controls: list) -> None:
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

    def __init__(self, dock) -> None:
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

    def __init__(self, dock) -> None:
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

    def __init__(self, dock) -> None:
        self.count = SpinBox(value=7, min=1, max=24, label="shown",
                             tooltip="How many of the nearest other objects are shown.")
        super().__init__(dock, [self.count])
        self.count.changed.connect(self.redraw)
        self.result = None  # ((key, k), [(movie, frame, label, distance, outline)…])
        self.thumbs: list = []
        self.worker = None
        self.failure = ""  # why the last search found nothing

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
        if not found:
            raise InputError(self.failure or "No object has features to compare with.")
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
            self.result, self.failure = ((key_, k), found), ""

        def failed(err):
            self.result = ((key, k), [])
            self.failure = f"The nearest shapes could not be found: {err}"

        def finished():
            self.worker = None
            self.redraw()  # drawn on screen when shown (PlotCanvas)

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

    def __init__(self, dock) -> None:
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
