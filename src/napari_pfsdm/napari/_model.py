"""The plugin's one model: what is known about each analysed Labels layer (no Qt, no napari).

Every dock is a view of an :class:`Analysis`: the run's table and options, the objects' identity
through time, the groups, the fitted PCA, the comparison, the predictions and the selected object.
Docks change it only through its methods; each kind of change has its own signal
(:class:`AnalysisEvents`). The :class:`Registry` keeps one :class:`Analysis` per layer, keyed by
napari's unique layer id, numbers the runs (a result of an older run is never taken for the
current one) and links each analysis to its layer (:class:`LayerLink`): the layer's ``features``,
its selected label and the time slider are kept in step with the model whichever docks are open,
and a removed layer's analysis and pictures are dropped.

The napari objects are used through their public attributes only (``layer.features``,
``layer.selected_label``, ``layer.events``, ``viewer.dims``, ``viewer.layers``), so that this
module imports neither napari nor Qt and runs on stand-ins in tests.

Examples
--------
>>> import pandas as pd
>>> reg = Registry()
>>> table = pd.DataFrame({"frame": [0, 0], "label": [1, 2], "error": ["", ""]})
>>> a = reg.new_run("layer-uuid", {"table": table, "options": {}, "axes": "yx"})
>>> seen = []
>>> _ = a.events.selection.connect(seen.append)
>>> a.select(0, 2)
>>> seen, a.selection, a.run
([(0, 2)], (0, 2), 1)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from psygnal import Signal, SignalGroup

from ..analysis.tables import left_out_reasons
from ..core.params import PFSDMParams
from ._features import layer_features

#: The picture layers' name suffixes (after the Labels layer's name), by picture.
PICTURE_SUFFIXES = {"sdf": "SDF", "disk": "PF-SDF disk", "intensity_disk": "intensity disk",
                    "lines": "outline and skeleton", "captions": "captions",
                    "shells": "PF-SDF shells", "surface": "surface"}


def picture_names(source: str) -> dict[str, str]:
    """The picture layers' names for the Labels layer called ``source``.

    >>> picture_names("cells")["disk"]
    'cells PF-SDF disk'
    """
    return {k: f"{source} {v}" for k, v in PICTURE_SUFFIXES.items()}


def is_picture(layer) -> bool:
    """Whether ``layer`` is one of the pictures the plugin makes."""
    return any(layer.name.endswith(" " + s) for s in PICTURE_SUFFIXES.values())


# --------------------------------------------------------------------------- where things are
def layer_shape(layer) -> tuple[int, ...]:
    """The full-resolution shape of a layer's data (the first level of a multiscale one)."""
    return tuple(int(n) for n in (layer.level_shapes[0] if layer.multiscale
                                  else layer.data.shape))


def frame_axis(dims, layer, time_lapse: bool) -> int | None:
    """The viewer's axis of the layer's frames (None without a time axis)."""
    return dims.ndim - layer.ndim if time_lapse else None


def current_frame(dims, layer, time_lapse: bool) -> int:
    """The frame of ``layer`` that the time slider (``viewer.dims``) shows."""
    ax = frame_axis(dims, layer, time_lapse)
    if ax is None:
        return 0
    t = (dims.point[ax] - layer.translate[0]) / layer.scale[0]
    return int(np.clip(np.rint(t), 0, layer_shape(layer)[0] - 1))


class AnalysisEvents(SignalGroup):
    """What changed in an :class:`Analysis`, one signal per kind."""

    #: The object looked at: ``(frame, label)`` (label 0: its object is not in that frame).
    selection = Signal(object)
    #: The objects' identities through time were found again (the sentence saying how).
    identity = Signal(str)
    #: Object → group name.
    groups = Signal(dict)
    #: Distances were computed for this key (frame or None, weight, re-ranked, elastic weight).
    comparison = Signal(tuple)
    #: A prediction was made; the table has its ``p_<group>`` columns.
    prediction = Signal(object)


@dataclass(eq=False)
class Analysis:
    """One run of the PF-SDM analysis of one Labels layer, and what the docks made of it.

    Attributes
    ----------
    layer_id : str
        napari's unique id of the Labels layer.
    run : int
        The run's number for that layer (1, 2, ...).
    table : DataFrame
        One row per (frame, label), as :func:`napari_pfsdm.measure` (``attrs["pfsdm"]``).
    options : dict
        The table's record of the options, plus ``intensity_weight``.
    params : PFSDMParams
        The method's options of the run (pictures are made with them).
    axes : str
        ``"yx"``, ``"tyx"``, ``"zyx"`` or ``"tzyx"``.
    spacing : tuple or None
        Voxel size (z, y, x) of Z-stacks.
    labels, intensity
        The measured arrays (references): pictures are made from them.
    boxes : mapping
        ``{(frame, label): box}``: each object's bounding box.
    pca : dict
        ``{"shape": scores, "intensity": scores}`` with ``frame``, ``label``, ``shape_PC1`` …
    measures : DataFrame or None
        Classic measures of 2-D objects (circularity, aspect ratio, solidity).
    tracking_message : str
        What was found about identity through time ("" when nothing to say).
    message : str
        What the run found, in words (the analysis dock's status line).
    features : DataFrame or None
        :func:`~._features.layer_features` of the table (made at first use when None).
    sentences : dict
        What the PCs follow, in words, by channel (made at first use).
    groups : dict
        Object (track id or label) → group name (at a Run: the layer's ``metadata["groups"]``).
    sources : dict
        The layers' names: ``{"labels": …, "reporter": …}`` (what a saved analysis names).
    paths : dict
        The files the layers came from, where napari knows them: ``{"labels": …}``.
    selection : (frame, label) or None
        The object looked at; label 0 when the selected object is not in that frame.
    selected_object : int or None
        The selected object's track id (its label without identities through time): the
        selection follows it from frame to frame.
    comparison : dict
        Distances computed by the comparison view, by what was compared.
    prediction : object or None
        The last prediction (:func:`napari_pfsdm.analysis.outcome.predict_outcome`).
    """

    layer_id: str
    run: int
    table: pd.DataFrame = field(repr=False)
    options: dict = field(repr=False)
    params: PFSDMParams = field(default_factory=PFSDMParams, repr=False)
    axes: str = "yx"
    spacing: tuple | None = None
    labels: Any = field(default=None, repr=False)
    intensity: Any = field(default=None, repr=False)
    boxes: Mapping = field(default_factory=dict, repr=False)
    pca: dict = field(default_factory=dict, repr=False)
    measures: pd.DataFrame | None = field(default=None, repr=False)
    tracking_message: str = ""
    message: str = field(default="", repr=False)
    features: pd.DataFrame | None = field(default=None, repr=False)
    sentences: dict = field(default_factory=dict, repr=False)
    groups: dict = field(default_factory=dict)
    sources: dict = field(default_factory=dict)
    paths: dict = field(default_factory=dict)
    selection: tuple[int, int] | None = None
    selected_object: int | None = None
    comparison: dict = field(default_factory=dict, repr=False)
    prediction: Any = field(default=None, repr=False)
    events: AnalysisEvents = field(default_factory=AnalysisEvents, init=False, repr=False)

    def __post_init__(self) -> None:
        self._index()

    # ------------------------------------------------------------------ reading
    @property
    def time_lapse(self) -> bool:
        return self.axes.startswith("t")

    @property
    def ndim(self) -> int:
        """2 for outlines in frames, 3 for objects in Z-stacks."""
        return 3 if "z" in self.axes else 2

    @property
    def key(self) -> tuple[str, int]:
        """(layer id, run): what a result computed from this analysis belongs to."""
        return self.layer_id, self.run

    def _index(self) -> None:
        frames = self.table["frame"].to_numpy().astype(np.int64)
        labels = self.table["label"].to_numpy().astype(np.int64)
        self._rows = {(int(f), int(lab)): i for i, (f, lab) in enumerate(zip(frames, labels,
                                                                              strict=True))}
        self._errors = (self.table["error"].fillna("").astype(str).to_numpy(object)
                        if "error" in self.table else np.full(len(self.table), "", object))
        self._left = left_out_reasons(self.table, self.options)
        self._objects = objects = self.objects()
        self._where = {(int(f), int(o)): int(lab) for f, o, lab in zip(frames, objects, labels,
                                                                         strict=True) if o >= 0}

    @property
    def measured(self) -> np.ndarray:
        """Whether each row enters the shape spaces: it has features (no error) and the
        options do not leave it out (``border_objects``, ``warned_objects``)."""
        return (self._errors == "") & (self._left == "")

    def row_of(self, frame: int, label: int) -> int | None:
        """Position of the (frame, label) row in :attr:`table` (None when absent)."""
        return self._rows.get((int(frame) if self.time_lapse else 0, int(label)))

    def labels_in(self, frame: int) -> np.ndarray:
        """Sorted labels present in one frame."""
        t = int(frame) if self.time_lapse else 0
        return np.array(sorted(lab for f, lab in self._rows if f == t), dtype=np.int64)

    def error_of(self, frame: int, label: int) -> str | None:
        """Why the object has no features ("" when it has them; None when it is absent)."""
        i = self.row_of(frame, label)
        if i is None:
            return None
        return str(self._errors[i])

    def objects(self) -> np.ndarray:
        """The object of each row: its ``track_id`` when the table has one, else its label."""
        if "track_id" in self.table:
            ids = self.table["track_id"].to_numpy(dtype=float, na_value=np.nan)
            return np.where(np.isfinite(ids), ids, -1).astype(np.int64)
        return self.table["label"].to_numpy().astype(np.int64)

    def object_of(self, frame: int, label: int) -> int | None:
        """The object (track id, or label) of the (frame, label) row; None when absent."""
        i = self.row_of(frame, label)
        return None if i is None else int(self._objects[i])

    def label_of(self, obj: int, frame: int) -> int | None:
        """The label that object ``obj`` has in ``frame`` (None when it is not there)."""
        return self._where.get((int(frame) if self.time_lapse else 0, int(obj)))

    def touches_border(self, frame: int, label: int) -> bool:
        """Whether the (frame, label) object touches the image's border (False when absent or
        unknown)."""
        i = self.row_of(frame, label)
        return bool(i is not None and "touches_border" in self.table
                    and self.table["touches_border"].iloc[i])

    def group_of_rows(self) -> np.ndarray:
        """Each row's group name ("" when its object has none)."""
        if not self.groups:
            return np.full(len(self.table), "", dtype=object)
        return np.array([self.groups.get(int(k), "") for k in self.objects()], dtype=object)

    def layer_features(self) -> pd.DataFrame:
        """The numbers of every row for plotters (:func:`~._features.layer_features`)."""
        if self.features is None:
            self.features = layer_features(self.table, self.pca, self.measures)
        return self.features

    def save(self, folder) -> Path:
        """Keep this analysis in ``folder`` (:func:`napari_pfsdm.saved.save_analysis`): its
        table, PCA, groups, boxes, the layers' names and files, the data's fingerprints."""
        from ..saved import save_analysis

        return save_analysis(folder, self.table, labels=self.labels, intensity=self.intensity,
                             pca=self.pca, groups=self.groups, boxes=self.boxes,
                             names=self.sources, paths=self.paths)

    # ------------------------------------------------------------------ changing
    def select(self, frame: int, label: int) -> None:
        """Make (frame, label) the object looked at (one signal when it changed); label 0 (the
        background) selects no object."""
        new = (int(frame) if self.time_lapse else 0, int(label))
        self.selected_object = self.object_of(*new)
        if new != self.selection:
            self.selection = new
            self.events.selection.emit(new)

    def show_frame(self, frame: int) -> int | None:
        """Another frame is shown: the selection follows its object (track) there. Returns
        the selected object's label in that frame (None when it is not there, or nothing is
        selected)."""
        if self.selection is None or not self.time_lapse:
            return None
        t = int(frame)
        label = self.label_of(self.selected_object, t) \
            if self.selected_object is not None else None
        new = (t, label or 0)
        if new != self.selection:
            self.selection = new
            self.events.selection.emit(new)
        return label

    def set_table(self, table: pd.DataFrame, message: str = "") -> None:
        """Replace the table by one with new identities through time (``track_id``)."""
        self.table, self.features, self.sentences = table, None, {}
        self.tracking_message = message
        self._index()
        if self.selection is not None:
            self.selected_object = self.object_of(*self.selection)
        self.events.identity.emit(message)

    def set_groups(self, groups: Mapping[int, str]) -> None:
        """Object (track id or label) → group name; replaces the previous groups."""
        self.groups = {int(k): str(v) for k, v in groups.items()}
        self.events.groups.emit(self.groups)

    def set_comparison(self, what: tuple, result: Any) -> None:
        """Keep the distances computed for ``what`` (frame or all, weight, re-ranked, μ)."""
        self.comparison[what] = result
        self.events.comparison.emit(what)

    def with_table(self, table: pd.DataFrame) -> Analysis:
        """A copy with another table, indexed and with nothing derived yet: made where the
        work is done (a worker), then taken by :meth:`set_prediction`."""
        return replace(self, table=table, features=None, sentences={})

    def set_prediction(self, prediction: Any, scored: Analysis | None = None) -> None:
        """Keep a prediction; ``scored`` (:meth:`with_table` of the table with its
        ``p_<group>`` columns) gives the new table, its index and its features."""
        self.prediction = prediction
        if scored is not None:
            self.table, self.features = scored.table, scored.features
            self.sentences = scored.sentences
            self._rows, self._errors, self._where = scored._rows, scored._errors, scored._where
            self._left, self._objects = scored._left, scored._objects
        self.events.prediction.emit(prediction)


class LayerLink:
    """Keeps one analysed napari Labels layer and its :class:`Analysis` in step.

    The layer's ``features`` hold every row (:func:`~._features.layer_features`), written when
    the link is made and when the table changes (new identities, a prediction), never at a frame
    step: other plugins recompute at each write. napari's selected label and the time slider
    move the selection, which follows its object (track) from frame to frame; removing the layer
    makes the registry forget its analysis and removes its pictures. ``viewer`` may be None (a
    script): then only ``features`` are written.
    """

    def __init__(self, registry: Registry, analysis: Analysis, layer, viewer=None) -> None:
        self.registry, self.analysis, self.layer = registry, analysis, layer
        self.dims = viewer.dims if viewer is not None else None
        self.layers = viewer.layers if viewer is not None else None
        self._connections: list[tuple[Any, Any]] = []
        self._shown = self.frame()  # the frame the selection was last moved to
        events = analysis.events
        for signal in (events.identity, events.prediction):
            self._connect(signal, self.publish)
        if viewer is not None:
            self._connect(self.dims.events.current_step, self.on_step)
            self._connect(layer.events.selected_label, self.on_label)
            self._connect(self.layers.events.removed, self.on_removed)

    def _connect(self, emitter, callback) -> None:
        emitter.connect(callback)
        self._connections.append((emitter, callback))

    def frame(self) -> int:
        """The frame the time slider shows (0 without a viewer or a time axis)."""
        if self.dims is None:
            return 0
        return current_frame(self.dims, self.layer, self.analysis.time_lapse)

    def publish(self, *_args) -> None:
        """Write the layer's ``features``: every row of the table."""
        self.layer.features = self.analysis.layer_features()

    def on_step(self, event=None) -> None:
        """The time slider moved: the selection follows its object (the features stay)."""
        t = self.frame()
        if not self.analysis.time_lapse or t == self._shown:  # another slider (e.g. Z)
            return
        self._shown = t
        label = self.analysis.show_frame(t)
        if label is not None and label != self.layer.selected_label:
            self.layer.selected_label = label  # napari selects the same object

    def on_label(self, event=None) -> None:
        self.analysis.select(self.frame(), int(self.layer.selected_label))

    def on_removed(self, event) -> None:
        if getattr(event.value, "unique_id", None) == self.analysis.layer_id:
            self.registry.forget(self.analysis.layer_id)

    def go_to(self, frame: int, label: int) -> None:
        """Select (frame, label): the time slider moves there and napari selects it."""
        self.analysis.select(frame, label)
        ax = frame_axis(self.dims, self.layer, self.analysis.time_lapse) \
            if self.dims is not None else None
        if ax is not None:
            self.dims.set_point(ax, self.layer.translate[0] + frame * self.layer.scale[0])
        self.layer.selected_label = int(label)

    def close(self, pictures: bool = False) -> None:
        """Stop following the layer; with ``pictures``, remove its picture layers."""
        for emitter, callback in self._connections:
            emitter.disconnect(callback)
        self._connections.clear()
        if pictures and self.layers is not None:
            for name in picture_names(self.layer.name).values():
                if name in self.layers:
                    self.layers.remove(name)


class Registry:
    """The analyses of every Labels layer, by napari's unique layer id; a new run of a layer
    replaces its analysis and gets the next run number."""

    #: (layer id): a layer got a new analysis, or lost it (then :meth:`get` gives None).
    updated = Signal(str)

    def __init__(self) -> None:
        self._items: dict[str, Analysis] = {}
        self._links: dict[str, LayerLink] = {}
        self._runs: dict[str, int] = {}

    def new_run(self, layer, fields: Mapping[str, Any], viewer=None) -> Analysis:
        """The new run of ``layer`` (a napari Labels layer, or a layer id for a script) from
        ``fields`` (:class:`Analysis`' attributes but ``layer_id`` and ``run``): it gets the
        next run number, replaces the layer's last analysis and is linked to the layer."""
        layer_id = layer if isinstance(layer, str) else layer.unique_id  # (a UUID in napari)
        run = self._runs.get(layer_id, 0) + 1
        self._runs[layer_id] = run
        analysis = Analysis(layer_id, run, **fields)
        old = self._links.pop(layer_id, None)
        if old is not None:
            old.close()
        self._items[layer_id] = analysis
        if not isinstance(layer, str):
            link = self._links[layer_id] = LayerLink(self, analysis, layer, viewer)
            link.publish()
        self.updated.emit(layer_id)
        return analysis

    def get(self, layer_id: str | None) -> Analysis | None:
        return self._items.get(layer_id) if layer_id is not None else None

    def link(self, layer_id: str | None) -> LayerLink | None:
        """The link of an analysed layer to its napari layer (None without one)."""
        return self._links.get(layer_id) if layer_id is not None else None

    def forget(self, layer_id: str) -> None:
        """Drop the analysis of a removed layer and its pictures (its run numbers are kept)."""
        link = self._links.pop(layer_id, None)
        if link is not None:
            link.close(pictures=True)
        if self._items.pop(layer_id, None) is not None:
            self.updated.emit(layer_id)

    def __contains__(self, layer_id: str) -> bool:
        return layer_id in self._items


#: The process's registry: napari's layer ids are unique across viewers.
REGISTRY = Registry()
