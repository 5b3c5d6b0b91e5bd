"""The elastic term's first call in a fresh process: compiled once, then loaded from numba's cache.

Each run is a new Python process (``--runs``, default 2, one after the other) with
``NUMBA_CACHE_DIR`` set to one folder that starts empty, so run 1 is a first-ever use of the
package and run 2 any later one. Each process, in order, on one frame of moving blobs
(``--objects`` objects, 256² px):

- ``import``: ``import napari_pfsdm`` and the names below;
- ``measure``: ``napari_pfsdm.measure(labels)``, the default table (no compiled code);
- ``D_PF``: ``distance_matrix(table)``, the default distance (the anchor: nothing to compile);
- ``signature``: ``measure(labels, elastic_signature="table")`` minus ``measure``'s time: the
  signature's kernel;
- ``d_E``: ``distance_matrix(table, elastic_weight=RECOMMENDED_ELASTIC_WEIGHT)``: the DTW kernel;
- ``neighbours``: ``nearest_neighbours(table, k=5, elastic_weight=...)``: its search kernel;

all wall-clock seconds of the first call, and numba's own count of the package's compiled
kernels loaded from the cache (hits) and compiled (misses), read from their dispatchers.
"First elastic distance" is ``signature`` + ``d_E``: what a first ``distance_matrix(...,
elastic_weight=μ)`` on new objects costs beyond the default.

``--ref REV`` measures the package as of git revision ``REV`` instead (its ``src`` unpacked
by ``git archive`` into a temporary folder; its own empty cache folder). Run (repository
root)::

    .venv/bin/python benchmarks/elastic_first_call.py
    .venv/bin/python benchmarks/elastic_first_call.py --ref c9e5a94

Quote ratios from one run: the machine is shared, absolute times move with its load.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
STEPS = ("import", "measure", "D_PF", "signature", "d_E", "neighbours")


def _kernel_stats() -> tuple[int, int]:
    """(cache hits, cache misses) summed over the numba dispatchers of the package's elastic
    modules (module globals, and tuples of them: how older versions kept their kernels)."""
    from numba.core.dispatcher import Dispatcher

    hits = misses = 0
    seen = set()
    for name, mod in list(sys.modules.items()):
        if not name.startswith("napari_pfsdm.core") or mod is None:
            continue
        for value in list(vars(mod).values()):
            values = value if isinstance(value, tuple) else (value,)
            for v in values:
                if isinstance(v, Dispatcher) and id(v) not in seen:
                    seen.add(id(v))
                    hits += sum(v.stats.cache_hits.values())
                    misses += sum(v.stats.cache_misses.values())
    return hits, misses


def child(n_objects: int) -> dict:
    """One fresh process's first calls (module docstring)."""
    times = {}
    t0 = time.perf_counter()
    import numpy as np  # noqa: F401

    import napari_pfsdm as pf
    from napari_pfsdm.core.distances import RECOMMENDED_ELASTIC_WEIGHT
    from napari_pfsdm.data.moving_blobs import make_moving_blobs

    times["import"] = time.perf_counter() - t0
    labels = make_moving_blobs(n_objects=n_objects, n_frames=1, size=256,
                               radius=(10.0, 16.0), seed=0).labels[0]
    t0 = time.perf_counter()
    table = pf.drop_failed(pf.measure(labels))
    times["measure"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    pf.distance_matrix(table)
    times["D_PF"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    table_e = pf.drop_failed(pf.measure(labels, elastic_signature="table"))
    times["signature"] = time.perf_counter() - t0 - times["measure"]
    mu = RECOMMENDED_ELASTIC_WEIGHT
    t0 = time.perf_counter()
    pf.distance_matrix(table_e, elastic_weight=mu)
    times["d_E"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    pf.nearest_neighbours(table_e, k=5, elastic_weight=mu)
    times["neighbours"] = time.perf_counter() - t0
    hits, misses = _kernel_stats()
    return {"times": times, "hits": hits, "misses": misses, "objects": len(table_e)}


def _source(ref: str | None, tmp: Path) -> Path:
    """The ``src`` folder to import the package from: this checkout's, or ``ref``'s."""
    if ref is None:
        return ROOT / "src"
    archive = tmp / "src.tar"
    subprocess.run(["git", "archive", "-o", str(archive), ref, "src"], cwd=ROOT, check=True)
    with tarfile.open(archive) as tar:
        tar.extractall(tmp / "at_ref", filter="data")
    return tmp / "at_ref" / "src"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=2)
    p.add_argument("--objects", type=int, default=30)
    p.add_argument("--ref", help="git revision of the package to measure instead")
    p.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        print(json.dumps(child(args.objects)))
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        src = _source(args.ref, Path(tmp))
        env = dict(os.environ, NUMBA_CACHE_DIR=str(Path(tmp) / "numba_cache"),
                   PYTHONPATH=str(src))
        rows = []
        for _ in range(args.runs):
            out = subprocess.run([sys.executable, __file__, "--child", "--objects",
                                  str(args.objects)], env=env, cwd=tmp, check=True,
                                 capture_output=True, text=True).stdout
            rows.append(json.loads(out.strip().splitlines()[-1]))
    what = f"git {args.ref}" if args.ref else "this checkout"
    print(f"{what}: fresh processes, one cache folder (empty before run 1), "
          f"{rows[0]['objects']} objects; wall-clock seconds of each first call\n")
    print("| run | " + " | ".join(STEPS) + " | first elastic distance (signature + d_E) "
          "| kernels loaded / compiled |")
    print("|---|" + "---|" * (len(STEPS) + 2))
    for i, r in enumerate(rows, 1):
        t = r["times"]
        cells = " | ".join(f"{t[s]:.2f}" for s in STEPS)
        print(f"| {i} | {cells} | {t['signature'] + t['d_E']:.2f} | {r['hits']} / "
              f"{r['misses']} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
