"""Clean shape spaces: objects on the border or with warnings left out of PCA, comparison and
prediction by the options ``border_objects`` and ``warned_objects``, kept in the table."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import napari_pfsdm as pf
from napari_pfsdm.analysis.outcome import predict_outcome
from napari_pfsdm.analysis.reduction import pca_scores
from napari_pfsdm.cli import main


def _movie() -> np.ndarray:
    """Four frames of six rectangles; labels 1 and 2 touch the border, label 6 is in two
    pieces (a warning)."""
    labels = np.zeros((4, 80, 160), np.uint16)
    for t in range(4):
        labels[t, 0:20, 10:30 + t] = 1
        labels[t, 30:50, 140 + t // 2:160] = 2
        labels[t, 30:50, 40:60 + 2 * t] = 3
        labels[t, 55:75, 40:52 + t] = 4
        labels[t, 30:70, 80:95 + t] = 5
        labels[t, 10:25, 80:100 + t] = 6
        labels[t, 10:14, 110:114] = 6  # a second piece
    return labels


@pytest.fixture(scope="module")
def tables():
    labels = _movie()
    return labels, pf.measure(labels), pf.measure(labels, border_objects="leave_out",
                                                  warned_objects="leave_out")


def test_the_rows_stay_in_the_table_with_the_same_features(tables):
    _labels, kept, left = tables
    assert len(kept) == len(left) == 24 and left.attrs["pfsdm"]["border_objects"] == "leave_out"
    pd.testing.assert_frame_equal(kept.filter(like="shape_r"), left.filter(like="shape_r"))
    assert left.loc[left["label"].isin([1, 2]), "touches_border"].all()
    assert (left.loc[left["label"] == 6, "warnings"] != "").all()


def test_pca_comparison_and_prediction_leave_them_out(tables):
    _labels, kept, left = tables
    with pytest.warns(UserWarning, match=r"left out 12 of 24 rows .*border_objects=leave_out"):
        inside = pf.drop_failed(left)
    assert sorted(inside["label"].unique()) == [3, 4, 5]
    scores, _ = pca_scores(left, "shape", 2)
    assert sorted(scores["label"].unique()) == [3, 4, 5]
    # the PCA of the kept rows is that of a table holding only them
    alone = kept[kept["label"].isin([3, 4, 5])].reset_index(drop=True)
    np.testing.assert_allclose(np.abs(scores["shape_PC1"]),
                               np.abs(pca_scores(alone, "shape", 2)[0]["shape_PC1"]), atol=1e-9)
    np.testing.assert_allclose(pf.distance_matrix(inside), pf.distance_matrix(alone))
    with pytest.raises(ValueError, match="left out by the options"):
        pf.distance_matrix(left)
    groups = {1: "a", 2: "a", 3: "a", 4: "b", 5: "b", 6: "b"}
    predict_outcome(kept, groups, [0, 1])  # three objects a group: a prediction
    with pytest.raises(ValueError, match="group 'a' has 1 object"):  # 1, 2 left out
        predict_outcome(left, groups, [0, 1])


def test_the_command_line_leaves_them_out_and_says_so(tmp_path, capsys):
    import tifffile

    tifffile.imwrite(tmp_path / "m.tif", _movie(), photometric="minisblack")
    out = tmp_path / "f.csv"
    assert main(["measure", str(tmp_path / "m.tif"), "-o", str(out), "--border-objects",
                 "leave_out", "--scheduler", "sync"]) == 0
    assert pf.read_table(out).attrs["pfsdm"]["border_objects"] == "leave_out"
    d = tmp_path / "d.csv"
    assert main(["compare", str(out), "--frames", "0", "-o", str(d)]) == 0
    names = pd.read_csv(d, index_col=0).index.tolist()
    assert len(names) == 4 and not any(n.endswith(("/l1", "/l2")) for n in names)
    assert "border_objects=leave_out" in capsys.readouterr().err
