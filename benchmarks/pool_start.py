"""The plugin's process pool (loky's executor) against a multiprocessing forkserver pool.

The pool of :mod:`napari_pfsdm.analysis.parallel` is loky's executor: fresh interpreters as
workers, which never import the caller's ``__main__`` and break the pool at once when one
dies. The anchor is what a multiprocessing ``forkserver`` pool does with the same tasks: a
server process imports the modules once and forks each worker from it (faster to start, but
its workers re-import ``__main__``, and a dead worker's task waits for ever).

In the same run, alternating, ``--repeats`` rounds of each:

- **start**: from nothing to every worker having measured one small object (what
  ``warm_pool`` does when the plugin is docked);
- **cold**: start, then a movie measured in the pool's tasks (a Run with no pool running);
- **warm**: the same movie on a pool already running (a Run after the dock warmed it).

Both pools get the same modules preloaded and the same tasks (``task_entries`` of the pool's
own plan, ``block_of_entries`` in the workers); the tables are checked equal. Run (about a
minute on 2 cores)::

    .venv/bin/python benchmarks/pool_start.py --workers 2 --repeats 3
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import multiprocessing.pool
import os
import statistics
import time

import pandas as pd

from napari_pfsdm.analysis import parallel
from napari_pfsdm.analysis.measuring import ObjectMeasurer
from napari_pfsdm.analysis.row_blocks import join_blocks
from napari_pfsdm.core.params import PFSDMParams
from napari_pfsdm.data.gastruloids import make_timelapse_montage


def _tasks(labels, intensity, workers):
    """The pool's own plan of the movie: the arguments of each task."""
    measurer = ObjectMeasurer.of(PFSDMParams(), with_intensity=True, axes="tyx")
    counts = parallel._labels_per_frame(labels, len(labels), True)
    total = sum(len(c) for c in counts)
    tasks = parallel.plan_tasks(counts, parallel.task_count(total, workers))
    boxes: dict = {}
    return [(measurer, parallel.task_entries(measurer, labels, intensity, True, task, counts,
                                             boxes))
            for task in tasks]


def _forkserver(workers: int):
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(list(parallel._PRELOAD))
    return ctx.Pool(workers)


def _loky(workers: int):
    return parallel._start(workers)


def _warm(pool, workers: int) -> None:
    if isinstance(pool, mp.pool.Pool):
        pool.map(parallel._warm_task, range(workers), chunksize=1)
    else:
        list(pool.map(parallel._warm_task, range(workers)))


def _measure(pool, args) -> pd.DataFrame:
    if isinstance(pool, mp.pool.Pool):
        blocks = pool.map(parallel.block_of_entries, args, chunksize=1)
    else:
        blocks = list(pool.map(parallel.block_of_entries, args))
    return join_blocks(blocks).table


def _stop(pool) -> None:
    if isinstance(pool, mp.pool.Pool):
        pool.terminate()
        pool.join()
    else:
        pool.shutdown(wait=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    labels, intensity = make_timelapse_montage(20, 30, 160, seed=4)[:2]  # 600 objects
    tasks = _tasks(labels, intensity, args.workers)
    print(f"load average before: {os.getloadavg()[0]:.2f}; {labels.shape[0]} frames, "
          f"{sum(len(t[0]) for t in tasks)} task entries in {len(tasks)} tasks, "
          f"{args.workers} workers")
    times: dict[tuple[str, str], list[float]] = {}
    reference = None
    for _ in range(args.repeats):
        for name, start in (("loky (the plugin's)", _loky), ("forkserver (anchor)", _forkserver)):
            t0 = time.perf_counter()
            pool = start(args.workers)
            _warm(pool, args.workers)
            t_start = time.perf_counter() - t0
            t0 = time.perf_counter()
            table = _measure(pool, tasks)
            t_warm = time.perf_counter() - t0
            _stop(pool)
            t0 = time.perf_counter()
            pool = start(args.workers)
            _measure(pool, tasks)
            t_cold = time.perf_counter() - t0
            _stop(pool)
            if reference is None:
                reference = table
            pd.testing.assert_frame_equal(table, reference)
            for what, t in (("start", t_start), ("cold", t_cold), ("warm", t_warm)):
                times.setdefault((name, what), []).append(t)
    print("\n| pool | start (s) | cold Run (s) | warm Run (s) |\n|---|---:|---:|---:|")
    for name in ("loky (the plugin's)", "forkserver (anchor)"):
        cells = [f"{statistics.median(times[(name, w)]):.2f}" for w in ("start", "cold", "warm")]
        print(f"| {name} | " + " | ".join(cells) + " |")
    ratios = [statistics.median(times[("loky (the plugin's)", w)])
              / statistics.median(times[("forkserver (anchor)", w)])
              for w in ("start", "cold", "warm")]
    print(f"| ratio loky / forkserver | {ratios[0]:.2f} | {ratios[1]:.2f} | {ratios[2]:.2f} |")
    print(f"\nload average after: {os.getloadavg()[0]:.2f}; medians of {args.repeats} rounds")


if __name__ == "__main__":
    main()
