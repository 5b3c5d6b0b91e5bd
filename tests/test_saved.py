"""A saved analysis comes back as it was, and refuses other data in words."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

import napari_pfsdm as pf
from napari_pfsdm.analysis.reduction import pca_scores
from napari_pfsdm.data.gastruloids import make_timelapse_montage
from napari_pfsdm.saved import fingerprint, open_analysis, save_analysis


@pytest.fixture(scope="module")
def run():
    labels, reporter, groups = make_timelapse_montage(seed=0, n_frames=3)
    table = pf.link(pf.measure(labels, reporter))
    scores, ratios = pca_scores(table, "shape", 3)
    scores.attrs = {"explained_variance_ratio": [float(r) for r in ratios]}
    boxes = {(0, 1): (slice(3, 40), slice(5, 60)), (1, 2): None}
    return labels, reporter, {int(k): v for k, v in groups.items()}, table, scores, boxes


def test_everything_saved_comes_back(run, tmp_path):
    labels, reporter, groups, table, scores, boxes = run
    table = table.assign(**{"p_multi-axes": np.linspace(0, 1, len(table))})
    save_analysis(tmp_path, table, labels=labels, intensity=reporter, pca={"shape": scores},
                  groups=groups, boxes=boxes, names={"labels": "gastruloids"},
                  paths={"labels": "/data/g.tif"})
    back = open_analysis(tmp_path, labels=labels, intensity=reporter)
    pd.testing.assert_frame_equal(back.table, table, check_dtype=False)
    assert back.table.attrs["pfsdm"] == table.attrs["pfsdm"]
    pd.testing.assert_frame_equal(back.pca["shape"], scores, check_dtype=False)
    assert back.explained["shape"] == pytest.approx(scores.attrs["explained_variance_ratio"])
    assert back.groups == groups and back.boxes == boxes
    assert back.sources["labels"]["name"] == "gastruloids"
    assert back.sources["labels"]["path"] == "/data/g.tif"
    assert back.sources["labels"]["sha256"] == fingerprint(labels)["sha256"]
    # the distances from the reopened table are the run's
    np.testing.assert_allclose(pf.distance_matrix(pf.drop_failed(back.table)),
                               pf.distance_matrix(pf.drop_failed(table)))


def test_other_data_and_broken_folders_are_refused_in_words(run, tmp_path):
    labels, reporter, groups, table, scores, boxes = run
    save_analysis(tmp_path, table, labels=labels, groups=groups)
    edited = labels.copy()
    edited[1, 10, 10] = 99
    with pytest.raises(ValueError, match="the labels changed since the analysis was saved"):
        open_analysis(tmp_path, labels=edited)
    with pytest.raises(ValueError, match=r"their shape is \(2, "):
        open_analysis(tmp_path, labels=labels[:2])
    with pytest.raises(ValueError, match="is not a saved analysis"):
        open_analysis(tmp_path / "nothing")
    (tmp_path / "groups.csv").unlink()
    with pytest.raises(ValueError, match="lacks groups.csv"):
        open_analysis(tmp_path, labels=labels)


def test_a_users_file_in_the_folder_is_kept(run, tmp_path):
    labels, reporter, groups, table, scores, boxes = run
    (tmp_path / "analysis.json").write_text(json.dumps({"my": "notes"}))
    with pytest.raises(ValueError, match="napari-pfsdm did not write it"):
        save_analysis(tmp_path, table, labels=labels)
    assert json.loads((tmp_path / "analysis.json").read_text()) == {"my": "notes"}
    save_analysis(tmp_path / "again", table, labels=labels)
    save_analysis(tmp_path / "again", table, labels=labels)  # its own files: replaced
