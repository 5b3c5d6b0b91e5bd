"""A feature table in blocks: what a worker process sends back for its objects.

A run kept one row object per measured object until the table was made (an
:class:`~napari_pfsdm.analysis.measuring.ObjectResult`, its light result, two dicts, a
bounding box of slices): 50,000 objects are some 400,000 Python objects that the garbage
collector walks at each full collection, holding the interpreter lock. In the viewer that
froze the GUI thread as long (20,000 objects: three collections of 56, 118 and 131 ms during
one Run, measured with ``gc.callbacks``). A :class:`RowBlock` holds the same rows as a few
arrays: the table's rows of its objects (made in the worker process by the run's
:class:`~napari_pfsdm.analysis.measuring.ObjectMeasurer`) and their bounding boxes as integers;
:func:`join_blocks` puts the blocks of a run together (tested equal to
:func:`~napari_pfsdm.measure`'s table).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..core.table_options import set_options
from .measuring import ObjectMeasurer, ObjectResult

__all__ = ["BoxLookup", "RowBlock", "block_of", "join_blocks"]

@dataclass(frozen=True)
class RowBlock:
    """Rows of a feature table and what else a run keeps of their objects.

    Attributes
    ----------
    table : DataFrame
        The objects' rows, as :meth:`~napari_pfsdm.analysis.measuring.ObjectMeasurer.table`
        makes them (``attrs["pfsdm"]`` holds the options).
    boxes : ndarray, shape (n, 2 * ndim), int64
        Each object's bounding box in its frame: the start on each axis, then the stop
        (``-1`` where an object has none).
    """

    table: pd.DataFrame
    boxes: np.ndarray


def block_of(objects: Sequence[ObjectResult], measurer: ObjectMeasurer) -> RowBlock:
    """The block of ``objects`` (as :func:`~napari_pfsdm.analysis.measuring.light` makes
    them), measured by ``measurer``."""
    table = measurer.table(objects)
    ndim = measurer.ndim
    boxes = np.full((len(objects), 2 * ndim), -1, dtype=np.int64)
    for i, obj in enumerate(objects):
        if obj.bbox is not None:
            boxes[i] = [s.start for s in obj.bbox] + [s.stop for s in obj.bbox]
    return RowBlock(table, boxes)


def join_blocks(blocks: Sequence[RowBlock]) -> RowBlock:
    """One block of all ``blocks``, in their order (a run's table and boxes)."""
    if not blocks:
        raise ValueError("no blocks to join")
    # blocks without rows have no dtypes (object columns), which would change the table's
    blocks = [b for b in blocks if len(b.table)] or list(blocks[:1])
    if len(blocks) == 1:
        return blocks[0]
    opts = blocks[0].table.attrs.get("pfsdm")
    table = pd.concat([b.table for b in blocks], ignore_index=True)
    if opts is not None:
        set_options(table, opts)
    return RowBlock(table, np.concatenate([b.boxes for b in blocks]))


class BoxLookup(Mapping):
    """``(frame, label)`` → bounding box (a tuple of slices), from a block's integer boxes.

    What the napari plugin keeps as each object's box (``Analysis.boxes``): the slices are made
    when an object's box is asked for, not kept for every object of a run.
    """

    def __init__(self, frames: np.ndarray, labels: np.ndarray, boxes: np.ndarray) -> None:
        keys = zip(np.asarray(frames).astype(np.int64).tolist(),
                   np.asarray(labels).astype(np.int64).tolist(), strict=True)
        self._row = {key: i for i, key in enumerate(keys)}
        self._boxes = np.asarray(boxes, dtype=np.int64)

    def __getitem__(self, key) -> tuple[slice, ...] | None:
        box = self._boxes[self._row[(int(key[0]), int(key[1]))]]
        ndim = len(box) // 2
        if box[0] < 0:
            return None
        return tuple(slice(int(box[i]), int(box[ndim + i])) for i in range(ndim))

    def __iter__(self) -> Iterator[tuple[int, int]]:
        return iter(self._row)

    def __len__(self) -> int:
        return len(self._row)
