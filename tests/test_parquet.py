"""Parquet tables: a name ending in .parquet is written as Parquet with the
same sidecar, read back identically (columns and dtypes), by every command that reads a feature
table; a plain message when pyarrow is missing; nothing half-written on failure."""

from __future__ import annotations

import importlib.util
import json
import sys

import numpy as np
import pandas as pd
import pytest
import tifffile

import napari_pfsdm as P
from napari_pfsdm.cli import main
from napari_pfsdm.core.table_options import plain
from napari_pfsdm.io import read_table, write_table
from test_cli_options import three_objects

#: Writing and reading Parquet needs pyarrow (the [parquet] extra); the message given without
#: it is tested either way.
needs_pyarrow = pytest.mark.skipif(importlib.util.find_spec("pyarrow") is None,
                                   reason="pyarrow is not installed (the [parquet] extra)")

FAST = ["--n-fourier", "6", "--n-radii", "8", "--scheduler", "sync", "-q"]


def _movie(n_frames=3):
    """Three objects per frame that change shape over time."""
    return three_objects(n_frames)[0]  # the CLI tests' movie (tests/test_cli_options.py)


@needs_pyarrow
def test_a_measured_table_reads_back_identically(tmp_path):
    table = P.measure(_movie(), n_fourier=6, n_radii=8)
    table["movie"] = "001"  # text that a CSV reader could take for a number
    table["track_id"] = np.int64(-1)
    out = write_table(table, tmp_path / "f.parquet", table_type="features")
    back = read_table(out)
    pd.testing.assert_frame_equal(plain(back), plain(table))  # dtypes included
    as_csv = read_table(write_table(table, tmp_path / "f.csv"))
    assert back.attrs["pfsdm"] == as_csv.attrs["pfsdm"]  # the same sidecar options
    assert back.attrs["pfsdm"]["n_fourier"] == 6
    pd.testing.assert_frame_equal(pd.read_parquet(out), plain(table))  # plain pandas too
    side = json.loads((tmp_path / "f.parquet.json").read_text())
    assert side["format"] == "parquet" and side["rows"] == len(table)
    with open(out, "rb") as handle:
        assert handle.read(4) == b"PAR1"


@needs_pyarrow
def test_odd_columns_round_trip(tmp_path):
    df = pd.DataFrame({
        "frame": np.array([0, 1, 2], np.int64), "label": np.array([1, 2, 3], np.int32),
        "x": [0.1, np.nan, 1e-300], "flag": [True, False, True],
        "movie": ["NA", "", "None"], "error": ["", "too small", ""],
    })
    p = write_table(df, tmp_path / "t.parquet", {"a": 1})
    pd.testing.assert_frame_equal(plain(read_table(p)), df)
    d = pd.DataFrame(np.eye(2), index=pd.Index(["a", "b"], name="object"), columns=["a", "b"])
    p = write_table(d, tmp_path / "d.parquet", {}, index=True)
    pd.testing.assert_frame_equal(plain(read_table(p, index_col=0)), d)


@needs_pyarrow
def test_measure_writes_parquet_that_every_reader_takes(tmp_path):
    tifffile.imwrite(tmp_path / "m.tif", _movie(), photometric="minisblack")
    for name in ("f.csv", "f.parquet"):
        assert main(["measure", str(tmp_path / "m.tif"), "-o", str(tmp_path / name),
                     "--link", "labels", *FAST]) == 0
    csv, pq = read_table(tmp_path / "f.csv"), read_table(tmp_path / "f.parquet")
    assert pq.attrs["pfsdm"] == csv.attrs["pfsdm"]
    pd.testing.assert_frame_equal(plain(pq), plain(csv))  # dtypes included
    # compare and trajectories read it: the same numbers as from the CSV
    for src in ("f.csv", "f.parquet"):
        assert main(["compare", str(tmp_path / src), "-o", str(tmp_path / f"d_{src}.csv"),
                     "-q"]) == 0
        assert main(["trajectories", str(tmp_path / src), "-o",
                     str(tmp_path / f"p_{src}.csv"), "--link", "labels", "-q"]) == 0
    for what in ("d", "p"):
        a = pd.read_csv(tmp_path / f"{what}_f.csv.csv")
        b = pd.read_csv(tmp_path / f"{what}_f.parquet.csv")
        pd.testing.assert_frame_equal(a, b, rtol=1e-12)


def test_without_pyarrow_a_plain_message_and_no_file(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # import pyarrow -> ImportError
    df = pd.DataFrame({"frame": [0], "label": [1]})
    with pytest.raises(ValueError, match=r'pip install "napari-pfsdm\[parquet\]"'):
        write_table(df, tmp_path / "t.parquet", {})
    assert list(tmp_path.iterdir()) == []
    tifffile.imwrite(tmp_path / "m.tif", _movie(1), photometric="minisblack")
    assert main(["measure", str(tmp_path / "m.tif"), "-o", str(tmp_path / "f.parquet"),
                 "--link", "labels", "--scheduler", "sync"]) == 2
    err = capsys.readouterr().err
    assert 'pip install "napari-pfsdm[parquet]"' in err and "Traceback" not in err
    assert not (tmp_path / "f.parquet").exists()


@needs_pyarrow
def test_a_failed_write_leaves_nothing_behind(tmp_path, monkeypatch):
    df = pd.DataFrame({"frame": [0, 1], "label": [1, 1]})
    write_table(df, tmp_path / "t.parquet", {"v": 1})
    before = (tmp_path / "t.parquet").read_bytes()

    def broken(self, handle, **kw):
        handle.write(b"PAR1 half a table")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(pd.DataFrame, "to_parquet", broken)
    with pytest.raises(OSError, match="No space"):
        write_table(df.assign(x=1.0), tmp_path / "t.parquet", {"v": 2})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.parquet", "t.parquet.json"]
    assert (tmp_path / "t.parquet").read_bytes() == before
    assert json.loads((tmp_path / "t.parquet.json").read_text())["options"] == {"v": 1}
