"""MPEG-7: the re-ranking's settings, chosen by leave-classes-out cross-validation.

Run from the repository root (after ``benchmarks/mpeg7_elastic.py``, whose cached features and
distances it reads, or computes the same way)::

    .venv/bin/python benchmarks/mpeg7_rerank.py

For the default distance D_PF and for D_PF + μ D_E (the elastic term at
``RECOMMENDED_ELASTIC_WEIGHT``), and for two variants of :func:`napari_pfsdm.rerank`:

- ``"tpg"``: sharpness (the affinities' exponent) ∈ {2, 1/0.35, 4, 1/0.15}, k ∈ {8, 10, 12,
  15}, steps ∈ {10, 20};
- ``"diffusion"``: k ∈ {5, 8, 10, 12, 15}, steps ∈ {1, 2, 3};

each of ``--seeds`` random splits of the 70 classes into two halves of 35 picks the setting
with the best bull's-eye among one half's 700 shapes and scores it on the other half's (the
halves swapped: 22 held-out scores). The table gives, per variant, the setting chosen most
often (and how often each value of each parameter was chosen), the mean held-out
bull's-eye, and that setting scored on the whole collection (bull's-eye and 1-NN), beside
the library's defaults.
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
from collections import Counter
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "2")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import mpeg7  # noqa: E402
import mpeg7_elastic  # noqa: E402
from napari_pfsdm.analysis.rerank import rerank  # noqa: E402
from napari_pfsdm.analysis.retrieval import bullseye, loo_1nn  # noqa: E402
from napari_pfsdm.core.distances import RECOMMENDED_ELASTIC_WEIGHT  # noqa: E402

GRIDS = {
    "tpg": [dict(sharpness=s, k=k, steps=t)
            for s, k, t in itertools.product((2.0, 1 / 0.35, 4.0, 1 / 0.15), (8, 10, 12, 15),
                                             (10, 20))],
    "diffusion": [dict(k=k, steps=t) for k, t in itertools.product((5, 8, 10, 12, 15),
                                                                   (1, 2, 3))],
}


def _key(setting: dict) -> str:
    return ", ".join(f"{k} {v:.3g}" for k, v in setting.items())


def held_out(d: np.ndarray, labels: np.ndarray, method: str, seeds: int) -> list[tuple]:
    """(chosen setting, held-out bull's-eye) for each split and each half fitted."""
    classes = np.unique(labels)
    grid = GRIDS[method]
    rows = []
    for seed in range(seeds):
        perm = np.random.default_rng(seed).permutation(classes)
        halves = [np.isin(labels, perm[: len(classes) // 2]),
                  np.isin(labels, perm[len(classes) // 2:])]
        scores = []
        for h in halves:
            ix = np.ix_(h, h)
            scores.append([bullseye(rerank(d[ix], method, **g), labels[h]).score
                           for g in grid])
        for fit, test in ((0, 1), (1, 0)):
            best = int(np.argmax(scores[fit]))
            rows.append((_key(grid[best]), grid[best], scores[test][best]))
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("folder", nargs="?", type=Path, default=mpeg7.DEFAULT_FOLDER)
    ap.add_argument("--seeds", type=int, default=11)
    args = ap.parse_args(argv)
    masks, labels, _, _ = mpeg7.load_masks(args.folder)
    f = mpeg7_elastic.features(masks, True)
    c = mpeg7_elastic.components(f, [(3.0, 5)], True)
    mu = RECOMMENDED_ELASTIC_WEIGHT
    distances = {"D_PF": c["D_PF"], f"D_PF + {mu} D_E": mpeg7_elastic.combined(c, (3.0, 5),
                                                                               mu, 0.0)}
    print("| distance | re-ranking | chosen most often (of 22 halves) | held-out bull's-eye "
          "(mean) | that setting, whole set: bull's-eye | 1-NN |")
    print("|---|---|---|---|---|---|")
    for name, d in distances.items():
        print(f"| {name} | none | | | {bullseye(d, labels).score:.2f} % | "
              f"{loo_1nn(d, labels):.2f} % |")
        for method in GRIDS:
            r = rerank(d, method)
            print(f"| {name} | {method}, the library's defaults | | | "
                  f"{bullseye(r, labels).score:.2f} % | {loo_1nn(r, labels):.2f} % |",
                  flush=True)
            rows = held_out(d, labels, method, args.seeds)
            key, n_times = Counter(r[0] for r in rows).most_common(1)[0]
            setting = next(r[1] for r in rows if r[0] == key)
            r = rerank(d, method, **setting)
            each = "; ".join(
                f"{p} " + ", ".join(f"{v:.3g} ×{c}" for v, c in
                                    Counter(r_[1][p] for r_ in rows).most_common())
                for p in setting)
            print(f"| {name} | {method} | {key} ({n_times}; {each}) | "
                  f"{np.mean([r_[2] for r_ in rows]):.2f} % | {bullseye(r, labels).score:.2f} % "
                  f"| {loo_1nn(r, labels):.2f} % |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
