"""The paper's synthetic benchmark: five base shapes under similarity transforms.

Two sets of ``5 × n_per_class`` masks (:func:`napari_pfsdm.data.shapes.make_benchmark_set`):
``"exact"`` (exact copies of each base shape under random translation, rotation, reflection
and 0.5×–2× scaling) and ``"perturbed"`` (each copy also mildly and randomly deformed). For
every method, the pairwise distance matrix of each set is scored by

- the **silhouette** (scikit-learn, ``metric="precomputed"``) with the 5 true classes: from −1
  to 1, high when each class is a tight cluster far from the others;
- the **leave-one-out 1-NN accuracy**: the fraction of objects whose nearest other object is
  of the same class.

Methods: PF-SDM (every ``mapping`` × ``sdf`` × ``normalization`` × ring placement, a few
ablations of the distance's ring weighting and mode exponent, and every ``invariance`` mode of
the distance; ``quick=True`` keeps the default only), and the
baselines of :mod:`napari_pfsdm.analysis.baselines`: normalised EFA with 10 harmonics as
``pyefd`` gives it (``"EFA (raw pyefd)"``, as in the paper), the same with its 180° ambiguities
removed (``"EFA"``), mirror-aware EFA, and GPA (Procrustes on 100 equidistant points of the
EFA outline, best start point and mirror image).

:func:`run` prints a table, writes ``synthetic_benchmark.csv`` and ``synthetic_mds.png`` (2-D
MDS of PF-SDM default, EFA and GPA side by side, coloured by class) and returns the table.
This is what ``pfsdm demo`` runs. Its steps are separate: :func:`build_set` makes a shape set,
:func:`score_set` scores every method on it and :func:`benchmark_table` collects the rows (no
printing, no files), :func:`write_outputs` writes the CSV and the figure.

Run it from the repository root with ``python examples/synthetic_five_shapes.py --out DIR
--quick`` (what ``pfsdm demo`` runs), or every variant with ``python benchmarks/synthetic.py
--full``.

Examples
--------
>>> table = run("results", quick=True)  # doctest: +SKIP
"""

from __future__ import annotations

import argparse
import itertools
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from napari_pfsdm.analysis import baselines
from napari_pfsdm.analysis.reduction import mds_coordinates
from napari_pfsdm.analysis.retrieval import loo_1nn_fraction
from napari_pfsdm.core import DEFAULTS, distance_matrix, pfsdm
from napari_pfsdm.data.shapes import base_shapes, make_benchmark_set
from napari_pfsdm.errors import InputError
from napari_pfsdm.io import save_figure, write_table

__all__ = [
    "DEFAULT_LABEL", "pfsdm_variants", "scores", "nn_accuracy", "mds_embedding", "run", "summary",
    "build_set", "score_set", "benchmark_table", "write_outputs",
]

#: Method name of the PF-SDM with the library's default options.
DEFAULT_LABEL = "PF-SDM (default)"

SETS = ("exact", "perturbed")

#: Columns of the benchmark table, in order.
COLUMNS = ["set", "method", "family", "mapping", "sdf", "normalization", "rings",
           "ring_weighting", "mode_exponent", "invariance", "is_default", "silhouette",
           "nn_accuracy", "ms_per_object", "error"]

#: A progress callback: called with a short message before each step.
Progress = Callable[[str], None]


def _silent(msg: str) -> None:
    """Progress callback that says nothing."""


def pfsdm_variants(quick: bool = False) -> list[dict]:
    """PF-SDM option sets of the benchmark.

    Parameters
    ----------
    quick : bool
        Only the library's defaults (``{}``).

    Returns
    -------
    list of dict
        Keyword arguments for :func:`napari_pfsdm.pfsdm`; ``{}`` first. The full grid is every
        ``mapping`` × ``sdf`` × ``normalization`` × ``radii`` (ring placement), the other
        options at the library's defaults, plus, where the core offers them, the default
        options with each other ``ring_weighting`` and with ``mode_exponent=0`` (the paper's
        plain distance).
    """
    if quick:
        return [{}]
    out: list[dict] = [{}]
    for mapping, sdf, norm, radii in itertools.product(
        ("harmonic", "bijective", "radial"), ("exact", "viscous"), ("none", "ring"),
        ("uniform", "boundary"),
    ):
        out.append({"mapping": mapping, "sdf": sdf, "normalization": norm, "radii": radii})
    if "ring_weighting" in DEFAULTS:
        for weighting in ("none", "boundary", "depth"):
            if weighting != DEFAULTS["ring_weighting"]:
                out.append({"ring_weighting": weighting})
    if "mode_exponent" in DEFAULTS and DEFAULTS["mode_exponent"] != 0:
        out.append({"mode_exponent": 0.0})
        if "ring_weighting" in DEFAULTS and DEFAULTS["ring_weighting"] != "none":
            out.append({"mode_exponent": 0.0, "ring_weighting": "none"})
    return out


def _full_options(options: dict) -> dict:
    return {**DEFAULTS, **options}


def _default_invariance() -> str:
    """The invariance ``distance_matrix`` uses for results when none is given."""
    import inspect

    default = inspect.signature(distance_matrix).parameters["invariance"].default
    return "magnitude" if default is None else str(default)


def _variant_label(options: dict, invariance: str) -> str:
    opts = _full_options(options)
    label = (f"PF-SDM {opts['mapping']}/{opts['sdf']}/norm={opts['normalization']}/"
             f"rings={opts['radii']}")
    for key, short in (("ring_weighting", "weights"), ("mode_exponent", "modes^")):
        if key in opts and opts[key] != DEFAULTS.get(key):
            label += f"/{short}{'=' if short == 'weights' else ''}{opts[key]}"
    return f"{label}/{invariance}"


def nn_accuracy(dist: np.ndarray, labels: np.ndarray) -> float:
    """Leave-one-out 1-nearest-neighbour accuracy of a distance matrix.

    Parameters
    ----------
    dist : ndarray, shape (n, n)
        Pairwise distances (the diagonal is ignored).
    labels : ndarray, shape (n,)
        True classes.

    Returns
    -------
    float
        Fraction of objects whose nearest other object has the same label (ties: the first).

    Examples
    --------
    >>> d = np.array([[0, 1, 5], [1, 0, 4], [5, 4, 0.0]])
    >>> nn_accuracy(d, np.array([0, 0, 1]))
    0.6666666666666666
    """
    return loo_1nn_fraction(dist, labels)


def scores(dist: np.ndarray, labels: np.ndarray) -> tuple[float, float]:
    """Silhouette (precomputed distances) and leave-one-out 1-NN accuracy.

    Returns ``(nan, nan)`` when the matrix holds NaN (an object could not be described).
    """
    from sklearn.metrics import silhouette_score

    dist = np.asarray(dist, float)
    if not np.all(np.isfinite(dist)):
        return float("nan"), float("nan")
    d = 0.5 * (dist + dist.T)
    np.fill_diagonal(d, 0.0)
    return float(silhouette_score(d, labels, metric="precomputed")), nn_accuracy(d, labels)


def _have_pyefd() -> bool:
    import importlib.util

    return importlib.util.find_spec("pyefd") is not None


def _pfsdm_results(masks: Sequence[np.ndarray], options: dict) -> tuple[list, float, str]:
    results, errors = [], []
    start = time.perf_counter()
    for i, mask in enumerate(masks):
        try:
            results.append(pfsdm(mask, **options))
        except ValueError as err:
            results.append(None)
            errors.append(f"object {i}: {err}")
    per_object = (time.perf_counter() - start) / max(len(masks), 1)
    return results, per_object, "; ".join(errors)


def _pfsdm_matrix(results: list, invariance: str, **more) -> np.ndarray:
    n = len(results)
    ok = [i for i, r in enumerate(results) if r is not None]
    dist = np.full((n, n), np.nan)
    if ok:
        dist[np.ix_(ok, ok)] = distance_matrix([results[i] for i in ok], invariance=invariance,
                                               **more)
    return dist


#: Rows shown next to the default: the SDF term alone (``invariance="combined"``, no boundary term)
#: and the boundary term alone, as (label, invariance, keyword arguments of distance_matrix).
REFERENCE_ROWS = (
    ("PF-SDM SDF only (combined, no boundary term)", "combined",
     {"boundary_weight": 0.0}),
    ("outline Procrustes (the boundary term alone)", "none", {}),
)


def _boundary_only(results: list) -> np.ndarray:
    from napari_pfsdm.core.distances import boundary_term

    n = len(results)
    ok = [i for i, r in enumerate(results) if r is not None]
    dist = np.full((n, n), np.nan)
    if ok:
        dist[np.ix_(ok, ok)] = boundary_term([results[i] for i in ok])
    return dist


def _row(set_name: str, method: str, family: str, dist: np.ndarray, labels: np.ndarray,
         ms: float, error: str = "", **info) -> dict:
    """One table row: the scores of a distance matrix and what it came from."""
    sil, nn = scores(dist, labels)
    return {"set": set_name, "method": method, "family": family, **info,
            "silhouette": sil, "nn_accuracy": nn, "ms_per_object": ms, "error": error}


def _resolve_invariances(invariances: Sequence[str] | None, quick: bool) -> list[str]:
    """The distance modes of the PF-SDM rows: the core's default first."""
    if invariances is not None:
        return list(invariances)
    default_inv = _default_invariance()
    out = [default_inv]
    if not quick:
        out += [i for i in ("combined", "magnitude", "align") if i != default_inv]
    return out


def build_set(
    set_name: str, *, n_per_class: int = 10, seed: int = 0, size: int = 256
) -> tuple[list[np.ndarray], np.ndarray, tuple[str, ...]]:
    """Build one shape set of the benchmark (the data step).

    Parameters
    ----------
    set_name : {"exact", "perturbed"}
        Exact copies of the base shapes, or mildly and randomly deformed copies.
    n_per_class : int
        Copies of each base shape.
    seed : int
        Seed of the random transforms (and deformations).
    size : int
        Masks are ``size × size`` pixels.

    Returns
    -------
    masks : list of ndarray
        ``5 * n_per_class`` boolean masks.
    labels : ndarray, shape (5 * n_per_class,)
        True class of each mask (index into ``names``).
    names : tuple of str
        Names of the five base shapes.

    Raises
    ------
    ValueError
        For an unknown ``set_name``.
    """
    if set_name not in SETS:
        raise InputError(f"Unknown set(s) {[set_name]}; choose from {SETS}.")
    return make_benchmark_set(n_per_class, perturb=set_name == "perturbed", seed=seed, size=size)


def _score_pfsdm(
    set_name: str,
    masks: Sequence[np.ndarray],
    labels: np.ndarray,
    variants: Sequence[dict],
    invariances: Sequence[str],
    progress: Progress,
) -> tuple[list[dict], dict[tuple[str, str], np.ndarray]]:
    """Rows and distance matrices of the PF-SDM variants on one set (duplicates skipped)."""
    default_inv = _default_invariance()
    default_key = tuple(sorted(_full_options({}).items()))
    rows: list[dict] = []
    matrices: dict[tuple[str, str], np.ndarray] = {}
    seen: set[tuple] = set()
    for options in variants:
        key = tuple(sorted(_full_options(options).items()))
        if key in seen:
            continue
        seen.add(key)
        opts = _full_options(options)
        is_default = key == default_key
        progress(f"[{set_name}] PF-SDM {opts['mapping']}/{opts['sdf']}/{opts['normalization']}"
                 f"/{opts['radii']} ...")
        results, per_obj, err = _pfsdm_results(masks, options)
        for inv in invariances:
            default_row = is_default and inv == default_inv
            method = DEFAULT_LABEL if default_row else _variant_label(options, inv)
            dist = _pfsdm_matrix(results, inv)
            matrices[(set_name, method)] = dist
            rows.append(_row(
                set_name, method, "PF-SDM", dist, labels, 1e3 * per_obj, err,
                mapping=opts["mapping"], sdf=opts["sdf"], normalization=opts["normalization"],
                rings=str(opts["radii"]), ring_weighting=str(opts.get("ring_weighting", "")),
                mode_exponent=opts.get("mode_exponent", np.nan), invariance=inv,
                is_default=default_row,
            ))
        if is_default:
            for label, inv, more in REFERENCE_ROWS:
                dist = (_boundary_only(results) if inv == "none"
                        else _pfsdm_matrix(results, inv, **more))
                matrices[(set_name, label)] = dist
                rows.append(_row(set_name, label, "PF-SDM", dist, labels, 1e3 * per_obj, err,
                                 mapping=opts["mapping"], sdf=opts["sdf"],
                                 normalization=opts["normalization"], rings=str(opts["radii"]),
                                 ring_weighting=str(opts.get("ring_weighting", "")),
                                 mode_exponent=opts.get("mode_exponent", np.nan),
                                 invariance=inv, is_default=False))
    return rows, matrices


def _score_baselines(
    set_name: str, masks: Sequence[np.ndarray], labels: np.ndarray
) -> tuple[list[dict], dict[tuple[str, str], np.ndarray]]:
    """Rows and distance matrices of raw EFA, EFA, mirror-aware EFA and GPA on one set."""
    t0 = time.perf_counter()
    contours = [baselines.mask_contour(m) for m in masks]
    t_contour = time.perf_counter() - t0
    t0 = time.perf_counter()
    raw = baselines.efa_descriptors(contours, contours=True, canonical=False)
    t_efa = t_contour + time.perf_counter() - t0
    desc = raw * np.where(raw[:, :1] < 0, -1.0, 1.0)  # = efa_descriptors(canonical=True)
    t0 = time.perf_counter()
    mirrored = baselines.efa_descriptors(contours, contours=True, mirror=True)
    t_mirror = time.perf_counter() - t0
    t0 = time.perf_counter()
    outlines = baselines.efa_outlines(contours, contours=True)
    t_gpa = t_contour + time.perf_counter() - t0
    n = len(masks)
    methods = [
        ("EFA (raw pyefd)", "EFA",
         baselines.efa_distance_matrix(descriptors=raw, resolve_start=False), t_efa),
        ("EFA", "EFA", baselines.efa_distance_matrix(descriptors=desc), t_efa),
        ("EFA (mirror-aware)", "EFA",
         baselines.efa_distance_matrix(descriptors=desc, mirrored=mirrored, mirror_aware=True),
         t_efa + t_mirror),
        ("GPA", "GPA", baselines.gpa_distance_matrix(outlines=outlines), t_gpa),
    ]
    rows = [_row(set_name, method, family, dist, labels, 1e3 * t / n, is_default=False)
            for method, family, dist, t in methods]
    matrices = {(set_name, method): dist for method, _, dist, _ in methods}
    return rows, matrices


def score_set(
    set_name: str,
    masks: Sequence[np.ndarray],
    labels: np.ndarray,
    *,
    variants: Sequence[dict],
    invariances: Sequence[str],
    progress: Progress | None = None,
) -> tuple[list[dict], dict[tuple[str, str], np.ndarray]]:
    """Score every method on one shape set (pure: no printing, no files).

    Parameters
    ----------
    set_name : str
        Name of the set, copied into the rows.
    masks : sequence of ndarray
        The set's masks (:func:`build_set`).
    labels : ndarray
        Their true classes.
    variants : sequence of dict
        PF-SDM option sets; options equal to an earlier set's are skipped.
    invariances : sequence of str
        Distance modes of the PF-SDM rows.
    progress : callable, optional
        Called with a short message before each step (default: silent).

    Returns
    -------
    rows : list of dict
        One row per method (see :func:`benchmark_table` for the columns). EFA and GPA are
        left out, with a progress message, when the optional ``pyefd`` is missing.
    matrices : dict
        ``(set_name, method) -> distance matrix``.
    """
    say = progress or _silent
    rows, matrices = _score_pfsdm(set_name, masks, labels, variants, invariances, say)
    if not _have_pyefd():
        say(f"[{set_name}] EFA and GPA skipped: the optional package 'pyefd' is missing "
            "(pip install 'napari-pfsdm[bench]').")
        return rows, matrices
    say(f"[{set_name}] EFA and GPA ...")
    more_rows, more_matrices = _score_baselines(set_name, masks, labels)
    return rows + more_rows, {**matrices, **more_matrices}


def benchmark_table(
    rows: Sequence[dict], matrices: dict[tuple[str, str], np.ndarray]
) -> pd.DataFrame:
    """The rows of :func:`score_set` as the benchmark table.

    Parameters
    ----------
    rows : sequence of dict
        Rows of all sets, in order.
    matrices : dict
        ``(set, method) -> distance matrix``, kept in ``table.attrs["matrices"]``.

    Returns
    -------
    pandas.DataFrame
        Columns :data:`COLUMNS`; option columns empty (``""``) for the baselines,
        ``mode_exponent`` NaN there.
    """
    table = pd.DataFrame(list(rows))
    for col in ("mapping", "sdf", "normalization", "rings", "ring_weighting", "invariance"):
        if col not in table:
            table[col] = ""
        table[col] = table[col].fillna("")
    table["is_default"] = table["is_default"].fillna(False).astype(bool)
    if "mode_exponent" not in table:
        table["mode_exponent"] = np.nan
    table = table[COLUMNS]
    table.attrs["matrices"] = matrices
    return table


#: The files :func:`run` writes into its folder (``pfsdm demo`` checks them before any work).
OUTPUT_FILES = ("synthetic_benchmark.csv", "synthetic_mds.png")


def write_outputs(
    table: pd.DataFrame,
    out: Path,
    *,
    labels_by_set: dict[str, np.ndarray],
    names: Sequence[str],
    sets: Sequence[str],
    seed: int = 0,
    plot: bool = True,
) -> list[Path]:
    """Write ``synthetic_benchmark.csv`` and, with ``plot``, ``synthetic_mds.png``.

    Parameters
    ----------
    table : pandas.DataFrame
        From :func:`benchmark_table` (its ``attrs["matrices"]`` feed the plot).
    out : Path
        Existing output folder.
    labels_by_set : dict
        True classes of each set.
    names : sequence of str
        Names of the five base shapes.
    sets : sequence of str
        The sets, one row of panels each.
    seed : int
        Seed of the MDS.
    plot : bool
        Write the MDS figure.

    Returns
    -------
    list of Path
        The files written.
    """
    written = [out / OUTPUT_FILES[0]]
    write_table(table, written[0], {}, table_type="benchmark")
    if plot:
        written.append(out / OUTPUT_FILES[1])
        _plot_mds(written[1], table.attrs["matrices"], labels_by_set, names, sets, seed)
    return written


def run(
    out_dir: str | Path,
    *,
    seed: int = 0,
    variants: Iterable[dict] | None = None,
    quick: bool = False,
    n_per_class: int = 10,
    size: int = 256,
    sets: Sequence[str] = SETS,
    invariances: Sequence[str] | None = None,
    plot: bool = True,
    verbose: bool = True,
    progress: Callable[[str], None] | None = None,
) -> pd.DataFrame:
    """Run the synthetic benchmark, print the table and write the CSV and MDS plot.

    Parameters
    ----------
    out_dir : str or Path
        Folder for ``synthetic_benchmark.csv`` and ``synthetic_mds.png`` (created).
    seed : int
        Seed of both shape sets.
    variants : iterable of dict, optional
        PF-SDM option sets (keyword arguments of :func:`napari_pfsdm.pfsdm`). Default:
        :func:`pfsdm_variants` — the full grid, or only the defaults with ``quick``.
    quick : bool
        Defaults only: PF-SDM default and the four baselines (runs in seconds).
    n_per_class : int
        Copies of each base shape per set (the paper: 10).
    size : int
        Masks are ``size × size`` pixels.
    sets : sequence of {"exact", "perturbed"}
        Which sets to build.
    invariances : sequence of {"combined", "magnitude", "align"}, optional
        Distance modes of the PF-SDM rows. Default: the core's default with ``quick``,
        all three otherwise (the core's default first).
    plot : bool
        Write the MDS figure.
    verbose : bool
        Print the summary table.
    progress : callable, optional
        Called with a short message before each step.

    Returns
    -------
    pandas.DataFrame
        Long format, one row per (set, method): ``set``, ``method``, ``family``,
        ``mapping``, ``sdf``, ``normalization``, ``rings``, ``ring_weighting``,
        ``mode_exponent``, ``invariance``, ``is_default``,
        ``silhouette``, ``nn_accuracy``, ``ms_per_object``, ``error``.
    """
    unknown = set(sets) - set(SETS)
    if unknown:
        raise InputError(f"Unknown set(s) {sorted(unknown)}; choose from {SETS}.")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    variants = pfsdm_variants(quick) if variants is None else [dict(v) for v in variants]
    invariances = _resolve_invariances(invariances, quick)
    say = progress or ((lambda msg: print(msg, flush=True)) if verbose else _silent)

    rows: list[dict] = []
    matrices: dict[tuple[str, str], np.ndarray] = {}
    labels_by_set: dict[str, np.ndarray] = {}
    names: tuple[str, ...] = ()
    for set_name in sets:
        say(f"[{set_name}] building {5 * n_per_class} shapes ...")
        masks, labels_by_set[set_name], names = build_set(
            set_name, n_per_class=n_per_class, seed=seed, size=size)
        set_rows, set_matrices = score_set(set_name, masks, labels_by_set[set_name],
                                           variants=variants, invariances=invariances,
                                           progress=say)
        rows += set_rows
        matrices.update(set_matrices)

    table = benchmark_table(rows, matrices)
    write_outputs(table, out, labels_by_set=labels_by_set, names=names, sets=sets, seed=seed,
                  plot=plot)
    if plot:
        say(f"wrote {out / 'synthetic_mds.png'}")
    if verbose:
        print()
        print(summary(table).to_string(float_format=lambda v: f"{v:.3f}"))
        print(f"\nwrote {out / 'synthetic_benchmark.csv'}")
    return table


def summary(table: pd.DataFrame) -> pd.DataFrame:
    """One row per method, silhouette and 1-NN accuracy per set side by side.

    Sorted by the silhouette on the perturbed set (or the first set), best first, with the
    PF-SDM default and the baselines kept in the table whatever their rank.
    """
    wide = table.pivot_table(index="method", columns="set",
                             values=["silhouette", "nn_accuracy"], sort=False)
    sets = [s for s in SETS if s in table["set"].unique()]
    wide = wide.reindex(columns=[(v, s) for s in sets for v in ("silhouette", "nn_accuracy")])
    wide.columns = [f"{s} {'sil' if v == 'silhouette' else '1-NN'}" for v, s in wide.columns]
    ms = table.groupby("method", sort=False)["ms_per_object"].mean()
    wide["ms/object"] = ms.reindex(wide.index)
    key = f"{sets[-1]} sil"
    return wide.sort_values(key, ascending=False, na_position="last")


def mds_embedding(dist: np.ndarray, seed: int = 0) -> np.ndarray:
    """2-D MDS of a precomputed distance matrix: the package's one (classical, deterministic)
    MDS, :func:`napari_pfsdm.analysis.reduction.mds_coordinates`; ``seed`` is kept for
    callers and ignored."""
    return mds_coordinates(0.5 * (np.asarray(dist, float) + np.asarray(dist, float).T))


def _plot_mds(path: Path, matrices: dict, labels_by_set: dict, names: Sequence[str],
              sets: Sequence[str], seed: int) -> None:
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from sklearn.metrics import silhouette_score

    methods = (DEFAULT_LABEL, "EFA", "GPA")
    colors = plt.get_cmap("tab10").colors
    fig, axes = plt.subplots(len(sets), len(methods) + 1, figsize=(4.2 * (len(methods) + 1),
                             4.0 * len(sets)), squeeze=False,
                             gridspec_kw={"width_ratios": [1] * len(methods) + [0.55]})
    for row, set_name in enumerate(sets):
        labels = labels_by_set[set_name]
        for col, method in enumerate(methods):
            ax = axes[row, col]
            dist = matrices.get((set_name, method))
            if dist is None or not np.all(np.isfinite(dist)):
                ax.set_axis_off()
                continue
            d = 0.5 * (dist + dist.T)
            np.fill_diagonal(d, 0.0)
            xy = mds_embedding(d, seed)
            for k, name in enumerate(names):
                sel = labels == k
                ax.scatter(xy[sel, 0], xy[sel, 1], s=28, color=colors[k], label=name,
                           edgecolors="k", linewidths=0.3)
            sil = silhouette_score(d, labels, metric="precomputed")
            ax.set_title(f"{method} — {set_name}\nsilhouette {sil:.2f}", fontsize=10)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_aspect("equal", adjustable="datalim")
        legend_ax = axes[row, -1]
        legend_ax.set_axis_off()
        for k, outline in enumerate(base_shapes(200)):
            cy = 1.0 - k * 0.42
            closed = np.vstack([outline, outline[:1]])
            legend_ax.fill(0.17 * closed[:, 1] + 0.2, 0.17 * closed[:, 0] + cy,
                           color=colors[k], ec="k", lw=0.5)
            legend_ax.text(0.45, cy, names[k], va="center", fontsize=9)
        legend_ax.set_xlim(0, 1.2)
        legend_ax.set_ylim(1.0 - 4 * 0.42 - 0.25, 1.25)
        legend_ax.set_aspect("equal")
    fig.suptitle("2-D MDS of the distance matrices (colours: true classes)", fontsize=12)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> pd.DataFrame:
    """Command line: ``python examples/synthetic_five_shapes.py --out DIR [--quick]``.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments (default: the command line).

    Returns
    -------
    pandas.DataFrame
        The table :func:`run` returns.
    """
    p = argparse.ArgumentParser(
        description="The synthetic five-shape benchmark: PF-SDM against EFA and GPA.")
    p.add_argument("--out", default="results", help="output folder")
    p.add_argument("--quick", action="store_true",
                   help="PF-SDM's defaults only, beside the baselines (seconds)")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
    return run(a.out, seed=a.seed, quick=a.quick)


if __name__ == "__main__":
    main()
