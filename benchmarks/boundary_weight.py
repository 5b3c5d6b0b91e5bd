"""The boundary term's weight λ in D = d_SDF + λ · d_B, on four kinds of shape set at once.

Run from the repository root (about 3 minutes on one core)::

    .venv/bin/python benchmarks/boundary_weight.py

For each set the two terms are computed once (``distance_matrix(results, boundary_weight=0)``
and :func:`~napari_pfsdm.core.boundary.boundary_distance_matrix` of the results' outlines),
then combined for λ in ``--weights``; "boundary only" is d_B alone (outline Procrustes). Sets:

* MPEG-7 (1,400 silhouettes, ``benchmarks/mpeg7.py``'s preprocessing): bull's-eye in percent;
* the five-shape set, exact and perturbed copies (10 per class, 256 px): silhouette;
* synthetic gastruloids at frame 24 (``data.gastruloids``, 78 objects, single against multiple
  axes, ``--gastruloid-seeds`` generated sets): silhouette, with mirror-aware EFA and GPA
  (``analysis.baselines``) in the same run.

Prints the score and the leave-one-out 1-NN of every (set, λ) and writes
``boundary_weight.csv`` and ``boundary_weight.png`` to ``--out``. The library's λ is
``core.distances.BOUNDARY_WEIGHT``.
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
import pandas as pd  # noqa: E402
from sklearn.metrics import silhouette_score  # noqa: E402

import napari_pfsdm as P  # noqa: E402
from napari_pfsdm.analysis import baselines as B  # noqa: E402
from napari_pfsdm.analysis.retrieval import bullseye, loo_1nn  # noqa: E402
from napari_pfsdm.core.boundary import boundary_distance_matrix  # noqa: E402
from napari_pfsdm.core.distances import BOUNDARY_WEIGHT  # noqa: E402
from napari_pfsdm.data import shapes as S  # noqa: E402
from napari_pfsdm.data.gastruloids import make_gastruloids  # noqa: E402

BOUNDARY_ONLY = "boundary only"


def _symmetric(D: np.ndarray) -> np.ndarray:
    D = (D + D.T) / 2
    np.fill_diagonal(D, 0.0)
    return D


def terms(masks) -> tuple[np.ndarray, np.ndarray]:
    """The SDF term and the boundary term of the default distance, for a list of masks."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        results = [P.pfsdm(m) for m in masks]
    sdf = P.distance_matrix(results, boundary_weight=0)
    boundary = boundary_distance_matrix(np.stack([r.outline for r in results]))
    return sdf, boundary


def load_sets(mpeg7_folder: Path, gastruloid_seeds: int):
    """(name, score kind, masks, labels) of every set."""
    sys.path.insert(0, str(Path(__file__).parent))
    import mpeg7

    masks, labels, _ = mpeg7.load_masks(mpeg7_folder)[:3]
    sets = [("MPEG-7", "bull's-eye %", list(masks), np.asarray(labels))]
    for perturb in (False, True):
        m, y, _ = S.make_benchmark_set(10, perturb=perturb, seed=0, size=256)
        sets.append((f"five shapes, {'perturbed' if perturb else 'exact'}", "silhouette", m, y))
    for seed in range(gastruloid_seeds):
        g = make_gastruloids(seed=seed)
        m = [g.labels[i, 24] == 1 for i in range(len(g.multi_axis))]
        sets.append((f"gastruloids, seed {seed}", "silhouette", m, g.multi_axis.astype(int)))
    return sets


def score(D: np.ndarray, labels, kind: str) -> float:
    if kind == "silhouette":
        return float(silhouette_score(D, labels, metric="precomputed"))
    return float(bullseye(D, labels).score)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mpeg7", type=Path, default=Path("../shared/data/mpeg7"))
    ap.add_argument("--out", type=Path, default=Path("benchmarks/out"))
    ap.add_argument("--weights", type=float, nargs="*", default=[0, 0.5, 1, 1.5, 2, 3, 5])
    ap.add_argument("--gastruloid-seeds", type=int, default=3)
    args = ap.parse_args(argv)

    rows = []
    for name, kind, masks, labels in load_sets(args.mpeg7, args.gastruloid_seeds):
        sdf, boundary = terms(masks)
        candidates = [(f"{w:g}", sdf + w * boundary) for w in args.weights]
        candidates.append((BOUNDARY_ONLY, boundary))
        if kind == "silhouette":
            candidates += [("EFA mirror-aware", B.efa_distance_matrix(masks, mirror_aware=True)),
                           ("GPA", B.gpa_distance_matrix(masks))]
        for weight, D in candidates:
            D = _symmetric(D)
            rows.append({"set": name, "score kind": kind, "lambda": weight,
                         "score": score(D, labels, kind), "1-NN": loo_1nn(D, labels)})
        print(f"{name}: done", flush=True)
    table = pd.DataFrame(rows)
    order = [f"{w:g}" for w in args.weights] + [BOUNDARY_ONLY, "EFA mirror-aware", "GPA"]
    for value, what in (("score", "MPEG-7: bull's-eye %; the other sets: silhouette"),
                        ("1-NN", "leave-one-out 1-NN %")):
        wide = table.pivot(index="lambda", columns="set", values=value).reindex(order)
        print(f"\n{what} (library λ = {BOUNDARY_WEIGHT:g})")
        print(wide[table["set"].unique()].to_string(float_format=lambda v: f"{v:.3f}"))
    args.out.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.out / "boundary_weight.csv", index=False)
    plot(table, args.weights, args.out / "boundary_weight.png")
    print(f"\nwrote {args.out / 'boundary_weight.csv'} and {args.out / 'boundary_weight.png'}")
    return 0


def plot(table: pd.DataFrame, weights: list[float], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sets = list(table["set"].unique())
    fig, axes = plt.subplots(1, len(sets), figsize=(2.6 * len(sets), 3.0), sharex=True)
    for ax, name in zip(np.atleast_1d(axes), sets, strict=True):
        sub = table[table["set"] == name].set_index("lambda")
        ax.plot(weights, [sub.loc[f"{w:g}", "score"] for w in weights], "o-", color="C0",
                label="SDF + λ·boundary")
        for ref, colour in ((BOUNDARY_ONLY, "C1"), ("EFA mirror-aware", "C2"), ("GPA", "C3")):
            if ref in sub.index:
                ax.axhline(sub.loc[ref, "score"], color=colour, ls="--", lw=1, label=ref)
        ax.axvline(BOUNDARY_WEIGHT, color="0.6", lw=0.8)
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("λ")
        ax.set_ylabel(sub["score kind"].iloc[0])
    np.atleast_1d(axes)[-1].legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
