"""Time done right: are a table's labels tracked, and linking them into tracks when not.

Per-frame segmentation (cellpose, StarDist, a threshold and ``skimage.measure.label``) numbers
the objects of each frame anew: label 3 in frame 0 and label 3 in frame 1 are usually
different objects, and a "trajectory" drawn by label jumps between objects. This module

* **detects** such labels from the feature table alone (:func:`check_tracking`): how often a
  label lands nearer another object than its own from one frame to the next, how far it
  jumps relative to the object's size, and how many of a frame's ids are still there in the
  next frame;
* **links** objects into tracks, giving each row a ``track_id`` (:func:`link`,
  :func:`link_movie`, :func:`add_track_ids`): by centroids (:func:`link_centroids`, the
  default: a frame-to-frame linear assignment with gap closing, built in; or the ``laptrack``
  package when installed), or by the overlap of the label masks (:func:`link_labels`);
* takes the identities from a **napari Tracks layer** (:func:`track_ids_from_tracks`).

Rows that no track reaches get ``track_id = -1`` (:data:`NO_TRACK`): the column stays whole
numbers, which CSV readers, pandas and Excel read without fuss (an empty cell would turn it
into floats, 3.0). Our own track ids start at 1, in order of first appearance. Which linking
is the default, and why, is measured by ``benchmarks/linking.py`` (docs/design.md §2.11).

Three modules: :mod:`.check` (is a table tracked?), :mod:`.linking` (the linkers, one per
method, with the gates their benchmark set) and :mod:`.tracks_layer` (a napari Tracks layer as
the source); this package gives their public names.
"""

from __future__ import annotations

from ...core.table_schema import NO_TRACK
from .check import PACKED, TrackingCheck, check_tracking, touching_fraction
from .linking import (
    DEFAULT_LINK,
    LINK_METHODS,
    LINK_RADII,
    MIN_IOU,
    add_track_ids,
    link,
    link_centroids,
    link_labels,
    link_movie,
)
from .tracks_layer import track_ids_from_tracks

__all__ = [
    "DEFAULT_LINK",
    "LINK_METHODS",
    "LINK_RADII",
    "MIN_IOU",
    "NO_TRACK",
    "PACKED",
    "TrackingCheck",
    "add_track_ids",
    "check_tracking",
    "link",
    "link_centroids",
    "link_labels",
    "link_movie",
    "touching_fraction",
    "track_ids_from_tracks",
]
