"""3-D benchmark: PF-SDM on the unit ball against moment and surface baselines.

Run from the repository root::

    .venv/bin/python benchmarks/volumes.py            # 12 classes x 8 copies, 64^3 (~2 min)
    .venv/bin/python benchmarks/volumes.py --quick    # 12 x 3 copies, 48^3 (CI-size smoke run)
    .venv/bin/python benchmarks/volumes.py --stardist STARDIST/data/images/mask3d.tif

(``STARDIST``: the stardist package unpacked from ``pip download stardist --no-deps``.)

Twelve classes of synthetic blobs (:mod:`napari_pfsdm.data.volumes`; six of them with
isotropic inertia, so that volume, inertia and sphericity cannot tell them apart), each copy
with a random rotation, a mirror image for every other copy, a 0.8-1.2x scale and smooth surface
noise. Prints, for PF-SDM (shells + surface term, the default distance; also with the
harmonic ball map), its interior shells alone, a surface-only spherical-harmonic baseline
(power of the outer surface's radial function, as in aicsshparam-like descriptors made
invariant) and the moment baseline (inertia eigenvalue
ratios and sphericity, standardised): silhouette over the 12 classes and over the six
moment-hard ones, leave-one-out 1-NN accuracy, time per object; then the invariance check (one
copy per class turned by 90 degrees about each axis and mirrored along each axis, distance to
the original over the median between-class distance) and the time per 128^3 object. Writes
``volumes_benchmark.csv`` and ``volumes_mds.png`` (classical MDS of the PF-SDM and moment
distances) to ``--out``. ``--non-star`` compares the two ball maps on four classes that are not
star-shaped; ``--stardist PATH`` adds a smoke test on a real 3-D label image.
"""

from __future__ import annotations

import os

# One BLAS/OpenMP thread: the target is one core per object, and the machine is shared.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import shlex  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from napari_pfsdm import distance_matrix, pfsdm  # noqa: E402
from napari_pfsdm.analysis.reduction import mds_coordinates  # noqa: E402
from napari_pfsdm.analysis.retrieval import loo_1nn_fraction  # noqa: E402
from napari_pfsdm.core.distances import Embeddings  # noqa: E402
from napari_pfsdm.data.volumes import (  # noqa: E402
    MOMENT_HARD,
    NON_STAR,
    blob_volume,
    make_volume_set,
)


def _euclid(f: np.ndarray) -> np.ndarray:
    d = np.sqrt(np.maximum(((f[:, None, :] - f[None, :, :]) ** 2).sum(-1), 0))
    np.fill_diagonal(d, 0)
    return d


def moment_features(result, mask: np.ndarray) -> np.ndarray:
    """Inertia eigenvalue ratios λ1/λ3, λ2/λ3 (physical, of the voxels) and the sphericity
    π^⅓ (6V)^⅔ / A of the smoothed surface."""
    pts = np.argwhere(mask) * result.spacing
    pts = pts - pts.mean(0)
    cov = pts.T @ pts / len(pts)
    lam = np.sort(np.linalg.eigvalsh(cov))[::-1]
    s = result.surface
    tri = s.verts[s.faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    sphericity = np.pi ** (1 / 3) * (6 * s.volume) ** (2 / 3) / area.sum()
    return np.array([lam[1] / lam[0], lam[2] / lam[0], sphericity])


def silhouette(d: np.ndarray, labels: np.ndarray) -> float:
    from sklearn.metrics import silhouette_score

    return float(silhouette_score(d, labels, metric="precomputed"))


def matrices(results, masks, harmonic=None) -> dict[str, np.ndarray]:
    """The distance matrices compared."""
    out = {"PF-SDM (shells + surface)": distance_matrix(results)}
    if harmonic is not None:
        out["PF-SDM, harmonic ball map"] = distance_matrix(harmonic)
    shells = Embeddings(shape=np.stack([r.embedding for r in results]),
                        weights=results[0].weights, mode_weights=results[0].mode_weights)
    out["PF-SDM interior shells only"] = distance_matrix(shells, boundary_weight=0)
    mw = results[0].mode_weights
    out["surface radial SH power"] = _euclid(np.stack([r.surface_embedding * mw
                                                       for r in results]))
    mom = np.stack([moment_features(r, m) for r, m in zip(results, masks, strict=True)])
    mom = (mom - mom.mean(0)) / np.maximum(mom.std(0), 1e-12)
    out["moments (inertia ratios, sphericity)"] = _euclid(mom)
    return out


def invariance(volumes, labels, results, d: np.ndarray) -> list[tuple[str, float]]:
    """For one copy per class: distance to its 90°-rotated and mirrored copies over the
    median between-class distance."""
    between = np.median(d[labels[:, None] != labels[None, :]])
    rows = []
    ops = {"rot90 zy": lambda v: np.rot90(v, axes=(0, 1)),
           "rot90 yx": lambda v: np.rot90(v, axes=(1, 2)),
           "rot90 zx": lambda v: np.rot90(v, axes=(0, 2)),
           "mirror z": lambda v: v[::-1], "mirror y": lambda v: v[:, ::-1],
           "mirror x": lambda v: v[:, :, ::-1]}
    firsts = [int(np.flatnonzero(labels == k)[0]) for k in np.unique(labels)]
    for name, op in ops.items():
        ratios = []
        for i in firsts:
            copy = pfsdm(np.ascontiguousarray(op(volumes[i])))
            ratios.append(distance_matrix([results[i], copy])[0, 1] / between)
        rows.append((name, float(np.max(ratios)), float(np.median(ratios))))
    return rows


def time_128(repeats: int = 3) -> list[tuple[str, float, float]]:
    """Seconds per 128³ object (median of ``repeats``), with the share spent before the ball."""
    out = []
    for name, radius in (("sphere-like (octahedron, r=40)", 40.0), ("tetrahedron (r=38)", 38.0)):
        kind = "octahedron" if name.startswith("sphere") else "tetrahedron"
        vol = blob_volume(kind, size=128, radius=radius)
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            pfsdm(vol)
            times.append(time.perf_counter() - t0)
        out.append((name, float(np.median(times)), float(vol.sum())))
    return out


def non_star(n: int, size: int, seed: int, noise: float) -> None:
    """The two ball maps on four classes that are not star-shaped from their centroid."""
    volumes, labels, names = make_volume_set(n, size=size, seed=seed, noise=noise,
                                             classes=NON_STAR)
    print(f"\nnot star-shaped: {', '.join(names)} x {n} copies, {size}^3")
    for ball_map in ("radial", "harmonic"):
        t0 = time.perf_counter()
        results = [pfsdm(v, ball_map=ball_map) for v in volumes]
        per = (time.perf_counter() - t0) / len(volumes)
        d = distance_matrix(results)
        fold = np.array([r.diagnostics["folded_fraction"] for r in results])
        print(f"  {ball_map:8s} silhouette {silhouette(d, labels):.3f}  1-NN "
              f"{loo_1nn_fraction(d, labels):.3f}  folded median {100 * np.median(fold):.1f} % "
              f"max {100 * fold.max():.1f} %  {per:.2f} s per object")


def stardist_smoke(path: str) -> None:
    import tifffile

    labels = tifffile.imread(path)
    print(f"\nstardist smoke test: {path}\n  labels {labels.shape} {labels.dtype}, "
          f"{len(np.unique(labels)) - 1} labels")
    from napari_pfsdm import measure

    for spacing in ((1.0, 1.0, 1.0), (2.0, 1.0, 1.0)):
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            table = measure(labels, axes="zyx", spacing=spacing)
        dt = time.perf_counter() - t0
        ok = table[table["error"] == ""]
        fold = ok["folded_fraction"]
        print(f"  spacing {spacing}: {len(table)} objects, {len(ok)} described in {dt:.1f} s "
              f"({dt / max(len(table), 1):.3f} s each); errors: "
              f"{sorted(set(table.loc[table['error'] != '', 'error'].str[:60]))}")
        print(f"    touching the border {int(table['touches_border'].sum())}, "
              f"folded > 0: {int((fold > 0).sum())}, > 5 %: {int((fold > 0.05).sum())} "
              f"(max {100 * fold.max():.1f} %), rays crossing twice > 0: "
              f"{int((ok['crossing_fraction'] > 0).sum())}; volumes "
              f"{int(table['volume'].min())}-{int(table['volume'].max())} voxels")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="benchmarks/out", help="output folder")
    parser.add_argument("--quick", action="store_true", help="3 copies per class at 48^3")
    parser.add_argument("--n-per-class", type=int, default=None)
    parser.add_argument("--size", type=int, default=None, help="volumes are size^3 voxels")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--noise", type=float, default=0.04)
    parser.add_argument("--non-star", dest="non_star", action="store_true",
                        help="also compare the ball maps on four classes that are not "
                             "star-shaped")
    parser.add_argument("--stardist", metavar="MASK3D.tif",
                        help="also measure this real 3-D label image (read by path)")
    args = parser.parse_args(argv)
    n = args.n_per_class or (3 if args.quick else 8)
    size = args.size or (48 if args.quick else 64)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print("command: " + " ".join(shlex.quote(a) for a in [sys.executable, *sys.argv]))
    start = time.perf_counter()

    volumes, labels, names = make_volume_set(n, size=size, seed=args.seed, noise=args.noise)
    t_gen = time.perf_counter() - start
    t0 = time.perf_counter()
    results = [pfsdm(v) for v in volumes]
    per_object = (time.perf_counter() - t0) / len(volumes)
    t0 = time.perf_counter()
    harmonic = [pfsdm(v, ball_map="harmonic") for v in volumes]
    per_object_h = (time.perf_counter() - t0) / len(volumes)
    folded = max(r.diagnostics["folded_fraction"] for r in results)
    folded_h = max(r.diagnostics["folded_fraction"] for r in harmonic)
    crossing = max(r.diagnostics["crossing_fraction"] for r in results)
    mats = matrices(results, volumes, harmonic)
    hard = np.isin(np.array(names)[labels], MOMENT_HARD)

    print(f"\n{len(names)} classes x {n} copies, {size}^3 voxels, noise {args.noise}, seed "
          f"{args.seed} (generated in {t_gen:.0f} s); PF-SDM {per_object:.3f} s per object "
          f"(one core; harmonic ball map {per_object_h:.3f} s); folded fraction max "
          f"{100 * folded:.1f} % (harmonic map {100 * folded_h:.1f} %), rays crossing twice "
          f"max {100 * crossing:.1f} %\n")
    header = f"{'method':40s} {'silhouette':>10s} {'sil. 6 hard':>11s} {'1-NN':>6s}"
    print(header)
    print("-" * len(header))
    rows = []
    for name, d in mats.items():
        sil = silhouette(d, labels)
        sil_hard = silhouette(d[np.ix_(hard, hard)], labels[hard])
        nn = loo_1nn_fraction(d, labels)
        rows.append((name, sil, sil_hard, nn))
        print(f"{name:40s} {sil:10.3f} {sil_hard:11.3f} {nn:6.3f}")

    inv = invariance(volumes, labels, results, mats["PF-SDM (shells + surface)"])
    print("\ninvariance (one copy per class; distance / median between-class distance)")
    for name, worst, med in inv:
        print(f"  {name:10s} max {100 * worst:5.1f} %   median {100 * med:5.1f} %")
    timing = [] if args.quick else time_128()
    for name, secs, vox in timing:
        print(f"128^3 {name}: {secs:.2f} s per object ({vox:.0f} voxels)")

    import pandas as pd

    table = pd.DataFrame(rows, columns=["method", "silhouette", "silhouette_moment_hard",
                                        "loo_1nn"])
    table.to_csv(out / "volumes_benchmark.csv", index=False)
    _plot(mats, labels, names, out / "volumes_mds.png")
    print(f"\nwrote {out / 'volumes_benchmark.csv'} and {out / 'volumes_mds.png'}")
    if args.non_star:
        non_star(n, size, args.seed, args.noise)
    if args.stardist:
        stardist_smoke(args.stardist)
    print(f"total {time.perf_counter() - start:.0f} s")
    return 0


def _plot(mats, labels, names, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = ["PF-SDM (shells + surface)", "moments (inertia ratios, sphericity)"]
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.5))
    cmap = plt.get_cmap("tab20")
    for ax, key in zip(axes, keys, strict=True):
        xy = mds_coordinates(mats[key])
        for k, name in enumerate(names):
            sel = labels == k
            hard = name in MOMENT_HARD
            ax.scatter(xy[sel, 0], xy[sel, 1], s=28, color=cmap(k), marker="o" if hard else "^",
                       label=name + (" *" if hard else ""))
        ax.set_title(f"{key}: classical MDS")
        ax.set_xticks([])
        ax.set_yticks([])
    axes[1].legend(fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5),
                   title="* isotropic inertia")
    fig.suptitle("3-D synthetic classes: PF-SDM on the unit ball vs moments")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
