"""Plots linked to the viewer: PCA trajectories and the shape comparison (distances + MDS).

Both read the last analysis of a Labels layer from the store. Clicking a point moves the time
slider to that frame and selects that label; moving the slider or selecting a label highlights
the matching points.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import NamedTuple

import napari
import numpy as np
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure
from matplotlib.text import Text
from napari.layers import Labels
from napari.qt.threading import thread_worker
from napari.utils.notifications import show_error
from qtpy.QtCore import QSize, QTimer
from qtpy.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFileDialog,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from ..analysis.reduction import read_groups
from ..core.table_schema import has_channel
from . import _layers
from ._alive import next_turn, offer
from ._canvas import DRAW_BUDGET_S, PlotCanvas
from ._compute import classical_mds, explanation, objects_of
from ._density import density_image, padded_extent
from ._graph import GRAPH_ROWS
from ._store import same_layer, store_for

#: A click selects the nearest point closer than this (screen pixels).
PICK_RADIUS_PX = 12
#: Above this many points the plots draw them as one density image (:mod:`._density`).
MANY_POINTS = 5000
#: The selected object's track is drawn thin and translucent above this many frames (the
#: 200 frames of a blob in the 47,700-object movie hid the density map under a 2.2 pt line).
LONG_TRACK = 50
#: Bars of the nearest-shapes panel (neighbour-graph view).
NEAREST_SHOWN = 10
RERANK_TIP = ("Re-rank the distances through the whole collection (diffusion on the "
              "10-nearest-neighbour graph, napari_pfsdm.rerank): helps find similar shapes "
              "among many objects with several of each kind (MPEG-7: 79.5 → 88.7 % "
              "bull's-eye); hurts with few objects per kind and for the single nearest "
              "neighbour. Off by default.")
#: The trajectory plot's own PC space, and a saved table as the reference space.
THIS_LAYER = "this layer"
SAVED_REFERENCE = "saved reference"
#: Plots follow the slider and the selection once they have been still this long (ms).
DEBOUNCE_MS = 120

#: True while the analysis panel docks a plot (Open plots): the plot shows its layer when the
#: panel asks for it, in a later turn, not inside napari's docking (55 ms for the dock, and
#: 60 ms for the plot with its first drawing on 3,000 objects, made one stretch of the GUI
#: thread: ``benchmarks/plugin.py --stacks "open plots"``).
_BINDING_LATER = [False]


@contextmanager
def binding_later() -> Iterator[None]:
    """Plots made meanwhile do not show any results yet (:data:`_BINDING_LATER`)."""
    _BINDING_LATER[0] = True
    try:
        yield
    finally:
        _BINDING_LATER[0] = False


def read_groups_csv(path) -> dict[int, str]:
    """Label → group from a groups CSV (``label,group``), read by the package's one groups
    reader (:func:`napari_pfsdm.analysis.reduction.read_groups`, as the command line)."""
    groups = read_groups(path)
    if "label" not in groups.columns:
        raise ValueError("The group file needs a 'label' column and a 'group' column "
                         "(e.g. 3,multi-axes).")
    return dict(zip(groups["label"].astype(int).tolist(), groups["group"].astype(str).tolist(),
                    strict=True))


def _percent(ratios, i: int) -> str:
    """' (12 %)': the share of the variance of component ``i`` (1-based)."""
    if len(ratios) < i:
        return ""
    r = 100 * float(ratios[i - 1])
    return f" ({r:.0f} %)" if r >= 10 else f" ({r:.2g} %)"


class _LinkedPlot(QWidget):
    """A themed matplotlib canvas bound to one analysed Labels layer."""

    def __init__(self, napari_viewer: napari.viewer.Viewer) -> None:
        super().__init__()
        self.viewer = napari_viewer
        self._highlight_artists: list = []
        self._axes_points = None
        self._objects = np.zeros(0, np.int64)  # the object (track or label) of each point
        # redraws and highlights wait until the slider or selection has been still for a moment:
        # scrubbing through frames does not redraw the figure at every step
        self._pending: str | None = None
        self._building = None  # the rest of a figure built over turns (a generator)
        self._timer = QTimer(self, singleShot=True, interval=DEBOUNCE_MS)
        # in a turn of its own (:func:`._alive.next_turn`), not in the pass in which Qt also
        # serves the pictures' timers and signals: the two would freeze the viewer as one
        self._timer.timeout.connect(lambda: next_turn(self._flush))
        self.layer_combo = QComboBox(toolTip="The analysed Labels layer whose results are shown.")
        self.figure = Figure(figsize=(3.6, 2.8), constrained_layout=True)
        self.canvas = PlotCanvas(self.figure)
        self.canvas.setMinimumSize(260, 220)
        self.info = QLabel("Run the PF-SDM analysis to fill this plot.", wordWrap=True)
        self.controls = QHBoxLayout()
        self.controls2 = QHBoxLayout()
        self.controls3 = QHBoxLayout()
        top = QHBoxLayout()
        top.addWidget(QLabel("Layer"))
        top.addWidget(self.layer_combo, 1)
        layout = QVBoxLayout(self)
        layout.addLayout(top)
        layout.addLayout(self.controls)
        layout.addLayout(self.controls2)
        layout.addLayout(self.controls3)
        layout.addWidget(self.canvas, 1)
        layout.addWidget(self.info)
        self._layer: Labels | None = None
        # made by Open plots: no layer until :meth:`show_layer` names the one analysed last
        # (a layer event meanwhile only offers the layers; binding the first would draw it)
        self._waiting = _BINDING_LATER[0]
        self._points = np.zeros((0, 2))  # data coordinates of clickable points
        self._keys: list[tuple[int, int]] = []  # (frame, label) of each clickable point
        self._axes_points = None
        self.canvas.mpl_connect("button_press_event", self._on_click)
        self._background = None  # the last full draw, without the highlight markers
        self._texts_left: list = []  # highlight texts still to draw (in the next turns)
        self._texts_turn = 0  # which highlight they are of
        self.canvas.mpl_connect("draw_event", self._on_draw)
        self.layer_combo.currentIndexChanged.connect(self._on_layer_choice)
        self._store = store_for(napari_viewer)
        self._store.results_changed.connect(self._on_results)
        for event in (napari_viewer.layers.events.inserted, napari_viewer.layers.events.removed):
            event.connect(self._refresh_layers)
        napari_viewer.dims.events.current_step.connect(self._on_step)
        napari_viewer.events.theme.connect(self._on_theme)
        self.destroyed.connect(self._disconnect)
        if not self._waiting:  # docked from the Plugins menu: the results at once
            self._refresh_layers()

    def sizeHint(self) -> QSize:  # noqa: N802 - Qt's name
        """Narrow enough to leave the canvas most of a laptop screen's width."""
        return QSize(400, 380)

    def _on_theme(self, event=None) -> None:
        self.redraw()

    def _disconnect(self, *args) -> None:
        try:
            self._store.results_changed.disconnect(self._on_results)
        except (TypeError, ValueError, RuntimeError):
            pass

    # --------------------------------------------------------------- layers
    def _analysed(self) -> list[Labels]:
        return [lay for lay in self.viewer.layers
                if isinstance(lay, Labels) and self._store.get(lay) is not None]

    def _refresh_layers(self, event=None) -> None:
        """Offer the analysed Labels layers; rebind (and redraw) only when the layer shown
        changes: the plugin's own picture layers come and go without touching the plots."""
        names = [lay.name for lay in self._analysed()]
        offer(self.layer_combo, names)
        self._on_layer_choice()

    def _on_results(self, layer) -> None:
        try:
            self._waiting = False  # new results: shown at once
            self._refresh_layers()
            if layer is not None and layer.name in [self.layer_combo.itemText(i)
                                                    for i in range(self.layer_combo.count())]:
                self.layer_combo.setCurrentText(layer.name)
                self._bind(layer, force=True)
        except RuntimeError:  # the Qt widget is gone
            self._disconnect()

    def _on_layer_choice(self, *args) -> None:
        if self._waiting:
            return
        name = self.layer_combo.currentText()
        layer = self.viewer.layers[name] if name in self.viewer.layers else None
        self._bind(layer)

    def _bind(self, layer: Labels | None, force: bool = False) -> None:
        unchanged = same_layer(layer, self._layer) or (layer is None and self._layer is None)
        if unchanged and not force:
            return
        if self._layer is not None:
            try:
                self._layer.events.selected_label.disconnect(self._on_selection)
            except (TypeError, ValueError, RuntimeError):
                pass
        self._layer = layer
        if layer is not None:
            layer.events.selected_label.connect(self._on_selection)
        self.redraw()

    @property
    def output(self):
        return self._store.get(self._layer)

    # ------------------------------------------------------------- linking
    def current(self) -> tuple[int, int]:
        """(frame, selected label) that the viewer shows."""
        if self._layer is None:
            return 0, 0
        return _layers.current_frame(self.viewer, self._layer), int(self._layer.selected_label)

    def _on_step(self, event=None) -> None:
        self.schedule("highlight")

    def _on_selection(self, event=None) -> None:
        self.schedule("highlight")

    def schedule(self, what: str) -> None:
        """Redraw (``"redraw"``) or re-highlight (``"highlight"``) soon, once."""
        if what == "redraw" or self._pending is None:
            self._pending = what
        self._timer.start()

    def _flush(self) -> None:
        what, self._pending = self._pending, None
        try:
            if what == "redraw":
                self.redraw()
            elif what == "highlight":
                self.highlight()
        except RuntimeError:  # the Qt widget is gone
            self._disconnect()

    def flush(self) -> None:
        """Do the pending redraw or highlight now, and build the rest of a figure built
        over turns (for scripts and tests)."""
        if self._pending is not None:
            self._timer.stop()
            self._flush()
        while self._building is not None:
            self._build_step()
        if self._texts_left:
            self._draw_texts()

    def show_layer(self, layer) -> None:
        """Show the results of ``layer`` (an analysed Labels layer; None or one without
        results: the first analysed layer), bound and drawn once."""
        self._waiting = True  # the choice offered first is not drawn on its way
        try:
            offer(self.layer_combo, [lay.name for lay in self._analysed()])
            if layer is not None and self.layer_combo.findText(layer.name) >= 0:
                self.layer_combo.setCurrentText(layer.name)
        finally:
            self._waiting = False
        self._on_layer_choice()

    def select_point(self, index: int) -> None:
        """Go to the frame and label of clickable point ``index``."""
        frame, label = self._keys[index]
        _layers.go_to(self.viewer, self._layer, frame, label)
        self.highlight()

    def _on_click(self, event) -> None:
        if event.inaxes is None or event.inaxes is not self._axes_points or not len(self._points):
            return
        xy = event.inaxes.transData.transform(self._points)
        d = np.hypot(xy[:, 0] - event.x, xy[:, 1] - event.y)
        i = int(np.nanargmin(d))
        if d[i] <= PICK_RADIUS_PX * self.canvas.device_pixel_ratio:
            self.select_point(i)

    def click_display_position(self, index: int) -> tuple[float, float]:
        """Canvas display coordinates of clickable point ``index`` (for tests and scripting)."""
        return tuple(self._axes_points.transData.transform(self._points[index]))

    # -------------------------------------------------------------- drawing
    def _theme(self) -> dict:
        try:
            from napari.utils.theme import get_theme

            theme = get_theme(self.viewer.theme)
            return {"bg": str(theme.canvas), "panel": str(theme.background),
                    "fg": str(theme.text), "grid": str(theme.foreground),
                    "accent": str(theme.current)}
        except Exception:
            return {"bg": "#262930", "panel": "#262930", "fg": "#f0f1f2", "grid": "#414851",
                    "accent": "#007acc"}

    def _style(self, ax) -> None:
        c = self._theme()
        ax.set_facecolor(c["panel"])
        for spine in ax.spines.values():
            spine.set_color(c["fg"])
        ax.tick_params(colors=c["fg"], labelsize=8)
        ax.xaxis.label.set_color(c["fg"])
        ax.yaxis.label.set_color(c["fg"])
        ax.title.set_color(c["fg"])

    def redraw(self) -> None:
        c = self._theme()
        self._background = None
        self._highlight_artists = []
        self._texts_left, self._texts_turn = [], self._texts_turn + 1
        self.figure.clear()
        self.figure.set_layout_engine("constrained")  # laid out in a turn of its own
        self.figure.set_facecolor(c["panel"])
        self._points = np.zeros((0, 2))
        self._keys = []
        self._axes_points = None
        self._building = None  # a figure built over turns before: not needed any more
        try:
            steps = self.draw_plot()
        except ValueError as err:
            self.info.setText(str(err))
            steps = None
        if steps is not None:  # the rest of the figure in the turns after
            self._building = steps
            next_turn(self._build_step)
            return
        self._built()

    def _build_step(self) -> None:
        """One more part of a figure built over turns (:meth:`draw_plot` returned a
        generator); highlighted and drawn once complete."""
        steps = self._building
        if steps is None:  # redrawn meanwhile
            return
        try:
            next(steps)
        except StopIteration:
            self._building = None
            self._built()
            return
        except ValueError as err:
            self._building = None
            self.info.setText(str(err))
            self._built()
            return
        next_turn(self._build_step)

    def _built(self) -> None:
        self.highlight(draw=False)
        self.canvas.draw_idle()

    def draw_plot(self):  # pragma: no cover - overridden
        """Fill the cleared figure; None, or a generator (its first part done) that builds
        the rest of it one part per turn of the event loop (a big figure built in one turn
        froze the viewer)."""
        raise NotImplementedError

    def _on_draw(self, event=None) -> None:
        """After each full draw: keep the figure without its highlight markers (they are
        animated artists), then draw the markers on top. A new highlight then only restores
        this picture and draws its few markers (blitting), instead of drawing the whole figure
        on the GUI thread at each slider step.

        Not after ``figure.savefig``'s drawing (at the file's size, with the markers in it):
        that picture is not the screen's, and blitting it repainted the widget outside a Qt
        paint ("Recursive repaint detected", "QPainter::begin: Paint device returned engine
        == 0")."""
        if self.canvas.is_saving():
            return
        if self.canvas.layout_pending:  # drawn directly (canvas.draw()): laid out now
            # the layout of a full redraw is kept: updates in place (a new frame's distances)
            # then draw without the layout engine, a third of the cost
            self.figure.set_layout_engine("none")
        self._background = self.canvas.copy_from_bbox(self.figure.bbox)
        self._blit_highlight()

    def _blit_highlight(self) -> None:
        """Draw the highlight markers on the picture and show it; their texts (the
        nearest shapes' names and distances) in the turns after, as many a turn as
        :data:`._canvas.DRAW_BUDGET_S` allows: matplotlib draws a text glyph by glyph,
        4 ms for each of the ten labels of the nearest-shapes bars (a /tmp probe), which
        made the highlight the longest gap of re-ranking (119 ms with the sampler)."""
        self._texts_turn += 1  # the texts of an older highlight: not drawn any more
        texts = []
        for artist in self._highlight_artists:
            if artist.axes is not None and artist.figure is self.figure:
                if isinstance(artist, Text):
                    texts.append(artist)
                else:
                    artist.axes.draw_artist(artist)
        self.canvas.blit(self.figure.bbox)
        if texts:
            self._texts_left = texts
            turn = self._texts_turn
            next_turn(lambda: self._draw_texts(turn))

    def _draw_texts(self, turn: int | None = None) -> None:
        """Highlight texts left to draw (of the highlight ``turn``; None: all, now)."""
        if turn is not None and turn != self._texts_turn:
            return
        try:
            start = time.perf_counter()
            while self._texts_left:
                text = self._texts_left.pop(0)
                if text.axes is not None and text.figure is self.figure:
                    text.axes.draw_artist(text)
                if turn is not None and time.perf_counter() - start > DRAW_BUDGET_S:
                    break
            self.canvas.blit(self.figure.bbox)
        except RuntimeError:  # the Qt widget is gone (its dock was closed)
            self._texts_left = []
            return
        if self._texts_left and turn is not None:
            next_turn(lambda: self._draw_texts(turn))

    def _finish_highlight(self, draw: bool = True) -> None:
        """Show the highlight markers just made: blitted onto the last full draw when there is
        one, else drawn with the next full draw."""
        for artist in self._highlight_artists:
            artist.set_animated(True)
        if not draw:
            return
        if self._background is None:
            self.canvas.draw_idle()
            return
        self.canvas.restore_region(self._background)
        self._blit_highlight()

    def _clear_highlight(self):
        """Remove the highlight markers; the axes to draw new ones on, or None if no points."""
        for artist in self._highlight_artists:
            try:
                artist.remove()
            except (ValueError, NotImplementedError):
                pass
        self._highlight_artists = []
        self._texts_left, self._texts_turn = [], self._texts_turn + 1
        ax = self._axes_points
        return None if ax is None or not len(self._points) else ax

    def highlight(self, draw: bool = True) -> None:  # pragma: no cover - overridden
        pass

    def _draw_density(self, ax, x: np.ndarray, y: np.ndarray, colors: np.ndarray) -> None:
        """Many points as one image (:mod:`._density`): a draw that costs the same for 5,000
        or 50,000 points."""
        extent = padded_extent(x, y)
        rgba = np.rint(density_image(x, y, colors, extent) * 255).astype(np.uint8)
        # 8 bits per channel: matplotlib resamples bytes faster than floats (~20 % of a draw)
        ax.imshow(rgba, origin="lower", extent=extent, aspect="auto",
                  interpolation="nearest", zorder=2)
        ax.set_xlim(extent[0], extent[1])
        ax.set_ylim(extent[2], extent[3])

    def _frame_points(self, ax, x: np.ndarray, y: np.ndarray, frames: np.ndarray,
                      size: float):
        """Points coloured by frame: markers, or one density image above
        :data:`MANY_POINTS`; returns what a colour bar of the frames needs."""
        import matplotlib

        viridis = matplotlib.colormaps["viridis"]
        low, high = (float(frames.min()), float(frames.max())) if len(frames) else (0.0, 1.0)
        if low == high:  # one frame: the middle of the colour map, not its darkest end,
            low, high = low - 1.0, high + 1.0  # which is all but invisible on a dark theme
        norm = matplotlib.colors.Normalize(low, high)
        if len(x) > MANY_POINTS:
            self._draw_density(ax, x, y, viridis(norm(frames)))
            return matplotlib.cm.ScalarMappable(norm=norm, cmap=viridis)
        return ax.scatter(x, y, c=frames, cmap=viridis, norm=norm, s=size, zorder=2,
                          edgecolors="none")

    def _set_keys(self, frames: np.ndarray, labels: np.ndarray) -> None:
        """:attr:`_keys` (a list of (frame, label) Python ints) and its array, from two
        arrays (50,000 tuples made one by one cost ~30 ms of the GUI thread)."""
        frames = np.asarray(frames).astype(np.int64)
        labels = np.asarray(labels).astype(np.int64)
        self._keys = list(zip(frames.tolist(), labels.tolist(), strict=True))
        self._key_cache = (self._keys, np.column_stack([frames, labels]))

    def _key_array(self) -> np.ndarray:
        """:attr:`_keys` as an (n, 2) array of (frame, label), made once per drawing (a
        highlight runs at every slider step: 50,000 tuples converted each time cost more
        than drawing the markers)."""
        keys = self._keys
        cached = getattr(self, "_key_cache", None)
        if cached is None or cached[0] is not keys:
            cached = (keys, np.asarray(keys, dtype=np.int64).reshape(-1, 2))
            self._key_cache = cached
        return cached[1]


class TrajectoryPlotWidget(_LinkedPlot):
    """PCA of all (frame, label) rows; one line per object through time.

    Points are coloured by time or by a group (from the Labels layer's ``metadata["groups"]`` or
    a CSV of label → group). Shape and intensity features have separate views.
    """

    def __init__(self, napari_viewer: napari.viewer.Viewer) -> None:
        self.view = QComboBox(toolTip="Which features: the outline (shape) or the reporter "
                                      "pattern (intensity, when an image was analysed).")
        self.view.addItems(["shape", "intensity"])
        self.pc_x = QSpinBox(minimum=1, maximum=5, value=1, toolTip="Component on the x axis")
        self.pc_y = QSpinBox(minimum=1, maximum=5, value=2, toolTip="Component on the y axis")
        self.color_by = QComboBox(toolTip="Colour the points by time (frame) or by group.")
        self.color_by.addItems(["time", "group"])
        self.groups_button = QPushButton("Groups CSV…", toolTip="Load a CSV with columns "
                                         "label,group (e.g. 3,multi-axes) to colour by group.")
        self.groups: dict[int, str] = {}
        self.space = QComboBox(toolTip="The axes of the plot: this layer's own PCA, or the PCA "
                               "of another analysed layer or of a saved feature table (a "
                               "control movie) with this layer projected into it.")
        self.space.addItem(THIS_LAYER)
        self.reference_button = QPushButton("Reference…", toolTip="Load a saved feature "
                                            "table (CSV) whose PCA gives the axes.")
        self.reference_table = None
        self.reference_path = ""
        self.space_note = ""
        #: Sentences on what PC1 and PC2 follow (classic measures), after each draw.
        self.explanation: list[str] = []
        super().__init__(napari_viewer)
        for w in (self.view, QLabel("PC"), self.pc_x, QLabel("vs"), self.pc_y):
            self.controls.addWidget(w)
        self.controls.addStretch(1)
        # colouring on a second row: one row of every control would set the dock's width
        self.controls2.addWidget(QLabel("Colour by"))
        self.controls2.addWidget(self.color_by, 1)
        self.controls2.addWidget(self.groups_button)
        for box in (self.view, self.color_by):
            box.currentIndexChanged.connect(lambda *a: self.redraw())
        for box in (self.pc_x, self.pc_y):
            box.valueChanged.connect(lambda *a: self.redraw())
        self.groups_button.clicked.connect(self._groups_dialog)
        self.controls3.addWidget(QLabel("PC space of"))
        self.controls3.addWidget(self.space, 1)
        self.controls3.addWidget(self.reference_button)
        self.space.currentIndexChanged.connect(lambda *a: self.redraw())
        self.reference_button.clicked.connect(self._reference_dialog)

    # ------------------------------------------------------------ reference space
    def _refresh_spaces(self) -> None:
        """'PC space of': this layer, the other analysed layers, a saved reference."""
        names = [THIS_LAYER] + [lay.name for lay in self._analysed()
                                if self._layer is None or not same_layer(lay, self._layer)]
        if self.reference_table is not None:
            names.append(SAVED_REFERENCE)
        offered = [self.space.itemText(k) for k in range(self.space.count())]
        if names != offered:
            current = self.space.currentText()
            self.space.blockSignals(True)
            self.space.clear()
            self.space.addItems(names)
            self.space.setCurrentText(current if current in names else THIS_LAYER)
            self.space.blockSignals(False)

    def load_reference(self, path) -> None:
        """Use a saved feature table (a control movie's) as the PC space."""
        from ..io_csv import read_table_csv

        self.reference_table = read_table_csv(path)
        self.reference_path = str(path)
        self._refresh_spaces()
        self.space.setCurrentText(SAVED_REFERENCE)
        self.redraw()

    def _reference_dialog(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Reference feature table", "",
                                              "CSV (*.csv);;All files (*)")
        if path:
            try:
                self.load_reference(path)
            except (ValueError, OSError) as err:
                show_error(f"Could not read the reference: {err}")

    def _scores(self, output, channel: str):
        """(scores with ``frame``, ``label``, ``PC1`` …, explained ratios) in the chosen
        space: the layer's own PCA, or the layer projected into a reference's
        (:class:`napari_pfsdm.analysis.shape_space.ShapePCA`; another layer analysed with
        other options is refused in words)."""
        space = self.space.currentText() or THIS_LAYER
        if space == THIS_LAYER:
            scores = output.pca.get(channel)
            if scores is None or "PC1" not in scores:
                raise ValueError(f"No {channel} features: analyse with an intensity image "
                                 "first." if channel == "intensity" else
                                 "Not enough objects for a PCA.")
            self.space_note = "PCA of this layer"
            return scores, scores.attrs.get("explained_variance_ratio", [])
        if space == SAVED_REFERENCE:
            reference, where = self.reference_table, self.reference_path
        else:
            ref_layer = self.viewer.layers[space] if space in self.viewer.layers else None
            ref_out = self._store.get(ref_layer)
            if ref_out is None:
                raise ValueError(f"'{space}' has no PF-SDM results any more.")
            reference, where = ref_out.table, f"layer '{space}'"
        key = ("space", id(reference), channel)
        if key not in output.derived:
            from ..analysis.shape_space import ShapePCA
            from ..core.table_schema import pc_columns

            model = ShapePCA(n_components=5, channel=channel).fit(reference)
            projected = model.transform(output.table)
            rename = {c: c[len(channel) + 1:] for c in pc_columns(projected.columns, channel)}
            output.derived[key] = (projected.rename(columns=rename),
                                   list(model.explained_variance_ratio_))
        self.space_note = f"in the PC space of {where}"
        return output.derived[key]

    def load_groups(self, path) -> None:
        """Colour by the groups of a CSV (label → group)."""
        self.groups = read_groups_csv(path)
        self.color_by.setCurrentText("group")
        self.redraw()

    def _groups_dialog(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Groups CSV (label,group)", "",
                                              "CSV (*.csv);;All files (*)")
        if path:
            try:
                self.load_groups(path)
            except (ValueError, OSError) as err:
                show_error(f"Could not read the group file: {err}")

    def _group_of(self) -> dict[int, str]:
        if self.groups:
            return self.groups
        if self._layer is not None:
            meta = self._layer.metadata.get("groups") or {}
            return {int(k): str(v) for k, v in meta.items()}
        return {}

    def draw_plot(self):
        """The trajectories; above :data:`MANY_POINTS` points the figure is built over
        turns (:meth:`_trajectory_parts`), below in one go."""
        steps = self._trajectory_parts()
        if next(steps, False):
            return steps
        for _part in steps:
            pass
        return None

    def _trajectory_parts(self):
        """Build the trajectory plot, a generator: it first yields whether there are more
        than :data:`MANY_POINTS` points, then once between parts (the points, the colour
        bar, the rest). Built in one turn at 47,700 objects, 168 ms of the 308 ms longest
        gap of Open plots (benchmarks/plugin.py ``--stacks``, sampler running)."""
        output = self.output
        if output is None:
            self.info.setText("Run the PF-SDM analysis to fill this plot.")
            return
        channel = self.view.currentText()
        self._refresh_spaces()
        scores, ratios = self._scores(output, channel)
        n_pc = sum(c.startswith("PC") for c in scores.columns)
        i, j = min(self.pc_x.value(), n_pc), min(self.pc_y.value(), n_pc)
        c = self._theme()
        ax = self.figure.add_subplot(111)
        self._style(ax)
        x, y = scores[f"PC{i}"].to_numpy(), scores[f"PC{j}"].to_numpy()
        frames, labels = scores["frame"].to_numpy(), scores["label"].to_numpy()
        objects = objects_of(output, scores, channel)  # a track or a label: one line each
        groups = self._group_of()
        by_group = self.color_by.currentText() == "group" and groups
        names = sorted(set(groups.values())) if by_group else []
        import matplotlib

        tab = matplotlib.colormaps["tab10"]
        many = len(x) > MANY_POINTS  # one density image, not 50,000 markers and lines
        yield many
        segments, seg_colors = [], []
        order = np.lexsort((frames, objects))  # by object, then frame: one sort, not n scans
        starts = np.flatnonzero(np.r_[True, objects[order][1:] != objects[order][:-1]])
        for sel in np.split(order, starts[1:]) if len(order) and not many else []:
            if objects[sel[0]] < 0 or len(sel) < 2:  # -1: rows no track reaches
                continue
            lab = labels[sel[0]]
            segments.append(np.column_stack([x[sel], y[sel]]))
            seg_colors.append(tab(names.index(groups[lab]) % 10) if by_group and lab in groups
                              else c["grid"])
        if not many:  # a line per object
            ax.add_collection(LineCollection(segments, colors=seg_colors, linewidths=1.0,
                                             alpha=0.8, zorder=1))
        if by_group:
            colors = [tab(names.index(groups[lab]) % 10) if lab in groups else c["grid"]
                      for lab in labels]
            if many:
                self._draw_density(ax, x, y, matplotlib.colors.to_rgba_array(colors))
            else:
                ax.scatter(x, y, c=colors, s=18, zorder=2, edgecolors="none")
            for k, name in enumerate(names):
                ax.scatter([], [], color=tab(k % 10), s=18, label=name)
            leg = ax.legend(fontsize=7, facecolor=c["panel"], edgecolor=c["grid"],
                            labelcolor=c["fg"], loc="best")
            leg.set_zorder(5)
        else:
            sc = self._frame_points(ax, x, y, frames, 18)
            if output.time_lapse:
                yield True
                cb = self.figure.colorbar(sc, ax=ax, pad=0.01)
                cb.set_label("frame", color=c["fg"])
                cb.ax.tick_params(colors=c["fg"], labelsize=7)
        ax.set_xlabel(f"PC{i}" + _percent(ratios, i))
        ax.set_ylabel(f"PC{j}" + _percent(ratios, j))
        ax.set_title(f"{channel} trajectories, {self.space_note}", fontsize=8)
        yield True
        self._points = np.column_stack([x, y])
        self._set_keys(frames, labels)
        self._objects = objects
        self._axes_points = ax
        words = []
        if self.space.currentText() in ("", THIS_LAYER):
            words = explanation(output, channel)  # computed in the Run's worker
        elif output.measures is not None and channel == "shape":
            from ..analysis.interpretation import explain_components

            words = explain_components(scores, output.measures, ratios, n=2)
        self.explanation = words
        warning = output.tracking_message if output.tracking_message.startswith("Warning") \
            else ""
        dense = (f"{len(x):,} points, drawn as a density (colour: the mean "
                 f"{'group' if by_group else 'frame'} of the objects in each pixel; the "
                 "selected object's track on top). ") if many else ""
        self.info.setText((warning + " " if warning else "") + dense
                          + ("; ".join(words) + ". " if words else "")
                          + "Click a point to go to that object and frame.")

    def highlight(self, draw: bool = True) -> None:
        ax = self._clear_highlight()
        if ax is None:
            return
        frame, label = self.current()
        keys = self._key_array()
        c = self._theme()
        in_frame = keys[:, 0] == frame
        # rings round this frame's points (small when there are many); none when every point
        # is of this frame (one image, or one frame chosen): they would hide the plot
        if in_frame.any() and not in_frame.all():
            many = len(keys) > MANY_POINTS
            self._highlight_artists.append(ax.scatter(
                *self._points[in_frame].T, s=16 if many else 60, facecolors="none",
                edgecolors=c["fg"], lw=0.5 if many else 0.8, zorder=3))
        here = np.flatnonzero(in_frame & (keys[:, 1] == label))
        if len(here) and self._objects[here[0]] >= 0:  # the selected object's whole track
            mine = self._objects == self._objects[here[0]]
        else:
            mine = keys[:, 1] == label if not len(here) else np.isin(np.arange(len(keys)), here)
        if mine.any():
            order = np.argsort(keys[mine, 0])
            # a long track (a movie of many frames) zigzags over the plot: thin and
            # translucent, the points under it stay visible
            long = int(mine.sum()) > LONG_TRACK
            (line,) = ax.plot(*self._points[mine][order].T, "-", color=c["accent"],
                              lw=1.0 if long else 2.2, alpha=0.6 if long else 1.0, zorder=3)
            self._highlight_artists.append(line)
        both = in_frame & mine
        if both.any():
            self._highlight_artists.append(ax.scatter(
                *self._points[both].T, s=140, marker="*", color=c["accent"], edgecolors=c["fg"],
                zorder=4))
        self._finish_highlight(draw)

    def highlighted_keys(self) -> list[tuple[int, int]]:
        """(frame, label) of the points currently marked as the selected object and frame."""
        frame, label = self.current()
        return [k for k in self._keys if k == (frame, label)]


class ShapeComparisonWidget(_LinkedPlot):
    """PF-SDM distance matrix of the objects of one frame and its 2-D MDS map.

    The distances, the re-ranking and the MDS map are computed in a worker thread (the plot
    says "computing…" meanwhile, with a Cancel button) and kept per frame; a new frame with
    as many objects as the one shown is drawn in place (new matrix, points and labels in the
    same axes), without laying out the figure again.
    """

    def __init__(self, napari_viewer: napari.viewer.Viewer) -> None:
        self.frame_choice = QComboBox(toolTip="Compare the objects of the frame shown by the "
                                              "time slider, or of all frames together.")
        self.frame_choice.addItems(["current frame", "all frames"])
        self.rerank = QCheckBox("re-rank", toolTip=RERANK_TIP)
        self.cancel_button = QPushButton("Cancel", visible=False,
                                         toolTip="Stop computing these distances.")
        self._shown_frame: int | None = None
        self._matrix_keys: list[tuple[int, int]] = []
        self._ax_matrix = None
        self._artists: dict = {}  # the full draw's image, colour bar, points, labels
        self._graph: GraphResult | None = None  # the neighbour-graph view's data
        self._ax_near = None
        self._nearest: list = []
        self._graph_rows: dict = {}
        # (id(output), frame or None, weight, re-ranked) → (distances, MDS map)
        self._cache: dict = {}
        self._worker = None
        self._worker_key = None
        self._cancelled_key = None
        super().__init__(napari_viewer)
        self.controls.addWidget(QLabel("Objects of"))
        self.controls.addWidget(self.frame_choice, 1)
        self.controls.addWidget(self.rerank)
        self.controls.addWidget(self.cancel_button)
        self.frame_choice.currentIndexChanged.connect(lambda *a: self.redraw())
        self.rerank.toggled.connect(self._on_rerank)
        self.cancel_button.clicked.connect(self.cancel)

    @property
    def computing(self) -> bool:
        """True while distances are being computed in the background."""
        return self._worker is not None

    def cancel(self) -> None:
        """Stop the distances being computed (nothing is kept, and they are not asked for
        again until the frame or an option changes)."""
        if self._worker is not None:
            self._cancelled_key = self._worker_key
            self._worker.quit()
            self.info.setText("Cancelled: no distances computed. Move the slider or change an "
                              "option to compute them again.")

    def _on_step(self, event=None) -> None:
        if self.frame_choice.currentText() == "current frame" and self._layer is not None:
            if self.current()[0] != self._shown_frame:
                self.schedule("redraw")
                return
        self.schedule("highlight")

    def _on_rerank(self, *args) -> None:
        """Re-ranking on or off: the neighbour-graph view changes in place (it stays shown
        while the new graph is computed); any other view is drawn again."""
        self._pending = "redraw"
        self._flush()

    def _flush(self) -> None:
        if self._pending == "redraw" and self._update_in_place():
            self._pending = None
            return
        super()._flush()

    # ------------------------------------------------------------ what to compare
    def _selection(self):
        """``(key, rows, frame shown or None, title, weight, re-ranked)`` of the objects to
        compare now (``rows``: their positions in the table); ``ValueError`` (plain words)
        when there is nothing to compare. Masks only: the rows themselves are taken in the
        worker (a copy of 50,000 rows took 0.2 s of the GUI thread)."""
        output = self.output
        table = output.table
        keep = output.measured()
        frame = self.current()[0]
        if self.frame_choice.currentText() == "current frame":
            keep = keep & (table["frame"].to_numpy() == frame)
            shown, title = frame, f"frame {frame}"
        else:
            shown, title = None, "all frames"
        if keep.sum() < 2:
            raise ValueError("Fewer than two measured objects here: nothing to compare.")
        w = output.options.get("intensity_weight", 0.0)
        if not has_channel(table.columns, "intensity"):
            w = 0.0
        if w:  # rows whose reporter could not be described (NaN pixels) have no intensity
            keep = keep & output.comparable(("shape", "intensity"))
            if keep.sum() < 2:
                raise ValueError("Fewer than two objects with intensity features here.")
        rows = np.flatnonzero(keep)
        reranked = self.rerank.isChecked() and len(rows) >= 3
        key = (id(output), shown, float(w), reranked)
        return key, rows, shown, title, w, reranked

    def _frames_labels(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Frames and labels of the table's ``rows``."""
        table = self.output.table
        return table["frame"].to_numpy()[rows], table["label"].to_numpy()[rows]

    def _start(self, key, rows: np.ndarray, w: float, reranked: bool) -> None:
        """Compute the distances of the table's ``rows`` in a worker (one at a time; the last
        asked wins)."""
        if self._worker is not None:
            if self._worker_key == key:
                return
            self._worker.quit()
        by_graph = len(rows) > GRAPH_ROWS
        if by_graph:
            worker = _graph_worker(self.output, rows, w, reranked, _ignore_errors=True)
        else:
            worker = _comparison_worker(self.output.table, rows, w, reranked,
                                        _ignore_errors=True)
        self._worker, self._worker_key = worker, key
        if by_graph:
            worker.yielded.connect(self._on_graph_progress)

        def done(result, key=key):
            if len(self._cache) > 256:
                self._cache.clear()
            self._cache[key] = result

        def finished(worker=worker, key=key):
            if self._worker is worker:
                self._worker, self._worker_key = None, None
                try:
                    self.cancel_button.setVisible(False)
                    if key != self._cancelled_key:  # show them: in place when possible
                        self._pending = "redraw"
                        self._flush()
                except RuntimeError:  # the widget is gone (the viewer was closed)
                    pass

        def failed(err):
            self._cache[key] = err

        worker.returned.connect(done)
        worker.errored.connect(failed)
        worker.finished.connect(finished)
        self.cancel_button.setVisible(True)
        worker.start()

    def _on_graph_progress(self, step) -> None:
        try:
            if isinstance(step, tuple):
                self.info.setText(f"Nearest neighbours: {step[0]:,} of {step[1]:,} objects…")
            else:
                self.info.setText(f"Drawing the map of the neighbour graph ({step})…")
        except RuntimeError:  # the widget is gone
            pass

    # ------------------------------------------------------------------ drawing
    def draw_plot(self) -> None:
        self._ax_matrix = None
        self._ax_near = None
        self._graph = None
        self._artists = {}
        if self.output is None:
            self.info.setText("Run the PF-SDM analysis to fill this view.")
            return
        key, rows, shown, title, w, reranked = self._selection()
        self._shown_frame = shown
        cached = self._cache.get(key)
        if cached is None and key == self._cancelled_key:
            raise ValueError("Cancelled: no distances computed. Move the slider or change an "
                             "option to compute them again.")
        self._cancelled_key = None
        if cached is None:
            self._start(key, rows, w, reranked)
            ax = self.figure.add_subplot(111)
            self._style(ax)
            ax.set_axis_off()
            ax.text(0.5, 0.5, f"computing the distances of {len(rows):,} objects…",
                    ha="center", va="center", color=self._theme()["fg"], fontsize=9,
                    transform=ax.transAxes)
            self.info.setText("Computing in the background; the viewer stays usable.")
            return
        if isinstance(cached, Exception):
            raise ValueError(f"The distances could not be computed: {cached}")
        if isinstance(cached, GraphResult):
            steps = self._draw_graph(rows, cached, title)
            next(steps)  # its first part now
            return steps
        d, xy = cached
        c = self._theme()
        ax_m = self.figure.add_subplot(121)
        ax_p = self.figure.add_subplot(122)
        for ax in (ax_m, ax_p):
            self._style(ax)
        im = ax_m.imshow(d, cmap="viridis", interpolation="nearest")
        cb = self.figure.colorbar(im, ax=ax_m, fraction=0.046, pad=0.02)
        cb.set_label("re-ranked distance" if reranked else "PF-SDM distance", color=c["fg"],
                     fontsize=7)
        cb.ax.tick_params(colors=c["fg"], labelsize=6)
        frames, labels = self._frames_labels(rows)
        self._set_keys(frames, labels)
        keys = self._keys
        if len(keys) <= 20:
            ticks = [str(lb) if shown is not None else f"{f}:{lb}" for f, lb in keys]
            ax_m.set_xticks(range(len(keys)), ticks, fontsize=6, rotation=90)
            ax_m.set_yticks(range(len(keys)), ticks, fontsize=6)
            ax_m.set_xlabel("label" if shown is not None else "frame:label", fontsize=7)
        elif shown is None:  # rows are sorted by frame: mark where frames start
            starts = np.flatnonzero(np.r_[True, frames[1:] != frames[:-1]])
            step = max(1, len(starts) // 8)
            ax_m.set_xticks(starts[::step], [str(frames[i]) for i in starts[::step]], fontsize=6)
            ax_m.set_yticks(starts[::step], [str(frames[i]) for i in starts[::step]], fontsize=6)
            ax_m.set_xlabel("objects, by frame (tick = first object of that frame)", fontsize=7)
        else:
            ax_m.set_xticks([])
            ax_m.set_yticks([])
            ax_m.set_xlabel(f"{len(keys)} objects, by label", fontsize=7)
        ax_m.set_title(f"distances, {title}", fontsize=9)
        if shown is None and self.output.time_lapse:
            sc = ax_p.scatter(xy[:, 0], xy[:, 1], s=14, c=frames, cmap="viridis",
                              edgecolors="none", rasterized=len(keys) > 2000)
            cb2 = self.figure.colorbar(sc, ax=ax_p, fraction=0.046, pad=0.02)
            cb2.set_label("frame", color=c["fg"], fontsize=7)
            cb2.ax.tick_params(colors=c["fg"], labelsize=6)
        else:
            sc = ax_p.scatter(xy[:, 0], xy[:, 1], s=30, color=c["grid"], edgecolors=c["fg"],
                              lw=0.5)
        notes = []
        if len(keys) <= 30:
            notes = [ax_p.annotate(str(lb), (px, py), fontsize=7, color=c["fg"],
                                   xytext=(3, 3), textcoords="offset points")
                     for (_f, lb), (px, py) in zip(keys, xy, strict=True)]
        ax_p.set_title("MDS map", fontsize=9)
        ax_p.set_xlabel("close = similar shapes", fontsize=7)
        ax_p.set_xticks([])
        ax_p.set_yticks([])
        self._artists = {"image": im, "colorbar": cb, "points": sc, "notes": notes,
                         "n": len(keys), "shown": shown, "reranked": reranked,
                         "ticks": len(keys) <= 20}
        self._set_shown(keys, xy, d, ax_p, ax_m)

    def _draw_graph(self, rows: np.ndarray, graph: GraphResult, title: str):
        """More objects than a matrix shows: each object's nearest shapes (left, for the
        object selected in the viewer; click a bar to go there) and the map of the neighbour
        graph (right; a density image above :data:`MANY_POINTS` points).

        A generator, the figure built a part per turn (:meth:`_LinkedPlot._build_step`): in
        one turn, 69-86 ms of the longest gaps of the all-frames view and re-ranking at
        47,700 objects (benchmarks/plugin.py ``--stacks``)."""
        c = self._theme()
        frames, labels = self._frames_labels(rows)
        self._set_keys(frames, labels)
        keys = self._keys
        ax_n = self.figure.add_subplot(121)
        self._style(ax_n)
        self._near_axis(ax_n, graph)
        ax_n.set_yticks([])
        ax_n.set_title("nearest shapes", fontsize=8)
        yield
        ax_p = self.figure.add_subplot(122)
        self._style(ax_p)
        sc = self._frame_points(ax_p, graph.xy[:, 0], graph.xy[:, 1], frames, 6)
        yield
        if self.output.time_lapse:
            cb = self.figure.colorbar(sc, ax=ax_p, fraction=0.046, pad=0.02)
            cb.set_label("frame", color=c["fg"], fontsize=7)
            cb.ax.tick_params(colors=c["fg"], labelsize=6)
        ax_p.set_title(f"{graph.method} map, {title}", fontsize=8)
        ax_p.set_xlabel("close = similar shapes", fontsize=7)
        ax_p.set_xticks([])
        ax_p.set_yticks([])
        self._graph = graph
        self._graph_output = self.output  # whose rows: changed in place for this Run only
        self._graph_rows_shown = rows
        self._ax_near = ax_n
        self._points, self._keys, self._axes_points = graph.xy, keys, ax_p
        self._matrix_keys = keys
        self._graph_rows = {key: i for i, key in enumerate(keys)}
        self.distances = None
        self._graph_info(graph)

    def _graph_info(self, graph: GraphResult) -> None:
        hint = (" (pip install umap-learn for a map that keeps kinds of shapes apart)"
                if graph.method == "spectral" else "")
        self.info.setText(f"{len(graph.xy):,} objects: compared by each one's {graph.k} "
                          "nearest shapes (exact), not all pairs. Click a point or a bar to "
                          f"select that object.{hint}")

    def _set_shown(self, keys, xy, d, ax_p, ax_m) -> None:
        self._points = xy
        self._keys = keys
        self._axes_points = ax_p
        self._ax_matrix = ax_m
        self._matrix_keys = keys
        self.distances = d
        self.info.setText("Close points = similar shapes. Click a point or a matrix row to "
                          "select that object.")

    def _update_in_place(self) -> bool:
        """Show a new frame in the axes of the last full draw when it has as many objects and
        its distances are ready; False when a full redraw is needed."""
        if self._graph is not None:
            return self._update_graph_in_place()
        art = self._artists
        if not art or art["shown"] is None or self.output is None:
            return False
        try:
            key, rows, shown, title, _w, reranked = self._selection()
        except ValueError:
            return False
        if len(rows) != art["n"] or reranked != art["reranked"] or key == self._cancelled_key:
            return False
        cached = self._cache.get(key)
        if cached is None:  # computed in a worker; the frame shown stays until they are ready
            self._start(key, rows, _w, reranked)
            self.info.setText(f"Computing the distances of {title}…")
            return True
        if isinstance(cached, Exception):
            return False
        d, xy = cached
        self._set_keys(*self._frames_labels(rows))
        keys = self._keys
        im, ax_m, ax_p = art["image"], self._ax_matrix, self._axes_points
        im.set_data(d)
        im.set_clim(float(np.min(d)), float(np.max(d)))
        if art["ticks"]:
            names = [str(lb) for _f, lb in keys]
            ax_m.set_xticklabels(names)
            ax_m.set_yticklabels(names)
        ax_m.set_title(f"distances, {title}", fontsize=9)
        art["points"].set_offsets(xy)
        for note, (_f, lb), p in zip(art["notes"], keys, xy, strict=False):
            note.set_text(str(lb))
            note.xy = (float(p[0]), float(p[1]))
        lo, hi = xy.min(axis=0), xy.max(axis=0)
        pad = 0.08 * np.maximum(hi - lo, 1e-9)
        ax_p.set_xlim(lo[0] - pad[0], hi[0] + pad[0])
        ax_p.set_ylim(lo[1] - pad[1], hi[1] + pad[1])
        self._shown_frame = shown
        self._set_shown(keys, xy, d, ax_p, ax_m)
        self._background = None
        self._clear_highlight()
        self.highlight(draw=False)
        self.canvas.draw_idle()
        return True

    def _update_graph_in_place(self) -> bool:
        """The neighbour-graph view of the same objects by other distances (re-ranked or
        not): the view shown stays while they are computed, then its map, bars and labels
        change in the same axes. False when a full redraw is needed.

        Building the view anew (two axes and a colour bar) was the longest gap of ticking
        re-rank at 47,700 objects (86 ms of 104, benchmarks/plugin.py ``--stacks``)."""
        if self.output is None:
            return False
        try:
            key, rows, shown, title, w, reranked = self._selection()
        except ValueError:
            return False
        if (shown is not None or key == self._cancelled_key
                or self._graph_output is not self.output
                or not np.array_equal(rows, self._graph_rows_shown)):
            return False  # other objects (or a new Run's): drawn anew
        cached = self._cache.get(key)
        if cached is None:
            self._start(key, rows, w, reranked)
            self.info.setText(f"Computing the nearest shapes of {len(rows):,} objects again; "
                              "the view shown stays until they are ready.")
            return True
        if not isinstance(cached, GraphResult):
            return False
        graph, ax_n, ax_p = cached, self._ax_near, self._axes_points
        self._clear_highlight()
        for artist in [*ax_p.images, *ax_p.collections]:  # the map before
            artist.remove()
        ax_p.ignore_existing_data_limits = True
        frames = self._key_array()[:, 0]
        self._frame_points(ax_p, graph.xy[:, 0], graph.xy[:, 1], frames, 6)
        ax_p.set_title(f"{graph.method} map, {title}", fontsize=8)
        self._near_axis(ax_n, graph)
        self._graph, self._points = graph, graph.xy
        self._graph_info(graph)
        self._background = None
        self.highlight(draw=False)
        self.canvas.draw_idle()
        return True

    def _near_axis(self, ax, graph: GraphResult) -> None:
        """The nearest-shapes panel's scale: up to the longest distance it may show."""
        k = min(NEAREST_SHOWN, graph.indices.shape[1])
        finite = graph.distances[:, :k][np.isfinite(graph.distances[:, :k])]
        ax.set_xlim(0, float(finite.max()) * 1.05 if finite.size else 1.0)
        ax.set_ylim(k - 0.5, -0.5)
        ax.set_xlabel("re-ranked distance" if graph.reranked else "PF-SDM distance",
                      fontsize=7)

    def nearest_shown(self) -> list[tuple[tuple[int, int], float]]:
        """The bars of the nearest-shapes panel: ((frame, label), distance), nearest first
        (empty outside the neighbour-graph view or when nothing is selected)."""
        return list(self._nearest)

    def _on_click(self, event) -> None:
        near = self._nearest
        if event.inaxes is not None and event.inaxes is self._ax_near and event.ydata is not None:
            i = int(np.rint(event.ydata))
            if 0 <= i < len(near):
                self.select_point(self._graph_rows[near[i][0]])
            return
        if event.inaxes is not None and event.inaxes is self._ax_matrix and event.ydata is not None:
            i = int(np.rint(event.ydata))
            if 0 <= i < len(self._keys):
                self.select_point(i)
            return
        super()._on_click(event)

    def highlight(self, draw: bool = True) -> None:
        ax = self._clear_highlight()
        if ax is None:
            return
        frame, label = self.current()
        keys = self._key_array()
        sel = keys[:, 1] == label
        if self._shown_frame is None:
            sel &= keys[:, 0] == frame
        c = self._theme()
        if self._graph is not None:
            self._highlight_graph(ax, np.flatnonzero(sel), c)
        if sel.any():
            self._highlight_artists.append(ax.scatter(
                *self._points[sel].T, s=120, marker="*", color=c["accent"], edgecolors=c["fg"],
                zorder=4))
            for i in np.flatnonzero(sel) if self._ax_matrix is not None else []:
                self._highlight_artists.append(self._ax_matrix.axhline(
                    i, color=c["accent"], lw=1.0, alpha=0.8))
        self._finish_highlight(draw)


    def _highlight_graph(self, ax, selected: np.ndarray, c: dict) -> None:
        """The selected object's nearest shapes: bars (left) and rings on the map."""
        self._nearest = []
        if not len(selected):
            return
        graph, i = self._graph, int(selected[0])
        k = min(NEAREST_SHOWN, graph.indices.shape[1])
        idx, dist = graph.indices[i, :k], graph.distances[i, :k]
        keep = idx >= 0
        idx, dist = idx[keep], dist[keep]
        self._nearest = [(self._keys[j], float(v)) for j, v in zip(idx, dist, strict=True)]
        self._highlight_artists.append(ax.scatter(
            *self._points[idx].T, s=50, facecolors="none", edgecolors=c["accent"], lw=1.2,
            zorder=3))
        near = self._ax_near
        # the bars as one collection: ten Rectangles cost ten draws at every selection
        bars = PolyCollection(
            [((0.0, r - 0.35), (v, r - 0.35), (v, r + 0.35), (0.0, r + 0.35))
             for r, v in enumerate(dist)], facecolors=c["accent"], edgecolors="none")
        near.add_collection(bars, autolim=False)
        self._highlight_artists.append(bars)
        for y, ((f, lb), v) in enumerate(self._nearest):
            name = f"{f}:{lb}" if self.output is not None and self.output.time_lapse \
                else str(lb)
            self._highlight_artists.append(near.text(
                0.01 * near.get_xlim()[1], y, f"{name}  {v:.3g}", va="center", fontsize=6,
                color=c["fg"], clip_on=True))


class GraphResult(NamedTuple):
    """What the neighbour-graph view shows: each object's k nearest (row numbers of the
    compared rows, nearest first), their distances, the 2-D map and how it was drawn."""

    indices: np.ndarray
    distances: np.ndarray
    xy: np.ndarray
    method: str
    reranked: bool

    @property
    def k(self) -> int:
        return int(self.indices.shape[1])


@thread_worker(start_thread=False)
def _graph_worker(output, rows: np.ndarray, intensity_weight: float, reranked: bool):
    """Worker: the neighbour graph of the table's ``rows`` (progress, and Cancel between
    blocks), re-ranked if asked, and its map (in a worker process, which Cancel
    terminates)."""
    from ._graph import graph_of, map_method, map_steps, rerank_graph

    idx, dist = yield from graph_of(output, rows, intensity_weight)
    if reranked:
        idx, dist = rerank_graph(idx, dist)
        yield "re-ranked"
    method = map_method(len(idx))
    xy = yield from map_steps(idx, dist, method)
    return GraphResult(idx, dist, xy, {"tsne": "t-SNE", "umap": "UMAP"}.get(method, method),
                       reranked)


@thread_worker(start_thread=False)
def _comparison_worker(table, rows: np.ndarray, intensity_weight: float, reranked: bool):
    """Worker: the distances of the ``table``'s ``rows``, re-ranked if asked, and their 2-D
    MDS map; it can stop between the steps (Cancel)."""
    from ..analysis.tables import distance_matrix

    d = np.asarray(distance_matrix(table.iloc[rows], intensity_weight=intensity_weight))
    yield "distances"
    if reranked:
        from ..analysis.rerank import rerank

        d = rerank(d, "diffusion", k=min(10, len(d) - 1))
        yield "re-ranked"
    return d, classical_mds(d, 2)
