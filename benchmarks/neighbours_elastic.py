"""Nearest neighbours with the elastic outline term, against the default search, in one run.

A moving-blobs movie (as ``benchmarks/neighbours.py``: 1024², 250 deforming blobs of radius
10–16 px per frame) with at least n described objects is measured once; then, in this process
and one after the other (BLAS on one thread, numba on ``--jobs`` threads):

- ``nearest_neighbours(table, k=10)``: the default distance (the anchor);
- ``nearest_neighbours(table, k=10, elastic_weight=μ)``: the elastic term on each object's
  ``ELASTIC_CANDIDATES`` × k candidates under the other terms, timed whole for the first
  ``--candidates`` value, and for each value as its two steps: the default search for C
  neighbours (``nearest_neighbours(table, C)``), then
  :func:`napari_pfsdm.core.elastic.elastic_nearest` on them (with the rows it certifies
  exact and the d_E it computes per object);
- the recall@10 of that shortcut on ``--sample`` random queries against their exact rows
  (the default distance of the query to all objects plus μ d_E to all objects);
- the per-object cost of ``measure`` with and without the signature (its columns computed, or
  the signature replaced by a stored constant), on the first ``--measure-frames`` frames.

Run (repository root)::

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/neighbours_elastic.py \\
        --sizes 50000

Quote ratios from one run: the machine is shared, absolute times move with its load.
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

K = 10
PER_FRAME = 250


def blob_movie(n: int, seed: int):
    from napari_pfsdm.data.moving_blobs import make_moving_blobs

    frames = int(np.ceil(n / (0.96 * PER_FRAME)))
    return make_moving_blobs(n_objects=PER_FRAME, n_frames=frames, size=1024,
                             radius=(10.0, 16.0), seed=seed)


def blob_table(movie, n: int):
    """The feature table (with the signature's columns) of a movie's first n described
    objects, and their signatures."""
    import napari_pfsdm as pf
    from napari_pfsdm.analysis.tables import signatures_from_table

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = pf.drop_failed(pf.measure(movie.labels, elastic_signature="table"))
    kept = table.iloc[:n].reset_index(drop=True)
    kept.attrs = table.attrs
    return kept, signatures_from_table(kept)


def _measure_cost(labels: np.ndarray, repeats: int = 2) -> tuple[float, float]:
    """Seconds of ``measure`` on ``labels`` with the signature, and without it: the least of
    ``repeats`` runs of each, in alternation."""
    import napari_pfsdm as pf

    pf.measure(labels[:1], elastic_signature="table")  # warm up
    with_sig, without = np.inf, np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        pf.measure(labels, elastic_signature="table")
        with_sig = min(with_sig, time.perf_counter() - t0)
        t0 = time.perf_counter()
        pf.measure(labels)
        without = min(without, time.perf_counter() - t0)
    return with_sig, without


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[50000])
    ap.add_argument("--weight", type=float, default=None,
                    help="μ (default: RECOMMENDED_ELASTIC_WEIGHT)")
    ap.add_argument("--sample", type=int, default=50)
    ap.add_argument("--candidates", type=int, nargs="+", default=[4, 8, 12],
                    help="candidates per object, as multiples of k")
    ap.add_argument("--measure-frames", type=int, default=8)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)

    import numba

    import napari_pfsdm as pf
    from napari_pfsdm.analysis.neighbours import ELASTIC_CANDIDATES
    from napari_pfsdm.core.distances import RECOMMENDED_ELASTIC_WEIGHT
    from napari_pfsdm.core.elastic import elastic_distance_between, elastic_nearest

    numba.set_num_threads(args.jobs)
    mu = RECOMMENDED_ELASTIC_WEIGHT if args.weight is None else args.weight
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; k = {K}; "
          f"mu = {mu}; candidates {ELASTIC_CANDIDATES} x k; numba threads {args.jobs}")
    print("| n | measure per object, with / without signature | nn default | candidates C "
          "| search for C | elastic_nearest | nn + elastic | ratio | rows certified exact "
          "| d_E per object | recall@10 of the shortcut |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for n in args.sizes:
        movie = blob_movie(n, args.seed)
        w, wo = _measure_cost(movie.labels[: args.measure_frames])
        per = args.measure_frames * PER_FRAME
        kept, sig = blob_table(movie, n)
        # compiled here
        elastic_distance_between(sig, np.arange(20), np.arange(20)[::-1])
        elastic_nearest(sig[:20], np.tile(np.arange(1, 20), (20, 1)) % 20,
                        np.ones((20, 19)), mu, 3)
        t0 = time.perf_counter()
        pf.nearest_neighbours(kept, K, n_jobs=args.jobs)
        t_default = time.perf_counter() - t0
        t0 = time.perf_counter()
        api, _ = pf.nearest_neighbours(kept, K, n_jobs=args.jobs, elastic_weight=mu,
                                       elastic_candidates=args.candidates[0] * K)
        t_api = time.perf_counter() - t0
        found = {}
        for mult in args.candidates:
            t0 = time.perf_counter()
            cand, base = pf.nearest_neighbours(kept, mult * K, n_jobs=args.jobs)
            t_cand = time.perf_counter() - t0
            t0 = time.perf_counter()
            idx, _, computed, exact = elastic_nearest(sig, cand, base, mu, K)
            t_el = time.perf_counter() - t0
            if mult == args.candidates[0] and not np.array_equal(idx, api):
                print(f"(nearest_neighbours differs from its two steps in "
                      f"{(idx != api).any(axis=1).sum()} rows)")
            found[mult] = (idx, t_cand, t_el, computed.mean(), exact.mean())
        print(f"(nearest_neighbours(..., elastic_weight={mu}, elastic_candidates="
              f"{args.candidates[0] * K}) whole: {t_api:.1f} s)")
        # exact rows of the sampled queries: default distance to all + μ d_E to all
        rng = np.random.default_rng(args.seed)
        queries = rng.choice(len(kept), args.sample, replace=False)
        features, outline = _default_terms(kept)
        truth = {}
        for q in queries:
            row = _default_row(features, outline, q)
            row += mu * elastic_distance_between(sig, np.full(len(kept), q),
                                                 np.arange(len(kept)))
            row[q] = np.inf
            truth[q] = set(np.argsort(row, kind="stable")[:K])
        for mult, (idx, t_cand, t_el, comp, ex) in found.items():
            recall = sum(len(truth[q] & set(idx[q])) for q in queries) / (K * len(queries))
            t_elastic = t_cand + t_el
            print(f"| {n:,} | {1e3 * w / per:.2f} / {1e3 * wo / per:.2f} ms "
                  f"({w / wo:.2f}x) | {t_default:.1f} s | {mult * K} | {t_cand:.1f} s | "
                  f"{t_el:.1f} s | {t_elastic:.1f} s | {t_elastic / t_default:.2f} | {ex:.3f} | "
                  f"{comp:.1f} | {recall:.4f} ({len(queries)} rows) |", flush=True)
    return 0


def _default_terms(table) -> tuple[np.ndarray, np.ndarray]:
    """The weighted magnitude features and the outline coefficients of a table."""
    from napari_pfsdm.analysis.tables import embeddings
    from napari_pfsdm.core.distances import weighted_features

    emb = embeddings(table)
    return weighted_features(emb), emb.outline


def _default_row(features: np.ndarray, outline: np.ndarray, q: int) -> np.ndarray:
    """The default distance of row q to every row: the weighted features' Euclidean distance
    plus the boundary term (:func:`napari_pfsdm.core.boundary.boundary_distance_matrix`)."""
    from napari_pfsdm.core.boundary import boundary_distance_matrix
    from napari_pfsdm.core.distances import BOUNDARY_WEIGHT

    row = np.sqrt(((features - features[q]) ** 2).sum(axis=1))
    row += BOUNDARY_WEIGHT * boundary_distance_matrix(outline[q:q + 1], outline)[0]
    return row


if __name__ == "__main__":
    raise SystemExit(main())
