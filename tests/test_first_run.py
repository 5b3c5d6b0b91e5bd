"""What a new user meets on a fresh clone, case by case, and what they get.

Real input: ``skimage.data.coins()`` segmented with Otsu (coins touch the border, some specks
are too small to describe). Every command runs in-process through ``pfsdm``'s ``main``.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tifffile
from skimage import data, filters, measure

import napari_pfsdm as pf
from napari_pfsdm.cli import main
from napari_pfsdm.errors import InputError


def imwrite(path, array):
    """Grey-level TIFF (a 3-frame stack would otherwise be taken for RGB)."""
    tifffile.imwrite(path, array, photometric="minisblack")


FAST = ["--n-fourier", "6", "--n-radii", "8", "--scheduler", "sync"]


def last_error(capsys) -> str:
    err = [ln for ln in capsys.readouterr().err.strip().splitlines() if ln]
    assert err, "nothing on stderr"
    assert not any(ln.startswith("Traceback") for ln in err)
    return err[-1]


@pytest.fixture(scope="module")
def coins(tmp_path_factory):
    """coins_labels.tif, coins_intensity.tif and their measured features.csv."""
    folder = tmp_path_factory.mktemp("coins")
    image = data.coins()
    labels = measure.label(image > filters.threshold_otsu(image)).astype(np.uint16)
    imwrite(folder / "coins_labels.tif", labels)
    imwrite(folder / "coins_intensity.tif", image.astype(np.float32))
    old = os.umask(0o022)
    try:
        assert main(["measure", str(folder / "coins_labels.tif"),
                     "-i", str(folder / "coins_intensity.tif"),
                     "-o", str(folder / "features.csv"), "-q", *FAST]) == 0
    finally:
        os.umask(old)
    return folder, labels


def test_features_are_plain_csv_with_a_sidecar_readable_by_others(coins):
    folder, labels = coins
    table = pd.read_csv(folder / "features.csv")  # no arguments
    n_objects = len(np.unique(labels)) - 1
    # movie, 11 base columns, 6 + 3 classic measures (shape, reporter), 2 channels of 8 rings
    # x 7 harmonics, 64 outline coefficients; no midline measures (profile_bins 0) nor
    # elastic signature (elastic_signature 'none'): the defaults
    assert table.shape == (n_objects, 1 + 11 + 9 + 2 * 8 * 7 + 64)
    assert list(table.columns[:4]) == ["movie", "frame", "label", "area"]
    side = json.loads((folder / "features.csv.json").read_text())
    assert side["table"] == "features" and side["options"]["n_fourier"] == 6
    assert side["options"]["elastic_smoothing"] == 4.0
    assert len(side["options"]["weights"]) == 8
    for name in ("features.csv", "features.csv.json"):  # honours umask 022: readable by all
        assert (folder / name).stat().st_mode & 0o777 == 0o644, name


def test_suspect_objects_are_flagged(coins, capsys):
    folder, _ = coins
    table = pd.read_csv(folder / "features.csv")
    table[["error", "warnings"]] = table[["error", "warnings"]].fillna("")
    border = table[table["touches_border"]]
    assert len(border) >= 1
    assert border["warnings"].str.contains("touches the image border").all()
    fine = table[~table["touches_border"] & (table["n_holes"] == 0) & (table["error"] == "")]
    assert len(fine) >= 1 and fine["warnings"].eq("").all()
    holes = table[table["n_holes"] > 0]
    assert holes["warnings"].str.contains("holes? filled", regex=True).all()
    big = table.loc[table["area"].idxmax()]  # the coin cut by the border, folded by the map
    assert "% of disk samples fold" in big["warnings"]
    # the one-line summary at the end of measure
    out = folder / "again.csv"
    assert main(["measure", str(folder / "coins_labels.tif"), "-o", str(out), *FAST]) == 0
    printed = capsys.readouterr().out
    assert f"{len(border)} object" in printed and "touch" in printed
    assert "see the warnings column" in printed


def test_output_never_replaces_a_users_file(coins, capsys):
    folder, _ = coins
    raw = folder / "coins_intensity.tif"
    before = raw.read_bytes()
    args = ["measure", str(folder / "coins_labels.tif"), "-o", str(raw), "-q", *FAST]
    assert main(args) == 2
    msg = last_error(capsys)
    assert "already exists and was not written by pfsdm" in msg and "--force" in msg
    # an input is never an output, even with --force
    assert main([*args, "-i", str(raw), "--force"]) == 2
    assert "is also an input" in last_error(capsys)
    assert raw.read_bytes() == before
    notes = folder / "notes.png"
    notes.write_bytes(b"\x89PNG\r\n\x1a\n my own plot")
    assert main(["compare", str(folder / "features.csv"), "-o", str(folder / "d.csv"),
                 "--mds", str(notes), "-q"]) == 2
    assert "notes.png already exists" in last_error(capsys)
    assert not (folder / "d.csv").exists()
    # a table and plot pfsdm wrote are replaced on a re-run
    for _ in range(2):
        assert main(["compare", str(folder / "features.csv"), "-o", str(folder / "d.csv"),
                     "--mds", str(folder / "mds.png"), "-q"]) == 0


def test_a_table_resaved_by_pandas_gives_the_same_numbers(coins, tmp_path, capsys):
    folder, _ = coins
    src = folder / "features.csv"
    copy = tmp_path / "resaved.csv"
    pd.read_csv(src).to_csv(copy)  # pandas defaults: with its index column
    shutil.copy(folder / "features.csv.json", tmp_path / "resaved.csv.json")
    for name in (src, copy):
        assert main(["compare", str(name), "-o", str(tmp_path / f"d_{name.stem}.csv"), "-q"]) == 0
        assert main(["trajectories", str(name), "-o", str(tmp_path / f"p_{name.stem}.csv"),
                     "-q"]) == 0
    d0 = pd.read_csv(tmp_path / "d_features.csv", index_col=0)
    d1 = pd.read_csv(tmp_path / "d_resaved.csv", index_col=0)
    pd.testing.assert_frame_equal(d0, d1, check_exact=True)
    p0 = pd.read_csv(tmp_path / "p_features.csv")
    p1 = pd.read_csv(tmp_path / "p_resaved.csv")
    pd.testing.assert_frame_equal(p0, p1, check_exact=True)
    # without its sidecar the same copy is refused, not reinterpreted
    (tmp_path / "resaved.csv.json").unlink()
    assert main(["compare", str(copy), "-o", str(tmp_path / "x.csv"), "-q"]) == 2
    msg = last_error(capsys)
    assert "does not say how it was measured" in msg and ".csv.json" in msg
    # a table missing a ring's columns is refused, naming them
    cut = pd.read_csv(src)
    cut = cut.drop(columns=[c for c in cut.columns if c.startswith("shape_r07_")])
    cut.to_csv(tmp_path / "cut.csv", index=False)
    shutil.copy(folder / "features.csv.json", tmp_path / "cut.csv.json")
    assert main(["trajectories", str(tmp_path / "cut.csv"), "-o", str(tmp_path / "y.csv")]) == 2
    assert "do not belong together: the table has no columns shape_r07_n00, " \
        "shape_r07_n01, shape_r07_n02 …" in last_error(capsys)
    # without the content in its sidecar (an older version's), the columns are counted
    side = json.loads((folder / "features.csv.json").read_text())
    del side["content"]
    (tmp_path / "cut.csv.json").write_text(json.dumps(side))
    os.utime(tmp_path / "cut.csv", ns=(0, (tmp_path / "cut.csv.json").stat().st_mtime_ns + 10**9))
    assert main(["trajectories", str(tmp_path / "cut.csv"), "-o", str(tmp_path / "y.csv")]) == 2
    assert "misses 7 of its 56 shape feature columns (shape_r07_n00 … shape_r07_n06" \
        in last_error(capsys)
    assert not (tmp_path / "x.csv").exists() and not (tmp_path / "y.csv").exists()


def test_older_tables_with_a_comment_line_still_read(coins, tmp_path):
    folder, _ = coins
    options = json.loads((folder / "features.csv.json").read_text())["options"]
    legacy = tmp_path / "old.csv"
    legacy.write_text("# pfsdm: " + json.dumps(options) + "\n"
                      + (folder / "features.csv").read_text())
    assert main(["compare", str(legacy), "-o", str(tmp_path / "d.csv"), "-q"]) == 0
    assert main(["compare", str(folder / "features.csv"), "-o", str(tmp_path / "e.csv"),
                 "-q"]) == 0
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "d.csv", index_col=0),
                                  pd.read_csv(tmp_path / "e.csv", index_col=0))


def test_failed_rows_are_left_out_and_named(tmp_path, capsys):
    labels = np.zeros((2, 80, 80), np.uint16)
    labels[:, 10:40, 10:30] = 1
    labels[:, 45:75, 40:75] = 2
    labels[0, 5, 70] = 3            # one pixel: too small to describe
    labels[1, 60:63, 5:8] = 4       # nine pixels: too small
    imwrite(tmp_path / "labels.tif", labels)
    features = tmp_path / "features.csv"
    assert main(["measure", str(tmp_path / "labels.tif"), "-o", str(features), "-q",
                 *FAST]) == 0
    out = tmp_path / "d.csv"
    assert main(["compare", str(features), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "left out 2 of 6 objects without features: frame 0 label 3 of labels (" in err
    d = pd.read_csv(out, index_col=0)
    assert d.shape == (4, 4) and np.isfinite(d.to_numpy()).all()
    left = json.loads((tmp_path / "d.csv.json").read_text())["left_out"]
    assert [(r["frame"], r["label"]) for r in left] == [(0, 3), (1, 4)]
    assert all("too small" in r["reason"] for r in left)
    assert main(["trajectories", str(features), "-o", str(tmp_path / "p.csv")]) == 0
    assert "left out 2 of 6 rows" in capsys.readouterr().err
    # fewer than two objects left: refused
    assert main(["compare", str(features), "--frames", "0", "-o", str(tmp_path / "e.csv"),
                 "-q"]) == 0
    only_bad = pd.read_csv(features)
    only_bad = only_bad[(only_bad["frame"] == 0) & only_bad["label"].isin([1, 3])]
    only_bad.to_csv(tmp_path / "bad.csv", index=False)
    shutil.copy(tmp_path / "features.csv.json", tmp_path / "bad.csv.json")
    # rows cut from a table are not the table its sidecar describes: refused, saying so
    assert main(["compare", str(tmp_path / "bad.csv"), "-o", str(tmp_path / "f.csv")]) == 2
    assert "do not belong together: the table has 2 rows where it had 6" in last_error(capsys)
    # written with pfsdm (the options travel with the table read), they are a table
    table = pf.read_table(features)
    pf.write_table(table[(table["frame"] == 0) & table["label"].isin([1, 3])], tmp_path / "bad.csv")
    assert main(["compare", str(tmp_path / "bad.csv"), "-o", str(tmp_path / "f.csv")]) == 2
    assert "only 1 of 2 objects have features; at least 2 are needed" in last_error(capsys)


def test_nan_reporter_costs_only_the_intensity_features(tmp_path):
    from napari_pfsdm import measure as pf_measure

    labels = np.zeros((60, 90), np.uint16)
    labels[10:50, 5:40] = 1
    labels[10:50, 50:85] = 2
    image = np.ones(labels.shape) + np.arange(90)[None, :] / 90
    image[20, 20] = np.nan          # inside object 1
    table = pf_measure(labels, image, n_fourier=6, n_radii=8)
    one, two = table.iloc[0], table.iloc[1]
    assert one["error"] == "" and np.isfinite(one.filter(like="shape_r").astype(float)).all()
    assert one.filter(like="intensity_r").astype(float).isna().all()
    assert "intensity features left empty" in one["warnings"] and "NaN" in one["warnings"]
    assert np.isfinite(two.filter(like="intensity_r").astype(float)).all()
    assert two["warnings"] == ""


def test_empty_labels(tmp_path, capsys):
    imwrite(tmp_path / "empty.tif", np.zeros((3, 32, 32), np.uint16))
    features = tmp_path / "features.csv"
    args = ["measure", str(tmp_path / "empty.tif"), "-o", str(features), "-q", *FAST]
    assert main(args) == 2
    msg = last_error(capsys)
    assert "no objects" in msg and "only background" in msg and "--allow-empty" in msg
    assert not features.exists()
    assert main([*args, "--allow-empty"]) == 0
    assert len(pd.read_csv(features)) == 0
    for cmd in (["compare", str(features), "-o", str(tmp_path / "d.csv")],
                ["trajectories", str(features), "-o", str(tmp_path / "p.csv")],
                ["classify", str(features), "--groups", str(features), "--frames", "0"]):
        assert main(cmd) == 2, cmd
        assert "holds no objects (0 rows)" in last_error(capsys), cmd


def classify_table(tmp_path, n_objects: int):
    labels = np.zeros((2, 40, 40 * n_objects), np.uint16)
    for k in range(n_objects):
        labels[:, 8:32, 40 * k + 8:40 * k + 20 + 2 * k] = k + 1
    imwrite(tmp_path / "labels.tif", labels)
    assert main(["measure", str(tmp_path / "labels.tif"), "-o", str(tmp_path / "f.csv"),
                 "-q", *FAST]) == 0
    return tmp_path / "f.csv"


def test_classify_messages(tmp_path, capsys):
    features = classify_table(tmp_path, 4)
    groups = tmp_path / "groups.csv"
    groups.write_text("label,group\n1,A\n2,B\n3,A\n4,B\n")
    assert main(["classify", str(features), "--groups", str(groups), "--frames", "0-1"]) == 2
    msg = last_error(capsys)
    assert "4 objects (2 A, 2 B) are too few for a 20% test split" in msg
    assert "--test-size" in msg
    wrong = tmp_path / "wrong.csv"
    wrong.write_text("label,group\n11,A\n12,B\n")
    assert main(["classify", str(features), "--groups", str(wrong), "--frames", "0"]) == 2
    msg = last_error(capsys)
    assert "no row of the groups file names an object of the table" in msg
    assert "the groups file has label 11; label 12" in msg and "the table has label 1" in msg
    assert main(["classify", str(features), "--groups", str(groups), "--frames", "7-9"]) == 2
    assert "frames 7-9 are not in the table (it has frames 0-1)" in last_error(capsys)
    assert main(["compare", str(features), "--frames", "7-9", "-o", str(tmp_path / "d.csv")]) \
        == 2
    assert "frames 7-9 are not in the table (it has frames 0-1)" in last_error(capsys)


def test_classify_progress_and_quiet(tmp_path, capsys):
    features = classify_table(tmp_path, 10)
    groups = tmp_path / "groups.csv"
    groups.write_text("label,group\n" + "".join(f"{k},{'AB'[k % 2]}\n" for k in range(1, 11)))
    base = ["classify", str(features), "--groups", str(groups), "--frames", "0-1"]
    assert main(base) == 0
    assert "classifying: step 11/11" in capsys.readouterr().err  # 5 splits x 2 repeats + 1
    assert main([*base, "-q"]) == 0
    assert capsys.readouterr().err == ""


def test_input_mistakes_get_plain_messages(tmp_path, capsys):
    movie = np.zeros((3, 32, 32), np.uint16)
    movie[:, 8:24, 8:24] = 1
    imwrite(tmp_path / "movie.tif", movie)
    # a movie given where a table is expected
    assert main(["trajectories", str(tmp_path / "movie.tif"), "-o", str(tmp_path / "p.csv")]) \
        == 2
    msg = last_error(capsys)
    assert "movie.tif is a TIFF image, not a CSV table" in msg and "pfsdm measure" in msg
    # -i swallowing the labels
    imwrite(tmp_path / "rep.tif", movie.astype(np.float32))
    assert main(["measure", "-i", str(tmp_path / "rep.tif"), str(tmp_path / "movie.tif"),
                 "-o", str(tmp_path / "f.csv")]) == 2
    assert "-i/--intensity took all of" in last_error(capsys)
    # a colour (T, S, Y, X) movie
    tifffile.imwrite(tmp_path / "rgb.tif", np.zeros((5, 3, 32, 32), np.uint8),
                     photometric="rgb", planarconfig="separate")
    assert main(["measure", str(tmp_path / "rgb.tif"), "-o", str(tmp_path / "f.csv")]) == 2
    msg = last_error(capsys)
    assert "rgb.tif has 4 dimensions" in msg and "colour (RGB) image" in msg
    # a truncated TIFF: the message names the file
    whole = (tmp_path / "movie.tif").read_bytes()
    (tmp_path / "cut.tif").write_bytes(whole[: len(whole) // 2])
    assert main(["measure", str(tmp_path / "cut.tif"), "-o", str(tmp_path / "f.csv"),
                 *FAST]) == 2
    msg = last_error(capsys)
    assert "cut.tif" in msg and ("damaged or truncated" in msg or "cannot read" in msg)
    assert not (tmp_path / "f.csv").exists()


def _command_raising(monkeypatch, exc: BaseException):
    """Make ``pfsdm compare`` raise ``exc`` (as a bug or an input error deep inside would)."""
    import napari_pfsdm.cli as cli

    def boom(args):
        raise exc

    parser = cli.build_parser()
    parser._subparsers._group_actions[0].choices["compare"].set_defaults(func=boom)
    monkeypatch.setattr(cli, "build_parser", lambda: parser)


@pytest.mark.parametrize("exc", [
    RuntimeError("something inside broke"),
    # a plain ValueError is not the user's: numpy, scikit-learn and our own slips raise them
    ValueError("operands could not be broadcast together with shapes (3,) (4,)"),
    KeyError("shape_PC1"),
    ModuleNotFoundError("No module named 'napari_pfsdm.gone'", name="napari_pfsdm.gone"),
])
def test_a_bug_says_it_is_a_bug_and_where_to_report_it(tmp_path, capsys, monkeypatch, exc):
    from napari_pfsdm.cli.common import BUG_REPORT

    _command_raising(monkeypatch, exc)
    assert main(["compare", "x.csv", "-o", str(tmp_path / "d.csv")]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and "pfsdm: error:" not in err
    assert "a bug of napari-pfsdm, not of your input" in err
    assert type(exc).__name__ in err and BUG_REPORT in err and "--debug" in err
    # with --debug: the traceback first, then the same words; the same exit status
    assert main(["--debug", "compare", "x.csv", "-o", str(tmp_path / "d.csv")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("Traceback (most recent call last):")
    assert "in boom" in err and BUG_REPORT in err


@pytest.mark.parametrize("exc, shown", [
    (InputError("the table has no intensity features"), "the table has no intensity features"),
    (FileNotFoundError(2, "No such file or directory", "x.csv"),
     "x.csv: No such file or directory"),
    (ImportError("linking with 'laptrack' needs the laptrack package", name="laptrack"),
     "linking with 'laptrack' needs the laptrack package"),
])
def test_an_input_error_is_one_line_and_exit_2(tmp_path, capsys, monkeypatch, exc, shown):
    _command_raising(monkeypatch, exc)
    assert main(["compare", "x.csv", "-o", str(tmp_path / "d.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"pfsdm: error: {shown}"]
    assert main(["--debug", "compare", "x.csv", "-o", str(tmp_path / "d.csv")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("Traceback") and err.rstrip().endswith(f"pfsdm: error: {shown}")


def test_the_bug_report_words_are_the_readmes():
    from napari_pfsdm.cli.common import BUG_REPORT

    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    assert " ".join(BUG_REPORT.split()) in " ".join(readme.split())


def test_input_errors_raised_inside_the_package_exit_2(tmp_path, capsys):
    # a real one from deep inside (the CSV reader), not a stand-in: "error:", exit 2, no bug
    bad = tmp_path / "bad.csv"
    bad.write_text("frame,label\n0,1\n")
    assert main(["compare", str(bad), "-o", str(tmp_path / "d.csv")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("pfsdm: error: ") and "bug" not in err


@pytest.mark.parametrize("umask, mode", [(0o022, 0o644), (0o027, 0o640), (0o002, 0o664)])
def test_written_files_follow_the_umask(tmp_path, umask, mode):
    from napari_pfsdm import write_table

    old = os.umask(umask)
    try:
        write_table(pd.DataFrame({"frame": [0], "label": [1]}), tmp_path / "t.csv", {})
    finally:
        os.umask(old)
    for name in ("t.csv", "t.csv.json"):
        assert (tmp_path / name).stat().st_mode & 0o777 == mode


def test_the_demo_runs_again_over_an_older_demos_folder(tmp_path, capsys):
    """An earlier version's results (a table with the old comment line, plots without
    pfsdm's PNG mark) cannot be told from a user's files: the demo names them and replaces
    them with --force; its own files of this version it replaces on every run."""
    (tmp_path / "features.csv").write_text('# pfsdm: {"n_fourier": 10}\nframe,label\n0,1\n')
    (tmp_path / "pca.png").write_bytes(b"\x89PNG\r\n\x1a\n an old plot")
    demo = ["demo", "--quick-only", "-o", str(tmp_path), "--scheduler", "sync", "-q"]
    assert main(demo) == 2
    assert "pca.png" in capsys.readouterr().err
    assert (tmp_path / "pca.png").read_bytes() == b"\x89PNG\r\n\x1a\n an old plot"
    assert main([*demo, "--force"]) == 0
    assert pd.read_csv(tmp_path / "features.csv").shape[0] == 72
    assert b"napari-pfsdm" in (tmp_path / "pca.png").read_bytes()[:4096]
    assert main(demo) == 0  # its own files, again
    # a folder of someone else's files is still protected
    other = tmp_path / "other"
    other.mkdir()
    (other / "features.csv").write_text("my,own\n1,2\n")
    assert main(["demo", "--quick-only", "-o", str(other), "-q"]) == 2
    assert (other / "features.csv").read_text() == "my,own\n1,2\n"
