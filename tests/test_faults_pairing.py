"""The fault battery, round 3 (issue 66), rule 2: pairings are checked by content.

A table and its sidecar belong together when the table's bytes are those the sidecar records
or its content is (a copy re-saved by pandas or a spreadsheet), whatever file name the
sidecar's ``csv`` field holds; labels given to a report or a saved analysis must hold, frame
by frame, the table's objects (id, size, centroid); every file of a saved analysis folder is
read with its checks: an edited folder opens with a warning in words or is refused in words,
never with another exception. Expected values come from numpy and the files' bytes.
"""

from __future__ import annotations

import json
import os
import shutil
import warnings

import numpy as np
import pandas as pd
import pytest
import tifffile

import napari_pfsdm as pf
from napari_pfsdm.cli import main
from napari_pfsdm.errors import InputError
from napari_pfsdm.io import read_table, write_table

FAST = {"n_fourier": 4, "n_radii": 4}


def blobs(n_frames: int = 3) -> np.ndarray:
    """Three objects of different sizes and shapes moving apart over time (ids follow them)."""
    yy, xx = np.mgrid[:80, :120]
    out = np.zeros((n_frames, 80, 120), np.uint16)
    for t in range(n_frames):
        out[t][((yy - 20) / 12) ** 2 + ((xx - 20 - t) / 7) ** 2 < 1] = 1
        out[t][((yy - 55) / 9) ** 2 + ((xx - 50) / 14) ** 2 < 1] = 2
        out[t][(np.abs(yy - 30) < 8 + t) & (np.abs(xx - 95) < 6)] = 3
    return out


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """Two tables of the same objects measured with other options (the same columns), each
    written with its sidecar in a folder of its own."""
    folder = tmp_path_factory.mktemp("pair")
    labels = blobs()
    a = pf.measure(labels, **FAST)
    b = pf.measure(labels, mapping="bijective", **FAST)
    assert list(a.columns) == list(b.columns)
    (folder / "a").mkdir()
    (folder / "b").mkdir()
    write_table(a, folder / "a" / "f.csv")
    write_table(b, folder / "b" / "g.csv")
    return folder, a, b


def _copy(src, dst, keep_time: bool = False):
    (shutil.copy2 if keep_time else shutil.copy)(src, dst)
    if not keep_time:  # copied now: newer than the table beside it
        t = os.stat(dst.with_name(dst.name[:-5])).st_mtime_ns + 10**9
        os.utime(dst, ns=(t, t))


@pytest.mark.parametrize("field", ["its own name", "another name", "no name", "edited name"])
def test_another_runs_sidecar_beside_a_table_is_refused_whatever_it_names(pair, tmp_path,
                                                                          field):
    folder, a, b = pair
    shutil.copy(folder / "a" / "f.csv", tmp_path / "f.csv")
    side = json.loads((folder / "b" / "g.csv.json").read_text())
    if field == "its own name":
        side["csv"] = "f.csv"
    elif field == "no name":
        del side["csv"]
    elif field == "edited name":
        side["csv"] = "something/else.csv"
    (tmp_path / "f.csv.json").write_text(json.dumps(side))
    t = os.stat(tmp_path / "f.csv").st_mtime_ns + 10**9
    os.utime(tmp_path / "f.csv.json", ns=(t, t))
    with pytest.raises(InputError, match="do not belong together: the table has other "
                                         "values in columns"):
        read_table(tmp_path / "f.csv")


def test_through_the_command_line_the_pair_is_refused_naming_both(pair, tmp_path, capsys):
    folder, a, b = pair
    shutil.copy(folder / "a" / "f.csv", tmp_path / "f.csv")
    _copy(folder / "b" / "g.csv.json", tmp_path / "f.csv.json")
    assert main(["compare", str(tmp_path / "f.csv"), "-o", str(tmp_path / "d.csv"),
                 "-q"]) == 2
    err = capsys.readouterr().err
    assert "f.csv and f.csv.json do not belong together" in err
    assert "internal error" not in err and not (tmp_path / "d.csv").exists()


def test_an_older_sidecar_of_another_run_is_never_used_silently(pair, tmp_path):
    """Copied keeping its time (older than the table): taken for an edit, so read with a
    warning that says what differs, never without a word."""
    folder, a, b = pair
    shutil.copy(folder / "a" / "f.csv", tmp_path / "f.csv")
    shutil.copy2(folder / "b" / "g.csv.json", tmp_path / "f.csv.json")
    os.utime(tmp_path / "f.csv.json", ns=(0, 0))
    with pytest.warns(UserWarning, match="changed after pfsdm wrote it .*other values in "
                                         "columns"):
        read_table(tmp_path / "f.csv")


@pytest.mark.parametrize("how", ["pandas with its index", "pandas without", "spreadsheet",
                                 "renamed copy"])
def test_the_same_table_written_again_is_its_sidecars(pair, tmp_path, how):
    folder, a, b = pair
    src = folder / "a" / "f.csv"
    copy = tmp_path / "copy.csv"
    if how == "pandas with its index":
        pd.read_csv(src).to_csv(copy)
    elif how == "pandas without":
        pd.read_csv(src).to_csv(copy, index=False)
    elif how == "spreadsheet":  # every cell quoted, Windows line ends
        pd.read_csv(src, dtype=str, keep_default_na=False).to_csv(
            copy, index=False, quoting=1, lineterminator="\r\n")
    else:
        shutil.copy(src, copy)
    _copy(folder / "a" / "f.csv.json", tmp_path / "copy.csv.json")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # not even a warning: it is the same table
        back = read_table(copy)
    pd.testing.assert_frame_equal(back, read_table(src))
    np.testing.assert_array_equal(pf.distance_matrix(back), pf.distance_matrix(a))


@pytest.mark.parametrize("edit", ["rows sorted", "a row removed", "a label changed",
                                  "a column dropped", "a value nudged"])
def test_an_edited_copy_with_a_copied_sidecar_is_refused_saying_what_changed(pair, tmp_path,
                                                                             edit):
    folder, a, b = pair
    t = pd.read_csv(folder / "a" / "f.csv")
    words = {"rows sorted": "other values in", "a row removed": "8 rows where it had 9",
             "a label changed": "whole-number or text columns", "a column dropped": "no column",
             "a value nudged": "other values in column shape_r00_n01"}[edit]
    if edit == "rows sorted":
        t = t.sort_values("area")
    elif edit == "a row removed":
        t = t.iloc[1:]
    elif edit == "a label changed":
        t.loc[0, "label"] = 7
    elif edit == "a column dropped":
        t = t.drop(columns=["area"])
    else:
        t.loc[0, "shape_r00_n01"] *= 1 + 1e-6
    t.to_csv(tmp_path / "f.csv", index=False)
    _copy(folder / "a" / "f.csv.json", tmp_path / "f.csv.json")
    with pytest.raises(InputError, match=f"do not belong together: the table has .*{words}"):
        read_table(tmp_path / "f.csv")
    # saved after its sidecar (edited in place): read, with a warning saying what changed
    os.utime(tmp_path / "f.csv.json", ns=(0, 0))
    with pytest.warns(UserWarning, match=f"changed after pfsdm wrote it .*{words}"):
        read_table(tmp_path / "f.csv")


def test_parquet_tables_are_paired_by_content_too(pair, tmp_path):
    pytest.importorskip("pyarrow")
    folder, a, b = pair
    write_table(a, tmp_path / "a.parquet")
    write_table(b, tmp_path / "b.parquet")
    _copy(tmp_path / "b.parquet.json", tmp_path / "a.parquet.json")
    with pytest.raises(InputError, match="do not belong together"):
        read_table(tmp_path / "a.parquet")


# --------------------------------------------------------------------------------------------
# labels against the table, by content
# --------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    folder = tmp_path_factory.mktemp("labels")
    labels = blobs()
    tifffile.imwrite(folder / "m.tif", labels, photometric="minisblack")
    assert main(["measure", str(folder / "m.tif"), "-o", str(folder / "f.csv"), "--link",
                 "labels", "-q", "--n-fourier", "4", "--n-radii", "4"]) == 0
    return folder, labels


def _swap(labels, a, b):
    out = labels.copy()
    out[labels == a], out[labels == b] = b, a
    return out


OTHER_LABELS = {
    "ids swapped": lambda m: _swap(m, 1, 2),
    "frames reversed": lambda m: m[::-1].copy(),
    "objects shifted": lambda m: np.roll(m, 2, axis=2),
    "objects grown": lambda m: np.maximum(m, np.roll(m, 1, axis=1)),
    "one object missing": lambda m: np.where(m == 3, 0, m),
    "other frame": lambda m: np.concatenate([m[1:2], m[1:]]),
}


@pytest.mark.parametrize("case", sorted(OTHER_LABELS))
def test_a_report_refuses_labels_that_are_not_the_tables(measured, tmp_path, capsys, case):
    folder, labels = measured
    other = OTHER_LABELS[case](labels)
    assert not np.array_equal(other, labels)
    tifffile.imwrite(tmp_path / "other.tif", other, photometric="minisblack")
    out = tmp_path / "r.html"
    assert main(["report", str(folder / "f.csv"), "-o", str(out), "--labels",
                 str(tmp_path / "other.tif"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "other.tif is not the segmentation the table was measured from" in err, err
    assert "internal error" not in err and not out.exists()
    # the Python door refuses the same labels
    from napari_pfsdm.report import write_report

    with pytest.raises(InputError, match="not the segmentation"):
        write_report(out, pf.read_table(folder / "f.csv"), labels=other)


def test_the_tables_own_labels_and_a_superset_are_accepted(measured, tmp_path):
    folder, labels = measured
    more = labels.copy()
    more[:, 70:78, 2:10] = 9  # an object the table does not have: the table's rows are there
    tifffile.imwrite(tmp_path / "more.tif", more, photometric="minisblack")
    for path in (folder / "m.tif", tmp_path / "more.tif"):
        assert main(["report", str(folder / "f.csv"), "-o", str(tmp_path / "r.html"),
                     "--labels", str(path), "-q"]) == 0


def test_equal_objects_with_their_ids_swapped_are_told_apart_by_where_they_are(tmp_path):
    from napari_pfsdm.analysis.label_images import check_labels_match

    frame = np.zeros((40, 60), np.uint8)
    frame[5:15, 5:15] = 1
    frame[20:30, 40:50] = 2  # the same area: only the centroid differs
    table = pf.measure(frame, **FAST)
    check_labels_match(frame, table)
    with pytest.raises(InputError, match="label 1 is centred at y, x = 24.5, 44.5 there"):
        check_labels_match(_swap(frame, 1, 2), table)


# --------------------------------------------------------------------------------------------
# a saved analysis, every file of it edited
# --------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    from napari_pfsdm.analysis.reduction import pca_scores
    from napari_pfsdm.saved import save_analysis

    labels = blobs()
    table = pf.measure(labels, **FAST)
    scores, ratios = pca_scores(table, "shape", 2)
    scores.attrs = {"explained_variance_ratio": [float(r) for r in ratios]}
    folder = tmp_path_factory.mktemp("saved") / "analysis"
    boxes = {(0, 1): (slice(7, 34), slice(12, 28)), (1, 2): (slice(45, 65), slice(35, 65))}
    save_analysis(folder, table, labels=labels, pca={"shape": scores}, groups={1: "a", 2: "b"},
                  boxes=boxes)
    return folder, labels, table


def _csv_edit(change):
    def edit(path):
        df = pd.read_csv(path)
        change(df).to_csv(path, index=False)
    return edit


def _json_edit(change):
    def edit(path):
        data = json.loads(path.read_text())
        path.write_text(json.dumps(change(data)))
    return edit


def _set(data, key, value):
    data[key] = value
    return data


MUTATIONS = {
    "deleted": lambda p: p.unlink(),
    "emptied": lambda p: p.write_bytes(b""),
    "cut in half": lambda p: p.write_bytes(p.read_bytes()[: len(p.read_bytes()) // 2]),
    "garbage": lambda p: p.write_bytes(b"\x00\xff\x10garbage\n" * 20),
    "a row removed": _csv_edit(lambda df: df.iloc[1:]),
    "rows doubled": _csv_edit(lambda df: pd.concat([df, df])),
    "text in a number": _csv_edit(lambda df: df.astype(object).assign(
        **{df.columns[min(2, len(df.columns) - 1)]: "n/a"})),
    "a big number": _csv_edit(lambda df: df.assign(**{df.columns[0]: 10**30})),
    "columns renamed": _csv_edit(lambda df: df.rename(columns=lambda c: f"x{c}")),
    "a list for the json": _json_edit(lambda d: [d]),
    "json keys removed": _json_edit(lambda d: {"written_by": d.get("written_by", "x")}),
    "json: a file outside": _json_edit(lambda d: _set(d, "files", {
        "features": "../../features.csv", "groups": "groups.csv", "boxes": "boxes.csv"})
        if "files" in d else _set(d, "options", [1, 2])),
    "json: numbers as text": _json_edit(lambda d: {k: (str(v) if not isinstance(v, dict)
                                                       else v) for k, v in d.items()}),
}
FILES = ["analysis.json", "features.csv", "features.csv.json", "pca_shape.csv",
         "pca_shape.csv.json", "groups.csv", "groups.csv.json", "boxes.csv", "boxes.csv.json"]


@pytest.mark.parametrize("name", FILES)
def test_every_file_of_a_saved_analysis_edited_opens_in_words_or_not_at_all(saved, tmp_path,
                                                                           name):
    from napari_pfsdm.saved import open_analysis

    src, labels, table = saved
    outcomes = {}
    for what, mutate in MUTATIONS.items():
        folder = tmp_path / what.replace(" ", "_").replace(":", "")
        shutil.copytree(src, folder)
        target = folder / name
        if name.endswith(".json") != ("json" in what) and what.startswith("json"):
            continue  # a JSON edit of a CSV file: not a case
        try:
            mutate(target)
        except (ValueError, pd.errors.ParserError, UnicodeDecodeError, KeyError, IndexError,
                pd.errors.EmptyDataError):
            continue  # the edit itself cannot be made on this file
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            try:
                back = open_analysis(folder, labels=labels)
            except InputError as exc:
                assert str(exc).strip() and "Traceback" not in str(exc)
                assert any(n in str(exc) for n in (name, str(folder), "labels")), str(exc)
                outcomes[what] = "refused"
                continue
        # opened: consistent with itself, and said so when anything differs
        words = " ".join(str(w.message) for w in said)
        keys = set(zip(back.table["frame"], back.table["label"], strict=True))
        assert set(back.boxes) <= keys
        for scores in back.pca.values():
            rows = list(zip(scores["frame"], scores["label"], strict=True))
            assert set(rows) <= keys and len(set(rows)) == len(rows)
        assert set(back.groups) <= set(back.table["label"])
        assert len(back.table) == len(table)
        assert words, f"{name} {what}: opened without a word"
        outcomes[what] = "opened with a warning"
    assert outcomes, name
