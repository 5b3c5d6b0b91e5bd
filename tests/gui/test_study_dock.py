"""The study dock: several Labels layers (movies whose labels repeat) measured as one study."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from napari_helpers import RUN_TIMEOUT_MS, dock
from skimage.measure import regionprops

pytestmark = pytest.mark.gui

STUDY = "PF-SDM study"
TIMES = [2.0, 5.0, 5.0, 9.0]  # uneven, one time imaged twice
PIXEL = 0.5  # µm


def _movie(size: float, n: int = 4, shift: int = 0) -> np.ndarray:
    """Two ellipses growing over ``n`` frames, labels 1 and 2 (as in every movie)."""
    yy, xx = np.mgrid[:72, :72]
    out = np.zeros((n, 72, 72), np.uint16)
    for t in range(n):
        r = size + t
        out[t][((yy - 22) / r) ** 2 + ((xx - 22 - shift) / (0.7 * r)) ** 2 <= 1] = 1
        out[t][((yy - 50) / (0.8 * r)) ** 2 + ((xx - 50) / (0.6 * r)) ** 2 <= 1] = 2
    return out


#: Clone "big" is √2 times wider than clone "small": twice the area.
MOVIES = {"small_a": _movie(6), "small_b": _movie(6, shift=2),
          "big_a": _movie(6 * 2 ** 0.5), "big_b": _movie(6 * 2 ** 0.5, shift=1)}


@pytest.fixture
def study_viewer(make_napari_viewer_proxy):
    viewer = make_napari_viewer_proxy()
    for name, data in MOVIES.items():
        viewer.add_labels(data, name=name, scale=(1, PIXEL, PIXEL))
    rng = np.random.default_rng(0)
    # big_a's reporter, named as it; and an image of small_a's shape named for another movie
    viewer.add_image(rng.random(MOVIES["big_a"].shape), name="big_a reporter")
    viewer.add_image(rng.random(MOVIES["small_a"].shape), name="other_movie reporter")
    widget = dock(viewer, STUDY)
    return viewer, widget


def _run(qtbot, widget):
    worker = widget.run()
    assert worker is not None, widget.status.value
    qtbot.waitUntil(lambda: widget.worker is None, timeout=RUN_TIMEOUT_MS)
    assert widget.study is not None, widget.status.value
    return widget.study


def _choose_all(widget):
    widget.movies.value = list(MOVIES)


def test_run_measures_every_movie_in_microns_and_days_with_groups_from_names(qtbot,
                                                                            study_viewer):
    viewer, w = study_viewer
    _choose_all(w)
    w.times.value = ", ".join(f"{t:g}" for t in TIMES)
    w.time_unit.value = "day"
    w.name_rule.value = "prefix"
    study = _run(qtbot, w)
    t = study.table
    assert sorted(t["movie"].unique()) == sorted(MOVIES)
    for movie, data in MOVIES.items():
        rows = t[t["movie"] == movie]
        for frame in range(data.shape[0]):
            for prop in regionprops(data[frame]):
                got = rows[(rows["frame"] == frame) & (rows["label"] == prop.label)]
                assert len(got) == 1
                assert got["area"].iloc[0] == pytest.approx(prop.area * PIXEL ** 2)
                assert got["time"].iloc[0] == TIMES[frame]
        assert set(rows["group"]) == {movie.split("_")[0]}
    # each movie's rows in its own layer's features, every frame, once per Run
    for movie in MOVIES:
        f = viewer.layers[movie].features
        mine = t[t["movie"] == movie]
        assert f["frame"].tolist() == mine["frame"].tolist()
        assert f["area"].tolist() == pytest.approx(mine["area"].tolist())
    # the statistics find the built-in difference (big objects: twice the area)
    over = w.plots[1]
    w.tabs.setCurrentIndex(1)
    over.measure.value = "area"
    over.redraw()
    sentence = " ".join(over.sentences)
    assert "the groups differ" in sentence and "day 9" in sentence, sentence
    assert "µm²" in sentence


def test_reporters_are_only_the_movies_own(qtbot, study_viewer):
    viewer, w = study_viewer
    _choose_all(w)
    found = w.reporter_names()
    # 'other_movie reporter' has small_a's shape but another name: never taken
    assert found == {"small_a": None, "small_b": None, "big_a": "big_a reporter",
                     "big_b": None}
    assert "big_a ← big_a reporter" in w.reporters.value
    assert "small_a: none" in w.reporters.value
    given = w.gather()
    assert set(given.reporters) == {"big_a"}
    np.testing.assert_array_equal(given.reporters["big_a"],
                                  viewer.layers["big_a reporter"].data)


def test_groups_file_with_another_column_and_a_click_shows_the_object(qtbot, study_viewer,
                                                                      tmp_path):
    viewer, w = study_viewer
    groups = tmp_path / "groups.csv"
    pd.DataFrame({"movie": [f"{m}.tif" for m in MOVIES],
                  "clone": ["A", "A", "B", "C"],
                  "lab": ["x"] * 4}).to_csv(groups, index=False)
    _choose_all(w)
    w.groups_file.value = groups
    assert list(w.group_column.choices) == ["clone", "lab"]
    w.group_column.value = "clone"
    study = _run(qtbot, w)
    per_movie = study.table.groupby("movie")["group"].first().to_dict()
    assert per_movie == {"small_a": "A", "small_b": "A", "big_a": "B", "big_b": "C"}
    # a click on the point of big_a frame 2 label 1 in Trajectories shows that object
    traj = w.plots[0]
    traj.redraw()
    i = traj.keys.index(("big_a", 2, 1))
    x, y = traj.points_axes.transData.transform(traj.xy[i])
    from matplotlib.backend_bases import MouseButton, MouseEvent

    traj.canvas.draw()
    event = MouseEvent("button_press_event", traj.canvas, x, y, button=MouseButton.LEFT)
    traj._on_click(event)
    layer = viewer.layers["big_a"]
    assert viewer.layers.selection.active.name == "big_a"
    assert layer.visible
    assert not viewer.layers["small_a"].visible
    assert viewer.dims.current_step[0] == 2
    assert layer.selected_label == 1
    assert w.selection == ("big_a", 2, 1)
    # napari's selected label moves the study's selection (the Similar tab follows it)
    layer.selected_label = 2
    assert w.selection == ("big_a", 2, 2)
    w.tabs.setCurrentIndex(2)
    similar = w.plots[2]
    qtbot.waitUntil(lambda: similar.worker is None and bool(similar.thumbs), timeout=RUN_TIMEOUT_MS)
    assert similar.thumbs[0][1] == ("big_a", 2, 2)
    assert {key[0] for _ax, key in similar.thumbs[1:]} - {"big_a"}  # other movies' shapes


def test_removing_a_layer_during_the_run_ends_it_cleanly(qtbot, study_viewer):
    viewer, w = study_viewer
    _choose_all(w)
    worker = w.run()
    assert worker is not None
    viewer.layers.remove("small_b")
    qtbot.waitUntil(lambda: w.worker is None, timeout=RUN_TIMEOUT_MS)
    assert w.study is None
    assert "removed during the Run" in w.status.value
    assert "small_b" not in w.movies.choices


def test_cancel_keeps_nothing(qtbot, study_viewer):
    _viewer, w = study_viewer
    _choose_all(w)
    assert w.run() is not None
    w.cancel()
    qtbot.waitUntil(lambda: w.worker is None, timeout=RUN_TIMEOUT_MS)
    assert w.study is None
    assert "Cancelled" in w.status.value
    assert w.run_button.enabled


def test_bad_times_are_refused_in_words(study_viewer):
    _viewer, w = study_viewer
    _choose_all(w)
    w.times.value = "2, 5, x"
    w.time_unit.value = "day"
    assert w.run() is None
    assert "'x' is not a number" in w.status.value


def test_prediction_tab_scores_the_groups(qtbot, study_viewer):
    _viewer, w = study_viewer
    _choose_all(w)
    _run(qtbot, w)
    tab = w.plots[3]
    w.tabs.setCurrentIndex(3)
    assert list(tab.frames.choices) == [0, 1, 2, 3]
    tab.frames.value = [3]
    assert tab.start() is not None
    qtbot.waitUntil(lambda: tab.worker is None, timeout=RUN_TIMEOUT_MS)
    assert tab.prediction is not None, tab.info.value
    assert tab.prediction.frames == [3]
    assert "fused balanced accuracy" in tab.info.value
    assert len(tab.figure.axes) >= 2  # the scores and the confusion matrix


def test_every_dock_at_1280x800_leaves_the_study_form_whole(qtbot, make_napari_viewer_proxy):
    from napari_helpers import ANALYSIS, PLOTS, PREDICTION

    from napari_pfsdm.napari._widgets import dock_of

    viewer = make_napari_viewer_proxy(show=True)
    viewer.window.resize(1280, 800)
    for name, data in MOVIES.items():
        viewer.add_labels(data, name=name)
    for name in (ANALYSIS, PLOTS, PREDICTION):
        dock(viewer, name)
    w = dock(viewer, STUDY)
    dock_of(w).raise_()
    _choose_all(w)
    qtbot.wait(300)
    form = w.form.native
    assert form.height() >= form.sizeHint().height()  # no row squeezed
    inside = w.rect()
    for widget in (w.movies, w.reporters, w.times, w.times_file, w.space_unit, w.groups_file,
                   w.group_column, w.name_rule, w.run_button, w.cancel_button):
        box = widget.native.rect().translated(widget.native.mapTo(w, widget.native.rect()
                                                                  .topLeft()))
        assert inside.contains(box), widget.label
        assert widget.native.isVisible()
    assert w.tabs.height() >= 250  # the plots keep room under the form


def test_units_from_napari_export_and_renamed_layers(qtbot, study_viewer, tmp_path):
    viewer, w = study_viewer
    for name in ("small_a", "big_a"):
        viewer.layers[name].units = ("pixel", "nm", "nm")
    w.movies.value = ["small_a", "big_a"]
    assert w.gather().space_unit == "nm"  # napari's unit wins over the form's µm
    study = _run(qtbot, w)
    assert "sizes in nm" in w.status.value
    out = w.export(tmp_path / "study.csv")
    back = pd.read_csv(out)
    assert back[["movie", "frame", "label"]].values.tolist() == \
        study.table[["movie", "frame", "label"]].values.tolist()
    assert "shape_PC1" in back
    # a renamed layer is renamed in the list
    viewer.layers["big_a"].name = "big_z"
    assert "big_z" in w.movies.choices and "big_a" not in w.movies.choices
