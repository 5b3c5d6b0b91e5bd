"""Feature tables over frames and labels."""

import numpy as np
import pytest

import napari_pfsdm as P


def stack(n_frames=3):
    labels = np.zeros((n_frames, 96, 96), np.uint16)
    yy, xx = np.mgrid[:96, :96]
    for t in range(n_frames):
        labels[t][((yy - 30) / (15 + t)) ** 2 + ((xx - 30) / 10) ** 2 < 1] = 1
        labels[t][(yy - 65) ** 2 + (xx - 65) ** 2 < (12 + 2 * t) ** 2] = 7
    return labels


def test_measure_gives_one_row_per_frame_and_label():
    table = P.measure(stack())
    assert len(table) == 6
    assert table[["frame", "label"]].to_numpy().tolist() == [
        [0, 1], [0, 7], [1, 1], [1, 7], [2, 1], [2, 7]]
    assert "shape_r03_n05" in table.columns and "intensity_r00_n00" not in table.columns
    assert (table["error"] == "").all()
    assert table["area"].iloc[1] == np.count_nonzero(stack()[0] == 7)
    assert table["centroid_y"].iloc[1] == pytest.approx(65, abs=0.5)
    opts = table.attrs["pfsdm"]
    assert len(opts["radii"]) == opts["n_radii"] == 16 and len(opts["weights"]) == 16


def test_measure_matches_pfsdm_on_each_object_and_takes_intensity():
    labels = stack()
    inten = np.random.default_rng(0).uniform(1, 2, labels.shape)
    table = P.measure(labels, inten, n_fourier=6)
    res = P.pfsdm(labels[1] == 7, inten[1], n_fourier=6)
    row = table[(table.frame == 1) & (table.label == 7)]
    cols = [c for c in table.columns if c.startswith("shape_")]
    np.testing.assert_allclose(row[cols].to_numpy().ravel(), res.embedding.ravel(), atol=1e-9)
    icols = [c for c in table.columns if c.startswith("intensity_r")]  # not intensity_mean
    np.testing.assert_allclose(row[icols].to_numpy().ravel(), res.intensity_embedding.ravel(),
                               atol=1e-9)


def test_measure_reports_progress_and_accepts_2d_and_dask():
    calls = []
    table = P.measure(stack()[0], progress=lambda d, t: calls.append((d, t)))
    assert calls == [(1, 2), (2, 2)] and (table.frame == 0).all()
    da = pytest.importorskip("dask.array")
    lazy = da.from_array(stack(), chunks=(1, 96, 96))
    np.testing.assert_allclose(P.measure(lazy).filter(like="shape_r").to_numpy(float),
                               P.measure(stack()).filter(like="shape_r").to_numpy(float))


def test_tiny_objects_become_nan_rows_with_a_reason():
    labels = stack(1)
    labels[0, 90, 90] = 3
    table = P.measure(labels)
    bad = table[table.label == 3].iloc[0]
    assert "too small" in bad["error"]
    assert np.isnan(bad["shape_r00_n00"])
    assert bad["area"] == 1
    # never silently NaN: the matrix of a table with failed rows is refused ...
    with pytest.raises(ValueError, match=r"1 of 3 rows have no shape features or are left "
                                         r"out by the options \(frame 0 label 3"):
        P.distance_matrix(table)
    # ... and drop_failed leaves them out, saying which
    with pytest.warns(UserWarning, match=r"left out 1 of 3 rows .*frame 0 label 3: .*too small"):
        measured = P.drop_failed(table)
    assert 3 not in measured["label"].tolist() and len(measured) == 2
    d = P.distance_matrix(measured)
    assert d.shape == (2, 2) and np.isfinite(d).all()


def test_border_objects_are_flagged():
    labels = stack(1)
    labels[0, 0:10, 40:60] = 5
    table = P.measure(labels)
    assert table.set_index("label")["touches_border"].to_dict() == {1: False, 5: True, 7: False}


@pytest.mark.parametrize(
    ("labels", "intensity", "message"),
    [
        (np.zeros((2, 3, 8, 8), int), None, "axes='tzyx'"),  # 4-D: must say its axes
        (np.zeros((8, 8), float), None, "integer"),
        (np.zeros((2, 8, 8), int), np.zeros((2, 8, 9)), "same frames"),
    ],
)
def test_measure_refuses_malformed_input(labels, intensity, message):
    with pytest.raises(ValueError, match=message):
        P.measure(labels, intensity)


def test_distance_matrix_of_table_equals_that_of_results():
    labels = stack()
    table = P.measure(labels)
    results = [o.result for o in P.iter_objects(labels)]
    np.testing.assert_allclose(P.distance_matrix(table),
                               P.distance_matrix(results, invariance="magnitude"), atol=1e-12)


def test_a_numerical_failure_costs_one_row_not_the_run(monkeypatch):
    """A qhull RuntimeError (degenerate triangulation) in one object becomes that row's
    error; the other objects are measured."""
    from scipy.spatial import QhullError

    from napari_pfsdm.analysis import measuring as features

    real = features.pfsdm

    def flaky(mask, *args, **kwargs):
        if mask.sum() < 460:  # the disk of frame 0 only
            raise QhullError("QH6154 Qhull precision error: initial simplex is flat")
        return real(mask, *args, **kwargs)

    monkeypatch.setattr(features, "pfsdm", flaky)
    table = P.measure(stack(2))
    bad = table["error"] != ""
    assert 0 < bad.sum() < len(table)
    assert table.loc[bad, "error"].str.startswith("numerical failure (QhullError: QH6154").all()
    assert np.isfinite(table.loc[~bad].filter(like="shape_r").to_numpy(float)).all()


def test_rows_are_stacked_in_pieces_as_np_array_would(monkeypatch):
    """The measurer stacks a table's rows piece by piece (a worker thread holding the
    interpreter lock for one np.array over 50,000 rows froze the viewer): same values and
    dtype as np.array, across piece boundaries, and for no rows."""
    from napari_pfsdm.analysis import measuring as features

    monkeypatch.setattr(features, "STACK_PIECE_ROWS", 3)
    rng = np.random.default_rng(0)
    rows = [rng.random(4) for _ in range(8)]
    rows[5] = np.full(4, np.nan)
    got = features.stack_rows(rows, 4)
    np.testing.assert_array_equal(got, np.array(rows))
    assert got.dtype == np.float64
    single = [r.astype(np.float32) for r in rows]
    assert features.stack_rows(single, 4).dtype == np.float32
    assert features.stack_rows(single[:4] + rows[4:], 4).dtype == np.float64  # as np.array
    lists = [[1.0, 2.0], [3.0, np.nan], [5.0, 6.0], [7.0, 8.0]]
    np.testing.assert_array_equal(features.stack_rows(lists, 2, float), np.array(lists, float))
    assert features.stack_rows([], 5).shape == (0, 5)
