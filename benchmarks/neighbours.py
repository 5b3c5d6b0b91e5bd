"""Nearest neighbours of many objects: ``nearest_neighbours`` against ``measure``.

For each size n (default 3,000, 10,000 and 50,000 objects) a moving-blobs movie (1024², 250
deforming blobs of radius 10–16 px per frame) is made and measured with
``napari_pfsdm.measure`` (one core, BLAS on one thread); then, in a fresh subprocess (so that its
peak memory is its own), ``napari_pfsdm.nearest_neighbours(table, k=10)`` runs with one thread
and with ``--jobs`` threads. Reported per size:

- measure time (one core) and nearest_neighbours time, and their ratio (target: ≤ 1 at 50,000);
- exact distances computed per object by the search (the brute force needs n − 1);
- recall@10 (and up to ties of 1e-6, see ``_recall``) against an independent reference:
  ``np.argsort`` of the rows of ``napari_pfsdm.distance_matrix`` where the full matrix is
  computed (n ≤ ``--exact-max``; also against itself on the objects in another order),
  else of reference rows for ``--sample`` random queries (the magnitude distance by
  ``scipy.spatial.distance.cdist`` plus ``boundary_distance_matrix(queries, all)``);
- peak memory (the subprocess's peak resident set, VmHWM, table included; target < 4 GiB);
- the brute force, blocked rows against all: its time per reference row × n (estimate) and the
  n × n matrix's size.

``--data mpeg7`` uses the 1,400 MPEG-7 CE-Shape-1 silhouettes instead (read by path from
``--folder``, default ../shared/data/mpeg7 beside the repository, preprocessed as
``benchmarks/mpeg7.py`` does), each copy after the first turned by a random angle and scaled by
0.7–1.2 (nearest-neighbour resampling); "measure" is then ``pfsdm`` on each mask, and the
search runs on their :class:`~napari_pfsdm.core.distances.Embeddings`.

Run (about 15 minutes on 2 cores; the 50,000-object movie is 0.4 GB of labels)::

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/neighbours.py \\
        --out benchmarks/out --figure docs/figures/neighbours.png
    .venv/bin/python benchmarks/neighbours.py --data mpeg7 --sizes 3000 10000

Quote ratios from one run: the machine is shared, absolute times move with its load.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import numpy as np  # noqa: E402

K = 10
PER_FRAME = 250
TIE = 1e-6


def _peak_mib() -> float:
    """This process's peak resident memory (MiB): VmHWM, which starts afresh at exec (Linux's
    ru_maxrss keeps the parent's peak across fork + exec, so it would count the parent)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _child(path: str, jobs: int) -> None:
    """Subprocess: load the table, run nearest_neighbours, print JSON (time, peak memory)."""
    import warnings

    import napari_pfsdm as pf
    from napari_pfsdm.core import neighbours as core_nn

    warnings.simplefilter("ignore")
    with open(path, "rb") as fh:
        table = pickle.load(fh)
    base = _peak_mib()
    counted = [0]
    exact = core_nn._exact_pairs

    def counting(index, ii, jj):
        counted[0] += len(ii)
        return exact(index, ii, jj)

    core_nn._exact_pairs = counting
    t0, c0 = time.perf_counter(), time.process_time()
    idx, dist = pf.nearest_neighbours(table, K, n_jobs=jobs)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    np.save(path + f".idx{jobs}.npy", idx)
    print(json.dumps({"wall": wall, "cpu": cpu, "pairs": counted[0] / len(idx),
                      "peak_mib": _peak_mib(), "base_mib": base}))


def _run_child(path: Path, jobs: int) -> dict:
    out = subprocess.run([sys.executable, __file__, "--child", str(path), "--jobs", str(jobs)],
                         capture_output=True, text=True)
    if out.returncode:
        raise SystemExit(f"the nearest_neighbours subprocess failed:\n{out.stderr}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def _movie_table(n: int, seed: int):
    """A moving-blobs movie with at least n described objects, measured; the first n rows."""
    import warnings

    import napari_pfsdm as pf
    from napari_pfsdm.data.moving_blobs import make_moving_blobs

    frames = int(np.ceil(n / (0.96 * PER_FRAME)))
    movie = make_moving_blobs(n_objects=PER_FRAME, n_frames=frames, size=1024,
                              radius=(10.0, 16.0), seed=seed)
    t0 = time.perf_counter()
    table = pf.measure(movie.labels)
    seconds = time.perf_counter() - t0
    measured = len(table)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = pf.drop_failed(table)
    if len(table) < n:
        raise SystemExit(f"only {len(table)} objects described for n = {n}")
    kept = table.iloc[:n].reset_index(drop=True)
    kept.attrs = table.attrs
    return kept, seconds * n / measured  # measure time of the n objects kept


def _mpeg7_embeddings(n: int, seed: int, folder: Path):
    """n MPEG-7 silhouettes (copies turned and scaled) described by ``pfsdm``: Embeddings and
    the time of the ``pfsdm`` calls."""
    from scipy import ndimage

    import napari_pfsdm as pf
    from napari_pfsdm.core.distances import Embeddings

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from mpeg7 import load_masks

    masks = load_masks(folder)[0]
    rng = np.random.default_rng(seed)
    shape, outline, seconds, weights, modes = [], [], 0.0, None, None
    for i in range(n):
        m = masks[i % len(masks)]
        if i >= len(masks):
            m = ndimage.zoom(m.astype(np.uint8), rng.uniform(0.7, 1.2), order=0)
            m = ndimage.rotate(m, rng.uniform(0, 360), order=0, reshape=True) > 0
        t0 = time.perf_counter()
        r = pf.pfsdm(m)
        seconds += time.perf_counter() - t0
        shape.append(r.embedding)
        outline.append(r.outline)
        weights, modes = r.weights, r.mode_weights
    return Embeddings(shape=np.stack(shape), weights=weights, mode_weights=modes,
                      outline=np.stack(outline)), seconds


def _reference_rows(table, queries: np.ndarray, idx: np.ndarray | None = None):
    """Reference neighbours of ``queries`` by the brute force on the public pieces: their
    indices, the reference k-th distance and the reference distances of ``idx[queries]``
    (the search's answer), and the time per query row."""
    from scipy.spatial.distance import cdist

    import napari_pfsdm as pf
    from napari_pfsdm.analysis.tables import embeddings
    from napari_pfsdm.core.boundary import boundary_distance_matrix
    from napari_pfsdm.core.distances import BOUNDARY_WEIGHT, Embeddings

    f = pf.weighted_features(table)
    a = table.outline if isinstance(table, Embeddings) else embeddings(table).outline
    t0 = time.perf_counter()
    ref = np.empty((len(queries), K), int)
    kth = np.empty(len(queries))
    got = np.empty((len(queries), K))
    for s in range(0, len(queries), 50):
        q = queries[s:s + 50]
        d = cdist(f[q], f) + BOUNDARY_WEIGHT * boundary_distance_matrix(a[q], a)
        d[np.arange(len(q)), q] = np.inf
        ref[s:s + 50] = np.argsort(d, axis=1, kind="stable")[:, :K]
        kth[s:s + 50] = np.take_along_axis(d, ref[s:s + 50, -1:], 1)[:, 0]
        if idx is not None:
            got[s:s + 50] = np.take_along_axis(d, idx[q], 1)
    return ref, kth, got, (time.perf_counter() - t0) / len(queries)


def _recall(idx: np.ndarray, ref: np.ndarray, kth: np.ndarray,
            got: np.ndarray) -> tuple[float, float, float]:
    """Recall@k (shared members), the fraction of rows with the same k in the same order,
    and the recall up to ties: a neighbour counts when its reference distance is within
    TIE of the reference's k-th (the reference itself moves by up to ~1e-3 when the objects
    come in another order: the boundary term's start-shift search, docs/design.md §2.9)."""
    hits = [len(set(a) & set(b)) / K for a, b in zip(idx, ref, strict=True)]
    return (float(np.mean(hits)), float(np.mean((idx == ref).all(axis=1))),
            float(np.mean(got <= kth[:, None] + TIE)))


def _self_recall(table, d: np.ndarray, seed: int) -> float:
    """Recall@k of distance_matrix against itself computed on the objects in another order."""
    import napari_pfsdm as pf
    from napari_pfsdm.core.distances import Embeddings

    perm = np.random.default_rng(seed + 1).permutation(len(d))
    if isinstance(table, Embeddings):
        other = Embeddings(shape=table.shape[perm], weights=table.weights,
                           mode_weights=table.mode_weights, outline=table.outline[perm])
    else:
        other = table.iloc[perm].reset_index(drop=True)
        other.attrs = table.attrs
    inv = np.argsort(perm)
    d2 = pf.distance_matrix(other)[np.ix_(inv, inv)]
    np.fill_diagonal(d2, np.inf)
    a = np.argsort(d, axis=1, kind="stable")[:, :K]
    b = np.argsort(d2, axis=1, kind="stable")[:, :K]
    return float(np.mean([len(set(x) & set(y)) / K for x, y in zip(a, b, strict=True)]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[3000, 10000, 50000])
    ap.add_argument("--jobs", type=int, default=2, help="threads of the second run (2)")
    ap.add_argument("--exact-max", type=int, default=3000,
                    help="largest n whose full distance_matrix is the reference (3000)")
    ap.add_argument("--sample", type=int, default=200,
                    help="reference queries above --exact-max (200)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-self-check", dest="self_check", action="store_false",
                    help="skip distance_matrix against itself on permuted objects")
    ap.add_argument("--data", choices=["blobs", "mpeg7"], default="blobs")
    ap.add_argument("--folder", type=Path,
                    default=Path(__file__).resolve().parents[2] / "shared" / "data" / "mpeg7",
                    help="MPEG-7 silhouettes for --data mpeg7")
    ap.add_argument("--out", default="benchmarks/out", help="folder for the CSV")
    ap.add_argument("--figure", default=None, help="PNG of times against n")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        _child(args.child, args.jobs)
        return 0

    import pandas as pd

    import napari_pfsdm as pf

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    what = (f"moving blobs, 1024², {PER_FRAME} per frame, radius 10-16 px"
            if args.data == "blobs" else
            "MPEG-7 silhouettes, copies turned and scaled 0.7-1.2")
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; k = {K}; {what}")
    rows = []
    with tempfile.TemporaryDirectory(prefix="pfsdm-nn-") as tmp:
        for n in args.sizes:
            if args.data == "blobs":
                table, t_measure = _movie_table(n, args.seed)
            else:
                table, t_measure = _mpeg7_embeddings(n, args.seed, args.folder)
            path = Path(tmp) / f"table{n}.pkl"
            with open(path, "wb") as fh:
                pickle.dump(table, fh)
            one = _run_child(path, 1)
            many = _run_child(path, args.jobs)
            idx = np.load(str(path) + ".idx1.npy")
            same_threads = bool((np.load(str(path) + f".idx{args.jobs}.npy") == idx).all())
            if n <= args.exact_max:
                t0 = time.perf_counter()
                d = pf.distance_matrix(table)
                t_matrix = time.perf_counter() - t0
                np.fill_diagonal(d, np.inf)
                ref = np.argsort(d, axis=1, kind="stable")[:, :K]
                kth = np.take_along_axis(d, ref[:, -1:], 1)[:, 0]
                recall, exact_rows, tied = _recall(idx, ref, kth,
                                                   np.take_along_axis(d, idx, 1))
                self_recall = _self_recall(table, d, args.seed) if args.self_check else None
                del d
                ref_rows = n
                t_row = _reference_rows(table, np.arange(min(100, n)))[-1]
            else:
                queries = np.random.default_rng(args.seed).choice(n, args.sample,
                                                                  replace=False)
                ref, kth, got, t_row = _reference_rows(table, queries, idx)
                recall, exact_rows, tied = _recall(idx[queries], ref, kth, got)
                ref_rows, t_matrix, self_recall = args.sample, None, None
            row = {
                "n": n,
                "measure_s": t_measure,
                "nn_1thread_s": one["wall"],
                f"nn_{args.jobs}threads_s": many["wall"],
                "nn_over_measure": min(one["wall"], many["wall"]) / t_measure,
                "exact_pairs_per_object": one["pairs"],
                "recall@10": recall,
                "recall@10_up_to_ties": tied,
                "rows_same_10_same_order": exact_rows,
                "matrix_vs_itself_permuted": self_recall,
                "reference_rows": ref_rows,
                "peak_mib": max(one["peak_mib"], many["peak_mib"]),
                "brute_blocked_est_s": t_row * n,
                "distance_matrix_s": t_matrix,
                "matrix_gib": n * n * 8 / 2**30,
                "threads_same": same_threads,
            }
            rows.append(row)
            print(pd.DataFrame([row]).to_string(index=False), flush=True)
    df = pd.DataFrame(rows)
    df.to_csv(out / f"neighbours_{args.data}.csv", index=False)
    show = df.copy()
    show["nn / measure"] = show.pop("nn_over_measure").map("{:.2f}".format)
    print("\n" + show.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    for r in rows:
        ok = r["nn_over_measure"] <= 1 and r["peak_mib"] < 4096
        print(f"  {'met ' if ok else 'MISS'} n = {r['n']}: nearest_neighbours "
              f"{r['nn_over_measure']:.2f}x measure, peak {r['peak_mib']:.0f} MiB, "
              f"recall@10 {r['recall@10']:.4f} ({r['recall@10_up_to_ties']:.4f} up to ties "
              f"of {TIE:g}) on {r['reference_rows']} rows")
    if args.figure:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 4))
        ax.loglog(df["n"], df["measure_s"], "o-", label="measure (one core)")
        ax.loglog(df["n"], df["nn_1thread_s"], "s-", label="nearest_neighbours, 1 thread")
        ax.loglog(df["n"], df[f"nn_{args.jobs}threads_s"], "s--",
                  label=f"nearest_neighbours, {args.jobs} threads")
        ax.loglog(df["n"], df["brute_blocked_est_s"], "x:", label="all pairs, blocked (est.)")
        ax.set_xlabel("objects")
        ax.set_ylabel("seconds")
        ax.set_title(f"k = {K} nearest neighbours, default distance (exact), {args.data}")
        ax.legend(fontsize=8)
        fig.tight_layout()
        Path(args.figure).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(args.figure, dpi=120)
        print(f"figure: {args.figure}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
