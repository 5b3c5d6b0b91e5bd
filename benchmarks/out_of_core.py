"""Out-of-core run: a Zarr label movie of >= 4 GiB streamed through ``pfsdm measure``.

1. Writes a (T, 4096, 4096) uint16 label movie to a Zarr store under /tmp, frame by frame
   (compressed on disk; the uncompressed size is what counts: T x 4096 x 4096 x 2 bytes),
   with a few moving, growing objects per frame (large frames, little work per frame).
2. Runs the real command line on it in a subprocess::

       python -m napari_pfsdm measure /tmp/.../movie.zarr -o /tmp/.../features.csv \\
           --scheduler processes --workers 2

   while sampling the resident memory (RSS) of that process and all its worker processes
   with psutil every 0.1 s.
3. Prints the peak RSS (largest single process, and the whole process tree at once) next to
   the movie's size, checks the table (one row per object and frame, no errors), and deletes
   the movie (unless --keep).

Run once (measured: 39 s to write + 106 s to measure on 2 busy cores)::

    .venv/bin/python benchmarks/out_of_core.py --out benchmarks/out
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np


def write_movie(path: Path, n_frames: int, size: int, n_objects: int, seed: int = 0) -> None:
    """Label movie with ``n_objects`` ellipses per frame drifting and growing over time."""
    import zarr
    from skimage.draw import ellipse

    rng = np.random.default_rng(seed)
    z = zarr.create_array(str(path), shape=(n_frames, size, size), dtype=np.uint16,
                          chunks=(1, size // 2, size // 2))
    centres = rng.uniform(0.2 * size, 0.8 * size, size=(n_objects, 2))
    velocity = rng.normal(0, size * 0.0005, size=(n_objects, 2))
    axes0 = rng.uniform(0.02 * size, 0.05 * size, size=(n_objects, 2))
    angle0 = rng.uniform(0, np.pi, n_objects)
    frame = np.zeros((size, size), np.uint16)
    for t in range(n_frames):
        frame[:] = 0
        grow = 1.0 + 0.5 * t / max(n_frames - 1, 1)
        for i in range(n_objects):
            cy, cx = centres[i] + velocity[i] * t
            ry, rx = axes0[i] * [grow, grow ** 0.5]
            rr, cc = ellipse(cy, cx, ry, rx, shape=frame.shape, rotation=angle0[i] + 0.01 * t)
            frame[rr, cc] = i + 1
        z[t] = frame


def du(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())


def sample_rss(pid: int, stop: threading.Event, out: dict) -> None:
    import psutil

    proc = psutil.Process(pid)
    peak_total, peak_single, n_procs = 0, 0, 0
    while not stop.is_set():
        try:
            procs = [proc, *proc.children(recursive=True)]
            rss = []
            for p in procs:
                try:
                    rss.append(p.memory_info().rss)
                except psutil.Error:
                    pass
            peak_total = max(peak_total, sum(rss))
            peak_single = max(peak_single, max(rss, default=0))
            n_procs = max(n_procs, len(rss))
        except psutil.Error:
            break
        time.sleep(0.1)
    out.update(peak_total=peak_total, peak_single=peak_single, n_procs=n_procs)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="benchmarks/out", help="folder for the result JSON")
    ap.add_argument("--gib", type=float, default=4.0, help="uncompressed labels, GiB (4)")
    ap.add_argument("--size", type=int, default=4096, help="frame side, px (4096)")
    ap.add_argument("--objects", type=int, default=4, help="objects per frame (4)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--tmp", default="/tmp", help="where the movie is written (/tmp)")
    ap.add_argument("--keep", action="store_true", help="keep the movie afterwards")
    args = ap.parse_args(argv)

    frame_bytes = args.size * args.size * 2
    n_frames = int(np.ceil(args.gib * 2**30 / frame_bytes))
    work = Path(tempfile.mkdtemp(prefix="pfsdm-ooc-", dir=args.tmp))
    movie, table = work / "movie.zarr", work / "features.csv"
    result: dict = {}
    try:
        t0 = time.perf_counter()
        write_movie(movie, n_frames, args.size, args.objects)
        t_write = time.perf_counter() - t0
        raw = n_frames * frame_bytes
        print(f"wrote {movie}: {n_frames} frames of {args.size}x{args.size} uint16 = "
              f"{raw / 2**30:.2f} GiB uncompressed, {du(movie) / 2**20:.1f} MiB on disk, "
              f"in {t_write:.0f} s")

        cmd = [sys.executable, "-m", "napari_pfsdm", "measure", str(movie), "-o", str(table),
               "--scheduler", "processes", "--workers", str(args.workers), "-q"]
        print("running:", " ".join(cmd))
        stop, peaks = threading.Event(), {}
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        sampler = threading.Thread(target=sample_rss, args=(proc.pid, stop, peaks))
        sampler.start()
        stdout, stderr = proc.communicate()
        t_run = time.perf_counter() - t0
        stop.set()
        sampler.join()
        if proc.returncode != 0:
            print(stderr, file=sys.stderr)
            return proc.returncode
        children_maxrss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024

        from napari_pfsdm.io import read_table

        tab = read_table(table)
        n_err = int(tab["error"].ne("").sum())
        result = {
            "frames": n_frames, "frame_size": args.size, "objects_per_frame": args.objects,
            "uncompressed_gib": raw / 2**30, "on_disk_mib": du(movie) / 2**20,
            "write_s": t_write, "measure_s": t_run, "rows": len(tab), "errors": n_err,
            "peak_rss_single_process_mib": peaks["peak_single"] / 2**20,
            "peak_rss_process_tree_mib": peaks["peak_total"] / 2**20,
            "max_processes": peaks["n_procs"],
            "getrusage_children_maxrss_mib": children_maxrss / 2**20,
            "load_average": os.getloadavg()[0], "command": " ".join(cmd),
        }
        print(f"measured {len(tab)} objects ({n_err} errors; expected "
              f"{n_frames * args.objects}) in {t_run:.0f} s "
              f"= {len(tab) / t_run:.1f} objects/s, {raw / 2**20 / t_run:.0f} MiB/s of labels")
        print(f"peak RSS: largest process {result['peak_rss_single_process_mib']:.0f} MiB, "
              f"whole process tree ({peaks['n_procs']} processes) "
              f"{result['peak_rss_process_tree_mib']:.0f} MiB "
              f"(getrusage children max {result['getrusage_children_maxrss_mib']:.0f} MiB) "
              f"for a {raw / 2**30:.2f} GiB movie")
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "out_of_core.json").write_text(json.dumps(result, indent=2))
        print(f"wrote {out / 'out_of_core.json'}")
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
