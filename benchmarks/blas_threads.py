"""``distance_matrix`` with the machine's default BLAS threads against one BLAS thread, on a
quiet machine and beside a busy process.

Run from the repository root (under the shared lock on a shared machine)::

    .venv/bin/python benchmarks/blas_threads.py
    .venv/bin/python benchmarks/blas_threads.py --sizes 99 500 2000 --reps 3

The objects are smooth random blobs (``benchmarks/speed.py``'s, radius 12-40 px) described by
``pfsdm``; ``distance_matrix`` runs with its default options (the SDF magnitudes and the
boundary term) on the first n of them, for each n of ``--sizes``:

* "default": BLAS as the process has it (threadpoolctl's ``threadpool_info()``: every core,
  unless an environment variable says otherwise), as a user's script or the viewer runs it;
* "one thread": inside ``threadpoolctl.threadpool_limits(1, "blas")``.

``--products`` also times single matrix products of the distances' shapes around the size
below which ``distance_matrix`` runs a product on one thread
(``napari_pfsdm.core.threads.SMALL_PRODUCT``), in the same two ways and conditions.

The two take turns within every pass, first on the machine as it is ("quiet"), then beside a
busy process (a Python process spinning on one core, started for that part and stopped after
it). Wall time (``time.perf_counter``: what the user waits; CPU time counts every thread),
the best of ``--reps`` passes (more for a small n: as many as fill about 2 s); the target is
default <= 1.1 x one thread in both conditions.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager, nullcontext
from pathlib import Path

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_info, threadpool_limits

sys.path.insert(0, str(Path(__file__).parent))

import napari_pfsdm as P  # noqa: E402
from speed import blob  # noqa: E402

TARGET = 1.1


@contextmanager
def busy_process() -> Iterator[None]:
    """A Python process spinning on one core for the duration of the block."""
    proc = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(0.5)  # let it start spinning
        yield
    finally:
        proc.kill()
        proc.wait()


def results(n: int, seed: int = 0) -> list:
    rng = np.random.default_rng(seed)
    return [P.pfsdm(blob(rng.uniform(12, 40), rng)) for _ in range(n)]


def best_walls(items: list, reps: int) -> dict[str, float]:
    """Best wall time (s) of ``distance_matrix`` with default threads and with one, over
    ``reps`` passes or as many more as fill about 2 s (at most 50)."""
    best = {"default": np.inf, "one thread": np.inf}
    start = time.perf_counter()
    P.distance_matrix(items)
    reps = max(reps, min(50, int(2.0 / (time.perf_counter() - start))))
    for _ in range(reps):
        start = time.perf_counter()
        P.distance_matrix(items)
        best["default"] = min(best["default"], time.perf_counter() - start)
        with threadpool_limits(1, user_api="blas"):
            start = time.perf_counter()
            P.distance_matrix(items)
            best["one thread"] = min(best["one thread"], time.perf_counter() - start)
    return best


#: (kind, rows, inner, columns) of the products ``--products`` times: the Gram matrix of the
#: default embeddings (16 x 11 = 176 numbers) and the boundary term's per-shift products (a
#: chunk of 256 rows, 32 modes), at sizes around :data:`napari_pfsdm.core.threads.SMALL_PRODUCT`.
PRODUCTS = [("real", 500, 176, 500), ("real", 1500, 176, 1500), ("real", 2500, 176, 2500),
            ("real", 4000, 176, 4000), ("complex64", 256, 32, 2000),
            ("complex64", 256, 32, 8000), ("complex64", 256, 32, 32000),
            ("complex64", 256, 32, 64000)]


def product_table(reps: int) -> pd.DataFrame:
    """Wall time of each of :data:`PRODUCTS` on the machine's BLAS threads and on one, quiet
    and beside a busy process, and whether ``blas_threads_for`` counts it small."""
    from napari_pfsdm.core.threads import SMALL_PRODUCT

    rng = np.random.default_rng(0)
    rows = []
    for condition in ("quiet", "beside a busy process"):
        for kind, m, k, n in PRODUCTS:
            a, b = rng.normal(size=(m, k)), rng.normal(size=(k, n))
            flops = 2.0 * m * k * n
            if kind == "complex64":
                a = (a + 1j * rng.normal(size=a.shape)).astype(np.complex64)
                b = (b + 1j * rng.normal(size=b.shape)).astype(np.complex64)
                flops *= 4
            best = {}
            with busy_process() if condition != "quiet" else nullcontext():
                for limit in (None, 1, None, 1, *(None, 1) * max(0, reps - 2)):
                    with threadpool_limits(limit, user_api="blas"):
                        start = time.perf_counter()
                        a @ b
                        seconds = time.perf_counter() - start
                    best[limit] = min(best.get(limit, np.inf), seconds)
            rows.append({"condition": condition, "product": f"{kind} {m} x {k} x {n}",
                         "gflop": flops / 1e9, "small": flops < SMALL_PRODUCT,
                         "one_thread_ms": 1e3 * best[1], "default_ms": 1e3 * best[None],
                         "default_x_one": best[None] / best[1]})
    return pd.DataFrame(rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[99, 500, 1000],
                        help="numbers of objects")
    parser.add_argument("--reps", type=int, default=5, help="passes (the best kept)")
    parser.add_argument("--out", default="benchmarks/out", help="output folder")
    parser.add_argument("--products", action="store_true",
                        help="also time single products around the small-product threshold")
    args = parser.parse_args(argv)

    import scipy.linalg  # noqa: F401  (SciPy's OpenBLAS loaded, as distance_matrix has it)

    blas = [f"{i['internal_api']} {i['version']} ({i['num_threads']} threads)"
            for i in threadpool_info() if i["user_api"] == "blas"]
    print(f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}; BLAS: "
          f"{', '.join(blas)}; wall time, best of {args.reps} passes", flush=True)
    everything = results(max(args.sizes))
    for r in everything:
        r.outline  # noqa: B018  (computed once, outside the timing)
    P.distance_matrix(everything[:10])  # warm-up
    rows = []
    for condition in ("quiet", "beside a busy process"):
        for n in args.sizes:
            items = everything[:n]
            if condition == "quiet":
                best = best_walls(items, args.reps)
            else:
                with busy_process():
                    best = best_walls(items, args.reps)
            rows.append({"condition": condition, "objects": n,
                         "one_thread_s": best["one thread"], "default_s": best["default"],
                         "default_x_one": best["default"] / best["one thread"]})
            print(f"  {condition}, {n} objects: done", flush=True)
    table = pd.DataFrame(rows)
    print()
    print(table.to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    print()
    for condition, part in table.groupby("condition", sort=False):
        worst = float(part["default_x_one"].max())
        ok = worst <= TARGET
        print(f"  {'met ' if ok else 'MISSED'}  {condition}: default threads <= {TARGET:g} x one "
              f"BLAS thread: worst {worst:.2f}x")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    table.to_csv(out / "blas_threads.csv", index=False)
    print(f"\nwrote {out / 'blas_threads.csv'}")
    if args.products:
        products = product_table(args.reps)
        print()
        print(products.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
        products.to_csv(out / "blas_products.csv", index=False)
        print(f"\nwrote {out / 'blas_products.csv'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
