"""Tables through CSV and back (napari_pfsdm.io): awkward values come back as written."""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest

from napari_pfsdm.batch.run import _read_part, _write_part
from napari_pfsdm.errors import InputError
from napari_pfsdm.io import read_table, sidecar_path, write_table


def awkward() -> pd.DataFrame:
    """Values a careless reader gets wrong: names that look like numbers or like "missing",
    empty strings, NaN, infinities, -0.0, floats with 17 significant digits, commas, quotes."""
    return pd.DataFrame({
        "movie": ["001", "NA", "None", "", "nan", "1e3", "007"],
        "frame": [0, 1, 2, 3, 4, 5, 6],
        "label": [1, 1, 2, 2, 3, 3, 4],
        "track_id": [1, -1, 2, 3, 4, 5, 6],
        "area": [0.1 + 0.2, np.nan, 1e-300, -0.0, np.inf, -np.inf, 2.0 / 3.0],
        "group": ["1", "", "a", "01", "NA", "x", "null"],
        "error": ["", "boom, with a comma", 'a "quoted" word', "", "line", "", "é"],
        "warnings": ["", "", "1 hole filled", "", "", "", ""],
    })


def test_awkward_values_round_trip_exactly(tmp_path):
    df = awkward()
    write_table(df, tmp_path / "t.csv", {"n_fourier": 6})
    back = read_table(tmp_path / "t.csv")
    assert back["movie"].tolist() == ["001", "NA", "None", "", "nan", "1e3", "007"]
    assert back["group"].tolist() == ["1", "", "a", "01", "NA", "x", "null"]
    assert back["error"].tolist()[1:3] == ["boom, with a comma", 'a "quoted" word']
    area = back["area"].to_numpy()
    assert area[0] == 0.30000000000000004 and area[6] == 2.0 / 3.0 and area[2] == 1e-300
    assert np.isnan(area[1]) and area[4] == np.inf and area[5] == -np.inf
    assert area[3] == 0 and np.signbit(area[3])  # -0.0 keeps its sign
    assert back["track_id"].dtype.kind == "i" and back["track_id"].tolist()[1] == -1
    assert back.attrs["pfsdm"] == {"n_fourier": 6}
    pd.testing.assert_frame_equal(back, df)


def test_a_copy_resaved_by_pandas_with_its_index_reads_the_same(tmp_path):
    df = awkward()
    write_table(df, tmp_path / "t.csv", {})
    read_table(tmp_path / "t.csv").to_csv(tmp_path / "copy.csv")  # index 0, 1, 2, ...
    shutil.copy(tmp_path / "t.csv.json", tmp_path / "copy.csv.json")
    pd.testing.assert_frame_equal(read_table(tmp_path / "copy.csv"), df)


def test_numbers_still_read_missing_words_as_nan(tmp_path):
    # a table edited by hand: "NA" in a number column is missing, in a name column a name
    (tmp_path / "t.csv").write_text("movie,area,track_id\nNA,NA,\n002,1.5,3\n")
    back = read_table(tmp_path / "t.csv")
    assert back["movie"].tolist() == ["NA", "002"]
    assert np.isnan(back["area"][0]) and back["area"][1] == 1.5
    assert back["track_id"].tolist() == [-1, 3]


def test_a_distance_table_keeps_its_row_names(tmp_path):
    names = ["001:0:1", "NA:0:2", "None:1:1"]
    d = pd.DataFrame([[0.0, 0.5, 1.0], [0.5, 0.0, 0.25], [1.0, 0.25, 0.0]],
                     index=pd.Index(names, name="object"), columns=names)
    write_table(d, tmp_path / "d.csv", {}, index=True)
    back = read_table(tmp_path / "d.csv", index_col=0)
    assert back.index.tolist() == names and back.columns.tolist() == names
    np.testing.assert_array_equal(back.to_numpy(), d.to_numpy())


def test_batch_parts_read_back_as_written(tmp_path):
    # a movie's part goes through the same reader as a table (batch/run.py uses io's)
    df = awkward()
    _write_part(df, tmp_path / "part.csv", {"n_fourier": 6})
    pd.testing.assert_frame_equal(_read_part(tmp_path / "part.csv"), df)


def test_a_table_written_in_small_chunks_is_the_file_pandas_writes_whole(tmp_path, monkeypatch):
    """The CSV is formatted a few rows at a time (a worker thread then holds Python's lock
    only briefly): the file is byte for byte what one ``to_csv`` call writes."""
    import napari_pfsdm.io.tables as tables

    rng = np.random.default_rng(4)
    df = pd.DataFrame(rng.normal(size=(23, 5)), columns=list("abcde"))
    df.insert(0, "label", np.arange(1, 24))
    df["name"] = [f"cell {i}" for i in range(23)]
    monkeypatch.setattr(tables, "CSV_CHUNK_CELLS", 15)  # two rows per chunk: 12 chunks
    path = tables.write_table(df, tmp_path / "t.csv", {})
    assert path.read_text() == df.to_csv(index=False, lineterminator="\n")
    pd.testing.assert_frame_equal(pd.read_csv(path), df)


def test_a_table_of_several_mebibytes_is_paired_with_its_sidecar(tmp_path):
    """The sidecar records the table file's size and SHA-256, read in 1 MiB blocks: a table
    of several blocks reads back as written, its recorded size and digest those of the file."""
    import hashlib
    import json

    rng = np.random.default_rng(0)
    df = pd.DataFrame(rng.normal(size=(20_000, 8)), columns=[f"c{i}" for i in range(8)])
    path = write_table(df, tmp_path / "big.csv", {})
    data = path.read_bytes()
    assert len(data) > 2 * 2**20  # three blocks
    side = json.loads(sidecar_path(path).read_text())
    assert side["table_bytes"] == len(data)
    assert side["table_sha256"] == hashlib.sha256(data).hexdigest()
    pd.testing.assert_frame_equal(read_table(path, strict=True), df)


@pytest.mark.parametrize("text", ['{"written_by": "napari-pfsdm 0.1"}', "[1, 2]", '"options"'])
def test_a_json_file_that_is_no_sidecar_is_refused_in_plain_words(tmp_path, text):
    path = tmp_path / "t.csv"
    pd.DataFrame({"a": [1.0]}).to_csv(path, index=False)
    sidecar_path(path).write_text(text)
    with pytest.raises(InputError, match="is not a napari-pfsdm sidecar"):
        read_table(path)
