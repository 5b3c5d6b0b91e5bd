"""The per-object diagnostics and the words they give (napari_pfsdm.analysis.features
object_warnings and warnings_summary; core descriptor's folded_fraction): a clean object or
table says nothing, each reason is named only when it holds, on the side of its threshold.
The diagnostics are set by hand; the folded fraction is checked against a case whose answer
is known without the descriptor (a disk never folds)."""

from __future__ import annotations

import types

import numpy as np
import pandas as pd
import pytest

import napari_pfsdm as pf
from napari_pfsdm.analysis.features import (
    FOLDED_WARNING,
    ObjectResult,
    object_warnings,
    warnings_summary,
)


def obj(touches_border=False, intensity_error="", **diagnostics):
    diag = {"folded_fraction": 0.0, "n_holes": 0, "n_components": 1, **diagnostics}
    return ObjectResult(frame=0, label=1, bbox=(slice(0, 1), slice(0, 1)), area=1,
                        centroid=np.zeros(2), touches_border=touches_border,
                        result=types.SimpleNamespace(diagnostics=diag),
                        intensity_error=intensity_error)


def test_a_clean_object_has_no_warnings():
    assert object_warnings(obj()) == []
    assert object_warnings(obj(folded_fraction=FOLDED_WARNING / 2)) == []
    assert object_warnings(obj(), with_intensity=True) == []


def test_each_reason_is_named_when_it_holds():
    assert object_warnings(obj(touches_border=True)) == [
        "touches the image border (may be cut off)"]
    assert object_warnings(obj(folded_fraction=0.125)) == [
        "12.5 % of disk samples fold (try mapping='bijective')"]  # 2-D: disk samples
    three_d = object_warnings(obj(folded_fraction=0.125, crossing_fraction=0.2))
    assert len(three_d) == 1 and three_d[0].startswith("12.5 % of ball samples fold")
    assert object_warnings(obj(n_components=2)) == ["2 pieces, the largest kept"]
    assert object_warnings(obj(n_holes=1)) == ["1 hole filled"]


def test_an_intensity_warning_only_when_the_intensity_was_asked_for():
    o = obj(intensity_error="NaN pixels")
    assert object_warnings(o) == []
    assert object_warnings(o, with_intensity=True) == [
        "intensity features left empty: NaN pixels"]


def test_a_clean_table_has_no_summary_and_each_count_is_right():
    clean = pd.DataFrame({"error": ["", ""], "touches_border": [False, False],
                          "folded_fraction": [0.0, FOLDED_WARNING / 2], "n_holes": [0, 0],
                          "n_components": [1, 1], "warnings": ["", ""]})
    assert warnings_summary(clean) == ""
    t = pd.DataFrame({"error": ["", "", "", "too small"],
                      "touches_border": [False, False, True, False],
                      "folded_fraction": [0.3, 0.1, 0.0, np.nan], "n_holes": [0, 1, 0, 0],
                      "n_components": [1, 1, 3, 1], "warnings": ["", "", "", ""]})
    assert warnings_summary(t) == (
        "1 object has no features (see the error column); 1 object touches the border, 2 are "
        "more than 5 % folded (up to 30 %), 1 had holes filled, 1 was in several pieces: see "
        "the warnings column")


def test_a_disk_does_not_fold_and_its_table_says_nothing():
    """A disk's push-forward is the disk itself (no sample outside the object): folded
    fraction 0, no warnings, for every mapping."""
    yy, xx = np.mgrid[:64, :64]
    labels = ((yy - 32) ** 2 + (xx - 31) ** 2 <= 20**2).astype(np.uint16)
    for mapping in ("harmonic", "bijective"):
        res = pf.pfsdm(labels.astype(bool), mapping=mapping)
        assert res.diagnostics["folded_fraction"] == 0.0
    table = pf.measure(labels)
    assert table.loc[0, "folded_fraction"] == 0.0
    assert table.loc[0, "warnings"] == "" and warnings_summary(table) == ""


def test_intensity_crop_by_hand():
    """A 3 × 3 box at offset (1, 1) of a 5 × 5 image, the object its centre pixel and the
    pixel right of it (values 2 and 6: mean 4). The box, divided by 4; a NaN pixel of the box
    outside the object counts as 0; the box beyond the image repeats the edge. A zero or
    negative mean is refused in plain words (the descriptor divides by it)."""
    from napari_pfsdm.core.intensity import intensity_crop
    from napari_pfsdm.errors import InputError

    image = np.arange(25.0).reshape(5, 5)
    image[2, 2], image[2, 3] = 2.0, 6.0
    image[1, 1] = np.nan
    mask = np.zeros((3, 3), bool)
    mask[1, 1] = mask[1, 2] = True
    got = intensity_crop(image, np.array([1, 1]), mask)
    want = image[1:4, 1:4] / 4.0
    want[0, 0] = 0.0
    np.testing.assert_array_equal(got, want)
    edge = intensity_crop(np.ones((2, 2)) * 3.0, np.array([-1, -1]), np.ones((3, 3), bool))
    np.testing.assert_array_equal(edge, np.ones((3, 3)))
    for value in (0.0, -1.0):
        flat = np.full((5, 5), value)
        with pytest.raises(InputError, match="mean intensity"):
            intensity_crop(flat, np.array([1, 1]), mask)
