"""Throughput of the dask batch path: 1 process vs a LocalCluster with 2 workers.

Writes a synthetic gastruloid time-lapse (several objects per frame) to a Zarr store under
/tmp, then measures it

- in one process with the core's ``napari_pfsdm.measure`` (the baseline),
- with ``measure_dask`` on the local ``threads`` and ``processes`` schedulers (2 workers),
- on a ``dask.distributed.LocalCluster`` with 1 worker and with 2 workers (one thread each,
  separate processes) — the same code path as a real cluster,

checks that every table equals the baseline, and prints objects/s, the scaling ratio
(2 workers / 1 worker) and the throughput per worker to plan a cluster run. Cluster start-up
is timed separately (workers are warmed up by importing the package before timing).

Run (about 2 minutes on 2 cores)::

    .venv/bin/python benchmarks/batch_scaling.py --out benchmarks/out

Options: --objects, --frames, --size, --repeats, --sdf/--mapping (heavier per-object work).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd


def _warm(_: object = None) -> int:
    """Import the package and measure one tiny object (first-call costs out of the timing)."""
    import napari_pfsdm

    labels = np.zeros((1, 48, 48), np.uint16)
    labels[0, 10:30, 12:40] = 1
    napari_pfsdm.measure(labels)
    time.sleep(0.5)  # so that every process of a pool gets one warm-up task
    return os.getpid()


def _cpu_seconds() -> float:
    t = os.times()
    return t.user + t.system


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="benchmarks/out", help="folder for the CSV and PNG")
    ap.add_argument("--objects", type=int, default=9, help="objects per frame (default 9)")
    ap.add_argument("--frames", type=int, default=48, help="frames (default 48)")
    ap.add_argument("--size", type=int, default=384, help="frame side in px (default 384)")
    ap.add_argument("--repeats", type=int, default=3,
                    help="best of N round-robin runs (default 3)")
    ap.add_argument("--sdf", default="exact")
    ap.add_argument("--mapping", default="harmonic")
    args = ap.parse_args(argv)

    from distributed import Client, LocalCluster, get_task_stream

    import napari_pfsdm
    from napari_pfsdm.batch import measure_dask, open_movie
    from napari_pfsdm.data.gastruloids import make_timelapse_montage

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    options = {"sdf": args.sdf, "mapping": args.mapping}
    tmp = Path(tempfile.mkdtemp(prefix="pfsdm-scaling-", dir="/tmp"))
    try:
        labels, intensity, _ = make_timelapse_montage(
            n_objects=args.objects, n_frames=args.frames, size=args.size, seed=0)
        import zarr

        for name, data in (("labels", labels), ("intensity", intensity)):
            z = zarr.create_array(str(tmp / f"{name}.zarr"), shape=data.shape,
                                  dtype=data.dtype, chunks=(1, *data.shape[1:]))
            z[:] = data
        lab = open_movie(tmp / "labels.zarr")
        img = open_movie(tmp / "intensity.zarr")
        print(f"movie: {labels.shape} uint16 labels + float32 reporter, "
              f"{args.objects} objects/frame; options {options}; "
              f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")

        ref = napari_pfsdm.measure(labels, intensity, **options)
        n_obj = len(ref)

        def same(table: pd.DataFrame) -> bool:
            return table.shape == ref.shape and np.allclose(
                table.drop(columns="error").to_numpy(float),
                ref.drop(columns="error").to_numpy(float), rtol=1e-10, atol=1e-12,
                equal_nan=True)

        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        with contextlib.ExitStack() as stack:
            # start everything first (start-up timed separately), then time the runs
            # round-robin so that every configuration sees the same background load
            startup = {}
            t0 = time.perf_counter()
            pool = stack.enter_context(
                ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")))
            list(pool.map(_warm, range(2)))
            startup["pool"] = time.perf_counter() - t0
            clients = {}
            for n in (1, 2):
                t0 = time.perf_counter()
                cluster = stack.enter_context(LocalCluster(
                    n_workers=n, processes=True, threads_per_worker=1, dashboard_address=":0"))
                clients[n] = stack.enter_context(Client(cluster))
                clients[n].run(_warm)
                startup[n] = time.perf_counter() - t0

            def worker_cpu(client) -> float:
                return sum(client.run(_cpu_seconds).values())

            configs = {
                "1 process, napari_pfsdm.measure (in memory)": (
                    1, 0.0, lambda: napari_pfsdm.measure(labels, intensity, **options), None),
                "measure_dask, local 'threads' scheduler": (
                    2, 0.0, lambda: measure_dask(lab, img, scheduler="threads", num_workers=2,
                                                 **options), None),
                "measure_dask, local 'processes' scheduler": (
                    2, startup["pool"],
                    lambda: measure_dask(lab, img, scheduler="processes", num_workers=2,
                                         pool=pool, **options), None),
                "LocalCluster, 1 worker process": (
                    1, startup[1], lambda: measure_dask(lab, img, client=clients[1], **options),
                    clients[1]),
                "LocalCluster, 2 worker processes": (
                    2, startup[2], lambda: measure_dask(lab, img, client=clients[2], **options),
                    clients[2]),
            }
            best = {k: np.inf for k in configs}
            overlap = {k: np.nan for k in configs}
            cpu = {k: np.inf for k in configs}
            checks = []
            for _ in range(args.repeats):
                for name, (_, _, fn, client) in configs.items():
                    c0 = worker_cpu(client) if client else time.process_time()
                    stream = (get_task_stream(client) if client is not None
                              else contextlib.nullcontext())
                    with stream as ts:
                        t0 = time.perf_counter()
                        table = fn()
                        wall = time.perf_counter() - t0
                    c1 = worker_cpu(client) if client else time.process_time()
                    checks.append(same(table))
                    if wall < best[name] and ts is not None:
                        # busy time of all workers / wall time: ~n_workers when they overlap
                        busy = sum(s["stop"] - s["start"] for t in ts.data
                                   for s in t["startstops"] if s["action"] == "compute")
                        overlap[name] = busy / wall
                    best[name] = min(best[name], wall)
                    if client is not None or name.startswith("1 process"):
                        cpu[name] = min(cpu[name], c1 - c0)
            rows = [{"run": name, "workers": w, "seconds": best[name], "startup_s": st,
                     "cpu_s": cpu[name] if np.isfinite(cpu[name]) else np.nan,
                     "worker_overlap": overlap[name]}
                    for name, (w, st, _, _) in configs.items()]
            load = os.getloadavg()[0]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    df = pd.DataFrame(rows)
    df["load_average"] = load
    df["objects"] = n_obj
    df["objects_per_cpu_s"] = n_obj / df["cpu_s"]
    df["objects_per_s"] = n_obj / df["seconds"]
    df["objects_per_s_per_worker"] = df["objects_per_s"] / df["workers"]
    one = df.loc[df.run.str.startswith("LocalCluster, 1"), "objects_per_s"].item()
    two = df.loc[df.run.str.startswith("LocalCluster, 2"), "objects_per_s"].item()
    per_cpu = df.loc[df.run.str.startswith("LocalCluster, 2"), "objects_per_cpu_s"].item()
    per_cpu_1 = df.loc[df.run.str.startswith("LocalCluster, 1"), "objects_per_cpu_s"].item()
    # what 2 workers would give on 2 free cores: 2 x (their CPU efficiency vs 1 worker)
    cpu_ratio = 2 * per_cpu / per_cpu_1
    ratio = two / one
    vs_core = two / df.loc[0, "objects_per_s"]
    with pd.option_context("display.width", 140, "display.precision", 2):
        print(df[["run", "workers", "seconds", "startup_s", "cpu_s", "worker_overlap",
                  "objects_per_s",
                  "objects_per_s_per_worker", "objects_per_cpu_s"]].to_string(index=False))
    print(f"\nall tables identical to the in-process one: {all(checks)}")
    print(f"scaling ratio, LocalCluster 2 workers / 1 worker: {ratio:.2f}x "
          f"(ideal 2.00x on 2 free cores; vs the plain in-process core: {vs_core:.2f}x)")
    print(f"CPU-normalised scaling (2 x objects per worker-CPU-second, 2 vs 1 worker): "
          f"{cpu_ratio:.2f}x = the expected wall-clock ratio on 2 otherwise idle cores")
    print(f"worker overlap (busy time of all workers / wall time) with 2 workers: "
          f"{overlap['LocalCluster, 2 worker processes']:.2f} (2.00 = always both busy)")
    print(f"load average during the runs: {load:.2f} on {os.cpu_count()} cores "
          "(other jobs share the machine: wall-clock scaling is bounded by the free cores)")
    print(f"throughput per worker: {two / 2:.1f} objects/s measured here; "
          f"{per_cpu:.1f} objects per CPU-second of a worker (= a dedicated core), options "
          f"{options}")
    print(f"planning: 1 million objects on 32 dedicated single-thread workers ≈ "
          f"{1e6 / (per_cpu * 32) / 60:.0f} min (+ cluster start-up)")
    df["scaling_ratio_2_vs_1"] = ratio
    df["cpu_normalised_ratio_2_vs_1"] = cpu_ratio
    df.to_csv(out / "batch_scaling.csv", index=False)

    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 3.8), layout="constrained")
    ax, ax2 = fig.subplots(1, 2, sharey=True, gridspec_kw={"width_ratios": [3, 2]})
    colours = ["0.5", "C0", "C0", "C1", "C1"]
    ax.barh(df["run"], df["objects_per_s"], color=colours)
    for y, v in enumerate(df["objects_per_s"]):
        ax.text(v, y, f" {v:.0f}", va="center", fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("objects per second, wall clock")
    ax.set_title(f"2 vs 1 worker: {ratio:.2f}x (load average {load:.1f} on "
                 f"{os.cpu_count()} cores)", fontsize=9)
    per = df["objects_per_cpu_s"].fillna(0)
    ax2.barh(df["run"], per, color=colours)
    for y, v in enumerate(df["objects_per_cpu_s"]):
        if np.isfinite(v):
            ax2.text(v, y, f" {v:.0f}", va="center", fontsize=8)
    ax2.set_xlabel("objects per CPU-second of the workers")
    ax2.set_title(f"CPU-normalised 2 vs 1 worker: {cpu_ratio:.2f}x", fontsize=9)
    fig.suptitle(f"PF-SDM batch throughput, {n_obj} objects", fontsize=10)
    fig.savefig(out / "batch_scaling.png", dpi=120)
    print(f"wrote {out / 'batch_scaling.csv'} and {out / 'batch_scaling.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
