"""The plots dock's "Over time" tab: any number of the layer's rows against time.

The column is any number of the layer's features (a classic measure, a PC score, a predicted
probability): each object's line through the frames (its track), each group's mean ± sd, the
selected object's line in red with its current frame starred; a click on a point moves napari
to that frame and object (:func:`napari_pfsdm.analysis.over_time.plot_over_time` draws it).
"""

from __future__ import annotations

import numpy as np
from magicgui.widgets import ComboBox

from ..analysis.over_time import numeric_columns, plot_over_time
from ..analysis.plot_text import plot_text
from ..analysis.reduction import object_ids
from ._plot_base import Plot
from ._results import plural


class OverTimePlot(Plot):
    """One number of every object against time, per object and per group."""

    READABLE = (300, 190)

    def __init__(self, viewer) -> None:
        self.column = ComboBox(choices=[], tooltip="The number drawn against time: a classic "
                               "measure, a PC score, a predicted probability, …")
        super().__init__(viewer, [self.column])

    def _columns(self) -> list[str]:
        columns = numeric_columns(self.analysis.layer_features())
        return [c for c in columns if c not in ("failed",)]

    def draw(self) -> None:
        a = self.analysis
        if not a.time_lapse:
            raise ValueError("Measures over time need a time-lapse.")
        with self.column.changed.blocked():  # (a new choice would draw again)
            chosen = self.column.value
            self.column.choices = self._columns()
            if chosen in self.column.choices:
                self.column.value = chosen
        column = self.column.value
        if column is None:
            raise ValueError("No numbers to draw against time.")
        features = a.layer_features()
        ax = self.figure.add_subplot(111)
        self.lines = plot_over_time(ax, features, column, groups=a.groups or None)
        self.objects = object_ids(features)
        ax.set_title(f"{plot_text(column)} of '{plot_text(self.layer.name)}' over time",
                     fontsize=9)
        self.points_axes = ax
        self.xy = self.lines[["time", "value"]].to_numpy(float)
        self.keys = self.lines[["frame", "label"]].to_numpy().astype(np.int64)
        n = self.lines["object"].nunique()
        self.info.value = (f"{plural(n, 'object')}; " + ("thick lines: each group's mean ± sd; "
                                                  if a.groups else "")
                           + "red: the selected object. Click a point to go there.")

    def mark(self, ax, frame: int, label: int) -> list:
        a = self.analysis
        i = a.row_of(frame, label)
        if i is None or not len(self.keys):
            return []
        obj = self.objects.iloc[i]
        rows = (self.lines["object"] == obj).to_numpy()
        path = self.mark_artist("path", lambda: ax.plot([], [], "-", color="#ff3c3c", lw=1.6,
                                                         zorder=4)[0])
        path.set_data(*self.xy[rows].T)
        return [path, *super().mark(ax, frame, label)]
