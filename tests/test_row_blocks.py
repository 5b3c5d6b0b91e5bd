"""A run's rows in blocks (napari_pfsdm.analysis.row_blocks): any split joins to measure's
table and boxes, failed objects included."""

from __future__ import annotations

import pandas as pd
import pytest

import napari_pfsdm as pf
from napari_pfsdm.analysis.features import iter_objects
from napari_pfsdm.analysis.measuring import ObjectMeasurer, light
from napari_pfsdm.analysis.row_blocks import BoxLookup, block_of, join_blocks
from napari_pfsdm.core.params import PFSDMParams
from napari_pfsdm.data.gastruloids import make_timelapse_montage


@pytest.fixture(scope="module")
def movie_rows():
    labels, intensity = make_timelapse_montage(3, 3, 128, seed=7)[:2]
    labels = labels.copy()
    labels[1, 2, 2] = 40  # a one-pixel object: a row without features
    labels[2, 5:7, 5:7] = 41
    params = PFSDMParams()
    objects = list(iter_objects(labels, intensity, params=params, axes="tyx"))
    rows = [light(obj) for obj in objects]
    return labels, intensity, params, objects, rows


@pytest.mark.parametrize("cuts", [[], [1], "around the failed", "every row", "empty blocks"])
def test_any_split_joins_to_measures_table_and_boxes(movie_rows, cuts):
    labels, intensity, params, objects, rows = movie_rows
    expected = pf.measure(labels, intensity)
    failed = [i for i, obj in enumerate(objects) if obj.result is None]
    assert len(failed) == 2  # the test needs them
    if cuts == "around the failed":  # blocks holding only a failed object
        cuts = sorted({c for i in failed for c in (i, i + 1)})
    elif cuts == "every row":
        cuts = list(range(1, len(rows)))
    elif cuts == "empty blocks":  # at the start, in the middle and at the end
        cuts = [0, 3, 3, len(rows)]
    edges = [0, *cuts, len(rows)]
    measurer = ObjectMeasurer.of(params, with_intensity=True, axes="tyx")
    blocks = [block_of(rows[a:b], measurer)
              for a, b in zip(edges, edges[1:], strict=False)]
    joined = join_blocks(blocks)
    pd.testing.assert_frame_equal(joined.table, expected)
    assert joined.table.attrs["pfsdm"] == expected.attrs["pfsdm"]
    boxes = BoxLookup(joined.table["frame"].to_numpy(), joined.table["label"].to_numpy(),
                      joined.boxes)
    assert dict(boxes) == {(int(o.frame), int(o.label)): o.bbox for o in objects}
    assert boxes.get((1, 40)) == (slice(2, 3), slice(2, 3)) and boxes.get((0, 40)) is None


def test_joining_nothing_is_refused():
    with pytest.raises(ValueError, match="no blocks"):
        join_blocks([])
