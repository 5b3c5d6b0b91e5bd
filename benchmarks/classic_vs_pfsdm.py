"""Classic measures against PF-SDM, and both together.

Run from the repository root::

    .venv/bin/python benchmarks/classic_vs_pfsdm.py --out benchmarks/out           # full (~1 min)
    .venv/bin/python benchmarks/classic_vs_pfsdm.py --out benchmarks/out --quick   # smoke run

One run scores three methods on three data sets and prints one table (dataset, method, score,
spread, time); it writes ``classic_vs_pfsdm.csv`` and ``classic_vs_pfsdm.png`` to ``--out``.

Methods
-------
classic
    The classic measures of :mod:`napari_pfsdm.analysis.classic` (scikit-image's
    ``regionprops``). On MPEG-7 and the five shapes the task is scale invariant (a class holds
    objects of every size), so only the **scale-free** measures are used: ``eccentricity``,
    ``solidity``, ``circularity`` and the axis ratio ``axis_minor_length / axis_major_length``
    (``area``, ``perimeter`` and the axis lengths would only add the object's size). Each
    column is standardised over the collection (no labels used) and objects are compared by
    the Euclidean distance of these z-scores. On the gastruloids size and brightness are
    evidence, so ``predict_outcome``'s "classic" channel is used as it is: every classic
    column of the table (area, perimeter, axis lengths, the four above and the reporter's
    mean, integrated intensity and polarity).
PF-SDM
    The library's default distance (``napari_pfsdm.distance_matrix``: SDF magnitudes +
    boundary term) on MPEG-7 and the five shapes; on the gastruloids ``predict_outcome``'s
    fusion of the shape and intensity channels (``channels=["shape", "intensity"]``).
both
    MPEG-7 and five shapes: ``D = w · D_classic / median(D_classic) + (1 − w) · D_PFSDM /
    median(D_PFSDM)`` (medians over the off-diagonal pairs). ``w`` is chosen on the grid
    0, 0.05, …, 1 on data not scored with it: on MPEG-7 by a 2-fold split of the 70 classes
    (the weight used for the queries of one half is the one with the best bull's-eye for the
    queries of the other half, retrieving among all 1,400 shapes), on the five shapes on a
    second, independently drawn set (seed + 1) of the same kind, by its silhouette. On the
    gastruloids ``predict_outcome``'s "fused" with the three channels (shape, intensity,
    classic); its fusion weights are chosen inside each training split, never on the test
    split.

Scores
------
MPEG-7 CE-Shape-1 (``benchmarks/mpeg7.py``'s loader and preprocessing; read from
``../shared/data/mpeg7``, never copied): bull's-eye in % (40 nearest, query included), spread =
standard deviation of the per-class bull's-eye over the 70 classes (how uneven it is, not an
uncertainty). Five shapes (``examples/synthetic_five_shapes.py``, exact and
perturbed sets, 10 per class): silhouette with the five classes and leave-one-out 1-NN
accuracy, as the five-shape benchmark reports them (no spread). Gastruloids (the generator as
``gastruloid_report`` uses it: 78 objects × 25 frames of 128², seed 0, frames 0–9):
``predict_outcome`` balanced accuracy, mean ± standard deviation over 10 stratified splits
(5 × 20 % test, 2 repeats). Time: wall seconds of the method end to end on that data set
(descriptors or measures, distances, weight choice or fits); data generation and loading are
not counted.
"""

from __future__ import annotations

import os

# BLAS threads: at most 2 (2 cores shared), set before numpy is imported
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "examples"))  # the paper's reproductions

#: The scale-free classic measures used where size must not matter (MPEG-7, five shapes).
SCALE_FREE = ("eccentricity", "solidity", "circularity", "axis_ratio")
#: Grid of the classic weight ``w`` of the combined distance.
WEIGHTS = np.round(np.linspace(0.0, 1.0, 21), 4)
METHODS = ("classic", "PF-SDM", "both")
COLUMNS = ["dataset", "method", "score", "score_name", "spread", "spread_name", "time_s",
           "notes"]


# =========================================================================== shared pieces
def scale_free_measures(masks) -> np.ndarray:
    """The scale-free classic measures of each mask.

    Parameters
    ----------
    masks : sequence of ndarray of bool
        One object per mask.

    Returns
    -------
    ndarray, (n, 4)
        ``eccentricity``, ``solidity``, ``circularity`` and ``axis_minor_length /
        axis_major_length`` (:data:`SCALE_FREE`), from
        :func:`napari_pfsdm.analysis.classic.classic_measures`.
    """
    from napari_pfsdm.analysis.classic import classic_measures

    rows = []
    for m in masks:
        c = classic_measures(m)
        major = c["axis_major_length"]
        ratio = c["axis_minor_length"] / major if major > 0 else np.nan
        rows.append([c["eccentricity"], c["solidity"], c["circularity"], ratio])
    return np.asarray(rows, float)


def classic_distance(x: np.ndarray) -> np.ndarray:
    """Euclidean distances of the columns standardised over the collection.

    Parameters
    ----------
    x : ndarray, (n, k)
        One row of measures per object (NaN replaced by the column mean).

    Returns
    -------
    ndarray, (n, n)
        Pairwise distances of the z-scores (a constant column is left out).
    """
    from scipy.spatial.distance import cdist

    x = np.asarray(x, float)
    mean = np.nanmean(x, axis=0)
    x = np.where(np.isfinite(x), x, mean)
    sd = x.std(axis=0)
    keep = sd > 0
    z = (x[:, keep] - mean[keep]) / sd[keep]
    return cdist(z, z)


def _median_offdiag(d: np.ndarray) -> float:
    iu = np.triu_indices(d.shape[0], 1)
    med = float(np.median(d[iu]))
    return med if med > 0 else 1.0


def normalised_pair(d_classic: np.ndarray, d_pfsdm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Both distance matrices divided by their median off-diagonal distance.

    Parameters
    ----------
    d_classic, d_pfsdm : ndarray, (n, n)
        The classic and the PF-SDM distances of the same objects.

    Returns
    -------
    (ndarray, ndarray)
        The two matrices, each with median pairwise distance 1.
    """
    return d_classic / _median_offdiag(d_classic), d_pfsdm / _median_offdiag(d_pfsdm)


def combined(dc: np.ndarray, dp: np.ndarray, w: float) -> np.ndarray:
    """``w · dc + (1 − w) · dp`` (both already normalised by :func:`normalised_pair`)."""
    return w * dc + (1.0 - w) * dp


def _row(dataset, method, score, score_name, spread, spread_name, seconds, notes=""):
    return {"dataset": dataset, "method": method, "score": float(score),
            "score_name": score_name, "spread": float(spread), "spread_name": spread_name,
            "time_s": float(seconds), "notes": notes}


# =========================================================================== MPEG-7
def run_mpeg7(folder: Path, n_classes: int, processes: int) -> list[dict]:
    """Bull's-eye of classic, PF-SDM and both on MPEG-7 CE-Shape-1.

    Parameters
    ----------
    folder : Path
        The folder of MPEG-7 ``.gif`` files (read, never copied).
    n_classes : int
        Use only the first ``n_classes`` classes (sorted names); 0 = all 70.
    processes : int
        Worker processes for the PF-SDM descriptors.

    Returns
    -------
    list of dict
        One row per method.
    """
    import mpeg7
    import napari_pfsdm
    from napari_pfsdm.analysis.retrieval import bullseye

    masks, labels, _, _ = mpeg7.load_masks(folder)
    classes = sorted(set(labels))
    if n_classes:
        keep = np.isin(labels, classes[:n_classes])
        masks = [m for m, k in zip(masks, keep, strict=True) if k]
        labels = labels[keep]
        classes = classes[:n_classes]
    name = f"MPEG-7 ({len(masks)} shapes, {len(classes)} classes)"
    print(f"[{name}] classic measures ...", flush=True)
    t0 = time.perf_counter()
    x = scale_free_measures(masks)
    dc = classic_distance(x)
    t_classic = time.perf_counter() - t0

    print(f"[{name}] PF-SDM defaults on {processes} process(es) ...", flush=True)
    t0 = time.perf_counter()
    mpeg7._PFSDM_KW.clear()
    res, _, _ = mpeg7.describe(mpeg7._pfsdm_one_slim, masks, processes)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dp = np.asarray(napari_pfsdm.distance_matrix(res), float)
    t_pfsdm = time.perf_counter() - t0

    # both: the weight for one half of the classes is chosen on the queries of the other half
    t0 = time.perf_counter()
    dcn, dpn = normalised_pair(dc, dp)
    half = np.isin(labels, classes[0::2])
    per_w = np.array([bullseye(combined(dcn, dpn, w), labels).per_query for w in WEIGHTS])
    chosen = {}
    per_query = np.empty(len(labels))
    for tune, score, which in ((~half, half, "even"), (half, ~half, "odd")):
        k = int(np.argmax(per_w[:, tune].mean(axis=1)))
        chosen[which] = float(WEIGHTS[k])
        per_query[score] = per_w[k, score]
    t_both = t_classic + t_pfsdm + time.perf_counter() - t0
    w_text = (f"w = {chosen['even']:.2f} for the even-indexed classes (chosen on the odd "
              f"ones), {chosen['odd']:.2f} for the odd ones (chosen on the even ones)")
    print(f"[{name}] both: {w_text}")

    rows = []
    spread_name = "sd over classes"
    for method, d, t, notes in (
        ("classic", dc, t_classic, "standardised Euclidean of " + ", ".join(SCALE_FREE)),
        ("PF-SDM", dp, t_pfsdm, "napari_pfsdm.distance_matrix defaults"),
    ):
        b = bullseye(d, labels)
        rows.append(_row(name, method, b.score, "bull's-eye %",
                         np.std(list(b.per_class.values()), ddof=1), spread_name, t, notes))
    per_class = [per_query[labels == c].mean() for c in classes]
    rows.append(_row(name, "both", per_query.mean(), "bull's-eye %",
                     np.std(per_class, ddof=1), spread_name, t_both,
                     f"median-normalised sum; {w_text}"))
    # for the record: the best weight chosen on all queries (optimistic, not in the table)
    best = int(np.argmax(per_w.mean(axis=1)))
    print(f"[{name}] (optimistic, tuned on all queries: w = {WEIGHTS[best]:.2f}, "
          f"{per_w[best].mean():.2f} %)")
    return rows


# =========================================================================== five shapes
def _five_shape_matrices(set_name: str, n_per_class: int, seed: int):
    import synthetic_five_shapes as s5

    masks, labels, _ = s5.build_set(set_name, n_per_class=n_per_class, seed=seed)
    t0 = time.perf_counter()
    dc = classic_distance(scale_free_measures(masks))
    t_classic = time.perf_counter() - t0
    t0 = time.perf_counter()
    results, _, err = s5._pfsdm_results(masks, {})
    if err:
        print(f"  [{set_name}, seed {seed}] PF-SDM errors: {err}")
    dp = s5._pfsdm_matrix(results, s5._default_invariance())
    t_pfsdm = time.perf_counter() - t0
    return labels, dc, dp, t_classic, t_pfsdm


def run_five_shapes(n_per_class: int, seed: int) -> list[dict]:
    """Silhouette and 1-NN of classic, PF-SDM and both on the five-shape sets.

    Parameters
    ----------
    n_per_class : int
        Copies of each base shape per set (the benchmark: 10).
    seed : int
        Seed of the scored sets; the weight of "both" is chosen on sets drawn with
        ``seed + 1``.

    Returns
    -------
    list of dict
        Two rows (silhouette, 1-NN) per set and method.
    """
    import synthetic_five_shapes as s5

    rows = []
    for set_name in s5.SETS:
        name = f"five shapes, {set_name} ({5 * n_per_class})"
        print(f"[{name}] classic measures and PF-SDM (scored set seed {seed}, weight set "
              f"seed {seed + 1}) ...", flush=True)
        labels, dc, dp, t_c, t_p = _five_shape_matrices(set_name, n_per_class, seed)
        t0 = time.perf_counter()
        lab_t, dc_t, dp_t, _, _ = _five_shape_matrices(set_name, n_per_class, seed + 1)
        sil_t = [s5.scores(combined(*normalised_pair(dc_t, dp_t), w), lab_t)[0]
                 for w in WEIGHTS]
        w = float(WEIGHTS[int(np.nanargmax(sil_t))])
        t_w = time.perf_counter() - t0
        d_both = combined(*normalised_pair(dc, dp), w)
        print(f"[{name}] both: w = {w:.2f} (best silhouette on the seed-{seed + 1} set)")
        for method, d, t, notes in (
            ("classic", dc, t_c, "standardised Euclidean of " + ", ".join(SCALE_FREE)),
            ("PF-SDM", dp, t_p, "napari_pfsdm.distance_matrix defaults"),
            ("both", d_both, t_c + t_p + t_w,
             f"median-normalised sum, w = {w:.2f} chosen on a seed-{seed + 1} set "
             "(its time included)"),
        ):
            sil, nn = s5.scores(d, labels)
            rows.append(_row(name, method, sil, "silhouette", np.nan, "", t, notes))
            rows.append(_row(name, method, nn, "1-NN (LOO)", np.nan, "", t, notes))
    return rows


# =========================================================================== gastruloids
def run_gastruloids(n_objects: int, n_frames: int, frames: str, n_repeats: int,
                    seed: int) -> list[dict]:
    """``predict_outcome`` balanced accuracy of each channel and of the fusions.

    Parameters
    ----------
    n_objects, n_frames : int
        Generator size (the report: 78 objects × 25 frames of 128²).
    frames : str
        Frames used to predict (the report: ``"0-9"``).
    n_repeats : int
        Repeats of the 5 stratified 20 % test splits.
    seed : int
        Seed of the generator and of the splits.

    Returns
    -------
    list of dict
        Rows for the classic channel alone, PF-SDM shape alone, intensity alone, PF-SDM fused
        (shape + intensity) and the fusion of all three.
    """
    from napari_pfsdm.analysis import classification as cl
    from napari_pfsdm.analysis.outcome import predict_outcome
    from napari_pfsdm.data.gastruloids import make_gastruloids

    data = make_gastruloids(n_objects=n_objects, n_frames=n_frames, size=128, seed=seed)
    sel = cl.parse_frames(frames, n_frames)
    name = (f"gastruloids ({n_objects}, {int(data.multi_axis.sum())} multi-axes, frames "
            f"{sel[0]}-{sel[-1]})")
    print(f"[{name}] measure ...", flush=True)
    t0 = time.perf_counter()
    table = cl.measure_movies(data.labels, data.intensity, frames=sel)
    t_measure = time.perf_counter() - t0
    groups = dict(enumerate(data.groups))
    kw = dict(frames=sel, object_col="object", n_repeats=n_repeats, curve=False, seed=seed)
    t0 = time.perf_counter()
    three = predict_outcome(table, groups, channels=["shape", "intensity", "classic"], **kw)
    t_three = time.perf_counter() - t0
    t0 = time.perf_counter()
    two = predict_outcome(table, groups, channels=["shape", "intensity"], **kw)
    t_two = time.perf_counter() - t0
    s3, s2 = three.summary, two.summary
    w3 = np.array(three.scores.loc[three.scores["method"] == "fused", "weights"].tolist())
    w_text = ("fusion weights (shape, intensity, classic) per split: mean "
              + ", ".join(f"{v:.2f}" for v in w3.mean(axis=0))
              + f"; classic weight {w3[:, 2].min():.2f}-{w3[:, 2].max():.2f}")
    print(f"[{name}] {w_text}")
    n = int(s3.loc["fused", "n_splits"])
    spread = f"sd over {n} splits"
    score = "balanced accuracy"
    note_fit = f"measure {t_measure:.1f} s + fits"
    rows = [
        _row(name, "classic", s3.loc["classic alone", "mean"], score,
             s3.loc["classic alone", "std"], spread, t_measure + t_three,
             "predict_outcome 'classic alone': all classic columns incl. area and reporter; "
             + note_fit + " (time of the 3-channel call)"),
        _row(name, "PF-SDM shape alone", s3.loc["shape alone", "mean"], score,
             s3.loc["shape alone", "std"], spread, t_measure + t_three,
             "predict_outcome 'shape alone'"),
        _row(name, "PF-SDM intensity alone", s3.loc["intensity alone", "mean"], score,
             s3.loc["intensity alone", "std"], spread, t_measure + t_three,
             "predict_outcome 'intensity alone'"),
        _row(name, "PF-SDM", s2.loc["fused", "mean"], score, s2.loc["fused", "std"], spread,
             t_measure + t_two, "predict_outcome 'fused', channels shape + intensity; "
             + note_fit),
        _row(name, "both", s3.loc["fused", "mean"], score, s3.loc["fused", "std"], spread,
             t_measure + t_three, "predict_outcome 'fused', channels shape + intensity + "
             "classic (weights chosen inside each training split); " + note_fit + "; "
             + w_text),
    ]
    return rows


# =========================================================================== output
def format_table(table: pd.DataFrame) -> str:
    """The results as fixed-width text: dataset, method, score, spread, time.

    Parameters
    ----------
    table : DataFrame
        Columns :data:`COLUMNS`.

    Returns
    -------
    str
        One line per row, under a header.
    """
    head = (f"{'dataset':<44} {'method':<24} {'score':<18} {'value':>7} {'spread':>16} "
            f"{'time':>8}")
    lines = [head, "-" * len(head)]
    for _, r in table.iterrows():
        fmt = "{:.1f}" if r.score_name.endswith("%") else "{:.3f}"
        spread = "" if not np.isfinite(r.spread) else ("± " + fmt.format(r.spread))
        lines.append(f"{r.dataset:<44} {r.method:<24} {r.score_name:<18} "
                     f"{fmt.format(r.score):>7} {spread:>16} {r.time_s:>7.2f}s")
    return "\n".join(lines)


def plot(table: pd.DataFrame, path: Path) -> None:
    """Bar chart: one panel per data set and score, one bar per method (± spread).

    Parameters
    ----------
    table : DataFrame
        Columns :data:`COLUMNS`.
    path : Path
        The PNG to write.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = list(dict.fromkeys(zip(table["dataset"], table["score_name"], strict=True)))
    colours = {"classic": "tab:orange", "PF-SDM": "tab:blue", "both": "tab:green",
               "PF-SDM shape alone": "lightsteelblue", "PF-SDM intensity alone": "cornflowerblue"}
    fig, axes = plt.subplots(1, len(panels), figsize=(2.5 * len(panels) + 1.5, 4.6),
                             squeeze=False)
    for ax, (ds, sc) in zip(axes[0], panels, strict=True):
        sub = table[(table["dataset"] == ds) & (table["score_name"] == sc)]
        x = np.arange(len(sub))
        err = np.nan_to_num(sub["spread"].to_numpy(float), nan=0.0)
        top = 100.0 if sc.endswith("%") else 1.0
        ax.bar(x, sub["score"], yerr=err if err.any() else None, capsize=3,
               color=[colours.get(m, "gray") for m in sub["method"]], edgecolor="black",
               linewidth=0.5)
        for xi, v, e in zip(x, sub["score"], err, strict=True):
            ax.text(xi, v + e + 0.01 * top, f"{v:.1f}" if top == 100 else f"{v:.2f}",
                    ha="center", va="bottom", fontsize=7)
        labels = [m.replace("PF-SDM ", "PF-SDM\n").replace(" alone", "\nalone")
                  for m in sub["method"]]
        ax.set_xticks(x, labels, fontsize=7)
        lo = min(0.0, float(sub["score"].min()) * 1.1)
        ax.set_ylim(lo, max(top, float((sub["score"] + err).max())) * 1.12)
        if sc == "balanced accuracy":
            ax.axhline(0.5, color="k", lw=0.8, ls=":")
        ax.set_ylabel(sc, fontsize=8)
        ax.set_title(ds.replace(" (", "\n(") + f"\n{sc}", fontsize=8)
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle("Classic measures (orange) against PF-SDM (blue) and both (green); "
                 "error bars: spread where there is one", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """Command line (module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=HERE / "out", help="output folder")
    ap.add_argument("--quick", action="store_true",
                    help="small fast run: 10 MPEG-7 classes, 4 shapes per class, 30 gastruloids")
    ap.add_argument("--mpeg7", type=Path, default=None,
                    help="MPEG-7 folder (default: ../shared/data/mpeg7 from the repository)")
    ap.add_argument("--processes", type=int, default=2, help="PF-SDM workers on MPEG-7")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    import mpeg7

    folder = args.mpeg7 or mpeg7.DEFAULT_FOLDER
    start = time.perf_counter()
    print(f"load average at start: {os.getloadavg()[0]:.1f} (2 cores shared)")
    rows = run_mpeg7(folder, 10 if args.quick else 0, args.processes)
    rows += run_five_shapes(4 if args.quick else 10, args.seed)
    rows += run_gastruloids(30 if args.quick else 78, 25, "0-9", 1 if args.quick else 2,
                            args.seed)
    table = pd.DataFrame(rows, columns=COLUMNS)
    args.out.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.out / "classic_vs_pfsdm.csv", index=False)
    plot(table, args.out / "classic_vs_pfsdm.png")
    print("\n" + format_table(table))
    print(f"\nload average at end: {os.getloadavg()[0]:.1f}; total "
          f"{time.perf_counter() - start:.0f} s")
    print(f"wrote {args.out / 'classic_vs_pfsdm.csv'} and {args.out / 'classic_vs_pfsdm.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
