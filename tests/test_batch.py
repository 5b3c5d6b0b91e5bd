"""Batch path: lazy TIFF/Zarr/OME-Zarr reading, dask measurement, resumable runs, CSV I/O."""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tifffile

import napari_pfsdm
import napari_pfsdm.errors
from napari_pfsdm.analysis.measuring import ObjectMeasurer
from napari_pfsdm.batch import Movie, find_movies, measure_dask, open_movie, pair_movies, run_batch
from napari_pfsdm.batch import run as run_module
from napari_pfsdm.batch import tasks as tasks_module
from napari_pfsdm.batch.io import check_labels
from napari_pfsdm.io import read_table, write_table
from unguarded_script import run_once

zarr = pytest.importorskip("zarr")  # the [batch] extra


def make_movie(n_frames: int = 4, shape=(64, 80)) -> tuple[np.ndarray, np.ndarray]:
    """Two objects changing over time, plus a third appearing at frame 2."""
    yy, xx = np.mgrid[: shape[0], : shape[1]]
    labels = np.zeros((n_frames, *shape), np.uint16)
    for t in range(n_frames):
        labels[t][((yy - 20) / (10 + t)) ** 2 + ((xx - 20) / 8) ** 2 < 1] = 1
        labels[t][(abs(yy - 45) < 6 + t) & (abs(xx - 55) < 15 - t)] = 3
        if t >= 2:
            labels[t][((yy - 52) ** 2 + (xx - 15) ** 2) < 49] = 7
    intensity = (yy[None] * 0.5 + xx[None] + 10.0 * np.arange(n_frames)[:, None, None])
    return labels, intensity.astype(np.float32)


@pytest.fixture
def measured(monkeypatch):
    """The objects the batch measures, as they reach the one per-object step every path
    calls (``ObjectMeasurer.measure``; the ``sync`` scheduler runs it in this process)."""
    seen: list[tuple[int, int]] = []
    real = ObjectMeasurer.measure

    def counting(self, crop):
        seen.append((crop.frame, crop.label))
        return real(self, crop)

    monkeypatch.setattr(ObjectMeasurer, "measure", counting)
    return seen


def write_zarr(path: Path, data: np.ndarray, zarr_format: int = 3, chunks=None) -> Path:
    z = zarr.create_array(str(path), shape=data.shape, dtype=data.dtype,
                          chunks=chunks or (1, *data.shape[1:]), zarr_format=zarr_format)
    z[:] = data
    return path


def write_ome_zarr(path: Path, data: np.ndarray) -> Path:
    """A two-level multiscale OME-Zarr (v0.4 layout, axes t c z y x)."""
    g = zarr.open_group(str(path), mode="w", zarr_format=2)
    full = data[:, None, None]
    a0 = g.create_array("0", shape=full.shape, dtype=data.dtype, chunks=(1, 1, 1, *data.shape[1:]))
    a0[:] = full
    half = full[..., ::2, ::2]
    a1 = g.create_array("1", shape=half.shape, dtype=data.dtype, chunks=(1, 1, 1, *half.shape[3:]))
    a1[:] = half
    axes = [{"name": "t", "type": "time"}, {"name": "c", "type": "channel"},
            {"name": "z", "type": "space"}, {"name": "y", "type": "space"},
            {"name": "x", "type": "space"}]
    g.attrs["multiscales"] = [{"version": "0.4", "axes": axes,
                               "datasets": [{"path": "0"}, {"path": "1"}]}]
    return path


# ------------------------------------------------------------------------------------------
# CSV with options header
# ------------------------------------------------------------------------------------------

def test_table_csv_round_trip_is_exact(tmp_path):
    rng = np.random.default_rng(1)
    df = pd.DataFrame({
        "movie": ["a", "a", "b"], "frame": [0, 1, 0], "label": [1, 1, 4],
        "area": rng.random(3) * 1e3, "shape_r00_n00": [rng.random(), np.nan, -1e-17],
        "error": ["", "object too small (12 px)", ""],
    })
    options = {"n_fourier": 10, "mapping": "harmonic", "radii": np.linspace(0.1, 0.9, 5),
               "weights": np.full(5, 0.2), "viscosity": np.float64(0.05)}
    path = write_table(df, tmp_path / "t.csv", options)
    assert path.read_text().startswith("movie,frame,label,")  # plain CSV, no comment line
    side = json.loads((tmp_path / "t.csv.json").read_text())
    assert side["options"]["n_fourier"] == 10 and side["written_by"].startswith("napari-pfsdm")
    back = read_table(path)
    pd.testing.assert_frame_equal(back, df, check_exact=True)
    assert back.attrs["pfsdm"]["radii"] == pytest.approx(np.linspace(0.1, 0.9, 5).tolist(),
                                                         rel=0, abs=0)
    assert back.attrs["pfsdm"]["mapping"] == "harmonic"
    # options default to df.attrs["pfsdm"]
    df.attrs["pfsdm"] = {"n_radii": 8}
    write_table(df, tmp_path / "u.csv")
    assert read_table(tmp_path / "u.csv").attrs["pfsdm"] == {"n_radii": 8}


def test_table_csv_is_atomic(tmp_path, monkeypatch):
    target = tmp_path / "features.csv"
    target.write_text("old content\n")
    df = pd.DataFrame({"frame": [0], "label": [1]})

    def broken(self, handle, **kwargs):
        handle.write("frame,label\n0,")
        raise RuntimeError("disk full")

    monkeypatch.setattr(pd.DataFrame, "to_csv", broken)
    with pytest.raises(RuntimeError):
        write_table(df, target, {"a": 1})
    assert target.read_text() == "old content\n"
    assert sorted(os.listdir(tmp_path)) == ["features.csv"]  # no temp file left
    monkeypatch.undo()
    with pytest.raises(ValueError, match="does not exist"):
        write_table(df, tmp_path / "missing" / "t.csv")


# ------------------------------------------------------------------------------------------
# reading movies
# ------------------------------------------------------------------------------------------

def test_open_movie_tiff_zarr_ome_zarr(tmp_path):
    labels, _ = make_movie()
    tifffile.imwrite(tmp_path / "m.tif", labels, photometric="minisblack")
    write_zarr(tmp_path / "v3.zarr", labels, zarr_format=3, chunks=(2, 64, 80))
    write_zarr(tmp_path / "v2.zarr", labels, zarr_format=2)
    write_ome_zarr(tmp_path / "ome.zarr", labels)
    for name, t_chunk in [("m.tif", 1), ("v3.zarr", 2), ("v2.zarr", 1), ("ome.zarr", 1)]:
        arr = open_movie(tmp_path / name)
        assert arr.shape == labels.shape, name
        assert arr.chunks[0][0] == t_chunk, name
        assert arr.dtype == labels.dtype
        np.testing.assert_array_equal(arr[1:3].compute(), labels[1:3])
    assert open_movie(tmp_path / "v2.zarr", frames_per_chunk=3).chunks[0] == (3, 1)
    # OME-Zarr 0.5 (Zarr v3, metadata under "ome")
    g = zarr.open_group(str(tmp_path / "v05.zarr"), mode="w", zarr_format=3)
    a = g.create_array("s0", shape=(4, 1, 64, 80), chunks=(1, 1, 64, 80), dtype="uint16")
    a[:] = labels[:, None]
    axes = [{"name": n} for n in "tcyx"]
    g.attrs["ome"] = {"version": "0.5",
                      "multiscales": [{"axes": axes, "datasets": [{"path": "s0"}]}]}
    np.testing.assert_array_equal(open_movie(tmp_path / "v05.zarr").compute(), labels)
    # a channel axis with several channels is refused with a plain message
    tifffile.imwrite(tmp_path / "chan.tif", np.zeros((3, 2, 16, 16), np.uint8), imagej=True,
                     metadata={"axes": "TCYX"})
    with pytest.raises(ValueError, match=r"2 channels.*one channel per file"):
        open_movie(tmp_path / "chan.tif")
    # 3 or 4 frames saved with tifffile's defaults are stored as planar RGB(A): still frames
    with warnings.catch_warnings():  # tifffile warns that this default will change
        warnings.simplefilter("ignore", DeprecationWarning)
        tifffile.imwrite(tmp_path / "rgb.tif", labels)
    np.testing.assert_array_equal(open_movie(tmp_path / "rgb.tif").compute(), labels)
    # a single 2-D image stays 2-D
    tifffile.imwrite(tmp_path / "one.tif", labels[0])
    assert open_movie(tmp_path / "one.tif").shape == labels.shape[1:]


def test_find_and_pair_movies(tmp_path):
    labels, intensity = make_movie(2)
    for name in ("e01", "e02"):
        tifffile.imwrite(tmp_path / f"{name}_labels.tif", labels)
        tifffile.imwrite(tmp_path / f"{name}_reporter.tif", intensity)
    (tmp_path / "notes.txt").write_text("not a movie")
    found = find_movies(tmp_path)
    assert [p.name for p in found] == ["e01_labels.tif", "e01_reporter.tif",
                                       "e02_labels.tif", "e02_reporter.tif"]
    lab = find_movies(str(tmp_path / "*_labels.tif"))
    img = find_movies(str(tmp_path / "*_reporter.tif"))
    movies = pair_movies(lab, img)
    assert [(m.name, m.intensity.name) for m in movies] == [
        ("e01_labels", "e01_reporter.tif"), ("e02_labels", "e02_reporter.tif")]
    with pytest.raises(ValueError, match="no intensity for e02_labels.tif"):
        pair_movies(lab, img[:1])
    with pytest.raises(ValueError, match="no such file"):
        find_movies(tmp_path / "absent.tif")
    with pytest.raises(ValueError, match="no TIFF or Zarr movie matches"):
        find_movies(str(tmp_path / "*.zarr"))


def test_check_labels_refuses_bad_inputs():
    labels, intensity = make_movie(2)
    check_labels(labels, intensity)
    with pytest.raises(ValueError, match="not a label image"):
        check_labels(intensity)
    with pytest.raises(ValueError, match="different shapes"):
        check_labels(labels, intensity[:, :32])


# ------------------------------------------------------------------------------------------
# dask measurement
# ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("scheduler", ["threads", "sync"])
@pytest.mark.parametrize("frames_per_task", [None, 1, 2, 3])
def test_measure_dask_offsets_frames(scheduler, frames_per_task):
    labels, intensity = make_movie(5)
    ref = napari_pfsdm.measure(labels, intensity, n_fourier=4, n_radii=4)
    seen = []
    got = measure_dask(labels, intensity, scheduler=scheduler, frames_per_task=frames_per_task,
                       progress=lambda d, n: seen.append((d, n)), n_fourier=4, n_radii=4)
    pd.testing.assert_frame_equal(got, ref, check_exact=True)
    assert got.attrs["pfsdm"]["n_radii"] == 4
    assert seen[-1] == (5, 5) and [d for d, _ in seen] == sorted(d for d, _ in seen)
    if frames_per_task:  # one call per task of whole frames
        assert len(seen) == -(-5 // frames_per_task)


def test_measure_dask_matches_core_measure(tmp_path):
    labels, intensity = make_movie(4)
    ref = napari_pfsdm.measure(labels, intensity, n_fourier=6, n_radii=8)
    lab = open_movie(write_zarr(tmp_path / "l.zarr", labels, chunks=(3, 64, 80)))
    img = open_movie(write_zarr(tmp_path / "i.zarr", intensity))
    got = measure_dask(lab, img, scheduler="threads", n_fourier=6, n_radii=8)
    assert got["frame"].tolist() == ref["frame"].tolist()
    assert set(got["label"]) == {1, 3, 7}
    pd.testing.assert_frame_equal(got, ref, check_exact=False, rtol=1e-12, atol=1e-12)
    assert got.attrs["pfsdm"]["n_radii"] == 8


def test_local_cluster_gives_the_in_process_table(tmp_path):
    distributed = pytest.importorskip("distributed")
    labels, intensity = make_movie(4)
    path = write_zarr(tmp_path / "movie.zarr", labels)
    ref = napari_pfsdm.measure(labels, n_fourier=6, n_radii=8)
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        done = []
        got = measure_dask(open_movie(path), client=client, n_fourier=6, n_radii=8,
                           progress=lambda d, n: done.append(d))
        # the work really ran in the two worker processes
        pids = client.run(os.getpid)
        assert len(pids) == 2 and os.getpid() not in pids.values()
        # same table through a scheduler address (a client opened for the call)
        again = measure_dask(open_movie(path), scheduler=cluster.scheduler_address,
                             n_fourier=6, n_radii=8)
    assert sorted(done) == done and done[-1] == 4
    pd.testing.assert_frame_equal(got, ref, check_exact=False, rtol=1e-12, atol=1e-12)
    pd.testing.assert_frame_equal(again, ref, check_exact=False, rtol=1e-12, atol=1e-12)


def _drain(gen):
    try:
        while True:
            next(gen)
    except StopIteration as stop:
        return stop.value


def test_dask_table_equals_the_process_pools_table(tmp_path, monkeypatch):
    """measure_dask plans its tasks with the pool's planner (fewer tasks per worker: a dask
    task costs more), reads the frames in the workers, and gives the pool's table exactly: on
    a LocalCluster of two worker processes, with the local 'processes' scheduler, from files
    and from arrays in memory."""
    distributed = pytest.importorskip("distributed")
    from napari_pfsdm.analysis import parallel
    from napari_pfsdm.analysis.row_blocks import join_blocks
    from napari_pfsdm.batch import io as io_module
    from napari_pfsdm.core.params import PFSDMParams
    from napari_pfsdm.data.gastruloids import make_timelapse_montage

    labels, intensity = make_timelapse_montage(8, 6, 160, seed=4)[:2]  # 48 objects
    params = PFSDMParams()
    monkeypatch.setattr(parallel, "MIN_OBJECTS", 1)  # a small movie, still in processes
    monkeypatch.setattr(parallel, "MIN_TASK_OBJECTS", 1)  # tasks of one object allowed
    plans = []
    real_plan = parallel.plan_tasks
    monkeypatch.setattr(parallel, "plan_tasks",
                        lambda counts, n: plans.append(real_plan(counts, n)) or plans[-1])
    try:
        pool = join_blocks(_drain(parallel.iter_blocks(
            labels, intensity, params=params, axes="tyx", workers=2))).table
        assert parallel._POOL["pool"] is not None  # it did use the pool
    finally:
        parallel.shutdown_pool()
    lab = open_movie(write_zarr(tmp_path / "l.zarr", labels))
    img = open_movie(write_zarr(tmp_path / "i.zarr", intensity))
    read_here = []
    real_read = io_module._Frames.__getitem__
    monkeypatch.setattr(io_module._Frames, "__getitem__",
                        lambda self, key: read_here.append(key) or real_read(self, key))
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        got = {"cluster, files": measure_dask(lab, img, client=client, params=params)}
        assert read_here == []  # the workers read the frames, not this process
        got["cluster, arrays"] = measure_dask(labels, intensity, client=client, params=params)
    got["processes, files"] = measure_dask(lab, img, scheduler="processes", num_workers=2,
                                           params=params)
    got["processes, arrays"] = measure_dask(labels, intensity, scheduler="processes",
                                            num_workers=2, params=params)
    assert len(pool) == 48
    for name, table in got.items():
        pd.testing.assert_frame_equal(table, pool, check_exact=True, obj=name)
    # one planner: the pool made 48 tasks of one object (2 workers, up to 32 tasks each);
    # each dask run the planner's 16 tasks of 3 objects (8 per worker), the same for all
    assert len(plans) == 5
    assert [len(task[0][1]) for task in plans[0]] == [1] * 48
    counts = [np.unique(frame)[1:] for frame in labels]
    expected = [[(t, ids.tolist()) for t, ids in task] for task in real_plan(counts, 16)]
    assert sum(len(ids) for task in expected for _, ids in task) == 48
    for plan in plans[1:]:
        assert [[(t, ids.tolist()) for t, ids in task] for task in plan] == expected


def test_a_script_without_a_main_guard_measures_once_in_processes(tmp_path):
    """Worker processes started by spawning import the main script first: a biologist's
    script with no ``if __name__ == "__main__":`` measures once with the 'processes'
    scheduler, not again in every worker (which stopped them: a failed run)."""
    out = run_once(tmp_path, [
        "from napari_pfsdm.batch import measure_dask",
        "from napari_pfsdm.data.gastruloids import make_timelapse_montage",
        "lab, img, _ = make_timelapse_montage(3, 2, 128, seed=1)",
        "table = measure_dask(lab, img, scheduler='processes', num_workers=2)",
        "print('rows', len(table))"])
    assert "rows 6" in out


# ------------------------------------------------------------------------------------------
# resumable batches
# ------------------------------------------------------------------------------------------

def test_a_batch_starts_its_worker_processes_once_and_only_to_measure(tmp_path, monkeypatch):
    """On the 'processes' scheduler the workers start once for all the movies to measure
    (the table equals measure's), and not at all when every movie is finished already."""
    labels, _ = make_movie(3)
    write_zarr(tmp_path / "a.zarr", labels)
    write_zarr(tmp_path / "b.zarr", labels[:, ::-1])
    movies = pair_movies(find_movies(tmp_path))
    out = tmp_path / "features.csv"
    started = []
    real = run_module.process_pool
    monkeypatch.setattr(run_module, "process_pool",
                        lambda n: started.append(n) or real(n))
    table = run_batch(movies, out, scheduler="processes", num_workers=1, n_fourier=5)
    assert started == [1]
    expected = napari_pfsdm.measure(labels, n_fourier=5)
    np.testing.assert_allclose(table.loc[table["movie"] == "a", "area"], expected["area"])
    log = []
    again = run_batch(movies, out, scheduler="processes", num_workers=1, log=log.append,
                      n_fourier=5)
    assert started == [1] and sum(line.startswith("skipped") for line in log) == 2
    pd.testing.assert_frame_equal(again, table)


def test_run_batch_resumes_after_a_failure(tmp_path, monkeypatch):
    labels, intensity = make_movie(3)
    write_zarr(tmp_path / "a.zarr", labels)
    write_zarr(tmp_path / "b.zarr", labels[:, ::-1])
    movies = pair_movies(find_movies(tmp_path))
    out = tmp_path / "out" / "features.csv"
    out.parent.mkdir()
    calls = []
    real = tasks_module._measure_task

    def dies_on_b(*args, **kw):
        calls.append(1)
        if len(calls) > 1:  # a: measured in one task, then b's first task: "killed"
            raise KeyboardInterrupt
        return real(*args, **kw)

    monkeypatch.setattr(tasks_module, "_measure_task", dies_on_b)
    with pytest.raises(KeyboardInterrupt):
        run_batch(movies, out, scheduler="sync", n_fourier=5)
    assert not out.exists()  # no final CSV from a killed run
    parts = sorted(p.name for p in out.with_name("features.csv.parts").iterdir())
    assert len(parts) == 2 and parts[0].startswith("a-") and parts[1].startswith("a-")

    calls.clear()
    monkeypatch.setattr(tasks_module, "_measure_task", real)
    log = []
    table = run_batch(movies, out, scheduler="sync", log=log.append, n_fourier=5)
    assert log[0].startswith("skipped a") and log[1].startswith("measured b")
    n = len(napari_pfsdm.measure(labels, n_fourier=5))
    assert n == 7 and table["movie"].tolist() == ["a"] * n + ["b"] * n
    back = read_table(out)
    assert back.attrs["pfsdm"]["n_fourier"] == 5
    pd.testing.assert_frame_equal(back, table, check_exact=False)

    # a third run measures nothing; other options measure again
    log.clear()
    run_batch(movies, out, scheduler="sync", log=log.append, n_fourier=5)
    assert all(m.startswith("skipped") for m in log)
    log.clear()
    run_batch(movies, out, scheduler="sync", log=log.append, n_fourier=6)
    assert all(m.startswith("measured") for m in log)


def test_run_batch_checks_every_movie_before_work(tmp_path, measured):
    labels, intensity = make_movie(2)
    write_zarr(tmp_path / "good.zarr", labels)
    write_zarr(tmp_path / "raw.zarr", intensity)
    movies = [Movie("good", tmp_path / "good.zarr"), Movie("raw", tmp_path / "raw.zarr")]
    with pytest.raises(ValueError, match="not a label image"):
        run_batch(movies, tmp_path / "f.csv", scheduler="sync")
    parts = tmp_path / "f.csv.parts"
    assert not (tmp_path / "f.csv").exists() and not any(parts.iterdir())
    assert measured == []  # not even the good movie's objects


def test_parts_are_parquet_when_pyarrow_is_installed(tmp_path, measured):
    pytest.importorskip("pyarrow")
    labels, _ = make_movie(2)
    write_zarr(tmp_path / "a.zarr", labels)
    movies = pair_movies(find_movies(tmp_path / "a.zarr"))
    first = run_batch(movies, tmp_path / "f.csv", scheduler="sync")
    # the part and its sidecar (options, the part's size and checksum)
    assert [p.name.split(".", 1)[1] for p in sorted((tmp_path / "f.csv.parts").iterdir())] \
        == ["parquet", "parquet.json"]
    log = []
    n = len(measured)
    again = run_batch(movies, tmp_path / "f.csv", scheduler="sync", log=log.append)
    assert log[0].startswith("skipped a") and len(measured) == n == len(first)
    pd.testing.assert_frame_equal(again, first)


# ------------------------------------------------------------------------------------------
# a movie replaced on disk (issue 21): new pixels, never the old ones from a cache
# ------------------------------------------------------------------------------------------

def _replace_atomically(path: Path, data: np.ndarray) -> None:
    """Write ``data`` beside ``path`` and move it over ``path``, as an atomic save does."""
    tmp = path.with_name(".new-" + path.name)
    tifffile.imwrite(tmp, data, photometric="minisblack")
    os.replace(tmp, path)


def test_a_tiff_replaced_on_disk_is_read_anew(tmp_path):
    path = tmp_path / "movie.tif"
    old = np.full((2, 64, 64), 3, np.uint16)
    tifffile.imwrite(path, old)
    assert int(open_movie(path)[1].compute().max()) == 3  # read once: now open in the cache
    new = np.zeros((2, 80, 80), np.uint16)
    new[1, 10:20, 10:30] = 9
    _replace_atomically(path, new)
    again = open_movie(path)
    assert again.shape == (2, 80, 80)
    np.testing.assert_array_equal(again.compute(), new)  # not the old 3s


def test_a_tiff_of_the_same_shape_replaced_on_disk_gives_its_own_pixels(tmp_path):
    # same shape and dtype, so only the file's identity tells the two apart
    path = tmp_path / "movie.tif"
    tifffile.imwrite(path, np.full((3, 32, 32), 1, np.uint8), photometric="minisblack")
    assert int(open_movie(path).sum().compute()) == 3 * 32 * 32
    _replace_atomically(path, np.full((3, 32, 32), 2, np.uint8))
    assert int(open_movie(path).sum().compute()) == 2 * 3 * 32 * 32


def test_a_movie_changed_after_opening_is_refused_in_plain_words(tmp_path):
    path = tmp_path / "movie.tif"
    tifffile.imwrite(path, np.zeros((2, 16, 16), np.uint8))
    arr = open_movie(path)  # shape read: (2, 16, 16)
    _replace_atomically(path, np.zeros((5, 40, 40), np.uint8))
    with pytest.raises(napari_pfsdm.errors.InputError, match="changed on disk"):
        arr.compute()


def test_run_batch_measures_a_replaced_movie_again(tmp_path, measured):
    path = tmp_path / "m.tif"
    small = np.zeros((1, 40, 40), np.uint16)
    small[0, 5:10, 5:10] = 1  # area 25
    tifffile.imwrite(path, small)
    out = tmp_path / "features.csv"
    first = run_batch(pair_movies([path]), out, scheduler="sync")
    assert first["area"].tolist() == [25.0]
    big = np.zeros((1, 40, 40), np.uint16)
    big[0, 5:15, 5:15] = 1  # area 100
    _replace_atomically(path, big)
    log = []
    second = run_batch(pair_movies([path]), out, scheduler="sync", log=log.append)
    assert second["area"].tolist() == [100.0]
    assert log[0].startswith("measured m") and measured == [(0, 1), (0, 1)]
