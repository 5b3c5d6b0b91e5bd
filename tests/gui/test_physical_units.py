"""The analysis dock in physical units: the layer's scale is the pixel size, the file's (or the
user's) times are the frames' times; the table's sizes and times follow, checked against
scikit-image's regionprops and the times written into the file."""

from __future__ import annotations

import numpy as np
import pytest
import tifffile
from napari_helpers import dock, run_and_wait
from skimage.measure import regionprops_table

PIXEL = 3.165  # µm, as the brain-organoid study's first microscope


def movie() -> np.ndarray:
    """Three frames of two ellipses that grow (labels 1, 2)."""
    yy, xx = np.mgrid[:80, :120]
    out = np.zeros((3, 80, 120), np.uint16)
    for t in range(3):
        out[t][((yy - 30) / (10 + 2 * t)) ** 2 + ((xx - 35) / 14) ** 2 < 1] = 1
        out[t][((yy - 45) / 9) ** 2 + ((xx - 85) / (12 + 3 * t)) ** 2 < 1] = 2
    return out


def expected_areas(labels: np.ndarray, side: float) -> dict[tuple[int, int], float]:
    out = {}
    for t, frame in enumerate(labels):
        props = regionprops_table(frame, properties=("label", "area"))
        for lab, area in zip(props["label"], props["area"], strict=True):
            out[(t, int(lab))] = float(area) * side ** 2
    return out


def test_a_calibrated_file_opens_with_its_scale_and_times_and_is_measured_in_them(
        make_napari_viewer_proxy, qtbot, tmp_path):
    labels = movie()
    path = tmp_path / "org01.tif"
    tifffile.imwrite(path, labels, imagej=True, resolution=(1 / PIXEL, 1 / PIXEL),
                     metadata={"axes": "TYX", "unit": "um", "finterval": 2.0, "tunit": "min"})
    viewer = make_napari_viewer_proxy()
    (layer,) = viewer.open(path, plugin="napari-pfsdm")
    assert tuple(layer.scale) == pytest.approx((1.0, PIXEL, PIXEL))
    assert layer.metadata["times"] == [0.0, 2.0, 4.0]
    widget = dock(viewer)
    assert widget.pixel_size.value == f"{PIXEL:g}" and widget.space_unit.value == "µm"
    assert widget.times.value == "0, 2, 4" and widget.time_unit.value == "min"
    table = run_and_wait(qtbot, widget).table
    want = expected_areas(labels, PIXEL)
    got = {(int(f), int(lab)): a for f, lab, a in table[["frame", "label", "area"]].to_numpy()}
    assert got.keys() == want.keys()
    for key, area in want.items():  # µm², not pixels
        assert got[key] == pytest.approx(area, rel=1e-9)
    assert table["time"].tolist() == [2.0 * f for f in table["frame"]]
    assert table.attrs["pfsdm"]["space_unit"] == "µm"
    assert table.attrs["pfsdm"]["time_unit"] == "min"


def test_the_panel_takes_uneven_times_and_refuses_a_wrong_count(make_napari_viewer_proxy,
                                                                 qtbot):
    labels = movie()
    viewer = make_napari_viewer_proxy()
    viewer.add_labels(labels, name="org02", scale=(1, 0.5, 0.5))  # a scale without a unit
    widget = dock(viewer)
    assert widget.pixel_size.value == "0.5" and widget.space_unit.value == "µm"
    widget.times.value = "2, 5"  # two times for three frames
    widget.time_unit.value = "day"
    assert widget.run() is None
    assert "3" in widget.status.value and "time" in widget.status.value
    widget.times.value = "2, 5, 5"  # uneven, a day imaged twice
    widget.pixel_size.value = "0.5, 0.4"  # not square: refused before any work
    assert widget.run() is None and "not square" in widget.status.value
    widget.pixel_size.value = "0.5"
    widget.space_unit.value = "pixels"  # sizes in pixels after all
    table = run_and_wait(qtbot, widget).table
    assert table["time"].tolist() == [[2.0, 5.0, 5.0][f] for f in table["frame"]]
    want = expected_areas(labels, 1.0)
    assert table["area"].tolist() == [want[(int(f), int(lab))]
                                      for f, lab in table[["frame", "label"]].to_numpy()]
    assert table.attrs["pfsdm"].get("space_unit") in (None, "pixels")
