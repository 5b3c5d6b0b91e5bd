"""Time and space in the table (issue 64, point 1): frames' times and pixel sizes from the
movies' metadata or given, sizes in physical units, the time column, one unit per table."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import tifffile
from skimage.measure import perimeter, regionprops_table

import napari_pfsdm as pf
from napari_pfsdm.cli import main
from napari_pfsdm.data.gastruloids import make_timelapse_montage
from napari_pfsdm.errors import InputError
from napari_pfsdm.io.metadata import read_metadata


@pytest.fixture(scope="module")
def movie():
    labels, reporter, _ = make_timelapse_montage(3, 3, 128, seed=4)
    return labels.astype(np.uint16), reporter


def _regionprops(labels, spacing):
    rows = []
    for t, frame in enumerate(labels):
        p = regionprops_table(frame, properties=("label", "area", "axis_major_length",
                                                  "axis_minor_length"), spacing=spacing)
        rows.append(pd.DataFrame(p).assign(frame=t))
    return pd.concat(rows, ignore_index=True)


def test_sizes_are_physical_with_a_pixel_size(movie):
    labels, reporter = movie
    s = 0.65
    got = pf.measure(labels, reporter, pixel_size=s, space_unit="um", profile_bins=4)
    ref = _regionprops(labels, (s, s)).merge(got, on=["frame", "label"],
                                              suffixes=("_ref", ""))
    assert len(ref) == len(got)
    np.testing.assert_allclose(ref["area"], ref["area_ref"], rtol=1e-12)
    np.testing.assert_allclose(ref["axis_major_length"], ref["axis_major_length_ref"],
                               rtol=1e-9)
    np.testing.assert_allclose(ref["axis_minor_length"], ref["axis_minor_length_ref"],
                               rtol=1e-9)
    frame0 = labels[0]
    for _, row in got[got["frame"] == 0].iterrows():
        assert row["perimeter"] == pytest.approx(s * perimeter(frame0 == row["label"], 4))
    pixels = pf.measure(labels, reporter, profile_bins=4)
    for column in ("midline_length", "width_mean", "width_b02"):
        np.testing.assert_allclose(got[column], s * pixels[column], rtol=1e-12)
    # shape features, ratios and the reporter do not depend on the pixel size
    for column in ("shape_r03_n02", "circularity", "solidity", "intensity_mean",
                   "centroid_x", "polarity_angle_midline"):
        np.testing.assert_array_equal(got[column], pixels[column])
    assert got.attrs["pfsdm"]["pixel_size"] == [s, s]
    assert got.attrs["pfsdm"]["space_unit"] == "µm"
    assert "space_unit" not in pixels.attrs["pfsdm"]


def test_a_3d_pixel_size_gives_volumes_in_its_unit():
    from napari_pfsdm.data.volumes import blob_volume

    spacing = (2.0, 0.5, 0.5)
    blob = blob_volume("tetrahedron", size=(16, 40, 40), radius=8, spacing=spacing)
    labels = blob.astype(np.uint8)
    got = pf.measure(labels, axes="zyx", pixel_size=spacing, space_unit="um")
    assert got["volume"].iloc[0] == pytest.approx(blob.sum() * 2.0 * 0.5 * 0.5)
    same = pf.measure(labels, axes="zyx", spacing=spacing)
    np.testing.assert_allclose(got["axis_major_length"], same["axis_major_length"])
    np.testing.assert_array_equal(got["shape_r02_l02"], same["shape_r02_l02"])
    with pytest.raises(InputError, match="differ"):
        pf.measure(labels, axes="zyx", spacing=(1, 1, 1), pixel_size=spacing)


def test_uneven_and_repeated_times_make_the_time_column(movie):
    labels, _ = movie
    got = pf.measure(labels, times=[2, 5, 5], time_unit="days")
    assert list(got.columns[:3]) == ["frame", "time", "label"]
    assert dict(zip(got["frame"], got["time"], strict=True)) == {0: 2.0, 1: 5.0, 2: 5.0}
    assert got.attrs["pfsdm"]["time_unit"] == "day"
    assert "time" not in pf.measure(labels[:1]).columns
    for bad, words in (([1, 2], "2 times given for a movie of 3 frames"),
                       ([3, 2, 4], "the times go back"), ([0, float("nan"), 1], "finite")):
        with pytest.raises(InputError, match=words):
            pf.measure(labels, times=bad)
    with pytest.raises(InputError, match="without times"):
        pf.measure(labels, time_unit="day")


def test_units_are_read_as_files_and_people_write_them():
    from napari_pfsdm.core.units import space_unit, time_unit

    assert {space_unit(u)[0] for u in ("um", "µm", "μm", "micron", "Microns")} == {"µm"}
    assert {time_unit(u)[0] for u in ("d", "day", "days")} == {"day"}
    with pytest.raises(InputError, match="not one napari-pfsdm knows"):
        space_unit("furlong")


def _write(path, labels, **kw):
    tifffile.imwrite(path, labels, photometric="minisblack", **kw)
    return path


def test_times_and_pixel_sizes_are_read_from_imagej_ome_and_resolution(tmp_path, movie):
    labels, _ = movie
    ij = _write(tmp_path / "ij.tif", labels, imagej=True, resolution=(1 / 0.65, 1 / 0.65),
                metadata={"axes": "TYX", "unit": "micron", "finterval": 30, "tunit": "min"})
    got = read_metadata(ij, 3)
    assert got.times == (0.0, 30.0, 60.0) and got.time_unit == "min"
    assert got.pixel_size == (0.65, 0.65) and got.space_unit == "µm"
    days = [2 * 86400, 5 * 86400, 5 * 86400]  # one day imaged twice, as OME writes DeltaT
    ome = _write(tmp_path / "uneven.ome.tif", labels, metadata={
        "axes": "TYX", "PhysicalSizeX": 3.165, "PhysicalSizeY": 3.165,
        "PhysicalSizeXUnit": "µm", "PhysicalSizeYUnit": "µm",
        "Plane": {"DeltaT": days, "DeltaTUnit": ["s"] * 3}})
    got = read_metadata(ome, 3)
    assert got.times == tuple(map(float, days)) and got.time_unit == "s"
    assert got.pixel_size == (3.165, 3.165)
    cm = _write(tmp_path / "cm.tif", labels, resolution=(1e4 / 0.5, 1e4 / 0.5),
                resolutionunit=3)
    assert read_metadata(cm, 3).pixel_size == pytest.approx((0.5, 0.5))
    dpi = _write(tmp_path / "dpi.tif", labels, resolution=(72, 72), resolutionunit=2)
    assert read_metadata(dpi, 3).pixel_size is None  # image software's default says nothing
    assert read_metadata(_write(tmp_path / "plain.tif", labels), 3) == read_metadata(dpi, 3)


def test_a_batch_of_two_microscopes_shares_one_unit(tmp_path, movie, capsys):
    labels, _ = movie
    _write(tmp_path / "ij.tif", labels, imagej=True, resolution=(1 / 0.65, 1 / 0.65),
           metadata={"axes": "TYX", "unit": "um", "finterval": 2, "tunit": "h"})
    _write(tmp_path / "other.ome.tif", labels, metadata={
        "axes": "TYX", "PhysicalSizeX": 1300, "PhysicalSizeY": 1300, "PhysicalSizeXUnit": "nm",
        "PhysicalSizeYUnit": "nm", "TimeIncrement": 120, "TimeIncrementUnit": "min"})
    out = tmp_path / "f.csv"
    assert main(["measure", str(tmp_path / "ij.tif"), str(tmp_path / "other.ome.tif"),
                 "-o", str(out), "--scheduler", "sync", "--n-fourier", "4", "--n-radii",
                 "4"]) == 0
    table = pd.read_csv(out)
    a, b = (table[table["movie"] == m].reset_index(drop=True) for m in ("ij", "other"))
    np.testing.assert_allclose(b["area"], 4 * a["area"])  # twice the pixel, in one unit
    np.testing.assert_allclose(a["area"], _regionprops(labels, (0.65, 0.65))["area"])
    assert a["time"].tolist() == b["time"].tolist() == [0.0] * 3 + [2.0] * 3 + [4.0] * 3
    side = json.loads((tmp_path / "f.csv.json").read_text())
    assert side["options"]["space_unit"] == "µm" and side["options"]["time_unit"] == "h"
    assert side["options"]["pixel_sizes"] == {"ij": [0.65, 0.65], "other": [1.3, 1.3]}
    said = capsys.readouterr()
    assert "ij: times from ImageJ metadata; pixel size from ImageJ metadata" in said.out
    assert "measuring: 100%" in said.err and "6/6" in said.err  # one bar over both movies


def test_given_times_and_pixel_size_win_and_a_times_file_names_movies_as_a_lab_does(
        tmp_path, movie, capsys):
    labels, _ = movie
    for name in ("e01", "e02"):
        _write(tmp_path / f"{name}.tif", labels)
    out = tmp_path / "f.csv"
    base = ["--scheduler", "sync", "--n-fourier", "4", "--n-radii", "4", "-q"]
    assert main(["measure", str(tmp_path / "e01.tif"), str(tmp_path / "e02.tif"), "-o",
                 str(out), "--times", "2,5,5", "--time-unit", "day", "--pixel-size", "3.165",
                 "--space-unit", "um", *base]) == 0
    table = pd.read_csv(out)
    pairs = set(zip(table["frame"], table["time"], strict=True))
    assert sorted(pairs) == [(0, 2.0), (1, 5.0), (2, 5.0)]
    np.testing.assert_allclose(table["area"], np.tile(
        _regionprops(labels, (3.165, 3.165))["area"], 2))
    times = tmp_path / "times.csv"
    times.write_text("movie,frame,time\n" + "".join(
        f"{m},{t},{v}\n" for m, off in (("plate1/e01.tif", 0), ("E02.TIF", 10))
        for t, v in enumerate(np.array([1.0, 2.0, 4.0]) + off)))
    assert main(["measure", str(tmp_path / "e01.tif"), str(tmp_path / "e02.tif"), "-o",
                 str(out), "--times", str(times), "--time-unit", "h", "--force", *base]) == 0
    table = pd.read_csv(out)
    assert table.groupby("movie")["time"].max().to_dict() == {"e01": 4.0, "e02": 14.0}
    assert "area" in table and table["area"].dtype.kind in "iu"  # no pixel size: pixels
    assert main(["measure", str(tmp_path / "e01.tif"), "-o", str(tmp_path / "g.csv"),
                 "--times", "1,2", *base]) == 2
    assert "2 times given for a movie of 3 frames" in capsys.readouterr().err


def test_a_batch_that_would_mix_pixels_and_micrometres_is_refused(tmp_path, movie, capsys):
    labels, _ = movie
    _write(tmp_path / "a.tif", labels, imagej=True, resolution=(1 / 0.65, 1 / 0.65),
           metadata={"axes": "TYX", "unit": "um"})
    _write(tmp_path / "b.tif", labels)
    assert main(["measure", str(tmp_path / "a.tif"), str(tmp_path / "b.tif"), "-o",
                 str(tmp_path / "f.csv"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "declare their pixel size (a) but 1 do not (b)" in err and "--pixel-size" in err
    assert not (tmp_path / "f.csv").exists()


def test_tracking_does_not_depend_on_the_pixel_size(movie):
    labels, _ = movie
    shuffled = labels.copy()
    shuffled[1][labels[1] > 0] = (labels[1][labels[1] > 0] % 9) + 1  # ids changed
    small = pf.link(pf.measure(shuffled, pixel_size=0.01, n_fourier=4, n_radii=4))
    big = pf.link(pf.measure(shuffled, pixel_size=100, n_fourier=4, n_radii=4))
    pixels = pf.link(pf.measure(shuffled, n_fourier=4, n_radii=4))
    assert small["track_id"].tolist() == big["track_id"].tolist() == pixels["track_id"].tolist()
    assert pf.check_tracking(big).verdict == pf.check_tracking(pixels).verdict
