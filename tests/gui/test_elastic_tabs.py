"""The elastic outline term in the plots dock: the Similar and Distances tabs' "elastic" box."""

from __future__ import annotations

import numpy as np
from napari_helpers import PLOTS, dock, run_and_wait

import napari_pfsdm as pf


def test_similar_with_the_elastic_term_is_the_nearest_under_the_full_elastic_distance(
        qtbot, viewer_widget):
    viewer, w = viewer_widget
    w.options["elastic_signature"].value = "table"
    analysis = run_and_wait(qtbot, w)
    plots = dock(viewer, PLOTS)
    plots.tabs.setCurrentIndex(4)
    gallery = plots.made[4]
    gallery.which.value = "any"  # the nearest rows, as the matrix orders them
    labels = viewer.layers["gastruloids"]
    viewer.dims.set_current_step(0, 3)
    labels.selected_label = 2
    qtbot.waitUntil(lambda: gallery.worker is None and len(gallery.thumbs) == 8,
                    timeout=60_000)
    plain = [(f, lab) for _ax, f, lab in gallery.thumbs]
    gallery.elastic.value = True  # computed again, with the term
    qtbot.waitUntil(lambda: gallery.worker is None and gallery.result is not None
                    and gallery.result[0][4] > 0 and len(gallery.thumbs) == 8,
                    timeout=120_000)
    measured = pf.drop_failed(analysis.table)
    d = pf.distance_matrix(measured, elastic_weight=pf.RECOMMENDED_ELASTIC_WEIGHT)
    me = int(np.flatnonzero((measured["frame"] == 3) & (measured["label"] == 2))[0])
    order = np.argsort(d[me], kind="stable")[:8]  # itself first, then the 7 nearest
    want = [(int(f), int(lab)) for f, lab in zip(measured["frame"].to_numpy()[order],
                                                measured["label"].to_numpy()[order],
                                                strict=True)]
    assert [(f, lab) for _ax, f, lab in gallery.thumbs] == want
    np.testing.assert_allclose(gallery.result[3], d[me][order], rtol=1e-6)
    assert "elastic term" in gallery.info.value
    assert plain != want or not np.allclose(d, pf.distance_matrix(measured))


def test_distances_with_the_elastic_term_and_without_signatures(qtbot, shown_viewer_widget):
    viewer, w = shown_viewer_widget
    analysis = run_and_wait(qtbot, w)  # the defaults: no signatures in the table
    plots = dock(viewer, PLOTS)
    plots.tabs.setCurrentIndex(1)
    comp = plots.comparison
    qtbot.waitUntil(lambda: comp.worker is None, timeout=60_000)
    comp.elastic.value = True
    qtbot.waitUntil(lambda: comp.worker is None and "elastic_signature" in comp.info.value,
                    timeout=60_000)
    assert "--elastic-signature table" in comp.info.value  # how to get them
    w.options["elastic_signature"].value = "table"
    analysis = run_and_wait(qtbot, w)
    frame = int(viewer.dims.current_step[0])
    key = (frame, 0.0, False, pf.RECOMMENDED_ELASTIC_WEIGHT)
    qtbot.waitUntil(lambda: key in analysis.comparison, timeout=120_000)
    measured = pf.drop_failed(analysis.table)
    shown = measured[measured["frame"] == frame]
    want = pf.distance_matrix(shown, elastic_weight=pf.RECOMMENDED_ELASTIC_WEIGHT)
    np.testing.assert_allclose(analysis.comparison[key]["d"], want, atol=1e-9)
