"""The plugin's model and results without Qt or napari: runs, signals, the rows behind a view,
the layer it keeps in step (napari's objects played by stand-ins with the same public API)."""

from __future__ import annotations

import gc
import weakref
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("psygnal")

from psygnal import Signal, SignalGroup  # noqa: E402

import napari_pfsdm as pf  # noqa: E402
from napari_pfsdm.napari._features import layer_features  # noqa: E402
from napari_pfsdm.napari._model import Analysis, Registry  # noqa: E402
from napari_pfsdm.napari._results import (  # noqa: E402
    identify,
    object_ids,
    object_line,
    reporter_channels,
    reporter_problem,
    run_analysis,
)


def _table() -> pd.DataFrame:
    return pd.DataFrame({"frame": [0, 0, 1, 1], "label": [1, 2, 1, 2], "area": [10, 20, 11, 21],
                         "error": ["", "too small", "", ""], "warnings": ["", "", "", "w"]})


def _finish(gen):
    """Run a generator to its end; return (its yields, its value)."""
    seen = []
    while True:
        try:
            seen.append(next(gen))
        except StopIteration as stop:
            return seen, stop.value


def _fields(table=None, axes="tyx", **more) -> dict:
    return {"table": _table() if table is None else table, "options": {}, "axes": axes, **more}


def test_each_run_of_a_layer_is_numbered_and_replaces_the_last():
    reg = Registry()
    events = []
    reg.updated.connect(events.append)
    first = reg.new_run("A", _fields())
    second = reg.new_run("A", _fields())
    other = reg.new_run("B", _fields())
    assert (first.run, second.run, other.run) == (1, 2, 1)
    assert reg.get("A") is second and first.key != second.key
    reg.forget("A")
    assert reg.get("A") is None and "A" not in reg and events == ["A", "A", "B", "A"]
    assert reg.new_run("A", _fields()).run == 3  # never reused


def test_one_signal_per_kind_of_change():
    a = Analysis("A", 1, _table(), {}, axes="tyx")
    seen = []
    for name in ("selection", "identity", "groups", "comparison", "prediction"):
        getattr(a.events, name).connect(lambda *args, name=name: seen.append((name, *args)))
    a.select(1, 2)
    a.select(1, 2)  # no change, no signal
    a.set_groups({1: "x"})
    a.set_comparison((0, 0.0, False), {"d": np.zeros((2, 2))})
    a.set_table(_table(), "linked")
    assert seen == [("selection", (1, 2)), ("groups", {1: "x"}),
                    ("comparison", (0, 0.0, False)), ("identity", "linked")]
    assert a.selection == (1, 2) and a.groups == {1: "x"}


def test_a_prediction_made_elsewhere_brings_its_table_and_index():
    a = Analysis("A", 1, _table(), {}, axes="tyx")
    a.sentences["shape"] = ["old"]
    scored = a.with_table(_table().iloc[[2, 3, 0]].assign(p_x=[0.1, 0.2, 0.3], error=""))
    assert a.row_of(1, 1) == 2 and not a.measured[1]  # the analysis is untouched so far
    seen = []
    a.events.prediction.connect(seen.append)
    a.set_prediction("prediction", scored)
    assert seen == ["prediction"] and a.prediction == "prediction"
    assert a.table["p_x"].tolist() == [0.1, 0.2, 0.3] and a.sentences == {}
    assert a.row_of(1, 1) == 0 and a.row_of(0, 2) is None and a.error_of(0, 1) == ""
    assert a.measured.tolist() == [True, True, True]
    assert a.layer_features()["p_x"].tolist() == [0.1, 0.2, 0.3]


# ---------------------------------------------------------------------------------------------
# stand-ins for the napari objects the model uses (their public attributes and events only)
# ---------------------------------------------------------------------------------------------
class _LayerEvents(SignalGroup):
    selected_label = Signal(object)


class _Layer:
    def __init__(self, data, name="cells"):
        self.data, self.name, self.unique_id = data, name, f"{name}-uuid"
        self.ndim, self.multiscale = data.ndim, False
        self.scale, self.translate = (1.0,) * data.ndim, (0.0,) * data.ndim
        self.features, self.events, self._label = None, _LayerEvents(), 1

    @property
    def selected_label(self):
        return self._label

    @selected_label.setter
    def selected_label(self, value):
        self._label = int(value)
        self.events.selected_label.emit(self._label)


class _DimsEvents(SignalGroup):
    current_step = Signal(object)


class _Dims:
    def __init__(self, ndim):
        self.ndim, self.point, self.events = ndim, [0.0] * ndim, _DimsEvents()

    def set_point(self, axis, value):
        self.point[axis] = float(value)
        self.events.current_step.emit(tuple(self.point))


class _LayersEvents(SignalGroup):
    removed = Signal(object)


class _Layers(list):
    def __init__(self, *layers):
        super().__init__(layers)
        self.events = _LayersEvents()

    def __contains__(self, name):
        return any(lay.name == name for lay in self)

    def remove(self, what):
        layer = next(lay for lay in self if what in (lay, lay.name))
        super().remove(layer)
        self.events.removed.emit(SimpleNamespace(value=layer))


def _viewer(*layers, ndim=3):
    return SimpleNamespace(dims=_Dims(ndim), layers=_Layers(*layers))


def _untracked_movie():
    """Three discs moving right (half a radius a frame), their ids shuffled in every frame.
    Returns the labels and each frame's label of each true object."""
    rng = np.random.default_rng(1)
    labels = np.zeros((5, 60, 120), np.uint16)
    yy, xx = np.mgrid[:60, :120]
    truth = []
    for t in range(5):
        ids = rng.permutation([3, 7, 11])
        for k, lab in enumerate(ids):
            labels[t][(yy - 15 - 15 * k) ** 2 + (xx - 20 - 3 * t - 4 * k) ** 2 <= 36] = lab
        truth.append([int(v) for v in ids])
    return labels, truth


def _measured(labels):
    _, fields = _finish(run_analysis(labels, workers=1))
    fields["table"], fields["tracking_message"] = identify(fields["table"], labels, True)
    return fields


def test_the_selection_follows_its_object_through_time_not_its_label():
    """On a movie whose ids change every frame, stepping the time slider keeps the object
    selected: the model's selection and napari's selected label follow it; the features hold
    every frame's rows, written once."""
    labels, truth = _untracked_movie()
    layer = _Layer(labels)
    viewer = _viewer(layer)
    reg = Registry()
    a = reg.new_run(layer, _measured(labels), viewer)
    assert "linked into 3 tracks" in a.tracking_message
    written = layer.features
    assert layer.features["frame"].tolist() == [t for t in range(5) for _ in range(3)]
    for k in range(3):  # each true object in turn
        viewer.dims.set_point(0, 0)
        layer.selected_label = truth[0][k]
        for t in (1, 3, 4, 2):
            viewer.dims.set_point(0, t)
            assert a.selection == (t, truth[t][k]) and layer.selected_label == truth[t][k]
            assert layer.features is written  # never written at a step


def test_an_object_missing_from_a_frame_is_followed_when_it_comes_back():
    labels, truth = _untracked_movie()
    labels[2][labels[2] == truth[2][0]] = 0  # object 0 missing in frame 2
    layer = _Layer(labels)
    viewer = _viewer(layer)
    reg = Registry()
    a = reg.new_run(layer, _measured(labels), viewer)
    layer.selected_label = truth[0][0]
    viewer.dims.set_point(0, 1)
    viewer.dims.set_point(0, 2)
    assert a.selection == (2, 0) and layer.selected_label == truth[1][0]  # napari's unchanged
    viewer.dims.set_point(0, 3)
    assert a.selection == (3, truth[3][0]) and layer.selected_label == truth[3][0]


def test_a_prediction_reaches_the_layer_features_with_no_dock_open():
    labels, _ = _untracked_movie()
    layer = _Layer(labels)
    reg = Registry()
    a = reg.new_run(layer, _measured(labels), _viewer(layer))
    assert "p_big" not in layer.features
    scored = a.with_table(a.table.assign(p_big=np.linspace(0, 1, len(a.table))))
    a.set_prediction("model", scored)
    np.testing.assert_allclose(layer.features["p_big"], scored.table["p_big"])


def test_removing_the_layer_frees_its_analysis_and_its_pictures():
    labels, _ = _untracked_movie()
    layer = _Layer(labels)
    pictures = [SimpleNamespace(name=f"cells {s}") for s in ("SDF", "PF-SDF disk", "captions")]
    other = SimpleNamespace(name="reporter")
    viewer = _viewer(layer, *pictures, other)
    reg = Registry()
    ref = weakref.ref(reg.new_run(layer, _measured(labels), viewer))
    gc.collect()
    assert ref() is not None
    viewer.layers.remove(layer)
    gc.collect()
    assert ref() is None and reg.get(layer.unique_id) is None
    assert [lay.name for lay in viewer.layers] == ["reporter"]  # its pictures went with it
    viewer.dims.set_point(0, 2)  # nothing follows the removed layer any more
    layer.selected_label = 5


def test_a_reporter_is_offered_by_channel_or_said_why_not():
    movie = (4, 32, 48)
    assert reporter_channels(movie, movie) == [None]
    assert reporter_channels((4, 3, 32, 48), movie) == [0, 1, 2]
    assert reporter_channels((3, 4, 32, 48), movie) == [0, 1, 2]
    assert reporter_channels((4, 32, 48, 3), movie) is None  # never Y or X
    assert reporter_channels((4, 32, 40), movie) is None
    assert reporter_channels(movie, movie, rgb=True) is None
    assert "65535 everywhere" in reporter_problem(np.full(movie, 65535, np.uint16))
    ramp = np.linspace(0, 1, np.prod(movie)).reshape(movie)
    assert reporter_problem(ramp) == ""
    ramp[0, :16] = np.nan
    assert "not numbers" in reporter_problem(ramp)


def test_rows_and_errors_are_looked_up_by_frame_and_label():
    a = Analysis("A", 1, _table(), {}, axes="tyx")
    assert a.row_of(1, 2) == 3 and a.row_of(2, 1) is None
    assert a.error_of(0, 2) == "too small" and a.error_of(0, 1) == "" and a.error_of(5, 5) is None
    assert a.labels_in(1).tolist() == [1, 2]
    assert a.measured.tolist() == [True, False, True, True]
    still = Analysis("A", 1, _table(), {}, axes="yx")  # no time axis: the frame is ignored
    assert still.row_of(7, 2) == 1
    read = _table().assign(error=[np.nan, "too small", np.nan, np.nan])  # as CSV reads ""
    a = Analysis("A", 1, read, {}, axes="tyx")
    assert a.error_of(0, 1) == "" and a.measured.tolist() == [True, False, True, True]


def test_the_line_on_an_object_says_what_its_row_holds():
    a = Analysis("A", 1, _table(), {}, axes="tyx")
    assert object_line(a, 0, 2) == "frame 0 · label 2 · area 20 px · no features: too small"
    assert object_line(a, 1, 2) == "frame 1 · label 2 · area 21 px · ⚠ w"
    assert object_line(a, 3, 1) == "frame 3 · label 1: not in this frame"


def test_layer_features_are_numbers_keyed_by_label_with_the_failed_rows_flagged():
    a = Analysis("A", 1, _table().assign(border=[True, False, True, False]), {}, axes="tyx")
    f = layer_features(a.table, {}, None)
    assert list(f.columns[:3]) == ["index", "frame", "label"]
    assert f["index"].tolist() == [1, 2, 1, 2]
    assert f["failed"].tolist() == [0, 1, 0, 0]
    assert "error" not in f and "warnings" not in f
    assert f["border"].tolist() == [1, 0, 1, 0]  # booleans as numbers for plotters


def test_objects_get_one_id_per_frame_and_label_in_the_table_order():
    labels = np.array([[[0, 1, 7]], [[7, 0, 1]]])  # label 7 moves, 1 moves
    table = pd.DataFrame({"frame": [0, 0, 1, 1], "label": [1, 7, 1, 7], "error": [""] * 4})
    ids = object_ids(labels, Analysis("A", 1, table, {}, axes="tyx"))
    assert ids.tolist() == [[[0, 1, 2]], [[4, 0, 3]]]


def test_the_run_gives_the_rows_of_measure_with_progress_to_the_total():
    labels = np.zeros((2, 64, 64), np.uint16)
    labels[:, 8:30, 8:26] = 1
    labels[0, 34:60, 30:50] = 2
    labels[1, 36:58, 28:52] = 2
    seen, fields = _finish(run_analysis(labels, workers=1))
    assert seen[-1] == (4, 4) and all(d <= n for d, n in seen)
    expected = pf.measure(labels)
    pd.testing.assert_frame_equal(fields["table"].reset_index(drop=True),
                                  expected.reset_index(drop=True), check_like=True)
    assert fields["axes"] == "tyx" and "shape_PC1" in fields["pca"]["shape"]
    # the line on a measured object gives its scores on the library's PCA (of the same table)
    from napari_pfsdm.analysis.reduction import pca_scores

    scores, _ = pca_scores(expected, "shape", 5)
    pc1, pc2 = scores.set_index(["frame", "label"]).loc[(1, 2), ["shape_PC1", "shape_PC2"]]
    area = int(expected.set_index(["frame", "label"]).loc[(1, 2), "area"])
    assert object_line(Analysis("A", 1, **fields), 1, 2) == \
        f"frame 1 · label 2 · area {area} px · PC1 {pc1:+.2f} PC2 {pc2:+.2f}"


def test_a_closed_run_stops_and_keeps_nothing():
    labels = np.zeros((3, 64, 64), np.uint16)
    labels[:, 8:30, 8:26] = 1
    gen = run_analysis(labels, workers=1)
    assert next(gen) is not None
    gen.close()
    with pytest.raises(StopIteration):
        next(gen)


def test_bad_layers_are_refused_in_words():
    with pytest.raises(ValueError, match="no objects"):
        _finish(run_analysis(np.zeros((8, 8), np.uint8)))
    with pytest.raises(ValueError, match="colour picture"):
        _finish(run_analysis(np.ones((32, 32, 3), np.uint8)))
    with pytest.raises(ValueError, match="colour picture"):  # a colour movie (T, Y, X, RGB)
        _finish(run_analysis(np.ones((4, 32, 32, 3), np.uint8)))
    with pytest.raises(ValueError, match="does not match"):
        _finish(run_analysis(np.ones((8, 8), np.uint8), np.ones((9, 8))))


def test_ids_that_jump_between_frames_are_linked_into_tracks():
    # two objects far apart whose ids swap from frame to frame (a per-frame segmentation)
    rows = []
    for t in range(6):
        swap = t % 2
        rows += [{"frame": t, "label": 1 + swap, "centroid_y": 10.0, "centroid_x": 10.0 + t,
                  "area": 100, "error": ""},
                 {"frame": t, "label": 2 - swap, "centroid_y": 80.0, "centroid_x": 80.0 - t,
                  "area": 100, "error": ""}]
    table = pd.DataFrame(rows)
    linked, message = identify(table, None, True, "auto")
    left = linked[linked["centroid_y"] == 10.0]["track_id"]
    assert left.nunique() == 1 and "Ids jump between frames" in message
    trusted, warning = identify(table, None, True, "labels")
    assert trusted["track_id"].tolist() == table["label"].tolist()
    assert warning.startswith("Warning")


def test_a_mask_of_booleans_gets_one_id_per_frame():
    labels = np.array([[[False, True]], [[True, False]]])
    table = pd.DataFrame({"frame": [0, 1], "label": [1, 1], "error": ["", ""]})
    ids = object_ids(labels, Analysis("A", 1, table, {}, axes="tyx"))
    assert ids.tolist() == [[[0, 1]], [[2, 0]]]


def test_a_z_stack_is_renumbered_as_one_object_set():
    labels = np.array([[[3, 0]], [[3, 9]]])  # Z × Y × X: label 3 on two slices
    table = pd.DataFrame({"frame": [0, 0], "label": [9, 3], "error": ["", ""]})
    ids = object_ids(labels, Analysis("A", 1, table, {}, axes="zyx"))
    assert ids.tolist() == [[[2, 0]], [[2, 1]]]


def test_the_neighbours_export_names_each_objects_row_in_the_features_file(tmp_path,
                                                                            monkeypatch):
    """Above the export's matrix limit each object's nearest shapes are written with its row
    in the features file: with an object without features first (too small), every ``row`` and
    ``neighbour`` is the row of the same frame and label in the features file, and each
    distance that of ``pf.distance_matrix`` between the two."""
    from napari_pfsdm.napari import _export

    monkeypatch.setattr(_export, "MAX_DISTANCE_ROWS", 4)
    labels = np.zeros((1, 96, 200), np.uint16)
    labels[0, 2:4, 2:4] = 1  # too small to measure: no features
    for k in range(6):  # rectangles of six aspect ratios
        labels[0, 20:40 - k, 8 + 30 * k:8 + 30 * k + 12 + 3 * k] = k + 2
    table = pf.measure(labels)
    assert table["error"].iloc[0] != ""
    paths, note = _export.export(Analysis("A", 1, table, {}, axes="tyx"), tmp_path, "x")
    assert note and paths[-1].name == "x_neighbours.csv"
    features = pd.read_csv(paths[0])
    edges = pd.read_csv(paths[-1])
    assert len(edges) == 6 * 5  # k = min(15, 6 - 1)
    for end in ("", "neighbour_"):
        at = edges["neighbour" if end else "row"]
        assert (features["label"].to_numpy()[at] == edges[end + "label"]).all()
    measured = table[table["error"] == ""]
    d = np.asarray(pf.distance_matrix(measured))
    pos = {lab: i for i, lab in enumerate(measured["label"])}
    want = [d[pos[a], pos[b]] for a, b in zip(edges["label"], edges["neighbour_label"],
                                                strict=True)]
    np.testing.assert_allclose(edges["distance"], want, rtol=1e-9)


def test_an_analysis_saves_itself_and_reads_back_with_its_files_and_names(tmp_path):
    """Saving goes through the model (no dock): the table, PCA, groups, the layers' names and
    the labels' file come back from the folder."""
    from napari_pfsdm.napari._results import saved_fields
    from napari_pfsdm.saved import open_analysis

    labels, _ = _untracked_movie()
    fields = _measured(labels)
    a = Registry().new_run("A", {**fields, "sources": {"labels": "nuclei"},
                                 "paths": {"labels": "/data/nuclei.tif"}})
    a.set_groups({1: "x", 2: "y"})
    a.save(tmp_path)
    saved = open_analysis(tmp_path, labels=labels)
    again = saved_fields(saved, labels)
    pd.testing.assert_frame_equal(again["table"], a.table, check_dtype=False)
    np.testing.assert_allclose(again["pca"]["shape"]["shape_PC1"], a.pca["shape"]["shape_PC1"])
    assert again["groups"] == {1: "x", 2: "y"}
    assert again["sources"] == {"labels": "nuclei"}
    assert again["paths"] == {"labels": "/data/nuclei.tif"}
