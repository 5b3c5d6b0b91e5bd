"""The measuring room (napari_pfsdm.analysis.measuring): one per-object step for every path,
a new measure declared once, and leave-out options that never reach it."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import tifffile
from skimage.measure import regionprops_table

import napari_pfsdm as pf
from napari_pfsdm.analysis import measuring, parallel
from napari_pfsdm.analysis.glossary import columns_markdown, describe_column
from napari_pfsdm.analysis.measuring import Measure, ObjectMeasurer
from napari_pfsdm.analysis.row_blocks import join_blocks
from napari_pfsdm.batch.movies import Movie
from napari_pfsdm.batch.run import run_batch
from napari_pfsdm.batch.tasks import measure_dask
from napari_pfsdm.core.columns import Column
from napari_pfsdm.core.params import PFSDMParams
from napari_pfsdm.data.gastruloids import make_timelapse_montage


def box_fill(view):
    """A measure no release has: the share of its bounding box the object fills (what
    scikit-image calls ``extent``)."""
    return {"box_fill": float(view.mask.sum()) / _box_size(view.mask)}


def _box_size(mask):
    rows, cols = np.nonzero(mask)
    return (rows.max() - rows.min() + 1) * (cols.max() - cols.min() + 1)


BOX_FILL = Measure("box fill", (Column("box_fill", "share of the bounding box the object "
                                                   "fills"),),
                   lambda m: ["box_fill"], box_fill, lambda m: m.ndim == 2)


@pytest.fixture
def with_box_fill(monkeypatch):
    monkeypatch.setattr(measuring, "MEASURES", (*measuring.MEASURES, BOX_FILL))


@pytest.fixture(scope="module")
def movie():
    labels, reporter, _ = make_timelapse_montage(3, 4, 128, seed=11)
    return labels, reporter


def _expected_extent(labels):
    rows = []
    for t, frame in enumerate(labels):
        props = regionprops_table(frame, properties=("label", "extent"))
        rows += [(t, int(lab), float(e)) for lab, e in zip(props["label"], props["extent"],
                                                           strict=True)]
    return pd.DataFrame(rows, columns=["frame", "label", "extent"])


def _drain(gen):
    try:
        while True:
            next(gen)
    except StopIteration as stop:
        return stop.value


def test_a_new_measure_reaches_the_table_the_glossary_and_every_path(movie, with_box_fill,
                                                                      tmp_path, monkeypatch):
    labels, reporter = movie
    expected = _expected_extent(labels)
    tables = {"measure": pf.measure(labels, reporter)}
    monkeypatch.setattr(parallel, "MIN_OBJECTS", 1)
    monkeypatch.setattr(parallel, "MIN_TASK_OBJECTS", 1)
    blocks = _drain(parallel.iter_blocks(labels, reporter, params=PFSDMParams(), axes="tyx",
                                         workers=2))
    assert len(blocks) > 1
    tables["process pool"] = join_blocks(blocks).table
    tables["dask processes"] = measure_dask(labels, reporter, scheduler="processes",
                                            num_workers=2)
    tifffile.imwrite(tmp_path / "m.tif", labels, photometric="minisblack")
    tifffile.imwrite(tmp_path / "m_reporter.tif", reporter, photometric="minisblack")
    run_batch([Movie("m", tmp_path / "m.tif", tmp_path / "m_reporter.tif")],
              tmp_path / "f.csv", scheduler="processes", num_workers=2)
    tables["batch"] = pf.read_table(tmp_path / "f.csv")
    from napari_pfsdm.napari._results import run_analysis

    tables["plugin"] = _drain(run_analysis(labels, reporter, workers=2))["table"]
    for path, table in tables.items():
        cols = list(table.columns)
        # between the other measures and the features, where MEASURES puts it
        assert cols.index("polarity_angle_midline" if "polarity_angle_midline" in cols
                          else "intensity_polarity") + 1 == cols.index("box_fill"), path
        got = table[["frame", "label", "box_fill"]].merge(expected, on=["frame", "label"])
        assert len(got) == len(expected) == len(table), path
        np.testing.assert_allclose(got["box_fill"], got["extent"], rtol=1e-12, err_msg=path)
    assert describe_column("box_fill") == "share of the bounding box the object fills"
    assert "| `box_fill` | share of the bounding box the object fills |  |" in \
        columns_markdown()


def test_the_measurer_is_what_every_path_sends():
    m = ObjectMeasurer.of(PFSDMParams(profile_bins=4), with_intensity=True, axes="tyx")
    assert [x.name for x in m.measures] == ["shape (2-D)", "reporter", "midline"]
    assert m.columns[:2] == ["frame", "label"]
    assert m.columns == list(pf.measure(make_timelapse_montage(1, 1, 64, seed=1)[0],
                                        make_timelapse_montage(1, 1, 64, seed=1)[1],
                                        profile_bins=4).columns)
    volumes = ObjectMeasurer.of(PFSDMParams(), ndim=3, axes="zyx", spacing=(2, 1, 1))
    assert [x.name for x in volumes.measures] == ["shape (3-D)"]
    assert volumes.record()["spacing"] == [2.0, 1.0, 1.0]


def test_leave_out_options_never_reach_the_measurer():
    p = PFSDMParams(border_objects="leave_out", warned_objects="leave_out", n_fourier=6)
    m = ObjectMeasurer.of(p)
    assert m.params == PFSDMParams(n_fourier=6)
    assert m.record()["border_objects"] == "keep"
    import pickle

    assert b"leave_out" not in pickle.dumps(m)


def test_changing_the_leave_out_options_measures_nothing_again_and_changes_the_space(
        tmp_path):
    """Measure a folder; change border_objects: no movie is measured again, the table's
    record and its shape space change (the border objects leave the PCA)."""
    from napari_pfsdm.cli import main

    labels, reporter, _ = make_timelapse_montage(3, 4, 128, seed=11)
    labels = labels.copy()
    labels[:, :6, 20:34] = 90  # an object cut by the top edge in every frame
    folder = tmp_path / "movies"
    folder.mkdir()
    for name in ("a", "b"):
        tifffile.imwrite(folder / f"{name}.tif", labels, photometric="minisblack")
    out = tmp_path / "f.csv"
    log = []
    first = run_batch([Movie(n, folder / f"{n}.tif") for n in ("a", "b")], out,
                      scheduler="sync", log=log.append)
    assert sum(m.startswith("measured") for m in log) == 2
    log.clear()
    second = run_batch([Movie(n, folder / f"{n}.tif") for n in ("a", "b")], out,
                       scheduler="sync", log=log.append, border_objects="leave_out")
    assert [m.split(" (")[0] for m in log if "measured" in m] == ["skipped a", "skipped b"]
    pd.testing.assert_frame_equal(first, second, check_exact=True)
    again = pf.read_table(out)
    assert again.attrs["pfsdm"]["border_objects"] == "leave_out"
    assert first.attrs["pfsdm"]["border_objects"] == "keep"
    from napari_pfsdm.analysis.shape_space import ShapePCA

    with pytest.warns(UserWarning):
        kept = pf.drop_failed(again)
    assert 90 not in kept["label"].tolist() and 90 in first["label"].tolist()
    n_border = int(first["touches_border"].sum())
    assert len(kept) == len(first) - n_border > 0
    # the same through the command line: nothing measured, the PCA leaves them out
    assert main(["measure", str(folder), "-o", str(out), "-q", "--force",
                 "--border-objects", "keep"]) == 0
    keep = pf.read_table(out)
    assert keep.attrs["pfsdm"]["border_objects"] == "keep"
    scores = ShapePCA().fit(keep).transform(keep)
    left = ShapePCA().fit(again).transform(again)
    assert len(scores) == len(first) and len(left) == len(kept)
    assert 90 in scores["label"].tolist() and 90 not in left["label"].tolist()
