"""2-D maps drawn from a neighbour graph, and re-ranking on it, scored on MPEG-7.

Above :data:`napari_pfsdm.analysis.reduction.FULL_MATRIX_LIMIT` objects ``pfsdm compare --mds``
does not compute the n x n matrix: it draws its map from the k-nearest-neighbour graph. Which
embedding of that graph keeps the kinds of shapes apart best? Run from the repository root::

    .venv/bin/python benchmarks/neighbour_maps.py              # MPEG-7 at ../shared/data/mpeg7
    .venv/bin/python benchmarks/neighbour_maps.py FOLDER --k 10 15 30
    .venv/bin/python benchmarks/neighbour_maps.py --scale 10000   # time the maps at that size

MPEG-7 CE-Shape-1 (1,400 silhouettes, 70 classes of 20) is read by path with the preprocessing
of ``benchmarks/mpeg7.py`` (never copied into the project); each shape is measured with the
default options and the graph is each object's K nearest under the default PF-SDM distance
(:func:`napari_pfsdm.nearest_neighbours` when present, else the exact ``argsort`` of the full
matrix: the same graph). Maps:

``MDS (full matrix)``
    classical MDS of the full n x n matrix: what ``compare --mds`` draws below the limit.
``spectral``
    scikit-learn ``SpectralEmbedding(affinity="precomputed")`` of the locally scaled Gaussian
    affinities on the graph, w_ij = exp(-d_ij / (σ_i σ_j)) with σ_i² the distance to the K-th
    neighbour (the PF-SDM distance is a squared Euclidean one: d = ‖x_i − x_j‖²).
``t-SNE``
    scikit-learn ``TSNE(metric="precomputed", init="random")`` on the sparse distance graph
    (the distances as they are: t-SNE's Gaussian takes squared distances), perplexity
    (K − 2) / 3, the largest its neighbour count allows, 500 iterations (K = 15: 93.6 % 5-NN
    in 10 s; 1,000 iterations 93.5 % in 24 s).
``UMAP``
    umap-learn ``UMAP(metric="precomputed")`` on the sparse graph of √d (a metric), when
    umap-learn is installed (the optional extra ``umap``: it pulls numba); its first call
    includes numba's compilation.

All three are :func:`napari_pfsdm.analysis.reduction.graph_coordinates`, what ``pfsdm compare
--mds --map METHOD`` draws.

Scores in the 2-D map against the 70 classes: leave-one-out 5-NN and 1-NN classification
accuracy (how often a point's neighbours in the picture are its kind) and the silhouette;
seconds for the embedding alone (the graph given). A second table compares the bull's-eye of
re-ranking (diffusion, k = 10) on the full matrix and on neighbour graphs
(:func:`napari_pfsdm.analysis.rerank.rerank_neighbours`: 40 re-ranked neighbours per object,
the rest of the row counted as misses), with the share of objects whose 40 (or 10) re-ranked
neighbours are certified equal to the full route's, and the share whose 10 actually are.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "2")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import mpeg7  # noqa: E402  (its reader and preprocessing)

CACHE = mpeg7.CACHE_DIR / "neighbour_maps_D.npz"


def mpeg7_distances(folder: Path):
    """Default PF-SDM distances of the 1,400 MPEG-7 shapes and their classes (cached in the
    temp folder, outside the repository), the measuring and matrix seconds."""
    import napari_pfsdm as pf

    masks, labels, _names, _ = mpeg7.load_masks(folder)
    if CACHE.exists():
        z = np.load(CACHE)
        if len(z["D"]) == len(masks):
            print(f"distances read from the cache {CACHE}")
            return z["D"], labels, float(z["t_measure"]), float(z["t_matrix"]), None
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        results = [pf.pfsdm(m) for m in masks]
    t_measure = time.perf_counter() - t0
    t0 = time.perf_counter()
    D = pf.distance_matrix(results)
    t_matrix = time.perf_counter() - t0
    CACHE.parent.mkdir(parents=True, exist_ok=True)
    np.savez(CACHE, D=D, t_measure=t_measure, t_matrix=t_matrix)
    return D, labels, t_measure, t_matrix, results


def knn_graph(D: np.ndarray, K: int, results=None):
    """(indices, distances, how): the K nearest of each object, itself excluded."""
    if results is not None:
        try:
            from napari_pfsdm import nearest_neighbours
        except ImportError:
            pass
        else:
            idx, dist = nearest_neighbours(results, k=K)
            return np.asarray(idx), np.asarray(dist), "nearest_neighbours"
    order = np.argsort(D + np.diag(np.full(len(D), np.inf)), axis=1)[:, :K]
    return order, np.take_along_axis(D, order, axis=1), "argsort of the full matrix"


def embed(method: str):
    """The map as ``pfsdm compare --mds`` draws it above the limit (the library's function)."""
    from napari_pfsdm.analysis.reduction import graph_coordinates

    def run(idx, dist):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return graph_coordinates(idx, dist, method)

    return run


def scores(xy: np.ndarray, labels) -> dict:
    from sklearn.metrics import silhouette_score

    d2 = ((xy[:, None] - xy[None]) ** 2).sum(-1)
    np.fill_diagonal(d2, np.inf)
    order = np.argsort(d2, axis=1)[:, :5]
    lab = np.asarray(labels)
    nn_lab = lab[order]
    acc1 = float((nn_lab[:, 0] == lab).mean())
    votes = []
    for row in nn_lab:
        names, counts = np.unique(row, return_counts=True)
        best = names[counts == counts.max()]
        votes.append(row[0] if len(best) > 1 and row[0] in best else best[0])
    acc5 = float((np.array(votes) == lab).mean())
    return {"5-NN": acc5, "1-NN": acc1, "silhouette": float(silhouette_score(xy, lab))}


def rerank_table(D, labels, ks=(30, 40, 60, 100)):
    from napari_pfsdm.analysis.rerank import rerank, rerank_neighbours
    from napari_pfsdm.analysis.retrieval import bullseye

    n = len(D)
    off = ~np.eye(n, dtype=bool)
    med = float(np.median(D[off]))
    rows = []
    t0 = time.perf_counter()
    full = rerank(D, "diffusion", k=10)
    full_top = np.argsort(full + np.diag(np.full(n, np.inf)), axis=1)[:, :10]
    # compared by value: MPEG-7 holds identical images (144 zero distances), whose re-ranked
    # distances tie exactly, and ties may come in any order
    full_top_d = np.take_along_axis(full, full_top, axis=1)
    rows.append(("full matrix (rerank)", bullseye(full, labels).score,
                 time.perf_counter() - t0, float("nan"), float("nan"), float("nan")))
    rng = np.random.default_rng(0)
    sample = rng.choice(n, size=min(400, n), replace=False)
    sub = D[np.ix_(sample, sample)]
    med_est = float(np.median(sub[~np.eye(len(sample), dtype=bool)]))
    for K in ks:
        order = np.argsort(D + np.diag(np.full(n, np.inf)), axis=1)[:, :K]
        dist = np.take_along_axis(D, order, axis=1)
        for what, scale in (("median of all pairs", med), ("median of 400 objects", med_est)):
            be = ex40 = float("nan")  # the bull's-eye needs the 40 nearest
            if K >= 40:
                idx, rd, exact = rerank_neighbours(order, dist, "diffusion", k=10,
                                                   scale=scale, n_neighbours=40,
                                                   return_exact=True)
                m = np.full((n, n), 10.0)  # the 40 returned, then everything else
                np.put_along_axis(m, idx, rd, axis=1)
                np.fill_diagonal(m, 0.0)
                be, ex40 = bullseye(m, labels).score, 100 * exact.mean()
            t0 = time.perf_counter()
            i10, d10, ex10 = rerank_neighbours(order, dist, "diffusion", k=10, scale=scale,
                                               n_neighbours=10, return_exact=True)
            dt = time.perf_counter() - t0
            got = np.sort(np.take_along_axis(full, i10, axis=1), axis=1)  # full route's values
            same10 = np.isclose(got, full_top_d, rtol=1e-9, atol=0).all(axis=1).mean()
            rows.append((f"graph K = {K}, scale: {what}", be, dt, ex40,
                         100 * ex10.mean(), 100 * same10))
    return rows, med, med_est


def time_at_scale(n: int, k: int = 15) -> None:
    """Seconds of each map of a k-neighbour graph of n points (70 Gaussian blobs in 20-D,
    squared Euclidean distances as the PF-SDM distance is): how the maps grow with n."""
    from sklearn.neighbors import NearestNeighbors

    rng = np.random.default_rng(0)
    centres = rng.normal(size=(70, 20)) * 3
    x = centres[rng.integers(0, 70, n)] + rng.normal(size=(n, 20))
    d, i = NearestNeighbors(n_neighbors=k + 1).fit(x).kneighbors(x)
    idx, dist = i[:, 1:], d[:, 1:] ** 2
    print(f"\n{n:,} points, {k}-neighbour graph\n\n| map | seconds |\n|---|---|")
    for name in ("spectral", "tsne", "umap"):
        try:
            t0 = time.perf_counter()
            embed(name)(idx, dist)
            print(f"| {name} | {time.perf_counter() - t0:.1f} |", flush=True)
        except ValueError as exc:  # umap-learn not installed
            print(f"| {name} | ({exc}) |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("folder", nargs="?", type=Path, default=mpeg7.DEFAULT_FOLDER)
    ap.add_argument("--k", type=int, nargs="+", default=[10, 15, 30],
                    help="neighbours per object in the graph")
    ap.add_argument("--scale", type=int, metavar="N",
                    help="only time the maps on a synthetic graph of N points")
    args = ap.parse_args(argv)
    if args.scale:
        time_at_scale(args.scale)
        return 0
    D, labels, t_measure, t_matrix, results = mpeg7_distances(args.folder)
    n = len(D)
    print(f"MPEG-7: {n} shapes, {len(set(labels))} classes; measured in {t_measure:.1f} s, "
          f"full matrix in {t_matrix:.1f} s")
    from napari_pfsdm.analysis.reduction import mds_coordinates

    methods = {"spectral": embed("spectral"), "t-SNE": embed("tsne")}
    try:
        import umap  # noqa: F401
    except ImportError:
        print('umap-learn is not installed: UMAP left out (pip install -e ".[umap]")')
    else:
        methods["UMAP"] = embed("umap")
    table = []
    t0 = time.perf_counter()
    xy = mds_coordinates(D)
    table.append(("MDS (full matrix)", "all", time.perf_counter() - t0, scores(xy, labels)))
    for K in args.k:
        idx, dist, how = knn_graph(D, K, results)
        for name, fn in methods.items():
            t0 = time.perf_counter()
            xy = fn(idx, dist)
            table.append((name, str(K), time.perf_counter() - t0, scores(xy, labels)))
            print(f"  {name}, K = {K}: done", flush=True)
    print(f"\ngraph: {how}\n")
    print("| map | K | 5-NN in 2-D | 1-NN in 2-D | silhouette | seconds |")
    print("|---|---|---|---|---|---|")
    for name, K, dt, s in table:
        print(f"| {name} | {K} | {100 * s['5-NN']:.1f} % | {100 * s['1-NN']:.1f} % | "
              f"{s['silhouette']:.3f} | {dt:.2f} |")
    rows, med, med_est = rerank_table(D, labels)
    print(f"\nre-ranking (diffusion, k = 10), bull's-eye of the 40 nearest; median distance "
          f"{med:.4g} (all pairs), {med_est:.4g} (400 random objects)\n")
    print("| route | bull's-eye | seconds | 40 nearest certified = full route | 10 nearest "
          "certified | 10 nearest = full route (ties aside) |")
    print("|---|---|---|---|---|---|")

    def pct(v):
        return "—" if np.isnan(v) else f"{v:.1f} %"

    for name, be, dt, ex, ex10, same10 in rows:
        print(f"| {name} | {pct(be)} | {dt:.2f} | {pct(ex)} | {pct(ex10)} | {pct(same10)} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
