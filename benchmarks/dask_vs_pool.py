"""measure_dask on a dask.distributed cluster against the local process pool, N workers each.

Issue 44, point 4: dask should cost no more per object than the pool. Writes one synthetic
movie (nucleus-sized objects, a float reporter) as TIFF and as Zarr in a temporary folder, then
measures it, in the same run, with

- the process pool of :func:`napari_pfsdm.analysis.parallel.iter_blocks` (what napari's Run
  uses), ``--workers`` processes, on the movie in memory (numpy: the pool's best case, the
  reference), and with ``--pool-from-file`` also on the movie opened by
  :func:`napari_pfsdm.batch.open_movie` from the TIFF;
- :func:`napari_pfsdm.batch.measure_dask` on a ``distributed.LocalCluster`` of ``--workers``
  single-threaded worker processes (the code path of a real cluster), from the TIFF and from
  the Zarr, and the same on a second LocalCluster whose workers' sampling profiler is off
  (``distributed.worker.profile.enabled: false``; distributed samples every worker's stack
  every 10 ms by default);
- :func:`napari_pfsdm.batch.measure_dask` on the local ``'processes'`` scheduler with a
  process pool kept between runs (what ``pfsdm measure`` uses by default), from the Zarr.

The workload is sized so that fixed costs (a task's start, the first pass that lists each
frame's labels, gathering the results) are small against the measuring: 32 frames of 150
objects, 4,800 objects, about 3.5 s per configuration on 2 workers. The pool and the cluster are
started and warmed first (start-up is not timed); the configurations then run in turn,
``--repeats`` rounds, the order rotated by one each round (so that none always runs first or
after the same neighbour). For each configuration the table gives the median wall time and
the median CPU time of the whole process tree, and the medians over the rounds of its ratios
to the pool's wall and CPU time in the same round. Every table is checked equal to the pool's,
exactly.

Run (about three minutes on 2 cores; the timings mean something only on otherwise idle cores:
the load average before and after is printed)::

    PYTHONPATH=src .venv/bin/python benchmarks/dask_vs_pool.py

Options: --frames, --size, --objects (per frame), --workers, --repeats, --pool-from-file.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

import dask
import numpy as np
import pandas as pd


def nuclei_movie(n_frames: int, size: int, per_frame: int, seed: int = 0):
    """A (T, size, size) uint16 movie of ~``per_frame`` ellipses of radii 8–15 px (nuclei) on
    a jittered grid, drifting a little from frame to frame, and a float32 reporter."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(per_frame)))
    step = size / side
    yy, xx = np.mgrid[:size, :size]
    centres = np.array([((i + 0.5) * step, (j + 0.5) * step)
                        for i in range(side) for j in range(side)])[:per_frame]
    radii = rng.uniform(8, 15, (per_frame, 2))
    radii = np.minimum(radii, step / 2 - 2)
    angles = rng.uniform(0, np.pi, per_frame)
    labels = np.zeros((n_frames, size, size), np.uint16)
    for t in range(n_frames):
        jitter = rng.normal(0, 1.5, centres.shape)
        for k, ((cy, cx), (a, b), th) in enumerate(zip(centres + jitter, radii, angles,
                                                       strict=True)):
            y0, y1 = int(max(cy - 16, 0)), int(min(cy + 17, size))
            x0, x1 = int(max(cx - 16, 0)), int(min(cx + 17, size))
            dy, dx = yy[y0:y1, x0:x1] - cy, xx[y0:y1, x0:x1] - cx
            u = dy * np.cos(th) + dx * np.sin(th)
            v = -dy * np.sin(th) + dx * np.cos(th)
            inside = (u / a) ** 2 + (v / b) ** 2 < 1
            labels[t, y0:y1, x0:x1][inside] = k + 1
    intensity = (rng.normal(100, 10, labels.shape) + 50.0 * (labels > 0)).astype(np.float32)
    return labels, intensity


def _warm(_: object = None) -> int:
    """Import the package and measure one small object (first-call costs out of the timing)."""
    import napari_pfsdm

    labels = np.zeros((1, 48, 48), np.uint16)
    labels[0, 10:30, 12:40] = 1
    napari_pfsdm.measure(labels, labels.astype(np.float32))
    return os.getpid()


def tree_cpu() -> float:
    """CPU-seconds (user + system) used so far by this process and all its descendants (the
    pool's workers and fork server; the cluster's nannies and workers; the scheduler runs in
    this process)."""
    import psutil

    me = psutil.Process()
    total = 0.0
    for proc in [me, *me.children(recursive=True)]:
        try:
            t = proc.cpu_times()
        except psutil.Error:  # ended meanwhile
            continue
        total += t.user + t.system
    return total


#: distributed's setting for its workers' sampling profiler.
PROFILER = "distributed.worker.profile.enabled"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=32)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--objects", type=int, default=150, help="objects per frame")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--pool-from-file", action="store_true",
                    help="also time the pool given the TIFF opened by open_movie")
    args = ap.parse_args(argv)

    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    import tifffile
    import zarr
    from distributed import Client, LocalCluster

    from napari_pfsdm.analysis import parallel
    from napari_pfsdm.analysis.row_blocks import join_blocks
    from napari_pfsdm.batch import measure_dask, open_movie
    from napari_pfsdm.core.params import PFSDMParams

    n = args.workers
    params = PFSDMParams()
    labels, intensity = nuclei_movie(args.frames, args.size, args.objects)
    tmp = Path(tempfile.mkdtemp(prefix="pfsdm-dask-vs-pool-"))
    try:
        for name, data in (("labels", labels), ("intensity", intensity)):
            tifffile.imwrite(tmp / f"{name}.tif", data, photometric="minisblack")
            z = zarr.create_array(str(tmp / f"{name}.zarr"), shape=data.shape,
                                  dtype=data.dtype, chunks=(1, *data.shape[1:]))
            z[:] = data
        tif = (open_movie(tmp / "labels.tif"), open_movie(tmp / "intensity.tif"))
        zar = (open_movie(tmp / "labels.zarr"), open_movie(tmp / "intensity.zarr"))

        def pool_run(movie):
            gen = parallel.iter_blocks(*movie, params=params, axes="tyx", workers=n)
            try:
                while True:
                    next(gen)
            except StopIteration as stop:
                return join_blocks(stop.value).table

        print(f"movie: {labels.shape} uint16 labels + float32 reporter, "
              f"{args.objects} objects per frame (radii 8-15 px); {n} workers; default "
              f"options; {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}")
        t0 = time.perf_counter()
        parallel.warm_pool(n).join(timeout=120)
        pool_start = time.perf_counter() - t0
        t0 = time.perf_counter()
        cluster = LocalCluster(n_workers=n, processes=True, threads_per_worker=1,
                               dashboard_address=None)
        client = Client(cluster)
        client.run(_warm)
        cluster_start = time.perf_counter() - t0
        # the same, its workers' sampling profiler (a stack sample every 10 ms) switched off
        with dask.config.set({PROFILER: False}):
            quiet_cluster = LocalCluster(n_workers=n, processes=True, threads_per_worker=1,
                                         dashboard_address=None)
        quiet = Client(quiet_cluster)
        quiet.run(_warm)
        if any(quiet.run(dask.config.get, PROFILER).values()):
            raise RuntimeError("the workers' profiler is still on")
        # what run_batch keeps for the 'processes' scheduler
        spawned = ProcessPoolExecutor(n, mp_context=multiprocessing.get_context("spawn"))
        list(spawned.map(_warm, range(n)))
        try:
            configs = {
                "process pool (iter_blocks), numpy": lambda: pool_run((labels, intensity)),
                **({"process pool (iter_blocks), TIFF": lambda: pool_run(tif)}
                   if args.pool_from_file else {}),
                "measure_dask, LocalCluster, TIFF":
                    lambda: measure_dask(*tif, client=client, params=params),
                "measure_dask, LocalCluster, Zarr":
                    lambda: measure_dask(*zar, client=client, params=params),
                "measure_dask, LocalCluster without profiler, TIFF":
                    lambda: measure_dask(*tif, client=quiet, params=params),
                "measure_dask, LocalCluster without profiler, Zarr":
                    lambda: measure_dask(*zar, client=quiet, params=params),
                "measure_dask, local 'processes', Zarr":
                    lambda: measure_dask(*zar, scheduler="processes", num_workers=n,
                                         pool=spawned, params=params),
            }
            ref = pool_run((labels, intensity))  # also warms the pool's processes
            for movie in (tif, zar):  # and the clusters' and the spawned ones, on each file
                for c in (client, quiet):
                    measure_dask(*movie, client=c, params=params)
            measure_dask(*zar, scheduler="processes", num_workers=n, pool=spawned,
                         params=params)
            times: dict[str, list[float]] = {k: [] for k in configs}
            cpu: dict[str, list[float]] = {k: [] for k in configs}
            same = {}
            names = list(configs)
            for rnd in range(args.repeats):
                for name in names[rnd % len(names):] + names[:rnd % len(names)]:
                    fn = configs[name]
                    c0 = tree_cpu()
                    t0 = time.perf_counter()
                    table = fn()
                    times[name].append(time.perf_counter() - t0)
                    cpu[name].append(tree_cpu() - c0)
                    try:
                        pd.testing.assert_frame_equal(table, ref, check_exact=True)
                        same[name] = same.get(name, True)
                    except AssertionError:
                        same[name] = False
            load = os.getloadavg()[0]
        finally:
            for c in (client, cluster, quiet, quiet_cluster):
                c.close()
            spawned.shutdown()
            parallel.shutdown_pool()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    pool_t = np.array(times["process pool (iter_blocks), numpy"])
    pool_c = np.array(cpu["process pool (iter_blocks), numpy"])
    rows = [{"run": name, "median_s": float(np.median(t)),
             "runs_s": " ".join(f"{v:.2f}" for v in t),
             # the ratio to the pool in the same round, median over the rounds
             "vs_pool": float(np.median(np.array(t) / pool_t)),
             "cpu_s": float(np.median(cpu[name])),
             "cpu_vs_pool": float(np.median(np.array(cpu[name]) / pool_c)),
             "objects_per_s": len(ref) / float(np.median(t)),
             "table_equal_to_pool": same[name]} for name, t in times.items()]
    df = pd.DataFrame(rows)
    with pd.option_context("display.width", 160, "display.precision", 2):
        print(df.to_string(index=False))
    print(f"{len(ref)} objects; start-up (not timed above): pool {pool_start:.1f} s, "
          f"LocalCluster {cluster_start:.1f} s; load average after the runs {load:.2f}")
    for which, rows_of in (("", lambda r: "LocalCluster," in r),
                           (" without its profiler", lambda r: "without profiler" in r)):
        sub = df[df.run.map(rows_of)]
        print(f"dask on a LocalCluster{which} of {n} workers / the pool of {n} processes "
              f"(numpy): {sub.vs_pool.max():.2f}x wall time, {sub.cpu_vs_pool.max():.2f}x CPU "
              "time, at worst (target <= 1.20x)")
    print("cpu_s: CPU-seconds of this process and all its descendants during the run (median);"
          " vs_pool, cpu_vs_pool: median over the rounds of the ratio to the pool's in the "
          "same round")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
