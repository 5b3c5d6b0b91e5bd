"""The plugin's one model: what is known about each analysed Labels layer (no Qt, no napari).

Every dock is a view of an :class:`Analysis`: the run's table and options, the objects' identity
through time, the groups, the fitted PCA, the comparison, the predictions and the selected object.
Docks change it only through its methods; each change is one ``changed`` signal naming what
changed (:data:`WHAT`). The :class:`Registry` keeps one :class:`Analysis` per layer, keyed by
napari's unique layer id, and numbers the runs: a result of an older run is never taken for the
current one.

Examples
--------
>>> import numpy as np
>>> import pandas as pd
>>> reg = Registry()
>>> table = pd.DataFrame({"frame": [0, 0], "label": [1, 2], "error": ["", ""]})
>>> a = reg.new_run("layer-uuid", Analysis("", 0, table, options={}, axes="yx"))
>>> seen = []
>>> _ = a.changed.connect(seen.append)
>>> a.select(0, 2)
>>> seen, a.selection, a.run
(['selection'], (0, 2), 1)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pandas as pd
from psygnal import Signal

from ..core.params import PFSDMParams

#: What a ``changed`` signal can name.
WHAT = ("selection", "identity", "groups", "comparison", "prediction")


@dataclass
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
    groups : dict
        Object (track id or label) → group name (at a Run: the layer's ``metadata["groups"]``).
    selection : (frame, label) or None
        The object looked at.
    comparison : dict
        Distances computed by the comparison view, by what was compared.
    prediction : object or None
        The last prediction (:func:`napari_pfsdm.analysis.prediction.predict_outcome`).
    derived : dict
        What views derive from the table and keep (e.g. the sentences on the PCs); emptied
        when the table changes.
    """

    changed = Signal(str)

    layer_id: str
    run: int
    table: pd.DataFrame
    options: dict
    params: PFSDMParams = field(default_factory=PFSDMParams)
    axes: str = "yx"
    spacing: tuple | None = None
    labels: Any = field(default=None, repr=False)
    intensity: Any = field(default=None, repr=False)
    boxes: Mapping = field(default_factory=dict, repr=False)
    pca: dict = field(default_factory=dict, repr=False)
    measures: pd.DataFrame | None = field(default=None, repr=False)
    tracking_message: str = ""
    groups: dict = field(default_factory=dict)
    selection: tuple[int, int] | None = None
    comparison: dict = field(default_factory=dict, repr=False)
    prediction: Any = field(default=None, repr=False)
    derived: dict = field(default_factory=dict, repr=False)

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

    @property
    def measured(self) -> np.ndarray:
        """Whether each row has features (no error)."""
        return self._errors == ""

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

    def group_of_rows(self) -> np.ndarray:
        """Each row's group name ("" when its object has none)."""
        if not self.groups:
            return np.full(len(self.table), "", dtype=object)
        return np.array([self.groups.get(int(k), "") for k in self.objects()], dtype=object)

    # ------------------------------------------------------------------ changing
    def select(self, frame: int, label: int) -> None:
        """Make (frame, label) the object looked at (one signal when it changed)."""
        new = (int(frame) if self.time_lapse else 0, int(label))
        if new != self.selection:
            self.selection = new
            self.changed.emit("selection")

    def set_table(self, table: pd.DataFrame, what: str = "identity", message: str = "") -> None:
        """Replace the table (new identities, new prediction columns)."""
        self.table = table
        if what == "identity":
            self.tracking_message = message
        self.derived.clear()
        self._index()
        self.changed.emit(what)

    def set_groups(self, groups: Mapping[int, str]) -> None:
        """Object (track id or label) → group name; replaces the previous groups."""
        self.groups = {int(k): str(v) for k, v in groups.items()}
        self.changed.emit("groups")

    def set_comparison(self, what: tuple, result: Any) -> None:
        """Keep the distances computed for ``what`` (frame or all, weight, re-ranked)."""
        self.comparison[what] = result
        self.changed.emit("comparison")

    def with_table(self, table: pd.DataFrame) -> Analysis:
        """A copy with another table, indexed and with nothing derived yet: made where the
        work is done (a worker), then taken by :meth:`set_prediction`."""
        return replace(self, table=table, derived={})

    def set_prediction(self, prediction: Any, scored: Analysis | None = None) -> None:
        """Keep a prediction; ``scored`` (:meth:`with_table` of the table with its
        ``p_<group>`` columns) gives the new table, its index and what was derived from it."""
        self.prediction = prediction
        if scored is not None:
            self.table, self.derived = scored.table, scored.derived
            self._rows, self._errors = scored._rows, scored._errors
        self.changed.emit("prediction")


class Registry:
    """The analyses of every Labels layer, by napari's unique layer id; a new run of a layer
    replaces its analysis and gets the next run number."""

    #: (layer id): a layer got a new analysis, or lost it (then :meth:`get` gives None).
    updated = Signal(str)

    def __init__(self) -> None:
        self._items: dict[str, Analysis] = {}
        self._runs: dict[str, int] = {}

    def new_run(self, layer_id: str, analysis: Analysis) -> Analysis:
        """Store ``analysis`` (made anywhere, e.g. in the Run's worker) as the new run of
        ``layer_id``: it gets that layer id and the next run number; returns it."""
        run = self._runs.get(layer_id, 0) + 1
        self._runs[layer_id] = run
        analysis.layer_id, analysis.run = layer_id, run
        self._items[layer_id] = analysis
        self.updated.emit(layer_id)
        return analysis

    def get(self, layer_id: str | None) -> Analysis | None:
        return self._items.get(layer_id) if layer_id is not None else None

    def forget(self, layer_id: str) -> None:
        """Drop the analysis of a removed layer (its run numbers are kept)."""
        if self._items.pop(layer_id, None) is not None:
            self.updated.emit(layer_id)

    def __contains__(self, layer_id: str) -> bool:
        return layer_id in self._items


#: The process's registry: napari's layer ids are unique across viewers.
REGISTRY = Registry()
