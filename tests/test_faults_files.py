"""The fault battery, round 2 (issue 57): what files really hold, names that collide, the
user's own files, numbers that would give NaN, formulas in cells, the drawer of each error.

Each test reproduces one case as a user meets it and asserts the plain words, the exit status
and the files left behind (or, for a case that is now handled, the right result). Expected
values are computed here from numpy and the bytes on disk, never from the code under test.
"""

from __future__ import annotations

import csv
import json

import numpy as np
import pandas as pd
import pytest
import tifffile

import napari_pfsdm as pf
from napari_pfsdm.batch.io import open_movie
from napari_pfsdm.cli import main

zarr = pytest.importorskip("zarr")

FAST = {"n_fourier": 4, "n_radii": 4}
CLI_FAST = ["--n-fourier", "4", "--n-radii", "4", "--link", "labels", "-q",
            "--scheduler", "sync"]


def ellipse_labels(shape=(64, 64), centre=(32, 30), axes=(20, 12), label=1) -> np.ndarray:
    """One elliptic object of id ``label`` in a frame of ``shape`` (uint8)."""
    yy, xx = np.mgrid[: shape[0], : shape[1]]
    inside = ((yy - centre[0]) / axes[0]) ** 2 + ((xx - centre[1]) / axes[1]) ** 2 < 1
    out = np.zeros(shape, np.uint8)
    out[inside] = label
    return out


def movie(n_frames: int = 3, shift: int = 1) -> np.ndarray:
    """``n_frames`` frames of one ellipse moving right by ``shift`` pixels per frame."""
    return np.stack([ellipse_labels(centre=(32, 24 + shift * t)) for t in range(n_frames)])


def cells(path) -> list[list[str]]:
    """The CSV's cells as a spreadsheet's importer sees them (no pandas)."""
    with open(path, newline="", encoding="utf-8") as handle:
        return list(csv.reader(handle))


def error_line(capsys) -> str:
    """The one ``pfsdm: error:`` line of the last command (and no traceback)."""
    err = capsys.readouterr().err
    assert "Traceback" not in err and "internal error" not in err, err
    lines = [ln for ln in err.splitlines() if ln.startswith("pfsdm: error:")]
    assert len(lines) == 1, err
    return lines[0]


# --------------------------------------------------------------------------------------------
# 5. tables safe to open in a spreadsheet
# --------------------------------------------------------------------------------------------

FORMULA_NAMES = ["=1+1", "+SUM(A1)", "-2+3", "@cmd", "\tx", "\rx", "'=quoted"]


@pytest.mark.parametrize("name", FORMULA_NAMES)
def test_a_text_cell_is_never_a_formula_and_reads_back_the_same(tmp_path, name):
    from napari_pfsdm.io import read_table, write_table

    df = pd.DataFrame({"movie": [name, "e1"], "group": ["a", name], "frame": [0, 1],
                       "x": [-1.5, 2.0], "n": [-3, 4]})
    out = tmp_path / "t.csv"
    write_table(df, out, {})
    rows = cells(out)
    header, first, second = rows[0], rows[1], rows[2]
    for cell in (first[header.index("movie")], second[header.index("group")]):
        assert cell[0] not in "=+-@\t\r", repr(cell)  # a spreadsheet shows it as text
    # negative numbers are numbers, not escaped
    assert first[header.index("x")] == "-1.5" and first[header.index("n")] == "-3"
    back = read_table(out)
    assert back["movie"].tolist() == [name, "e1"] and back["group"].tolist() == ["a", name]
    assert back["x"].tolist() == [-1.5, 2.0] and back["n"].tolist() == [-3, 4]


def test_movie_names_that_look_like_formulas_are_safe_through_the_command_line(tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    for name in ("=e1", "+e2", "-e3", "@e4"):
        tifffile.imwrite(folder / f"{name}.tif", movie(2))
    out = tmp_path / "f.csv"
    assert main(["measure", str(folder), "-o", str(out), *CLI_FAST]) == 0
    rows = cells(out)
    col = rows[0].index("movie")
    assert all(r[col].startswith("'") for r in rows[1:])
    assert sorted(set(pf.read_table(out)["movie"])) == ["+e2", "-e3", "=e1", "@e4"]


# --------------------------------------------------------------------------------------------
# 3. never touch a file the run did not write
# --------------------------------------------------------------------------------------------

@pytest.fixture()
def one_movie(tmp_path):
    path = tmp_path / "m.tif"
    tifffile.imwrite(path, movie(2))
    return path


USERS_OWN = {
    "sidecar json": ("o.csv.json", b'{"my": "notes"}\n'),
    "sidecar text": ("o.csv.json", b"notes for the run\n"),
    "sidecar of another program": ("o.csv.json",
                                   b'{"written_by": "other", "options": {}}\n'),
    "lock": (".o.csv.lock", b"my lock of another tool\n"),
    "parts": ("o.csv.parts", b"not a folder\n"),
}


@pytest.mark.parametrize("case", sorted(USERS_OWN))
def test_a_file_beside_the_output_that_pfsdm_did_not_write_is_kept(tmp_path, one_movie,
                                                                   capsys, case):
    name, content = USERS_OWN[case]
    theirs = tmp_path / name
    theirs.write_bytes(content)
    out = tmp_path / "o.csv"
    assert main(["measure", str(one_movie), "-o", str(out), *CLI_FAST]) == 2
    line = error_line(capsys)
    assert name in line and ("--force" in line or "--parts" in line)
    assert theirs.read_bytes() == content
    assert not out.exists()


def test_force_replaces_a_users_sidecar(tmp_path, one_movie):
    side = tmp_path / "o.csv.json"
    side.write_text('{"my": "notes"}\n')
    out = tmp_path / "o.csv"
    assert main(["measure", str(one_movie), "-o", str(out), "--force", *CLI_FAST]) == 0
    assert json.loads(side.read_text())["written_by"].startswith("napari-pfsdm")
    # and a second run replaces pfsdm's own pair without --force
    assert main(["measure", str(one_movie), "-o", str(out), *CLI_FAST]) == 0


@pytest.mark.parametrize("command", ["trajectories", "compare"])
def test_the_sidecar_of_any_commands_output_is_checked(tmp_path, one_movie, capsys, command):
    table = tmp_path / "f.csv"
    assert main(["measure", str(one_movie), "-o", str(table), *CLI_FAST]) == 0
    side = tmp_path / "r.csv.json"
    side.write_text("[1, 2, 3]\n")
    assert main([command, str(table), "-o", str(tmp_path / "r.csv"), "-q"]) == 2
    assert "r.csv.json" in error_line(capsys)
    assert side.read_text() == "[1, 2, 3]\n" and not (tmp_path / "r.csv").exists()


# --------------------------------------------------------------------------------------------
# 2. one name, one movie
# --------------------------------------------------------------------------------------------

def _zarr_movie(path, data) -> None:
    arr = zarr.create_array(str(path), shape=data.shape, dtype=data.dtype,
                            chunks=(1, *data.shape[1:]))
    arr[:] = data


COLLIDING = {
    "tif and tiff": ["e1.tif", "e1.tiff"],
    "tif and zarr": ["e1.tif", "e1.zarr"],
    "tif, tiff and zarr": ["e1.tif", "e1.tiff", "e1.zarr"],
    "ome.tif and tif": ["e1.ome.tif", "e1.tif"],
    "ome.zarr and zarr": ["e1.ome.zarr", "e1.zarr"],
}


@pytest.mark.parametrize("case", sorted(COLLIDING))
def test_movies_that_would_share_a_name_are_refused(tmp_path, capsys, case):
    folder = tmp_path / "in"
    folder.mkdir()
    for name in COLLIDING[case]:
        if name.endswith(".zarr"):
            _zarr_movie(folder / name, movie(2))
        else:
            tifffile.imwrite(folder / name, movie(2))
    out = tmp_path / "f.csv"
    assert main(["measure", str(folder), "-o", str(out), *CLI_FAST]) == 2
    line = error_line(capsys)
    assert "'e1'" in line and all(n in line for n in COLLIDING[case])
    assert not out.exists()


@pytest.mark.parametrize("twice", [["a.tif", "a.tif"], ["a.tif", "./a.tif"],
                                   ["in", "in/a.tif"]])
def test_the_same_file_given_twice_is_refused(tmp_path, capsys, monkeypatch, twice):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "in").mkdir()
    tifffile.imwrite(tmp_path / "in" / "a.tif", movie(2))
    tifffile.imwrite(tmp_path / "a.tif", movie(2))
    assert main(["measure", *twice, "-o", "f.csv", *CLI_FAST]) == 2
    assert "twice" in error_line(capsys)
    assert not (tmp_path / "f.csv").exists()


def test_the_same_file_name_in_two_folders_gets_two_names(tmp_path):
    for sub in ("a", "b"):
        (tmp_path / sub).mkdir()
        tifffile.imwrite(tmp_path / sub / "e1.tif", movie(2))
    out = tmp_path / "f.csv"
    assert main(["measure", str(tmp_path / "a"), str(tmp_path / "b"), "-o", str(out),
                 *CLI_FAST]) == 0
    table = pf.read_table(out)
    names = sorted(set(table["movie"]))
    assert len(names) == 2 and names[0].endswith("a/e1") and names[1].endswith("b/e1")
    assert len(table) == 4  # 2 frames x 1 object each, never merged


def test_run_batch_refuses_two_movies_of_one_name(tmp_path):
    from napari_pfsdm.batch.movies import Movie
    from napari_pfsdm.batch.run import run_batch

    for name in ("a.tif", "b.tif"):
        tifffile.imwrite(tmp_path / name, movie(2))
    with pytest.raises(ValueError, match="two movies are named 'x'"):
        run_batch([Movie("x", tmp_path / "a.tif"), Movie("x", tmp_path / "b.tif")],
                  tmp_path / "f.csv", scheduler="sync", **FAST)
    with pytest.raises(ValueError, match="given twice"):
        run_batch([Movie("x", tmp_path / "a.tif"), Movie("y", tmp_path / "a.tif")],
                  tmp_path / "f.csv", scheduler="sync", **FAST)
    assert not (tmp_path / "f.csv").exists()


# --------------------------------------------------------------------------------------------
# 1. read what the file holds, or refuse
# --------------------------------------------------------------------------------------------

TIFF_KINDS = {"plain": {}, "imagej": {"imagej": True, "metadata": {"axes": "TYX"}},
              "ome": {"ome": True, "metadata": {"axes": "TYX"}},
              "zlib": {"compression": "zlib"},
              "no metadata": {"photometric": "minisblack", "metadata": None}}


@pytest.mark.parametrize("cut", [0.5, 0.9])
@pytest.mark.parametrize("kind", sorted(TIFF_KINDS))
def test_a_truncated_tiff_is_refused_never_a_shorter_movie(tmp_path, capsys, kind, cut):
    whole = tmp_path / "whole.tif"
    tifffile.imwrite(whole, movie(10), **TIFF_KINDS[kind])
    data = whole.read_bytes()
    cut_file = tmp_path / "m.tif"
    cut_file.write_bytes(data[: int(len(data) * cut)])
    out = tmp_path / "f.csv"
    assert main(["measure", str(cut_file), "-o", str(out), *CLI_FAST]) == 2
    line = error_line(capsys)
    assert "m.tif" in line and "truncated" in line and "again" in line
    assert not out.exists()
    with pytest.raises(ValueError, match="truncated"):
        open_movie(cut_file)
    # the whole file is read whole
    assert open_movie(whole).shape == (10, 64, 64)


def two_series_tiff(path, first, second, **kw) -> None:
    with tifffile.TiffWriter(path, **kw) as tif:
        tif.write(first, **({"metadata": {"axes": "TYX"}} if kw.get("ome") else {}))
        tif.write(second, **({"metadata": {"axes": "TYX"}} if kw.get("ome") else {}))


def test_an_ome_tiff_of_two_positions_needs_a_series(tmp_path, capsys):
    path = tmp_path / "two.ome.tif"
    two_series_tiff(path, movie(5), movie(3, shift=2), ome=True)
    out = tmp_path / "f.csv"
    assert main(["measure", str(path), "-o", str(out), *CLI_FAST]) == 2
    line = error_line(capsys)
    assert "2 image series" in line and "--series" in line
    assert not out.exists()
    for series, frames in ((0, 5), (1, 3), (-1, 3)):
        assert main(["measure", str(path), "-o", str(out), "--series", str(series),
                     *CLI_FAST]) == 0
        assert pf.read_table(out)["frame"].tolist() == list(range(frames))


def test_a_series_that_does_not_exist_is_refused(tmp_path, capsys):
    path = tmp_path / "two.ome.tif"
    two_series_tiff(path, movie(5), movie(3), ome=True)
    assert main(["measure", str(path), "-o", str(tmp_path / "f.csv"), "--series", "2",
                 *CLI_FAST]) == 2
    assert "no series 2" in error_line(capsys)
    with pytest.raises(SystemExit) as stop:  # argparse's own usage error
        main(["measure", str(path), "-o", str(tmp_path / "f.csv"), "--series", "one",
              *CLI_FAST])
    assert stop.value.code == 2
    assert "--series must be a whole number" in capsys.readouterr().err


def test_a_thumbnail_before_the_image_is_not_taken_for_the_movie(tmp_path, capsys):
    path = tmp_path / "thumb.tif"
    with tifffile.TiffWriter(path) as tif:
        tif.write(np.zeros((16, 16, 3), np.uint8), photometric="rgb", subfiletype=1)
        tif.write(movie(4), photometric="minisblack")
    assert main(["measure", str(path), "-o", str(tmp_path / "f.csv"), *CLI_FAST]) == 2
    assert "--series" in error_line(capsys)
    assert open_movie(path, series=1).shape == (4, 64, 64)


def ome_zarr(path, levels: dict[str, np.ndarray], scales: dict[str, list] | None,
             axes=("t", "y", "x")) -> None:
    """An OME-Zarr (v0.4 layout) with the given levels, listed in the given order."""
    g = zarr.open_group(str(path), mode="w", zarr_format=2)
    for name, data in levels.items():
        a = g.create_array(name, shape=data.shape, dtype=data.dtype,
                           chunks=(1, *data.shape[1:]))
        a[:] = data
    datasets = [{"path": name, **({"coordinateTransformations": [
        {"type": "scale", "scale": scales[name]}]} if scales else {})} for name in levels]
    g.attrs["multiscales"] = [{"version": "0.4", "datasets": datasets,
                               "axes": [{"name": a} for a in axes]}]


def test_the_ome_zarr_level_is_chosen_by_its_scale_not_its_place(tmp_path):
    full = movie(3)
    half = full[:, ::2, ::2]
    path = tmp_path / "m.ome.zarr"
    ome_zarr(path, {"low": half, "high": full}, {"low": [1, 2, 2], "high": [1, 1, 1]})
    got = open_movie(path)
    assert got.shape == full.shape
    np.testing.assert_array_equal(np.asarray(got), full)


def test_without_scales_the_largest_ome_zarr_level_is_read(tmp_path):
    full = movie(3)
    path = tmp_path / "m.ome.zarr"
    ome_zarr(path, {"small": full[:, ::4, ::4], "big": full}, None)
    assert open_movie(path).shape == full.shape


def test_an_ome_zarr_level_that_is_declared_but_absent_is_refused(tmp_path, capsys):
    import shutil

    full = movie(3)
    path = tmp_path / "m.ome.zarr"
    ome_zarr(path, {"0": full, "1": full[:, ::2, ::2]}, {"0": [1, 1, 1], "1": [1, 2, 2]})
    shutil.rmtree(path / "0")
    assert main(["measure", str(path), "-o", str(tmp_path / "f.csv"), *CLI_FAST]) == 2
    assert "'0'" in error_line(capsys)
    assert not (tmp_path / "f.csv").exists()


@pytest.mark.parametrize("axes", [("y", "x", "t"), ("t", "x", "y"), ("x", "y")])
def test_axes_stored_out_of_order_are_refused_not_misread(tmp_path, capsys, axes):
    data = movie(3) if len(axes) == 3 else movie(1)[0]
    order = {"t": 0, "y": 1, "x": 2} if len(axes) == 3 else {"y": 0, "x": 1}
    stored = np.transpose(data, [order[a] for a in axes])
    path = tmp_path / "m.zarr"
    arr = zarr.create_array(str(path), shape=stored.shape, dtype=stored.dtype,
                            chunks=stored.shape, dimension_names=list(axes))
    arr[:] = stored
    assert main(["measure", str(path), "-o", str(tmp_path / "f.csv"), *CLI_FAST]) == 2
    assert "order" in error_line(capsys)
    assert not (tmp_path / "f.csv").exists()


def test_ome_axes_that_do_not_match_the_array_are_refused(tmp_path, capsys):
    path = tmp_path / "m.ome.zarr"
    ome_zarr(path, {"0": movie(3)}, None, axes=("c", "t", "y", "x"))
    assert main(["measure", str(path), "-o", str(tmp_path / "f.csv"), *CLI_FAST]) == 2
    assert "4 axes" in error_line(capsys)


def test_two_images_in_one_ome_zarr_group_are_refused(tmp_path, capsys):
    path = tmp_path / "m.ome.zarr"
    ome_zarr(path, {"0": movie(3)}, None)
    g = zarr.open_group(str(path), mode="r+")
    ms = g.attrs["multiscales"]
    g.attrs["multiscales"] = [ms[0], {**ms[0], "name": "other"}]
    assert main(["measure", str(path), "-o", str(tmp_path / "f.csv"), *CLI_FAST]) == 2
    assert "2 OME-Zarr images" in error_line(capsys)


# --------------------------------------------------------------------------------------------
# 4. numbers that would give NaN: refused before any work
# --------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    """A feature table of 2 frames x 2 objects, with a reporter, and its sidecar."""
    folder = tmp_path_factory.mktemp("measured")
    labels = movie(2)
    labels[:, 5:15, 5:15] = 2
    image = np.broadcast_to(1.0 + np.arange(64) / 64, labels.shape).astype(np.float32)
    tifffile.imwrite(folder / "m.tif", labels, photometric="minisblack")
    tifffile.imwrite(folder / "i.tif", image, photometric="minisblack")
    out = folder / "f.csv"
    assert main(["measure", str(folder / "m.tif"), "-i", str(folder / "i.tif"), "-o", str(out),
                 *CLI_FAST]) == 0
    return out


def _huge(key, value):
    def damage(options):
        options[key] = [value] * len(options[key])
    return damage


SIDECAR_DAMAGE = {
    "weights 1e308": _huge("weights", 1e308),
    "weights 1e200": _huge("weights", 1e200),
    "mode_weights 1e308": _huge("mode_weights", 1e308),
    "surface_weight 1e308": lambda o: o.update(surface_weight=1e308),
    "intensity_weight 1e308": lambda o: o.update(intensity_weight=1e308),
    "boundary_weight -1": lambda o: o.update(boundary_weight=-1.0),
}


@pytest.mark.parametrize("case", sorted(SIDECAR_DAMAGE))
def test_a_sidecar_number_that_would_give_nan_is_refused(tmp_path, measured, capsys, case):
    import shutil

    table = tmp_path / "f.csv"
    shutil.copy(measured, table)
    side = json.loads((measured.parent / "f.csv.json").read_text())
    SIDECAR_DAMAGE[case](side["options"])
    (tmp_path / "f.csv.json").write_text(json.dumps(side))
    for command in ("compare", "trajectories"):
        out = tmp_path / f"{command}.csv"
        assert main([command, str(table), "-o", str(out), "-q"]) == 2
        assert case.split()[0] in error_line(capsys)
        assert not out.exists()


@pytest.mark.parametrize(("flag", "value"), [("--intensity-weight", "1e308"),
                                             ("--intensity-weight", "-1"),
                                             ("--intensity-weight", "nan"),
                                             ("--boundary-weight", "1e300"),
                                             ("--boundary-weight", "inf")])
def test_a_distance_weight_that_would_give_nan_is_refused(tmp_path, measured, capsys,
                                                          flag, value):
    out = tmp_path / "d.csv"
    with pytest.raises(SystemExit) as stop:
        main(["compare", str(measured), "-o", str(out), flag, value, "-q"])
    assert stop.value.code == 2
    assert "must be a number from 0 to 1e+12" in capsys.readouterr().err
    assert not out.exists()


def test_the_distance_functions_refuse_the_same_weights(measured):
    table = pf.read_table(measured)
    with pytest.raises(ValueError, match="intensity_weight must be"):
        pf.distance_matrix(table, intensity_weight=1e308)
    with pytest.raises(ValueError, match="boundary_weight must be"):
        pf.distance_matrix(table, boundary_weight=1e308)
    d = pf.distance_matrix(table, intensity_weight=1e12, boundary_weight=1e12)
    assert np.isfinite(np.asarray(d, float)).all()  # the largest allowed stay finite


# --------------------------------------------------------------------------------------------
# 6. the right drawer for every error: a test per door
# --------------------------------------------------------------------------------------------

def _edited(measured, tmp_path, change) -> str:
    """A copy of the measured table with ``change`` applied, its sidecar copied beside it."""
    table = pd.read_csv(measured)
    change(table)
    out = tmp_path / "edited.csv"
    table.to_csv(out, index=False)
    side = json.loads((measured.parent / "f.csv.json").read_text())
    side.pop("table_sha256")
    side.pop("table_bytes")
    side["csv"] = out.name
    (tmp_path / "edited.csv.json").write_text(json.dumps(side))
    return str(out)


def _set(col, value, row=0):
    def change(t):
        t[col] = t[col].astype(object)
        t.loc[row, col] = value
    return change


def _first_shape(t):
    return next(c for c in t.columns if c.startswith("shape_r"))


TABLE_CELLS = {
    "text frame": (_set("frame", "abc"), "'frame'"),
    "negative frame": (_set("frame", -1), "'frame'"),
    "fractional frame": (_set("frame", 0.5), "'frame'"),
    "label 0": (_set("label", 0), "'label'"),
    "fractional label": (_set("label", 1.5), "'label'"),
    "text feature": (lambda t: _set(_first_shape(t), "x")(t), "'shape_r00_n00'"),
    "a repeated object": (lambda t: t.loc.__setitem__((1, "label"), t.loc[0, "label"])
                          or t.loc.__setitem__((1, "frame"), t.loc[0, "frame"]),
                          "repeat an object"),
}


@pytest.mark.parametrize("case", sorted(TABLE_CELLS))
@pytest.mark.parametrize("command", ["trajectories", "compare"])
def test_an_odd_table_cell_is_the_users_mistake_in_plain_words(tmp_path, measured, capsys,
                                                               case, command):
    change, words = TABLE_CELLS[case]
    path = _edited(measured, tmp_path, change)
    out = tmp_path / "r.csv"
    assert main([command, path, "-o", str(out), "-q"]) == 2
    line = error_line(capsys)
    assert words in line and "row" in line
    assert not out.exists()


def test_the_api_refuses_the_same_cells(tmp_path, measured):
    path = _edited(measured, tmp_path, _set("frame", "abc"))
    table = pf.read_table(path)
    with pytest.raises(ValueError, match="'frame' holds 'abc'"):
        pf.distance_matrix(pf.drop_failed(table))


def test_rows_of_a_groups_file_that_match_nothing_are_named(tmp_path, measured, capsys):
    groups = tmp_path / "g.csv"
    groups.write_text("label,group\n1,a\n2,b\n7,b\n9,a\n")
    assert main(["trajectories", str(measured), "-o", str(tmp_path / "p.csv"),
                 "--groups", str(groups), "-q"]) == 0
    err = capsys.readouterr().err
    assert "2 rows of the groups file match no object" in err
    assert "label 7 -> b" in err and "label 9 -> a" in err
    assert "label 1 ->" not in err


def test_rows_of_a_groups_file_with_an_empty_cell_are_named(tmp_path, measured, capsys):
    groups = tmp_path / "g.csv"
    groups.write_text("label,group\n1,a\n2,\n")
    assert main(["trajectories", str(measured), "-o", str(tmp_path / "p.csv"),
                 "--groups", str(groups), "-q"]) == 0
    assert "row 3" in capsys.readouterr().err


@pytest.mark.parametrize(("content", "words"), [(b"", "is empty"),
                                                (b"label,group\n1,a\n2,b,c,d\n", "not a readable"),
                                                (b"label,group\n1,\xff\xfe\n", "not a readable")])
def test_a_groups_file_that_cannot_be_read_is_the_users_mistake(tmp_path, measured, capsys,
                                                                content, words):
    groups = tmp_path / "g.csv"
    groups.write_bytes(content)
    assert main(["trajectories", str(measured), "-o", str(tmp_path / "p.csv"),
                 "--groups", str(groups), "-q"]) == 2
    assert words in error_line(capsys)


def test_a_pipe_given_as_a_movie_or_a_table_is_named_as_such(tmp_path, measured, capsys):
    import os

    fifo = tmp_path / "fifo.tif"
    os.mkfifo(fifo)
    assert main(["measure", str(fifo), "-o", str(tmp_path / "f.csv"), *CLI_FAST]) == 2
    line = error_line(capsys)
    assert "pipe" in line and "Errno" not in line
    table = tmp_path / "fifo.csv"
    os.mkfifo(table)
    assert main(["trajectories", str(table), "-o", str(tmp_path / "p.csv"), "-q"]) == 2
    assert "pipe" in error_line(capsys)  # and it did not wait for a writer


def test_an_ome_zarr_scale_that_is_not_numbers_is_the_users_mistake(tmp_path, capsys):
    path = tmp_path / "m.ome.zarr"
    ome_zarr(path, {"0": movie(3)}, {"0": ["a", 1, 1]})
    assert main(["measure", str(path), "-o", str(tmp_path / "f.csv"), *CLI_FAST]) == 2
    assert "scale" in error_line(capsys)


def test_a_frame_too_big_for_memory_is_not_called_damaged(tmp_path, monkeypatch):
    from napari_pfsdm.batch import io

    path = tmp_path / "m.tif"
    tifffile.imwrite(path, movie(2))
    arr = open_movie(path)
    source = io.movie_source(arr)

    def no_memory(*args, **kwargs):
        raise MemoryError("Unable to allocate 40.0 GiB")

    monkeypatch.setattr(io._TiffFrames, "_open", lambda self: type(
        "H", (), {"__getitem__": no_memory})())
    with pytest.raises(ValueError) as info:
        source[0:1]
    assert "memory" in str(info.value) and "damaged" not in str(info.value)


@pytest.mark.parametrize(("frames", "expected"), [([-1], [2]), ([0, -1], [0, 2]),
                                                  (-2, [1])])
def test_negative_frame_indexes_in_the_api_are_the_frames_they_name(frames, expected):
    got = [o.frame for o in pf.iter_objects(movie(3), frames=frames, **FAST)]
    assert got == expected


@pytest.mark.parametrize(("frames", "words"), [([3], "frame 3 is not in the movie"),
                                               ([-4], "frame -4 is not in the movie"),
                                               ([1, -2], "given twice"),
                                               ([0.5], "whole numbers")])
def test_frame_indexes_outside_the_movie_are_refused(frames, words):
    with pytest.raises(ValueError, match=words):
        list(pf.iter_objects(movie(3), frames=frames, **FAST))


COUNTS = [("measure", "--workers", "0"), ("measure", "--workers", "-2"),
          ("measure", "--frames-per-task", "0"), ("measure", "--frames-per-task", "-1"),
          ("trajectories", "--components", "-1"), ("trajectories", "--components", "0"),
          ("compare", "--rerank-k", "0"), ("compare", "--max-objects", "-1"),
          ("classify", "--test-size", "1.5"), ("classify", "--splits", "1"),
          ("predict", "--test-size", "0")]


@pytest.mark.parametrize(("command", "flag", "value"), COUNTS)
def test_an_odd_count_on_the_command_line_is_refused_in_words(tmp_path, one_movie, measured,
                                                              capsys, command, flag, value):
    first = str(one_movie) if command == "measure" else str(measured)
    extra = ["--groups", str(measured), "--frames", "0"] if command in ("classify", "predict") \
        else []
    with pytest.raises(SystemExit) as stop:
        main([command, first, "-o", str(tmp_path / "r.csv"), flag, value, *extra, "-q"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert f"{flag} must be" in err and "Traceback" not in err
    assert not (tmp_path / "r.csv").exists()


def test_show_beyond_the_components_is_refused(tmp_path, measured, capsys):
    assert main(["trajectories", str(measured), "-o", str(tmp_path / "p.csv"), "--plot",
                 str(tmp_path / "p.png"), "--show", "1", "9", "-q"]) == 2
    assert "--components 3" in error_line(capsys)
    assert not (tmp_path / "p.png").exists()


@pytest.fixture()
def one_stack(tmp_path):
    z, y, x = np.mgrid[:20, :32, :32]
    mask = (((z - 10) / 7) ** 2 + ((y - 16) / 10) ** 2 + ((x - 16) / 8) ** 2 < 1)
    path = tmp_path / "s.tif"
    tifffile.imwrite(path, mask.astype(np.uint8), photometric="minisblack")
    return path


@pytest.mark.parametrize("spacing", [["1e308", "1", "1"], ["1e-300", "1", "1"],
                                     ["1", "1", "1000"]])
def test_a_voxel_size_that_would_overflow_is_refused(tmp_path, one_stack, capsys, spacing):
    out = tmp_path / "s.csv"
    assert main(["measure", str(one_stack), "--axes", "zyx", "--spacing", *spacing, "-o",
                 str(out), "-q", "--link", "labels", "--scheduler", "sync"]) == 2
    assert "spacing must be numbers from" in error_line(capsys)
    assert not out.exists()


def test_a_users_temporary_file_in_the_parts_folder_is_kept(tmp_path, one_movie):
    parts = tmp_path / "mine"
    parts.mkdir()
    theirs = [parts / ".notes.csv.tmp", parts / ".draft.json.tmp", parts / ".a.parquet.tmp"]
    for f in theirs:
        f.write_text("mine")
    ours = parts / ".m-0123456789.parquet.x1y2z3w4.tmp"
    ours.write_text("half")
    assert main(["measure", str(one_movie), "-o", str(tmp_path / "o.csv"), "--parts",
                 str(parts), *CLI_FAST]) == 0
    assert all(f.read_text() == "mine" for f in theirs) and not ours.exists()
