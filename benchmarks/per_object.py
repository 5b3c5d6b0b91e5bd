"""Where the per-object time of ``measure`` goes: each part of one object's step, timed inside
``measure`` itself.

Run from the repository root (under the shared lock on a shared machine)::

    .venv/bin/python benchmarks/per_object.py
    .venv/bin/python benchmarks/per_object.py --frames 8 --reps 5

On the nucleus-sized movie of ``benchmarks/speed.py`` (``--frames`` frames of 512 x 512,
blobs of radius 10-20 px, about 150 a frame), with the default options, and with a smooth
reporter image over it:

1. Throughput: ``measure`` without and with the reporter, and scikit-image's
   ``regionprops_table`` on the same frames (label, area, centroid and the classic measures
   ``measure`` reports), in objects per CPU-second, and ``measure``'s throughput over
   regionprops' (the anchor: load slows both alike).
2. The parts: every function of the step (mask preparation, marching squares, contour, SDF
   build and evaluation, map, FFT and embedding, outline coefficients, classic measures,
   the reporter's) is wrapped, wherever the package refers to it, by a timer that adds up its
   CPU time, and ``measure`` runs as it is. A part called inside another (the trace inside
   the mask's preparation, the perimeter inside the classic measures) is shown under it.
   What ``measure`` spends outside the parts is its own glue: the frames' object boxes and
   crops, the label's mask, the records, the loop and the table (and the timers' own cost,
   the table's last row: the timed run minus the plain one). The timed runs are passes of
   their own, apart from the throughput's.

``--against REF`` also measures the package as of git revision ``REF`` (``git archive`` into a
temporary folder, renamed so that both load in this process): its ``measure`` and this
checkout's take turns in ``--against-runs`` runs each on the same movie, and the script prints
the ratio of their best runs, the median of the paired runs' ratios, and whether the two
tables are the same to the bit.

CPU time (``time.process_time``), one BLAS thread, each figure the best of ``--reps``
passes; the passes take turns over the methods, so that a change of load hits all alike.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import atexit  # noqa: E402
import functools  # noqa: E402
import importlib  # noqa: E402
import io  # noqa: E402
import re  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tarfile  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Iterator  # noqa: E402
from contextlib import contextmanager  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))

import napari_pfsdm as P  # noqa: E402
from napari_pfsdm.analysis import classic  # noqa: E402
from napari_pfsdm.core import (  # noqa: E402
    boundary,
    contour,
    descriptor,
    marching_squares,
    morphometric,
    pushforward,
    sdf,
)
from speed import TARGET_THROUGHPUT, nucleus_movie, regionprops_frames  # noqa: E402

#: (part, the part it lies within or "", where the function is, its name); a part made of
#: several functions lists each of them. Functions are found by object, so every module that
#: imported one has it wrapped.
PARTS = [
    ("mask preparation (box, checks, pieces)", "", contour, "prepare_mask"),
    ("marching squares (the trace)", "mask preparation (box, checks, pieces)",
     marching_squares, "_trace"),
    ("contour (resample, smooth, centre, scale)", "", contour, "extract_contour"),
    ("SDF build", "", sdf, "make_sdf"),
    ("map: coefficients (FFT of the outline)", "", pushforward, "make_map"),
    ("map: samples and Jacobian", "", pushforward.FourierMap, "polar_and_jacobian"),
    ("SDF evaluation at the samples", "", sdf.ExactSDF, "__call__"),
    ("FFT and embedding", "", morphometric, "spectrum"),
    ("FFT and embedding", "", morphometric, "magnitude_embedding"),
    ("outline coefficients", "", boundary, "normalised_modes"),
    ("classic measures", "", classic, "classic_measures"),
    ("perimeter", "classic measures", classic, "perimeter_4"),
    ("convex area", "classic measures", classic, "convex_area"),
    ("reporter: intensity crop and samples", "", descriptor, "_intensity_crop"),
    ("reporter: intensity crop and samples", "", descriptor, "sample_intensity"),
    ("reporter: classic measures", "classic measures", classic, "reporter_measures"),
]


def reporter_movie(movie: np.ndarray, seed: int = 1) -> np.ndarray:
    """A positive reporter over the movie: a smooth gradient across each frame, brighter
    inside the objects, with noise."""
    rng = np.random.default_rng(seed)
    _, h, w = movie.shape
    ramp = np.add.outer(np.linspace(1, 2, h), np.linspace(0, 1, w))
    return (ramp[None] + 2.0 * (movie > 0) + 0.1 * rng.random(movie.shape)).astype(np.float32)


@contextmanager
def timed_parts(spent: dict[str, int]) -> Iterator[None]:
    """Within the block, every function of :data:`PARTS` adds its CPU time (ns) to
    ``spent[part]``, wherever the package refers to it."""
    patches = []
    for part, _, owner, name in PARTS:
        original = getattr(owner, name)
        wrapper = _timer(original, part, spent)
        if isinstance(owner, type):
            patches.append((owner, name, original))
            setattr(owner, name, wrapper)
            continue
        for module in [m for m in list(sys.modules.values())
                       if m is not None and m.__name__.startswith("napari_pfsdm")]:
            for attr, value in list(vars(module).items()):
                if value is original:
                    patches.append((module, attr, original))
                    setattr(module, attr, wrapper)
    try:
        yield
    finally:
        for owner, name, original in reversed(patches):
            setattr(owner, name, original)


def _timer(fn: Callable, part: str, spent: dict[str, int]) -> Callable:
    clock = time.process_time_ns

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        start = clock()
        try:
            return fn(*args, **kwargs)
        finally:
            spent[part] = spent.get(part, 0) + clock() - start

    return wrapper


def package_at(ref: str):
    """The ``napari_pfsdm`` package as of git revision ``ref``, imported under another name
    (``napari_pfsdm_at_<ref>``, every reference to the package in its sources renamed)."""
    root = Path(__file__).resolve().parent.parent
    archive = subprocess.run(["git", "archive", ref, "src/napari_pfsdm"], cwd=root,
                             capture_output=True, check=True).stdout
    folder = Path(tempfile.mkdtemp(prefix="pfsdm_at_"))
    atexit.register(shutil.rmtree, folder, True)
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(folder, filter="data")
    name = "napari_pfsdm_at_" + re.sub(r"\W", "_", ref)
    package = folder / "src" / name
    (folder / "src" / "napari_pfsdm").rename(package)
    for path in package.rglob("*.py"):
        path.write_text(re.sub(r"\bnapari_pfsdm\b", name, path.read_text()))
    sys.path.insert(0, str(folder / "src"))
    return importlib.import_module(name)


def against(ref: str, movie: np.ndarray, runs: int) -> None:
    """Print ``measure`` of this checkout against that of git revision ``ref``."""
    other = package_at(ref)
    n = int(sum(len(np.unique(f)) - 1 for f in movie))
    ours, theirs = P.measure(movie), other.measure(movie)  # (and warm-ups)
    same = ours.equals(theirs) and list(ours.columns) == list(theirs.columns)
    times: dict[str, list[float]] = {"this checkout": [], ref: []}
    for i in range(runs):
        pair = [("this checkout", P), (ref, other)]
        for name, package in pair if i % 2 else pair[::-1]:
            start = time.process_time()
            package.measure(movie)
            times[name].append(time.process_time() - start)
    now, then = np.array(times["this checkout"]), np.array(times[ref])
    print(f"\nmeasure at {ref} against this checkout, {runs} runs each taking turns: "
          f"{n / then.min():.0f} and {n / now.min():.0f} objects per CPU-second (best runs); "
          f"this checkout {then.min() / now.min():.2f}x as fast by the best runs, "
          f"{float(np.median(then / now)):.2f}x by the median of the paired runs; the tables "
          f"{'are the same to the bit' if same else 'DIFFER'}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=4, help="frames of the nucleus movie")
    parser.add_argument("--reps", type=int, default=3, help="passes (the best kept)")
    parser.add_argument("--out", default="benchmarks/out", help="output folder")
    parser.add_argument("--against", metavar="REF",
                        help="also compare measure with the package at this git revision")
    parser.add_argument("--against-runs", type=int, default=12,
                        help="--against: runs of each (best and median kept)")
    args = parser.parse_args(argv)

    movie = nucleus_movie(args.frames)
    image = reporter_movie(movie)
    n = int(sum(len(np.unique(f)) - 1 for f in movie))
    print(f"{n} objects ({args.frames} frames of 512 x 512, blobs of radius 10-20 px); CPU "
          f"time, best of {args.reps} passes; one thread; load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs", flush=True)
    runs: dict[str, Callable[[], object]] = {
        "measure": lambda: P.measure(movie),
        "measure with the reporter": lambda: P.measure(movie, image),
        "regionprops": lambda: regionprops_frames(movie),
    }
    parts: dict[str, dict[str, float]] = {"measure": {}, "measure with the reporter": {}}
    best = dict.fromkeys([*runs, *(f"{k}, timed parts" for k in parts)], np.inf)
    for fn in runs.values():
        fn()  # warm-up
    for _ in range(args.reps):
        for name, fn in runs.items():
            start = time.process_time()
            fn()
            best[name] = min(best[name], time.process_time() - start)
        for name in parts:
            spent: dict[str, int] = {}
            with timed_parts(spent):
                start = time.process_time()
                runs[name]()
                whole = time.process_time() - start
            best[f"{name}, timed parts"] = min(best[f"{name}, timed parts"], whole)
            for part, ns in spent.items():
                parts[name][part] = min(parts[name].get(part, np.inf), ns * 1e-9)

    tables = {name: part_table(parts[name], best[f"{name}, timed parts"], best[name], n)
              for name in parts}
    for name, table in tables.items():
        print(f"\n{name} (us per object; timers on)")
        print(table.to_string(index=False, float_format=lambda v: f"{v:.1f}"))
    rp = best["regionprops"] / n
    per = {k: best[k] / n for k in ("measure", "measure with the reporter")}
    throughput = 1 / per["measure"]
    print(f"\nmeasure: {throughput:.0f} objects per CPU-second; with the reporter "
          f"{1 / per['measure with the reporter']:.0f}; regionprops_table on the same frames "
          f"{1 / rp:.0f}")
    print(f"measure's throughput / regionprops': {rp / per['measure']:.2f} (with the reporter "
          f"{rp / per['measure with the reporter']:.2f})")
    ok = throughput >= TARGET_THROUGHPUT
    print(f"  {'met ' if ok else 'MISSED'}  measure >= {TARGET_THROUGHPUT:,.0f} objects per "
          f"CPU-second (nucleus-sized, default options): {throughput:.0f}/s")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    pd.concat([t.assign(run=name) for name, t in tables.items()]).to_csv(
        out / "per_object.csv", index=False)
    print(f"\nwrote {out / 'per_object.csv'}")
    if args.against:
        against(args.against, movie, args.against_runs)
    return 0


def part_table(seconds: dict[str, float], whole: float, plain: float, n: int) -> pd.DataFrame:
    """µs per object and share of the whole (``whole``, timers on) of each part (in
    :data:`PARTS`' order, a part within another indented under it), the glue, the whole, and
    what the timers cost (``whole`` minus ``plain``, the same run without them)."""
    within = {part: parent for part, parent, _, _ in PARTS}
    rows = []
    for part in dict.fromkeys(p for p, _, _, _ in PARTS):
        if part not in seconds or within[part]:
            continue
        rows.append((part, seconds[part]))
        children = [c for c in dict.fromkeys(p for p, _, _, _ in PARTS)
                    if within[c] == part and c in seconds]
        for child in children:
            rows.append(("  " + child, seconds[child]))
        if children:
            rows.append(("  the rest", seconds[part] - sum(seconds[c] for c in children)))
    top = sum(s for p, s in seconds.items() if not within[p])
    rows.append(("measure's glue (boxes, crops, label masks, records, table)", whole - top))
    rows.append(("measure, per object", whole))
    rows.append(("  of which the timers (timed run minus plain run)", whole - plain))
    return pd.DataFrame([(name, 1e6 * s / n, 100 * s / whole) for name, s in rows],
                        columns=["part", "us_per_object", "percent"])


if __name__ == "__main__":
    raise SystemExit(main())
