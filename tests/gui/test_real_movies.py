"""The plugin on what biologists bring: untracked movies, label images opened as images,
multi-channel and odd reporters, docks closed mid-run, napari-clusters-plotter beside it."""

from __future__ import annotations

import numpy as np
import pytest
from napari.layers import Labels
from napari_helpers import PLOTS, PREDICTION, dock, run_and_wait, wait_pictures

import napari_pfsdm as pf

pytestmark = pytest.mark.gui


def untracked_movie(n_frames: int = 6, seed: int = 2):
    """Four ellipses of different shapes drifting right half a radius a frame, their ids
    shuffled in every frame (a per-frame segmentation). Returns the labels and, for each
    frame, the label of each true object."""
    rng = np.random.default_rng(seed)
    labels = np.zeros((n_frames, 96, 160), np.uint16)
    yy, xx = np.mgrid[:96, :160]
    axes = [(14, 7), (9, 9), (16, 5), (11, 6)]
    truth = []
    for t in range(n_frames):
        ids = rng.choice(np.arange(1, 40), 4, replace=False)
        for k, ((a, b), lab) in enumerate(zip(axes, ids, strict=True)):
            cy, cx = 24 + 48 * (k // 2), 30 + 60 * (k % 2) + 4 * t
            labels[t][((yy - cy) / b) ** 2 + ((xx - cx) / a) ** 2 <= 1] = lab
        truth.append([int(v) for v in ids])
    return labels, truth


def test_the_selection_follows_the_track_on_an_untracked_movie(qtbot, make_napari_viewer_proxy):
    """Select an object, step one and three frames: napari's selected label, the pictures
    and the trajectory plot's star are those of the same object (its track), not of the
    same label number."""
    labels, truth = untracked_movie()
    viewer = make_napari_viewer_proxy()
    layer = viewer.add_labels(labels, name="nuclei")
    w = dock(viewer)
    analysis = run_and_wait(qtbot, w)
    assert "linked into 4 tracks" in w.status.value
    plots = dock(viewer, PLOTS)
    traj = plots.trajectories
    for k in (0, 2):
        viewer.dims.set_current_step(0, 0)
        layer.selected_label = truth[0][k]
        for t in (1, 4, 3):
            viewer.dims.set_current_step(0, t)
            want = truth[t][k]
            assert layer.selected_label == want and analysis.selection == (t, want)
            wait_pictures(qtbot, w)
            assert w.pictures.shown[1:] == (t, want)
            expected = pf.render_disk(pf.pfsdm(labels[t] == want), 128)
            np.testing.assert_allclose(viewer.layers["nuclei PF-SDF disk"].data[:, :128],
                                       np.nan_to_num(expected), atol=1e-4)
            i = int(np.flatnonzero((traj.keys[:, 0] == t) & (traj.keys[:, 1] == want))[0])
            np.testing.assert_allclose(traj.marks[-1].get_offsets()[0], traj.xy[i])
    # a click on the plot lands on that object, and stepping on follows it from there
    i = int(np.flatnonzero((traj.keys[:, 0] == 2) & (traj.keys[:, 1] == truth[2][3]))[0])
    traj.select(i)
    assert viewer.dims.current_step[0] == 2 and layer.selected_label == truth[2][3]
    viewer.dims.set_current_step(0, 5)
    assert layer.selected_label == truth[5][3]


def test_a_dock_closed_during_a_run_shows_its_results_when_opened_again(
        qtbot, make_napari_viewer_proxy):
    from napari_pfsdm.napari._model import REGISTRY

    labels, truth = untracked_movie()
    viewer = make_napari_viewer_proxy()
    layer = viewer.add_labels(labels, name="nuclei")
    dock_widget, w = viewer.window.add_plugin_dock_widget("napari-pfsdm", "PF-SDM analysis")
    assert w.run() is not None
    viewer.window.remove_dock_widget(dock_widget)
    qtbot.waitUntil(lambda: REGISTRY.get(layer.unique_id) is not None, timeout=120_000)
    assert layer.features["frame"].tolist() == [t for t in range(6) for _ in range(4)]
    again = dock(viewer)
    assert again.bound is not None and again.export_button.enabled
    assert "linked into 4 tracks" in again.status.value
    viewer.dims.set_current_step(0, 0)
    layer.selected_label = truth[0][1]
    wait_pictures(qtbot, again)
    assert again.pictures.shown[1:] == (0, truth[0][1])
    viewer.dims.set_current_step(0, 2)
    wait_pictures(qtbot, again)
    assert again.pictures.shown[1:] == (2, truth[2][1])


def test_removing_the_layer_removes_its_pictures(qtbot, viewer_widget):
    viewer, w = viewer_widget
    run_and_wait(qtbot, w)
    wait_pictures(qtbot, w)
    pictures = [lay.name for lay in viewer.layers if lay.name.startswith("gastruloids ")
                and lay.name != "gastruloids reporter"]
    assert len(pictures) >= 4
    w.run()  # removed during a second Run
    viewer.layers.remove("gastruloids")
    qtbot.waitUntil(lambda: w.worker is None, timeout=120_000)
    assert [lay.name for lay in viewer.layers] == ["gastruloids reporter"]
    assert w.bound is None and not w.export_button.enabled


def test_a_label_image_opened_as_an_image_is_shown_as_labels_once_chosen(
        qtbot, make_napari_viewer_proxy):
    """A label TIFF napari opened as an Image layer (grey, black on small ids) is offered and,
    once chosen, shown as a Labels layer of the same data; a raw intensity image of whole
    numbers and a float image are not offered as labels."""
    labels, _ = untracked_movie(3)
    viewer = make_napari_viewer_proxy()
    viewer.add_image(np.random.default_rng(0).poisson(300, labels.shape).astype(np.uint16),
                     name="raw")  # a microscope image: whole numbers, but noise
    viewer.add_image(labels.astype(float) * 0.5, name="photo")  # not whole numbers
    image = viewer.add_image(labels, name="mask.tif")  # File ▸ Open of a label TIFF
    w = dock(viewer)  # the only label image: chosen, so shown as labels at once
    made = viewer.layers["mask.tif labels"]
    assert isinstance(made, Labels) and made.data is image.data  # the same array, no copy
    assert not image.visible and w.labels.value == "mask.tif labels"
    assert w.labels.choices == ("mask.tif labels",)
    assert w.reporter.value == ("raw", None)  # the raw image is a reporter
    analysis = run_and_wait(qtbot, w)
    assert len(analysis.table) == 12


def test_a_reporter_is_offered_by_channel_and_an_unfit_one_is_named(qtbot,
                                                                    make_napari_viewer_proxy):
    labels, _ = untracked_movie(3)
    rng = np.random.default_rng(0)
    two = rng.uniform(100, 200, (3, 2, *labels.shape[1:]))
    viewer = make_napari_viewer_proxy()
    viewer.add_labels(labels, name="nuclei")
    viewer.add_image(two, name="stains")  # T × C × Y × X
    viewer.add_image(rng.uniform(size=(3, 50, 50)), name="thumbnail")
    w = dock(viewer)
    assert w.reporter.choices == (None, ("stains", 0), ("stains", 1))
    assert "'thumbnail'" in w.not_offered.value and not w.not_offered.native.isHidden()
    w.reporter.value = ("stains", 1)
    analysis = run_and_wait(qtbot, w)
    expected = pf.measure(labels, two[:, 1])
    np.testing.assert_allclose(analysis.table.filter(like="intensity_r").to_numpy(),
                               expected.filter(like="intensity_r").to_numpy(), rtol=1e-9)


def test_a_constant_reporter_is_measured_with_a_warning(qtbot, make_napari_viewer_proxy):
    labels, _ = untracked_movie(2)
    viewer = make_napari_viewer_proxy()
    viewer.add_labels(labels, name="nuclei")
    viewer.add_image(np.full(labels.shape, 65535, np.uint16), name="page 2")
    w = dock(viewer)
    assert w.reporter.value == ("page 2", None)
    run_and_wait(qtbot, w)
    assert "65535 everywhere" in w.status.value


def test_each_picture_has_its_own_colour_bar_with_its_numbers(qtbot, viewer_widget):
    from napari_pfsdm.napari._pictures import BAR, SIZE, caption_texts

    viewer, w = viewer_widget
    run_and_wait(qtbot, w)
    wait_pictures(qtbot, w)
    texts = caption_texts(viewer.layers["gastruloids captions"])
    for suffix in ("SDF", "PF-SDF disk", "intensity disk"):
        layer = viewer.layers[f"gastruloids {suffix}"]
        lo, hi = layer.contrast_limits
        bar = layer.data[:, -BAR:]
        np.testing.assert_allclose(bar[:, 0], np.linspace(hi, lo, SIZE))  # top = high
        assert not layer.colorbar.visible  # napari's would stack in one corner
        assert f"{hi:.3g}" in texts and f"{lo:.3g}" in texts
    assert any(t.startswith("SDF") for t in texts) and any("reporter" in t for t in texts)
    # the object's own axis: its midline drawn on the object, as its row measured it
    from napari_pfsdm.analysis.pictures import object_midline

    a = w.bound[1]
    frame, label = a.selection
    m = object_midline(a.labels, a.intensity, frame, label, params=a.params, axes=a.axes,
                       box=a.boxes.get((frame, label)))
    lines = viewer.layers["gastruloids outline and skeleton"]
    drawn = [d for d in lines.data if d.shape == m.points.shape
             and np.allclose(d, m.points * lines.scale[-2:] + lines.translate[-2:])]
    assert len(drawn) == 1
    assert any(f"midline (cyan) {m.length:.0f} px" in t for t in texts)


def packed_movie(side: int = 5, frames: int = 4, cell: int = 24, seed: int = 0):
    """Cells that fill the field (each pixel to its nearest centre on a jittered lattice),
    ids shuffled in every frame."""
    rng = np.random.default_rng(seed)
    grid = (np.stack(np.mgrid[:side, :side], -1).reshape(-1, 2) + 0.5) * cell
    centres = grid + rng.uniform(-0.2, 0.2, grid.shape) * cell
    yy, xx = np.mgrid[:side * cell, :side * cell]
    labels = np.zeros((frames, side * cell, side * cell), np.uint16)
    for t in range(frames):
        at = centres + rng.normal(0, 0.08 * cell, centres.shape)
        nearest = np.argmin((yy[..., None] - at[:, 0]) ** 2 + (xx[..., None] - at[:, 1]) ** 2,
                            axis=-1)
        labels[t] = (rng.permutation(len(centres)) + 1)[nearest]
    return labels


def test_packed_cells_are_linked_by_overlap_and_the_panel_offers_both_links(
        qtbot, make_napari_viewer_proxy):
    viewer = make_napari_viewer_proxy()
    viewer.add_labels(packed_movie(), name="epidermis")
    w = dock(viewer)
    assert set(w.identity.choices) >= {"auto", "labels", "centroid", "overlap"}
    analysis = run_and_wait(qtbot, w)
    assert "linked into 25 tracks by overlap (the objects touch)" in w.status.value
    assert analysis.table["track_id"].nunique() == 25
    w.identity.value = "centroid"  # found again from the same run
    assert "Linked into 25 tracks by centroids" in w.status.value
    assert w.bound[1] is analysis and "by centroids" in analysis.tracking_message


def test_thousands_of_tracks_draw_a_sample_of_paths_and_the_selected_one(
        qtbot, make_napari_viewer_proxy):
    from napari_helpers import many_objects

    from napari_pfsdm.napari._plots import MAX_PATHS

    frame = many_objects(20, 40, cell=20)  # 800 objects
    viewer = make_napari_viewer_proxy()
    layer = viewer.add_labels(np.stack([frame, frame]), name="many")
    w = dock(viewer)
    w.identity.value = "labels"
    run_and_wait(qtbot, w)
    plots = dock(viewer, PLOTS)
    traj = plots.trajectories
    paths = traj.artists["paths"].get_segments()
    assert MAX_PATHS // 2 < len(paths) <= MAX_PATHS
    assert f"paths of {len(paths):,} of 800 tracks" in traj.info.value
    viewer.dims.set_current_step(0, 1)
    layer.selected_label = 777
    path = traj.mark_artists["path"]  # the selected track, drawn over the others
    i = [int(np.flatnonzero((traj.keys[:, 0] == t) & (traj.keys[:, 1] == 777))[0])
         for t in (0, 1)]
    np.testing.assert_allclose(np.column_stack(path.get_data()), traj.xy[i])
    assert path.get_zorder() > traj.artists["paths"].get_zorder()
    # the row's numbers with their meanings, as a tooltip of the selected object's line
    area_line = next(line for line in w.hover.native.toolTip().splitlines()
                     if line.startswith("area = "))
    assert area_line.endswith("(pixels)")  # the value, what it means and its unit


def test_a_dock_opened_and_closed_leaves_no_callback_on_the_viewer(qtbot, viewer_widget):
    viewer, w = viewer_widget
    run_and_wait(qtbot, w)

    def callbacks() -> int:
        events = [viewer.dims.events.current_step, viewer.cursor.events.position,
                  *(getattr(viewer.layers.events, k) for k in ("inserted", "removed",
                                                                 "reordered"))]
        return sum(len(e.callbacks) for e in events)

    from napari_pfsdm.napari._model import REGISTRY

    before, registry = callbacks(), len(REGISTRY.updated)
    for _ in range(20):
        for name in (PLOTS, PREDICTION):
            dock_widget, _w = viewer.window.add_plugin_dock_widget("napari-pfsdm", name)
            viewer.window.remove_dock_widget(dock_widget)
        qtbot.wait(10)
    from qtpy.QtWidgets import QApplication

    QApplication.processEvents()
    assert callbacks() == before and len(REGISTRY.updated) == registry


def test_border_objects_left_out_of_the_shape_space_in_the_panel(qtbot,
                                                                  make_napari_viewer_proxy):
    labels = np.zeros((3, 80, 160), np.uint16)
    for t in range(3):
        labels[t, 0:20, 10:30 + t] = 1  # on the border
        labels[t, 30:50, 40:60 + 2 * t] = 2
        labels[t, 55:75, 40:52 + t] = 3
        labels[t, 30:70, 80:95 + t] = 4
    viewer = make_napari_viewer_proxy()
    viewer.add_labels(labels, name="cells")
    w = dock(viewer)
    w.options["border_objects"].value = "leave_out"
    analysis = run_and_wait(qtbot, w)
    assert "3 objects left out of PCA, comparison and prediction: touching the border " \
           "(border_objects)" in w.status.value  # label 1 in each of the 3 frames
    assert len(analysis.table) == 12 and 1 not in analysis.pca["shape"]["label"].tolist()
    assert analysis.measured.sum() == 9
    plots = dock(viewer, PLOTS)
    assert 1 not in plots.trajectories.keys[:, 1]


def test_any_measure_over_time_follows_tracks_and_groups(qtbot, make_napari_viewer_proxy):
    """The Over time tab: the chosen column's line of each object (track), the groups'
    means, the selection's line in red; a click lands on that point's object and frame."""
    from napari_pfsdm.analysis.over_time import over_time

    labels, truth = untracked_movie()
    viewer = make_napari_viewer_proxy()
    layer = viewer.add_labels(labels, name="nuclei")
    w = dock(viewer)
    analysis = run_and_wait(qtbot, w)
    analysis.set_groups({1: "a", 2: "a", 3: "b", 4: "b"})
    plots = dock(viewer, PLOTS)
    plots.tabs.setCurrentIndex(3)
    plot = plots.made[3]
    plot.column.value = "area"
    lines, groups = over_time(analysis.layer_features(), "area", analysis.groups)
    assert lines["object"].nunique() == 4 and len(plot.keys) == 24
    means = [ln for ln in plot.points_axes.get_lines() if ln.get_linewidth() == 2]
    np.testing.assert_allclose(sorted(np.concatenate([m.get_ydata() for m in means])),
                               sorted(groups["mean"]))
    viewer.dims.set_current_step(0, 0)
    layer.selected_label = truth[0][2]
    path = plot.mark_artists["path"]
    track = analysis.object_of(0, truth[0][2])
    want = analysis.table[analysis.table["track_id"] == track].sort_values("frame")["area"]
    np.testing.assert_allclose(path.get_ydata(), want)
    i = int(np.flatnonzero((plot.keys[:, 0] == 4) & (plot.keys[:, 1] == truth[4][1]))[0])
    plot.select(i)
    assert viewer.dims.current_step[0] == 4 and layer.selected_label == truth[4][1]


def test_objects_like_the_selected_one_are_other_objects_and_a_click_goes_there(
        qtbot, viewer_widget):
    """The Similar tab shows by default other objects, each once in its frame nearest the
    selected shape (on a time-lapse the nearest rows are mostly the object itself in other
    frames); its own frames and any object and frame are choices."""
    viewer, w = viewer_widget
    analysis = run_and_wait(qtbot, w)
    plots = dock(viewer, PLOTS)
    plots.tabs.setCurrentIndex(4)
    gallery = plots.made[4]
    labels = viewer.layers["gastruloids"]
    viewer.dims.set_current_step(0, 3)
    labels.selected_label = 2
    measured = pf.drop_failed(analysis.table)
    d = pf.distance_matrix(measured)  # the record's intensity weight: 0
    me = int(np.flatnonzero((measured["frame"] == 3) & (measured["label"] == 2))[0])
    order = [i for i in np.argsort(d[me], kind="stable") if i != me]
    track = measured["track_id"].to_numpy()
    others, seen = [], set()
    for i in order:  # each other object's nearest row
        if track[i] != track[me] and track[i] not in seen:
            seen.add(track[i])
            others.append(i)
    own = [i for i in order if track[i] == track[me]]
    for which, rows in (("others", others[:7]), ("own", own[:7]), ("any", order[:7])):
        gallery.which.value = which
        qtbot.waitUntil(lambda rows=rows: gallery.worker is None
                        and len(gallery.thumbs) == len(rows) + 1, timeout=60_000)
        want = [(3, 2)] + [(int(measured["frame"].iat[i]), int(measured["label"].iat[i]))
                           for i in rows]
        assert [(f, lab) for _ax, f, lab in gallery.thumbs] == want, which
        np.testing.assert_allclose(gallery.result[3], [0, *d[me][rows]], rtol=1e-9)
    assert len(others) == 5  # the sample: six objects
    gallery.which.value = "others"
    qtbot.waitUntil(lambda: gallery.worker is None and len(gallery.thumbs) == 6,
                    timeout=60_000)
    ax, frame, label = gallery.thumbs[3]

    class Click:  # what matplotlib hands the canvas's click handler
        inaxes, button = ax, 1

    gallery._on_click(Click)
    assert viewer.dims.current_step[0] == frame and labels.selected_label == label


def test_an_analysis_saved_and_opened_again_is_the_same_and_changed_data_are_refused(
        qtbot, viewer_widget, tmp_path):
    viewer, w = viewer_widget
    analysis = run_and_wait(qtbot, w)
    analysis.set_groups({1: "left", 2: "left", 3: "right", 4: "right"})
    assert w.save(tmp_path) is not None
    qtbot.waitUntil(lambda: w.export_worker is None, timeout=60_000)
    assert "Saved the analysis" in w.status.value
    analysis.set_groups({})
    assert w.open(tmp_path) is not None
    qtbot.waitUntil(lambda: w.worker is None, timeout=60_000)
    again = w.bound[1]
    assert again is not analysis and again.run == analysis.run + 1
    assert again.groups == {1: "left", 2: "left", 3: "right", 4: "right"}
    np.testing.assert_allclose(again.table.filter(like="shape_r").to_numpy(),
                               analysis.table.filter(like="shape_r").to_numpy())
    np.testing.assert_allclose(again.pca["shape"]["shape_PC1"], analysis.pca["shape"]["shape_PC1"])
    assert "Opened the analysis" in w.status.value
    labels = viewer.layers["gastruloids"]
    data = np.asarray(labels.data).copy()
    data[0][data[0] == 1] = 0  # an object erased
    labels.data = data
    assert w.open(tmp_path) is not None
    qtbot.waitUntil(lambda: w.worker is None, timeout=60_000)
    assert "changed since the analysis was saved" in w.status.value
    assert w.bound[1] is again  # nothing replaced


def test_the_report_button_writes_the_runs_page(qtbot, viewer_widget, tmp_path):
    import base64
    import re

    viewer, w = viewer_widget
    run_and_wait(qtbot, w)
    assert w.report_button.enabled
    assert w.report(tmp_path / "run.html") is not None
    qtbot.waitUntil(lambda: w.export_worker is None, timeout=120_000)
    assert "opens in any browser" in w.status.value
    page = (tmp_path / "run.html").read_text(encoding="utf-8")
    assert "gastruloids" in page and "http://" not in page and "https://" not in page
    images = re.findall(r'src="data:image/png;base64,([^"]+)"', page)
    assert len(images) > 5 and all(base64.b64decode(i)[:4] == b"\x89PNG" for i in images)


def test_a_dock_opened_during_a_run_shows_it_and_its_cancel_stops_it(qtbot,
                                                                      make_napari_viewer_proxy):
    from napari_helpers import many_objects

    from napari_pfsdm.napari._jobs import JOBS
    from napari_pfsdm.napari._model import REGISTRY

    viewer = make_napari_viewer_proxy()
    layer = viewer.add_labels(np.stack([many_objects()] * 4), name="many")
    dock_widget, w = viewer.window.add_plugin_dock_widget("napari-pfsdm", "PF-SDM analysis")
    assert w.run() is not None
    viewer.window.remove_dock_widget(dock_widget)
    again = dock(viewer)  # while the Run goes on
    assert "Measuring the objects of 'many'" in again.status.value, again.status.value
    assert not again.run_button.enabled and again.cancel_button.enabled
    again.cancel()
    qtbot.waitUntil(lambda: not JOBS.of(layer.unique_id), timeout=120_000)
    assert again.status.value == "Cancelled: nothing was kept."
    assert again.run_button.enabled and not again.cancel_button.enabled
    assert REGISTRY.get(layer.unique_id) is None


def test_a_layer_removed_during_a_run_clears_the_dock_and_shows_the_image_again(
        qtbot, make_napari_viewer_proxy):
    from napari_helpers import many_objects

    viewer = make_napari_viewer_proxy()
    image = viewer.add_image(np.stack([many_objects()] * 4), name="mask.tif")  # File ▸ Open
    w = dock(viewer)
    assert w.run() is not None
    assert not image.visible and "mask.tif labels" in viewer.layers  # the Run made the labels
    w.hover.value = "Selected: frame 0 · label 1"  # a line left by an earlier run
    viewer.layers.remove("mask.tif labels")
    qtbot.waitUntil(lambda: w.worker is None, timeout=120_000)
    assert image.visible  # what the Run hid is shown again
    assert w.status.value == ("The Labels layer 'mask.tif labels' was removed during the Run: "
                              "nothing was kept.")
    assert w.hover.value == "" and w.run_button.enabled and not w.cancel_button.enabled


def test_a_saved_analysis_reopens_after_file_open_of_the_same_tiff(
        qtbot, make_napari_viewer_proxy, tmp_path, monkeypatch):
    """Saved from a label TIFF that napari opened as an image; reopened in another viewer
    where File ▸ Open made it an Image layer again (found by its data, not its name), and in
    one where nothing is open (read from the file it recorded). The words say opened."""
    import tifffile

    from napari_pfsdm.napari import _jobs

    labels, _ = untracked_movie(3)
    path = tmp_path / "mask.tif"
    tifffile.imwrite(path, labels)
    viewer = make_napari_viewer_proxy()
    viewer.open(str(path), plugin="napari")  # napari's own reader: an Image layer 'mask'
    w = dock(viewer)
    analysis = run_and_wait(qtbot, w)
    assert analysis.paths == {"labels": str(path)}
    assert w.save(tmp_path / "kept") is not None
    qtbot.waitUntil(lambda: w.export_worker is None, timeout=60_000)
    said = []
    monkeypatch.setattr(_jobs, "show_info", said.append)
    for opened_first in (True, False):
        other = make_napari_viewer_proxy()
        if opened_first:
            other.open(str(path), plugin="napari")
            other.layers[0].name = "renamed"  # found by its data
        w2 = dock(other)
        assert w2.open(tmp_path / "kept") is not None
        qtbot.waitUntil(lambda w2=w2: w2.worker is None, timeout=60_000)
        assert w2.bound is not None, w2.status.value
        again = w2.bound[1]
        np.testing.assert_array_equal(np.asarray(again.labels), labels)
        assert len(again.table) == len(analysis.table) == 12
        assert w2.status.value.startswith(f"Opened the analysis saved in {tmp_path / 'kept'}: "
                                          "12 objects, nothing measured.")
        assert said[-1] == "PF-SDM: 12 objects opened."
        made = "renamed labels" if opened_first else "mask labels"
        assert w2.bound[0].name == made and isinstance(other.layers[made], Labels)
        assert not opened_first or not other.layers["renamed"].visible


def test_label_files_open_as_labels_with_the_plugins_reader(qtbot, make_napari_viewer_proxy,
                                                             tmp_path):
    """napari offers the plugin's reader for label TIFFs and Zarr stores (File ▸ Open, drag and
    drop) under the plugin's name; it opens whole numbers as a Labels layer with the file's
    values, and leaves other images to napari's own reader."""
    import tifffile
    import zarr
    from napari.plugins._npe2 import get_readers

    labels, _ = untracked_movie(3)
    tif, floats = tmp_path / "nuclei.tif", tmp_path / "photo.tif"
    tifffile.imwrite(tif, labels)
    tifffile.imwrite(floats, labels.astype(np.float32))
    store = tmp_path / "nuclei.zarr"
    zarr.save_array(str(store), labels)
    viewer = make_napari_viewer_proxy()
    for path in (tif, store):
        assert get_readers(path)["napari-pfsdm"] == "PF-SDM morphometrics"
        (layer,) = viewer.open(str(path), plugin="napari-pfsdm")
        assert isinstance(layer, Labels) and layer.name.startswith("nuclei")  # the file's name
        np.testing.assert_array_equal(np.asarray(layer.data), labels)
        assert layer.source.path == str(path)
    from napari_pfsdm.napari._reader import get_reader

    assert get_reader(str(floats)) is None  # napari's own reader opens it
    (image,) = viewer.open(str(floats), plugin="napari")
    assert not isinstance(image, Labels)


def _shown(viewer) -> np.ndarray:
    """What the canvas shows (RGB), as a mask of lit pixels."""
    return viewer.screenshot(canvas_only=True, flash=False)[..., :3].max(axis=-1) > 60


@pytest.mark.parametrize("size", [(1280, 800), (900, 640)])
def test_captions_never_overlap_the_pictures_or_each_other_in_the_fit_view(
        qtbot, make_napari_viewer, size):
    """A folded three-armed object with a reporter: every caption (titles, the object, the
    colour bars' numbers, the folded samples' words, the midline note) drawn alone in napari's
    fit view lies apart from the pictures and from every other caption, at two window sizes;
    the SDF's colours span the object's depth, the disk's its own values."""
    from scipy import ndimage

    from napari_pfsdm.data.shapes import rasterize, three_armed
    from napari_pfsdm.napari._pictures import caption_texts

    labels = rasterize(three_armed() * 140 + 160, (320, 320)).astype(np.uint16)
    reporter = ndimage.gaussian_filter(np.random.default_rng(0).uniform(0, 1, labels.shape),
                                       20) * 1000
    viewer = make_napari_viewer(show=True)
    viewer.window._qt_window.resize(*size)
    viewer.add_image(reporter, name="reporter", visible=False)
    viewer.add_labels(labels, name="arms")
    w = dock(viewer)
    analysis = run_and_wait(qtbot, w)
    wait_pictures(qtbot, w)
    viewer.reset_view()  # napari's fit
    qtbot.wait(300)
    a = analysis.table.iloc[0]
    sdf, disk = viewer.layers["arms SDF"], viewer.layers["arms PF-SDF disk"]
    depth = float(-sdf.data[:, :128].min())
    assert sdf.contrast_limits == [-depth, depth] and sdf.data.max() > 2 * depth
    assert disk.contrast_limits[1] == pytest.approx(np.abs(disk.data[:, :128]).max())
    captions = viewer.layers["arms captions"]
    texts = caption_texts(captions)
    assert f"red: {100 * a['folded_fraction']:.1f} % of the samples lie" in texts
    assert any(t.startswith("midline (cyan)") for t in texts) and "reporter (× mean)" in texts
    for lay in viewer.layers:
        lay.visible = lay.name.startswith("arms ") and lay is not captions
    pictures = ndimage.binary_dilation(_shown(viewer), iterations=1)
    boxes = []
    for i, text in enumerate(texts):
        if not text:
            continue
        captions.text.string = [t if k == i else "" for k, t in enumerate(texts)]
        for lay in viewer.layers:
            lay.visible = lay is captions
        qtbot.wait(50)
        lit = _shown(viewer)
        assert lit.any(), text
        rows, cols = np.flatnonzero(lit.any(1)), np.flatnonzero(lit.any(0))
        box = (rows[0], rows[-1] + 1, cols[0], cols[-1] + 1)
        assert not pictures[box[0]:box[1], box[2]:box[3]].any(), (text, size)
        assert box[0] > 0 and box[2] > 0 and box[1] < lit.shape[0] and box[3] < lit.shape[1]
        boxes.append((text, box))
    for k, (t1, b1) in enumerate(boxes):
        for t2, b2 in boxes[k + 1:]:
            apart = b1[1] <= b2[0] or b2[1] <= b1[0] or b1[3] <= b2[2] or b2[3] <= b1[2]
            assert apart, (t1, t2, size)
    assert len(boxes) >= 12
