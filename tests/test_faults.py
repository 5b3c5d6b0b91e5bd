"""The fault battery (issue 43): what the user gets when data, files, the cluster or the machine
misbehave, and that nothing good is lost or clobbered on the way.

Each test reproduces one fault as a user meets it (a missing Zarr chunk, a re-segmented store,
a planted symlink, a full disk, a killed worker, ...) and asserts the plain words, the exit
status and the files left behind. Expected values are computed here, independently of the code
under test (counts of objects from numpy, sizes and checksums from the bytes on disk).
"""

from __future__ import annotations

import numpy as np
import pytest
import tifffile

import napari_pfsdm as pf
from napari_pfsdm.analysis.label_images import count_objects
from napari_pfsdm.cli import main
from napari_pfsdm.core.table_schema import table_feature_columns

zarr = pytest.importorskip("zarr")

FAST = {"n_fourier": 4, "n_radii": 4}
CLI_FAST = ["--n-fourier", "4", "--n-radii", "4", "--link", "labels", "-q"]


def ellipse_labels(shape=(64, 64), centre=(32, 30), axes=(20, 12), label=1) -> np.ndarray:
    """One elliptic object of id ``label`` in a frame of ``shape`` (uint8 when it fits)."""
    yy, xx = np.mgrid[: shape[0], : shape[1]]
    inside = ((yy - centre[0]) / axes[0]) ** 2 + ((xx - centre[1]) / axes[1]) ** 2 < 1
    dtype = np.uint8 if label < 256 else np.uint64
    out = np.zeros(shape, dtype)
    out[inside] = label
    return out


def ramp(shape=(64, 64)) -> np.ndarray:
    """A positive reporter that grows to the right: every object has a finite, positive mean."""
    return np.broadcast_to(1.0 + np.arange(shape[1]) / shape[1], shape).copy()


def intensity_columns(table) -> list[str]:
    return table_feature_columns(table.attrs["pfsdm"], "intensity")


# --------------------------------------------------------------------------------------------
# 3. non-finite reporter values, RGB labels, reporters of 3 or 4 frames
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("bad", [np.inf, -np.inf, np.nan])
def test_a_non_finite_reporter_pixel_gives_nan_features_and_a_warning(bad):
    labels = np.stack([ellipse_labels(), ellipse_labels()])
    image = np.stack([ramp(), ramp()])
    image[1, 32, 30] = bad  # inside the object of frame 1 only
    table = pf.measure(labels, image, **FAST)
    cols = intensity_columns(table)
    assert len(cols) == 4 * 5
    good, spoilt = table.iloc[0], table.iloc[1]
    assert np.isfinite(good[cols].to_numpy(float)).all() and good["warnings"] == ""
    assert np.isnan(spoilt[cols].to_numpy(float)).all()  # never zeros
    assert "intensity features left empty" in spoilt["warnings"]
    word = {np.inf: "+inf", -np.inf: "-inf"}.get(bad, "NaN")
    assert word in spoilt["warnings"]
    # the shape features do not depend on the reporter
    shape = table_feature_columns(table.attrs["pfsdm"], "shape")
    np.testing.assert_array_equal(good[shape].to_numpy(float), spoilt[shape].to_numpy(float))


def test_a_non_finite_pixel_outside_the_object_does_not_spoil_it():
    labels = ellipse_labels()
    image = ramp()
    clean = pf.measure(labels, image, **FAST)
    cols = intensity_columns(clean)
    far, near = image.copy(), image.copy()
    far[0, 0] = np.inf  # outside the object's box: never read
    np.testing.assert_array_equal(pf.measure(labels, far, **FAST)[cols].to_numpy(float),
                                  clean[cols].to_numpy(float))
    from scipy import ndimage as ndi

    rim = ndi.binary_dilation(labels > 0) & (labels == 0)
    near[rim] = np.inf  # every pixel touching the outline from outside: 0, not 1.8e308
    got = pf.measure(labels, near, **FAST)
    assert got["warnings"][0] == ""
    np.testing.assert_allclose(got[cols].to_numpy(float), clean[cols].to_numpy(float),
                               atol=0.1)


@pytest.mark.parametrize("channels", [3, 4])
def test_measure_refuses_rgb_labels_as_the_command_line_does(channels):
    rgb = np.zeros((64, 64, channels), np.uint8)
    rgb[10:30, 10:30] = 1
    with pytest.raises(ValueError, match="colour .RGB"):
        pf.measure(rgb)
    with pytest.raises(ValueError, match="colour .RGB"):
        pf.measure(np.stack([rgb, rgb]))  # an RGB time-lapse (T, Y, X, C)
    # saying the axes is an explicit choice: 64 frames of 64 x 3 pixels
    assert len(pf.measure(np.moveaxis(rgb, 2, 0)[:, :, :], axes="tyx", **FAST)) == channels


def test_an_rgb_reporter_is_named_as_such():
    labels = ellipse_labels()
    with pytest.raises(ValueError, match="colour .RGB"):
        pf.measure(labels, np.stack([ramp()] * 3, axis=-1))


@pytest.mark.parametrize("n_frames", [3, 4])
def test_a_float_reporter_of_three_or_four_frames_is_a_time_lapse(tmp_path, n_frames):
    labels = np.stack([ellipse_labels()] * n_frames)
    image = np.stack([ramp() * (t + 1) for t in range(n_frames)]).astype(np.float32)
    tifffile.imwrite(tmp_path / "l.tif", labels)
    tifffile.imwrite(tmp_path / "i.tif", image)  # tifffile stores 3 or 4 planes as planar RGB
    out = tmp_path / "f.csv"
    assert main(["measure", str(tmp_path / "l.tif"), "-i", str(tmp_path / "i.tif"),
                 "-o", str(out), "--scheduler", "sync", *CLI_FAST]) == 0
    table = pf.read_table(out)
    assert table["frame"].tolist() == list(range(n_frames))
    assert (table["warnings"] == "").all()


def test_the_command_line_still_refuses_an_rgb_tiff(tmp_path, capsys):
    rgb = np.zeros((64, 64, 3), np.uint8)
    rgb[10:30, 10:30] = 1
    tifffile.imwrite(tmp_path / "rgb.tif", rgb, photometric="rgb")
    assert main(["measure", str(tmp_path / "rgb.tif"), "-o", str(tmp_path / "f.csv"),
                 "--scheduler", "sync", *CLI_FAST]) == 2
    assert "colour (RGB)" in capsys.readouterr().err
    assert not (tmp_path / "f.csv").exists()


# --------------------------------------------------------------------------------------------
# 7. any label ids; empty and zero-size arrays
# --------------------------------------------------------------------------------------------

BIG_IDS = [(np.uint32, 4_000_000_000), (np.uint64, 2**63 - 1), (np.uint64, 2**40 + 7),
           (np.int64, 2**62)]


def two_objects(dtype, big: int) -> np.ndarray:
    """Two frames, the same two objects (ids 5 and ``big``) moving right by 2 pixels."""
    out = np.zeros((2, 64, 64), dtype)
    for t in range(2):
        out[t] = ellipse_labels(centre=(20, 20 + 2 * t), axes=(10, 7)).astype(bool) * 5
        out[t][ellipse_labels(centre=(45, 40 + 2 * t), axes=(8, 14)).astype(bool)] = big
    return out


@pytest.mark.parametrize(("dtype", "big"), BIG_IDS)
def test_huge_label_ids_are_measured_as_any_others(dtype, big):
    labels = two_objects(dtype, big)
    table = pf.measure(labels, **FAST)
    assert table["label"].tolist() == [5, big, 5, big]
    small = pf.measure(np.where(labels == big, 9, labels).astype(np.uint8), **FAST)
    shape = table_feature_columns(table.attrs["pfsdm"], "shape")
    np.testing.assert_array_equal(table[shape].to_numpy(float), small[shape].to_numpy(float))
    assert count_objects(labels) == 4


def test_one_object_of_id_1e8_takes_memory_for_one_object():
    """Memory follows the objects, not the largest id (its time: benchmarks, not here)."""
    import tracemalloc

    labels = np.zeros((64, 64), np.uint32)
    labels[20:40, 15:45] = 100_000_000
    tracemalloc.start()
    try:
        table = pf.measure(labels, **FAST)
        n = count_objects(labels)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert table["label"].tolist() == [100_000_000] and n == 1
    assert peak < 64 * 2**20  # a table sized by the largest id would be 400 MB and more


@pytest.mark.parametrize("link", ["overlap", "centroid"])
def test_huge_ids_link_over_time(tmp_path, link):
    labels = two_objects(np.uint64, 2**63 - 1)
    tifffile.imwrite(tmp_path / "l.tif", labels, photometric="minisblack")
    out = tmp_path / "f.csv"
    cli = [a for a in CLI_FAST if a not in ("--link", "labels")]
    assert main(["measure", str(tmp_path / "l.tif"), "-o", str(out), "--scheduler", "sync",
                 "--link", link, *cli]) == 0
    table = pf.read_table(out)
    assert table["label"].tolist() == [5, 2**63 - 1, 5, 2**63 - 1]
    if "track_id" in table.columns:  # the same object keeps its track
        assert table["track_id"].iloc[0] == table["track_id"].iloc[2]
        assert table["track_id"].iloc[1] == table["track_id"].iloc[3]


def test_the_parallel_run_takes_huge_ids():
    from napari_pfsdm.analysis.measuring import ObjectMeasurer
    from napari_pfsdm.analysis.parallel import _labels_per_frame, plan_tasks, task_entries
    from napari_pfsdm.core.params import PFSDMParams

    labels = two_objects(np.uint64, 2**63 - 1)
    counts = _labels_per_frame(labels, 2, True)
    assert [c.tolist() for c in counts] == [[5, 2**63 - 1]] * 2
    tasks = plan_tasks(counts, 4)  # one object per task: a frame split between tasks, crops
    measurer = ObjectMeasurer.of(PFSDMParams())
    sent = [task_entries(measurer, labels, None, True, task, counts, {}) for task in tasks]
    crops = [c for entries in sent for e in entries if e[0] == "crops" for c in e[1]]
    assert {c.label for c in crops} <= {5, 2**63 - 1} and crops


@pytest.mark.parametrize("shape", [(0, 16, 16), (3, 0, 16), (0, 0), (16, 0)])
def test_zero_size_labels_are_refused_in_plain_words(shape):
    with pytest.raises(ValueError, match="no pixels"):
        pf.measure(np.zeros(shape, np.uint8))


def test_a_zero_frame_tiff_is_refused_in_plain_words(tmp_path, capsys):
    tifffile.imwrite(tmp_path / "empty.tif", np.zeros((0, 16, 16), np.uint8))
    code = main(["measure", str(tmp_path / "empty.tif"), "-o", str(tmp_path / "f.csv"),
                 "--scheduler", "sync", *CLI_FAST])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "no pixels" in err or "no frames" in err or "cannot read" in err
    assert "internal error" not in err and not (tmp_path / "f.csv").exists()


# --------------------------------------------------------------------------------------------
# 8. errors in the right drawer: the environment's faults are plain words and exit 2
# --------------------------------------------------------------------------------------------

def write_tiff_movie(path, n_frames: int = 2, label: int = 1):
    labels = np.stack([ellipse_labels(centre=(32, 26 + 2 * t), label=label)
                       for t in range(n_frames)])
    tifffile.imwrite(path, labels, photometric="minisblack")
    return labels


def not_measured(monkeypatch) -> list:
    """Replace the batch's measuring with a recorder: it must not be reached."""
    from napari_pfsdm.batch import run as run_module

    calls: list = []
    monkeypatch.setattr(run_module, "measure_dask", lambda *a, **k: calls.append(a))
    return calls


def plain_error(capsys, *words: str) -> str:
    err = capsys.readouterr().err
    assert "internal error" not in err and "Traceback" not in err, err
    for word in words:
        assert word in err, err
    return err


def test_missing_pyarrow_is_found_before_measuring(tmp_path, monkeypatch, capsys):
    import sys

    write_tiff_movie(tmp_path / "m.tif")
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # import pyarrow -> ImportError
    calls = not_measured(monkeypatch)
    assert main(["measure", str(tmp_path / "m.tif"), "-o", str(tmp_path / "f.parquet"),
                 "--scheduler", "sync", *CLI_FAST]) == 2
    plain_error(capsys, 'pip install "napari-pfsdm[parquet]"')
    assert calls == [] and not (tmp_path / "f.parquet").exists()
    with pytest.raises(ValueError, match="pyarrow"):  # the library checks first too
        from napari_pfsdm.batch import run_batch
        from napari_pfsdm.batch.movies import Movie

        run_batch([Movie("m", tmp_path / "m.tif")], tmp_path / "g.parquet", scheduler="sync")
    assert calls == []


def broken_pool(*args, **kwargs):
    from concurrent.futures.process import BrokenProcessPool

    raise BrokenProcessPool("A process in the process pool was terminated abruptly")


def test_a_killed_worker_is_a_plain_message_and_finished_movies_stay(tmp_path, monkeypatch,
                                                                       capsys):
    from napari_pfsdm.batch import tasks

    for name in ("a", "b"):
        write_tiff_movie(tmp_path / f"{name}.tif")
    out = tmp_path / "f.csv"
    real = tasks._run_local
    seen: list = []

    def dies_on_b(*args, **kwargs):
        seen.append(1)
        return real(*args, **kwargs) if len(seen) == 1 else broken_pool()

    monkeypatch.setattr(tasks, "_run_local", dies_on_b)
    assert main(["measure", str(tmp_path / "a.tif"), str(tmp_path / "b.tif"), "-o", str(out),
                 "--scheduler", "sync", *CLI_FAST]) == 2
    err = plain_error(capsys, "worker process", "run the same command again")
    assert "memory" in err
    parts = sorted(p.name for p in (tmp_path / "f.csv.parts").iterdir())
    assert [p[:2] for p in parts if not p.endswith(".json")] == ["a-"]  # a is kept
    assert not out.exists()
    monkeypatch.setattr(tasks, "_run_local", real)  # the re-run resumes
    assert main(["measure", str(tmp_path / "a.tif"), str(tmp_path / "b.tif"), "-o", str(out),
                 "--scheduler", "sync", *CLI_FAST]) == 0
    assert pf.read_table(out)["movie"].tolist() == ["a", "a", "b", "b"]


class _DiesInWorker:
    """A (2, 64, 64) label movie whose pixels kill the process that reads them, unless it is
    the process that made it: a worker killed by the system (e.g. out of memory)."""

    shape, dtype, ndim = (2, 64, 64), np.dtype(np.uint8), 3

    def __init__(self):
        import os

        self.parent = os.getpid()

    def __getitem__(self, key):
        return self

    def __array__(self, dtype=None, copy=None):
        import os
        import signal

        if os.getpid() != self.parent:
            os.kill(os.getpid(), signal.SIGKILL)
        return np.zeros(self.shape, np.uint8)


def test_a_worker_killed_by_the_system_is_a_plain_message():
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from napari_pfsdm.batch import measure_dask

    pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"))
    with pool, pytest.raises(ValueError, match="worker process .* stopped") as info:
        measure_dask(_DiesInWorker(), scheduler="processes", num_workers=1, pool=pool, **FAST)
    assert pf.errors.InputError in type(info.value).__mro__


@pytest.mark.parametrize("fault", ["KilledWorker", "CommClosedError", "FutureCancelledError"])
def test_a_lost_cluster_is_a_plain_message(fault):
    distributed = pytest.importorskip("distributed", reason="needs dask.distributed (batch extra)")
    from distributed.client import FutureCancelledError
    from distributed.comm.core import CommClosedError

    from napari_pfsdm.batch.tasks import environment_fault

    exc = {"KilledWorker": distributed.KilledWorker("pfsdm-chunk-0", None, 3),
           "CommClosedError": CommClosedError("in <TCP (closed)>: Stream is closed"),
           "FutureCancelledError": FutureCancelledError("pfsdm-chunk-0", reason="lost")}[fault]
    got = environment_fault(exc, "tcp://10.0.0.5:8786")
    assert got is not None and isinstance(got, ValueError)
    assert "tcp://10.0.0.5:8786" in str(got) and "run the same command again" in str(got)
    assert environment_fault(ZeroDivisionError("a bug"), "tcp://10.0.0.5:8786") is None


# --------------------------------------------------------------------------------------------
# 1. missing data is never silent: empty frames named, missing Zarr chunks refused
# --------------------------------------------------------------------------------------------

def three_objects_per_frame(n_frames: int = 3) -> np.ndarray:
    """``n_frames`` frames of three objects (ids 1, 2, 3) each."""
    out = np.zeros((n_frames, 64, 64), np.uint16)
    for t in range(n_frames):
        out[t][ellipse_labels(centre=(16, 16 + t), axes=(8, 6)) > 0] = 1
        out[t][ellipse_labels(centre=(44, 20), axes=(9, 12)) > 0] = 2
        out[t][ellipse_labels(centre=(30, 48), axes=(12, 7)) > 0] = 3
    return out


def zarr_movie(path, data, zarr_format: int = 3):
    z = zarr.create_array(str(path), shape=data.shape, dtype=data.dtype,
                          chunks=(1, *data.shape[1:]), zarr_format=zarr_format)
    z[:] = data
    return z


def chunk_file(path, zarr_format: int, frame: int):
    """The chunk file of ``frame`` in a store of one chunk per frame (computed here from the
    Zarr specifications: v3 'c/t/0/0', v2 't.0.0')."""
    return path / ("c" if zarr_format == 3 else "") / (
        f"{frame}/0/0" if zarr_format == 3 else f"{frame}.0.0")


def sidecar(path) -> dict:
    import json

    return json.loads(path.with_name(path.name + ".json").read_text())


@pytest.mark.parametrize("zarr_format", [2, 3])
def test_a_zarr_store_missing_a_chunk_is_refused_in_plain_words(tmp_path, capsys, zarr_format):
    store = tmp_path / "m.zarr"
    zarr_movie(store, three_objects_per_frame(3), zarr_format)
    chunk = chunk_file(store, zarr_format, 1)
    assert chunk.is_file()
    chunk.unlink()  # lost in a copy
    out = tmp_path / "f.csv"
    assert main(["measure", str(store), "-o", str(out), "--scheduler", "sync", *CLI_FAST]) == 2
    err = plain_error(capsys, "missing", "frame 1", "--allow-missing-chunks")
    assert "m.zarr" in err and not out.exists()
    # read as it is only when the user says so, and then warned per frame and recorded
    assert main(["measure", str(store), "-o", str(out), "--scheduler", "sync",
                 "--allow-missing-chunks", *CLI_FAST[:-1]]) == 0
    said = capsys.readouterr()
    assert "frame 1" in said.out + said.err and "missing" in said.out + said.err
    table = pf.read_table(out)
    assert table["frame"].tolist() == [0, 0, 0, 2, 2, 2]
    assert sidecar(out)["missing_chunks"] == {"m": {"1": 1}}


def test_measure_dask_refuses_missing_chunks_unless_allowed(tmp_path):
    from napari_pfsdm.batch import measure_dask, open_movie

    store = tmp_path / "m.zarr"
    zarr_movie(store, three_objects_per_frame(3))
    chunk_file(store, 3, 2).unlink()
    with pytest.raises(ValueError, match="frame 2"):
        measure_dask(open_movie(store), scheduler="sync", **FAST)
    with pytest.warns(UserWarning, match="frame 2"):
        table = measure_dask(open_movie(store), scheduler="sync", allow_missing_chunks=True,
                             **FAST)
    assert sorted(set(table["frame"])) == [0, 1]


def test_frames_without_objects_are_named(tmp_path, capsys):
    movie = three_objects_per_frame(5)
    movie[1] = 0
    movie[3] = 0
    tifffile.imwrite(tmp_path / "m.tif", movie, photometric="minisblack")
    out = tmp_path / "f.csv"
    assert main(["measure", str(tmp_path / "m.tif"), "-o", str(out), "--scheduler", "sync",
                 *CLI_FAST[:-1]]) == 0
    said = capsys.readouterr().out
    assert "no objects in frames 1, 3" in said
    assert sidecar(out)["empty_frames"] == {"m": [1, 3]}
    assert sorted(set(pf.read_table(out)["frame"])) == [0, 2, 4]


def test_a_movie_without_empty_frames_says_nothing_about_them(tmp_path, capsys):
    tifffile.imwrite(tmp_path / "m.tif", three_objects_per_frame(2), photometric="minisblack")
    out = tmp_path / "f.csv"
    assert main(["measure", str(tmp_path / "m.tif"), "-o", str(out), "--scheduler", "sync",
                 *CLI_FAST[:-1]]) == 0
    assert "no objects" not in capsys.readouterr().out
    assert sidecar(out)["empty_frames"] == {}


# --------------------------------------------------------------------------------------------
# 5. files safe in a shared folder
# --------------------------------------------------------------------------------------------

def measure_into(tmp_path, out, *extra: str) -> int:
    return main(["measure", str(tmp_path / "m.tif"), "-o", str(out), "--scheduler", "sync",
                 *extra, *CLI_FAST])


def test_a_planted_symlink_never_redirects_a_write(tmp_path):
    from napari_pfsdm.batch import run as run_module
    from napari_pfsdm.batch.movies import Movie
    from napari_pfsdm.core.params import PFSDMParams

    write_tiff_movie(tmp_path / "m.tif")
    victim = tmp_path / "precious.txt"
    victim.write_text("a colleague's file\n")
    out = tmp_path / "f.csv"
    parts = tmp_path / "f.csv.parts"
    parts.mkdir()
    stem = run_module._part_name(Movie("m", tmp_path / "m.tif"), PFSDMParams(**FAST))
    for suffix in (".parquet", ".csv", ".json"):  # the old fixed names, all planted
        (parts / f".{stem}{suffix}.tmp").symlink_to(victim)
    (tmp_path / ".f.csv.tmp").symlink_to(victim)
    assert measure_into(tmp_path, out) == 0
    assert victim.read_text() == "a colleague's file\n"
    assert len(pf.read_table(out)) == 2


def test_a_sidecar_from_another_write_is_refused_in_plain_words(tmp_path):
    import shutil

    from napari_pfsdm.io import read_table, write_table

    a, b = tmp_path / "a.csv", tmp_path / "b" / "a.csv"
    b.parent.mkdir()
    df = pd_frame()
    write_table(df, a, {"v": 1})
    write_table(df.assign(area=df["area"] * 2), b, {"v": 2})
    shutil.copy(b.with_name("a.csv.json"), a.with_name("a.csv.json"))  # v2's sidecar by v1's
    with pytest.raises(ValueError, match="do not belong together"):
        read_table(a)
    # under another name too: the sidecar's file name does not make a pair, the content does
    shutil.copy(a, tmp_path / "copy.csv")
    shutil.copy(tmp_path / "b" / "a.csv.json", tmp_path / "copy.csv.json")
    with pytest.raises(ValueError, match="do not belong together.*other values in column "
                                         "area"):
        read_table(tmp_path / "copy.csv")
    # a copy of a table with its own sidecar, under another name, is that table
    shutil.copy(b, tmp_path / "copy.csv")
    assert read_table(tmp_path / "copy.csv").attrs["pfsdm"] == {"v": 2}


def pd_frame():
    import pandas as pd

    return pd.DataFrame({"frame": [0, 1, 2], "label": [1, 1, 2], "area": [10.5, 11.0, 9.25]})


def test_a_reader_beside_a_writer_never_pairs_two_writes(tmp_path):
    import threading

    from napari_pfsdm.io import read_table, write_table

    out = tmp_path / "t.csv"
    base = pd_frame()
    write_table(base.assign(v=0), out, {"v": 0})
    stop = threading.Event()

    def writer() -> None:
        v = 0
        while not stop.is_set():
            v += 1
            rows = base.assign(v=v) if v % 2 else base.iloc[:2].assign(v=v)
            write_table(rows, out, {"v": v})

    thread = threading.Thread(target=writer)
    thread.start()
    pairs = refused = 0
    try:
        for _ in range(60):
            try:
                got = read_table(out)
            except ValueError as exc:
                assert "do not belong together" in str(exc)
                refused += 1
                continue
            assert set(got["v"]) == {got.attrs["pfsdm"]["v"]}  # the table is its sidecar's
            pairs += 1
    finally:
        stop.set()
        thread.join()
    assert pairs > 0


def test_a_second_run_into_the_same_output_refuses(tmp_path, capsys):
    from napari_pfsdm.io import output_lock

    write_tiff_movie(tmp_path / "m.tif")
    out = tmp_path / "f.csv"
    with output_lock(out):  # another run is writing f.csv
        assert measure_into(tmp_path, out) == 2
        plain_error(capsys, "another pfsdm run", "f.csv")
        assert not out.exists()
    assert measure_into(tmp_path, out) == 0  # free again
    assert not list(tmp_path.glob(".*lock*"))


def test_a_killed_run_leftovers_are_cleaned_by_the_next(tmp_path):
    write_tiff_movie(tmp_path / "m.tif")
    out = tmp_path / "f.csv"
    parts = tmp_path / "f.csv.parts"
    parts.mkdir()
    ours = [tmp_path / ".f.csv.k2j4h5g6.tmp", tmp_path / ".f.csv.json.a_b1c2d3.tmp",
            parts / ".m-0123456789.parquet.tmp", parts / ".m-0123456789.parquet.x1y2z3w4.tmp"]
    others = [tmp_path / ".g.csv.k2j4h5g6.tmp", tmp_path / "notes.tmp"]
    for f in ours + others:
        f.write_text("half")
    (tmp_path / ".f.csv.lock").write_text("12345 a host that died\n")  # a stale lock
    assert measure_into(tmp_path, out) == 0
    assert [f for f in ours if f.exists()] == []
    assert all(f.read_text() == "half" for f in others)


def test_a_full_disk_keeps_the_good_output(tmp_path, monkeypatch, capsys):
    import errno

    import pandas as pd

    write_tiff_movie(tmp_path / "m.tif")
    out = tmp_path / "f.csv"
    assert measure_into(tmp_path, out) == 0
    before = {p.name: p.read_bytes() for p in (out, out.with_name("f.csv.json"))}

    def full(self, *args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(pd.DataFrame, "to_csv", full)
    assert measure_into(tmp_path, out, "--n-angles", "32") == 2  # other options: measured again
    plain_error(capsys, "No space left on device")
    assert {p.name: p.read_bytes() for p in (out, out.with_name("f.csv.json"))} == before
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")] == []


# --------------------------------------------------------------------------------------------
# 2. a resume is never stale
# --------------------------------------------------------------------------------------------

def run_logged(store, out, **kw) -> tuple[list[str], object]:
    from napari_pfsdm.batch import find_movies, pair_movies, run_batch

    log: list[str] = []
    table = run_batch(pair_movies(find_movies(store)), out, scheduler="sync", log=log.append,
                      **FAST, **kw)
    return log, table


@pytest.mark.parametrize("zarr_format", [2, 3])
def test_a_zarr_store_resegmented_in_place_is_measured_again(tmp_path, zarr_format):
    store = tmp_path / "m.zarr"
    movie = three_objects_per_frame(3)
    zarr_movie(store, movie, zarr_format)
    out = tmp_path / "f.csv"
    log, first = run_logged(store, out)
    assert log[0].startswith("measured m") and len(first) == 9
    z = zarr.open_array(str(store), mode="r+")
    z[1] = np.where(movie[1] == 3, 0, movie[1])  # frame 1 re-segmented: object 3 gone
    log, second = run_logged(store, out)
    assert log[0].startswith("measured m"), log  # not "skipped (already measured)"
    assert len(second) == 8 and 3 not in second.loc[second["frame"] == 1, "label"].tolist()


def test_a_chunk_rewritten_with_the_same_size_and_time_is_measured_again(tmp_path):
    import os

    store = tmp_path / "m.zarr"
    movie = three_objects_per_frame(2)
    z = zarr.create_array(str(store), shape=movie.shape, dtype=movie.dtype,
                          chunks=(1, 64, 64), compressors=None)  # every chunk the same size
    z[:] = movie
    chunk = chunk_file(store, 3, 1)
    out = tmp_path / "f.csv"
    run_logged(store, out)
    stat = chunk.stat()
    swapped = np.where(movie[1] == 1, 2, np.where(movie[1] == 2, 1, movie[1]))
    z[1] = swapped  # the ids of two objects swapped: same bytes count
    os.utime(chunk, ns=(stat.st_atime_ns, stat.st_mtime_ns))  # and the same time
    assert chunk.stat().st_size == stat.st_size
    log, table = run_logged(store, out)
    assert log[0].startswith("measured m"), log
    frame1 = table[table["frame"] == 1].set_index("label")["area"]
    assert frame1[1] == int((swapped == 1).sum()) and frame1[2] == int((swapped == 2).sum())


@pytest.mark.parametrize("parquet", [True, False])
def test_a_damaged_part_is_measured_again(tmp_path, monkeypatch, parquet):
    if parquet:
        pytest.importorskip("pyarrow", reason="parts as Parquet need pyarrow (parquet extra)")
    from napari_pfsdm.batch import run as run_module

    monkeypatch.setattr(run_module, "_have_parquet", lambda: parquet)
    store = tmp_path / "m.zarr"
    zarr_movie(store, three_objects_per_frame(2))
    out = tmp_path / "f.csv"
    _, good = run_logged(store, out)
    (part,) = [p for p in (tmp_path / "f.csv.parts").iterdir() if p.suffix != ".json"]
    data = part.read_bytes()
    part.write_bytes(data[: len(data) // 2])  # truncated: a full disk, a killed copy
    logs = []
    for _ in range(2):  # measured again, and then resumed as usual
        log, table = run_logged(store, out)
        logs.append(log)
        assert table["label"].tolist() == good["label"].tolist()
    assert "is damaged" in logs[0][0] and logs[0][1].startswith("measured m")
    assert logs[1][0].startswith("skipped m")
    assert len(part.read_bytes()) == len(data)


# --------------------------------------------------------------------------------------------
# 4. a scheduler address that is not a dask scheduler
# --------------------------------------------------------------------------------------------

@pytest.fixture
def silent_server():
    """A TCP server on 127.0.0.1 that accepts connections and never says a word (as a web
    dashboard does until it gets a request); its address."""
    import socket
    import threading

    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    held: list = []

    def accept() -> None:
        while True:
            try:
                held.append(srv.accept()[0])
            except OSError:
                return

    threading.Thread(target=accept, daemon=True).start()
    yield f"tcp://127.0.0.1:{srv.getsockname()[1]}"
    srv.close()
    for conn in held:
        conn.close()


def test_a_port_that_is_not_a_dask_scheduler_fails_within_the_timeout(
        tmp_path, monkeypatch, capsys, silent_server):
    import threading

    pytest.importorskip("distributed")
    from napari_pfsdm.analysis import schedulers

    monkeypatch.setattr(schedulers, "CONNECT_TIMEOUT", 1.0)
    write_tiff_movie(tmp_path / "m.tif")
    result: dict = {}

    def run() -> None:
        result["code"] = main(["measure", str(tmp_path / "m.tif"), "-o",
                               str(tmp_path / "f.csv"), "--scheduler", silent_server,
                               *CLI_FAST])

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(30)  # the probe's timeout is 1 s here: far longer means it hangs
    assert not thread.is_alive(), "pfsdm hangs on a port that is not a dask scheduler"
    assert result["code"] == 2
    plain_error(capsys, silent_server, "not answer as a dask scheduler")
    assert not (tmp_path / "f.csv").exists()


def test_a_closed_port_is_a_plain_message(tmp_path, capsys):
    import socket

    pytest.importorskip("distributed")
    probe = socket.socket()
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()  # nothing listens there now
    write_tiff_movie(tmp_path / "m.tif")
    assert main(["measure", str(tmp_path / "m.tif"), "-o", str(tmp_path / "f.csv"),
                 "--scheduler", f"tcp://127.0.0.1:{port}", *CLI_FAST]) == 2
    plain_error(capsys, "cannot reach the dask scheduler", f"127.0.0.1:{port}")


# --------------------------------------------------------------------------------------------
# 9. more of the battery: a cluster lost for real, a full disk mid-run, a bug stays a bug
# --------------------------------------------------------------------------------------------

def test_a_scheduler_lost_during_the_run_is_a_plain_message(tmp_path, monkeypatch):
    import threading
    import time

    distributed = pytest.importorskip("distributed")
    from napari_pfsdm.analysis import parallel
    from napari_pfsdm.batch import measure_dask

    started, gone = threading.Event(), threading.Event()

    def slow(*args, **kwargs):
        started.set()
        gone.wait(20)  # the scheduler goes away meanwhile
        time.sleep(3)

    def close() -> None:
        started.wait(20)
        gone.set()
        cluster.close()

    monkeypatch.setattr(parallel, "measure_entries", slow)  # the objects of a task
    cluster = distributed.LocalCluster(n_workers=1, processes=False, threads_per_worker=1,
                                       dashboard_address=None, protocol="tcp")
    address = cluster.scheduler_address
    threading.Thread(target=close, daemon=True).start()
    with pytest.raises(ValueError, match="run the same command again") as info:
        measure_dask(np.stack([ellipse_labels()] * 2), scheduler=address, frames_per_task=1)
    assert isinstance(info.value, pf.errors.RunFault) and address in str(info.value)


def test_a_full_disk_while_writing_a_part_keeps_the_finished_ones(tmp_path, monkeypatch,
                                                                   capsys):
    import errno

    from napari_pfsdm.batch import run as run_module

    for name in ("a", "b"):
        write_tiff_movie(tmp_path / f"{name}.tif")
    out = tmp_path / "f.csv"
    real = run_module._write_part
    written: list = []

    def fills_up(table, path, options):
        if written:
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        written.append(path)
        real(table, path, options)

    monkeypatch.setattr(run_module, "_write_part", fills_up)
    args = ["measure", str(tmp_path / "a.tif"), str(tmp_path / "b.tif"), "-o", str(out),
            "--scheduler", "sync", *CLI_FAST]
    assert main(args) == 2
    plain_error(capsys, "No space left on device")
    kept = sorted(p.name for p in (tmp_path / "f.csv.parts").iterdir())
    assert [n[:2] for n in kept] == ["a-", "a-"] and not out.exists()
    assert [p for p in tmp_path.rglob("*.tmp")] == []
    monkeypatch.setattr(run_module, "_write_part", real)
    assert main(args) == 0 and len(pf.read_table(out)) == 4


def test_a_bug_is_still_reported_as_a_bug(tmp_path, monkeypatch, capsys):
    from napari_pfsdm.analysis import parallel

    def buggy(*args, **kwargs):
        return 1 // 0

    monkeypatch.setattr(parallel, "measure_entries", buggy)
    write_tiff_movie(tmp_path / "m.tif")
    assert main(["measure", str(tmp_path / "m.tif"), "-o", str(tmp_path / "f.csv"),
                 "--scheduler", "sync", *CLI_FAST]) == 1
    assert "internal error" in capsys.readouterr().err


def test_a_worker_killed_during_a_pool_run_stops_it_in_plain_words():
    import multiprocessing
    import os
    import signal

    from napari_pfsdm.analysis import parallel
    from napari_pfsdm.core.params import PFSDMParams

    frames = np.stack([three_objects_per_frame(1)[0]] * 120)  # 360 objects
    parallel.shutdown_pool()
    before = set(multiprocessing.active_children())
    parallel.warm_pool(2).join(timeout=120)
    victims = [proc.pid for proc in set(multiprocessing.active_children()) - before]
    assert len(victims) == 2  # the pool's workers
    run = parallel.iter_blocks(frames, params=PFSDMParams(mapping="bijective", **FAST),
                               axes="tyx", workers=2)
    try:
        with pytest.raises(ValueError, match="worker process stopped") as info:
            for step, _ in enumerate(run):
                if step == 0:
                    for pid in victims:  # the system's out-of-memory killer, say
                        os.kill(pid, signal.SIGKILL)
                # one value per object, and one about every 0.2 s while a task is awaited:
                # far more than the 360 objects means the run keeps waiting for a dead worker
                assert step < 2000, "the run waits for a dead worker"
        assert isinstance(info.value, pf.errors.RunFault)
    finally:
        parallel.shutdown_pool()


def test_a_table_edited_in_place_is_read_with_a_warning(tmp_path):
    import os

    from napari_pfsdm.io import read_table, write_table

    path = tmp_path / "t.csv"
    write_table(pd_frame(), path, {"v": 1})
    text = path.read_text().replace("10.5", "10.75")  # a cell corrected by hand
    path.write_text(text)
    side = path.with_name("t.csv.json").stat()
    os.utime(path, ns=(side.st_atime_ns, side.st_mtime_ns + 10**9))  # saved after the .json
    with pytest.warns(UserWarning, match="changed after pfsdm wrote it"):
        back = read_table(path)
    assert back["area"].tolist() == [10.75, 11.0, 9.25] and back.attrs["pfsdm"] == {"v": 1}


def test_without_flock_the_lock_is_an_exclusive_file(tmp_path, monkeypatch):
    import sys

    from napari_pfsdm.io import output_lock

    monkeypatch.setitem(sys.modules, "fcntl", None)  # as on Windows
    out = tmp_path / "t.csv"
    with output_lock(out) as lock:
        assert lock.is_file()
        with pytest.raises(ValueError, match="another pfsdm run .* delete"), output_lock(out):
            pass
    assert not lock.exists()
