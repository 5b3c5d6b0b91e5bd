"""MPEG-7 CE-Shape-1 retrieval benchmark: PF-SDM against EFA, GPA, Hu moments and shape context.

Run from the repository root (2 processes by default)::

    .venv/bin/python benchmarks/mpeg7.py                 # every method, every PF-SDM variant
    .venv/bin/python benchmarks/mpeg7.py --subset 0      # skip the (slow) shape context
    .venv/bin/python benchmarks/mpeg7.py --variants default "radii=boundary,invariance=align"
    .venv/bin/python benchmarks/mpeg7.py --variants default --subset 0 --rerank   # + re-ranking

With ``default`` among the variants, the table also shows the SDF term alone
(``invariance=combined, boundary_weight=0``) and the boundary term alone
("outline Procrustes").

The images are read from ``../shared/data/mpeg7`` (relative to the repository root) or the
folder given as the first argument; they are never copied into the project. Outputs go to
``benchmarks/out/``: ``mpeg7_results.csv`` (one row per method and shape set),
``mpeg7_results.md`` (the same as a Markdown table, with the command line),
``mpeg7_per_class.csv`` (bull's-eye per class and method), ``mpeg7_per_class.png`` and
``mpeg7_gallery.png``.

Preprocessing, the same for every method (cached in a temporary ``.npz`` outside the repo):

1. read ``numpy.asarray(PIL.Image.open(f)) > 0``; the class is the file name before the last
   hyphen;
2. keep the largest 8-connected component (28 masks have several);
3. crop to the object's box with a 4 px margin; if the box's longer side exceeds 256 px, shrink
   by 256 / longer side with ``skimage.transform.rescale(..., order=1, anti_aliasing=True,
   mode="constant")`` and threshold at 0.5;
4. keep the largest component again (shrinking can cut thin parts) and fill holes (shrinking
   can close the 1–2 px gaps that join apparent holes to the outside);
5. crop tight and pad by 4 px (517 objects touch the image border).

Scores: bull's-eye (the 40 nearest, the query included, same-class hits / 20, averaged, in
percent) and leave-one-out 1-NN; see :mod:`napari_pfsdm.analysis.retrieval`. Timing: ms per
shape for the descriptor (contour extraction included; the mean single-process time per shape,
measured inside the workers) and the seconds for all pairwise distances.
"""

from __future__ import annotations

import argparse
import copy
import csv
import hashlib
import importlib
import inspect
import itertools
import multiprocessing as mp
import os
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

# BLAS threads: at most 2 (the benchmark's budget), set before numpy is imported
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "2")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(HERE))

import mpeg7_peers as peers  # noqa: E402
from napari_pfsdm.analysis.retrieval import bullseye, loo_1nn, nearest  # noqa: E402

MAX_SIDE = 256
PAD = 4
DEFAULT_FOLDER = REPO.parent / "shared" / "data" / "mpeg7"
OUT = HERE / "out"
CACHE_DIR = Path(tempfile.gettempdir()) / "napari_pfsdm_mpeg7"
REF = "EFA resolved mirror-aware"  # the reference of the per-class plot


# =========================================================================== data
def class_of(path: Path) -> str:
    """Class name of an MPEG-7 file: everything before the last hyphen."""
    return path.stem.rsplit("-", 1)[0]


def _largest_component(mask: np.ndarray) -> tuple[np.ndarray, int]:
    from scipy import ndimage as ndi

    lab, n = ndi.label(mask, structure=np.ones((3, 3), bool))
    if n <= 1:
        return mask, n
    sizes = np.bincount(lab.ravel())[1:]
    return lab == (1 + int(np.argmax(sizes))), n


def _crop(mask: np.ndarray, pad: int) -> np.ndarray:
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    box = mask[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1]
    return np.pad(box, pad)


def preprocess(
    raw: np.ndarray, max_side: int = MAX_SIDE, pad: int = PAD
) -> tuple[np.ndarray, dict]:
    """The documented preprocessing (module docstring): returns the mask and what was done."""
    from scipy import ndimage as ndi
    from skimage.transform import rescale

    info = {}
    mask, info["n_components"] = _largest_component(raw)
    longer = max(_crop(mask, 0).shape)
    info["box_side"] = longer
    work = _crop(mask, pad)
    if longer > max_side:
        scale = max_side / longer
        small = rescale(
            work.astype(np.float32), scale, order=1, anti_aliasing=True, mode="constant"
        )
        work = small > 0.5
    work, n_after = _largest_component(work)
    info["split_by_resize"] = n_after > 1
    filled = ndi.binary_fill_holes(work)
    info["holes_filled"] = int(filled.sum() - work.sum())
    return _crop(filled, pad), info


def _folder_key(files: list[Path]) -> str:
    h = hashlib.sha256(f"{MAX_SIDE}-{PAD}-v1".encode())
    for f in files:
        h.update(f"{f.name}:{f.stat().st_size}".encode())
    return h.hexdigest()[:16]


def load_masks(folder: Path, use_cache: bool = True):
    """Preprocessed masks, class labels and file names (cached in a temp .npz)."""
    from PIL import Image

    files = sorted(folder.glob("*.gif"))
    if not files:
        raise ValueError(
            f"No .gif files in {folder}. Give the MPEG-7 CE-Shape-1 folder as the first "
            "argument (default ../shared/data/mpeg7 relative to the repository root)."
        )
    names = [f.stem for f in files]
    labels = np.array([class_of(f) for f in files])
    cache = CACHE_DIR / f"prep_{_folder_key(files)}.npz"
    if use_cache and cache.exists():
        z = np.load(cache)
        shapes, flat = z["shapes"], z["flat"]
        ends = np.cumsum(shapes.prod(axis=1))
        masks = [
            b.reshape(s) for b, s in zip(np.split(flat, ends[:-1]), shapes, strict=True)
        ]
        stats = {k: int(z[k]) for k in ("multi", "split", "holes", "shrunk")}
        print(f"preprocessed masks read from the cache {cache}")
        return masks, labels, names, stats
    t0 = time.perf_counter()
    masks, infos = [], []
    for f in files:
        m, info = preprocess(np.asarray(Image.open(f)) > 0)
        masks.append(m)
        infos.append(info)
    stats = {
        "multi": sum(i["n_components"] > 1 for i in infos),
        "split": sum(i["split_by_resize"] for i in infos),
        "holes": sum(i["holes_filled"] > 0 for i in infos),
        "shrunk": sum(i["box_side"] > MAX_SIDE for i in infos),
    }
    multi_names = [n for n, i in zip(names, infos, strict=True) if i["n_components"] > 1]
    print(
        f"preprocessed {len(files)} masks in {time.perf_counter() - t0:.1f} s; "
        f"{stats['multi']} had several components (largest kept): {', '.join(multi_names)}"
    )
    CACHE_DIR.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        cache,
        shapes=np.array([m.shape for m in masks]),
        flat=np.concatenate([m.ravel() for m in masks]),
        **{k: np.array(v) for k, v in stats.items()},
    )
    return masks, labels, names, stats


# =========================================================================== timing
_WORK: dict = {}


class Stopwatch:
    """``with Stopwatch() as sw: ...`` then ``sw.wall`` and ``sw.cpu`` (this process's CPU
    seconds, all its threads: insensitive to other jobs on a shared machine)."""

    def __enter__(self):
        self._w, self._c = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc):
        self.wall = time.perf_counter() - self._w
        self.cpu = time.process_time() - self._c
        return False


def _timed(i):
    fn, masks = _WORK["fn"], _WORK["masks"]
    t0 = time.process_time()
    out = fn(masks[i])
    return i, out, time.process_time() - t0


def describe(fn, masks: list[np.ndarray], processes: int) -> tuple[list, float, float]:
    """Run ``fn`` on every mask; returns the descriptors, the mean CPU ms per shape (measured
    in the workers, so other jobs on the machine do not inflate it) and the wall seconds."""
    _WORK.update(fn=fn, masks=masks)
    n = len(masks)
    out: list = [None] * n
    times = np.zeros(n)
    t0 = time.perf_counter()
    if processes > 1:
        try:
            with mp.get_context("fork").Pool(processes) as pool:
                for i, d, t in pool.imap_unordered(_timed, range(n), chunksize=8):
                    out[i], times[i] = d, t
        except Exception as exc:  # e.g. a result that cannot be pickled
            print(f"  (multiprocessing failed: {type(exc).__name__}: {exc}; running serially)")
            processes = 1
    if processes <= 1:
        for i in range(n):
            _, out[i], times[i] = _timed(i)
    return out, 1e3 * float(times.mean()), time.perf_counter() - t0


# =========================================================================== methods
@dataclass
class Method:
    """One row of the results table."""

    name: str
    D: np.ndarray
    ms_per_shape: float
    s_pairs: float
    s_pairs_cpu: float = float("nan")
    subset_only: bool = False
    notes: str = ""
    extra: dict = field(default_factory=dict)


def run_peers(masks, processes: int) -> list[Method]:
    out = []
    efa, ms, _ = describe(peers.efa_descriptor, masks, processes)
    for mirror, name in ((False, "EFA pyefd"), (True, "EFA pyefd mirror-aware")):
        with Stopwatch() as sw:
            D = peers.efa_distances(efa, mirror_aware=mirror)
        out.append(Method(name, D, ms, sw.wall, sw.cpu))
        print(f"  {name}: {ms:.2f} ms/shape, all pairs {out[-1].s_pairs:.2f} s")
    efa, ms, _ = describe(peers.efa_resolved_descriptor, masks, processes)
    for mirror, name in ((False, "EFA resolved"), (True, REF)):
        with Stopwatch() as sw:
            D = peers.efa_resolved_distances(efa, mirror_aware=mirror)
        out.append(Method(name, D, ms, sw.wall, sw.cpu,
                          notes="analysis.baselines (180-degree ambiguities removed)"))
        print(f"  {name}: {ms:.2f} ms/shape, all pairs {out[-1].s_pairs:.2f} s")
    gpa, ms, _ = describe(peers.gpa_descriptor, masks, processes)
    with Stopwatch() as sw:
        D = peers.gpa_distances(gpa)
    out.append(Method("GPA (Procrustes, EFA outline)", D, ms, sw.wall, sw.cpu))
    print(f"  GPA: {ms:.2f} ms/shape, all pairs {out[-1].s_pairs:.2f} s")
    try:
        import cv2  # noqa: F401
    except ImportError:
        print("  Hu moments skipped: OpenCV is not installed (pip install -e '.[bench]')")
        return out
    hu, ms, _ = describe(peers.hu_descriptor, masks, processes)
    with Stopwatch() as sw:
        D = peers.hu_distances(hu)
    err = peers.check_hu_against_opencv(masks, D)
    out.append(Method("OpenCV matchShapes (Hu, I1)", D, ms, sw.wall, sw.cpu,
                      notes=f"max |diff| vs cv2.matchShapes {err:.1e}"))
    print(f"  Hu: {ms:.2f} ms/shape, all pairs {sw.wall:.2f} s (vs cv2.matchShapes: {err:.1e})")
    return out


def run_shape_context(masks, subset_idx, processes: int, key: str, use_cache: bool) -> Method:
    sub = [masks[i] for i in subset_idx]
    descs, ms, _ = describe(peers.sc_descriptor, sub, processes)
    sub_key = hashlib.sha256(np.asarray(subset_idx).tobytes()).hexdigest()[:8]
    cache = CACHE_DIR / f"sc_{key}_{len(subset_idx)}_{sub_key}.npz"
    n_pairs = len(sub) * (len(sub) - 1) // 2
    if use_cache and cache.exists():
        z = np.load(cache)
        D, s = z["D"], float(z["seconds"])
        print(f"  shape context: matrix read from the cache {cache} (measured {s:.0f} s)")
    else:
        print(f"  shape context: {n_pairs} pairs on {processes} processes ...", flush=True)
        t0 = time.perf_counter()
        step = max(1, len(sub) // 10)

        def progress(done, total):
            if done % step == 0:
                print(f"    {done}/{total} rows, {time.perf_counter() - t0:.0f} s", flush=True)

        D = peers.sc_distances(descs, processes=processes, progress=progress)
        s = time.perf_counter() - t0
        CACHE_DIR.mkdir(parents=True, exist_ok=True)
        np.savez(cache, D=D, seconds=s)
    # CPU time per pair on a sample, in this process (the wall time above depends on the load)
    import cv2

    ext = cv2.createShapeContextDistanceExtractor()
    rng = np.random.default_rng(2)
    sample = rng.choice(len(sub), size=(100, 2))
    with Stopwatch() as sw:
        for i, j in sample:
            ext.computeDistance(descs[i], descs[j])
    cpu_pair = sw.cpu / len(sample)
    print(f"  shape context: {ms:.2f} ms/shape, {s:.0f} s wall for {n_pairs} pairs; "
          f"{1e3 * cpu_pair:.1f} CPU ms per pair")
    return Method("OpenCV shape context (100 pts)", D, ms, s, cpu_pair * n_pairs,
                  subset_only=True,
                  notes=f"{1e3 * cpu_pair:.1f} CPU ms/pair; d(i<j) used for both orders")


# --------------------------------------------------------------------------- PF-SDM variants
# option name -> (module, constant) in the core listing its values; only options present in the
# signatures of pfsdm / distance_matrix are used
OPTION_VALUES = {
    "radii": ("napari_pfsdm.core.morphometric", "RADII_PLACEMENTS"),
    "ring_weighting": ("napari_pfsdm.core.morphometric", "RING_WEIGHTINGS"),
    "mode_weighting": ("napari_pfsdm.core.morphometric", "MODE_WEIGHTINGS"),
    "mode_exponent": ("napari_pfsdm.core.morphometric", "MODE_EXPONENTS"),
    "invariance": ("napari_pfsdm.core.distances", "INVARIANCES"),
}
FALLBACK_VALUES = {
    "radii": ("uniform", "boundary"),
    "ring_weighting": ("none", "boundary"),
    "mode_exponent": (0.0, 0.25, 0.5),
    "invariance": ("magnitude", "align", "combined"),
}


def option_values(name: str) -> tuple:
    """The values the core accepts for one option (its constant, or a fallback)."""
    import importlib

    module, const = OPTION_VALUES[name]
    try:
        return tuple(getattr(importlib.import_module(module), const))
    except (ImportError, AttributeError):
        return FALLBACK_VALUES.get(name, ())


def _parse_value(v: str):
    for cast in (int, float):
        try:
            return cast(v)
        except ValueError:
            pass
    return {"true": True, "false": False}.get(v.lower(), v)


def expand_spec(spec: str) -> list[str]:
    """``"ring_weighting=*,invariance=align"`` -> one spec per value the core accepts."""
    parts = [p.strip() for p in spec.split(",") if p.strip()]
    choices = []
    for part in parts:
        key, _, value = part.partition("=")
        if value.strip() == "*" and key.strip() in OPTION_VALUES:
            choices.append([f"{key.strip()}={v}" for v in option_values(key.strip())])
        else:
            choices.append([part])
    return [",".join(c) for c in itertools.product(*choices)] if choices else [spec]


def parse_variant(spec: str) -> dict:
    """``"radii=boundary,invariance=align"`` -> dict; ``"default"`` -> {}."""
    if spec.strip().lower() in ("default", ""):
        return {}
    opts = {}
    for part in spec.split(","):
        if "=" not in part:
            raise ValueError(
                f"Cannot read the variant {spec!r}: write options as name=value separated by "
                "commas, e.g. radii=boundary,invariance=align (or 'default')."
            )
        k, v = part.split("=", 1)
        opts[k.strip()] = _parse_value(v.strip())
    return opts


def variant_name(opts: dict, defaults: dict | None = None) -> str:
    """"PF-SDM defaults" or "PF-SDM a=x, b=y" listing the options that differ from the
    defaults."""
    defaults = defaults or {}
    changed = {k: v for k, v in opts.items() if defaults.get(k, object()) != v}
    return "PF-SDM " + (", ".join(f"{k}={v}" for k, v in changed.items()) or "defaults")


def discover_variants(api) -> tuple[list[dict], dict, dict]:
    """Every combination of the known options present in ``pfsdm`` / ``distance_matrix``.

    Returns the variants and the parameter names of both functions (name -> default)."""
    p_params = {k: v.default for k, v in inspect.signature(api.pfsdm).parameters.items()}
    d_params = {k: v.default for k, v in inspect.signature(api.distance_matrix).parameters.items()}
    axes = []
    for name in OPTION_VALUES:
        if name in p_params or name in d_params:
            axes.append([(name, v) for v in option_values(name)])
    variants = [dict(combo) for combo in itertools.product(*axes)] if axes else [{}]
    return variants, p_params, d_params


def split_options(opts: dict, p_params: dict, d_params: dict) -> tuple[dict, dict]:
    p_opts, d_opts = {}, {}
    for k, v in opts.items():
        if k in p_params:
            p_opts[k] = v
        elif k in d_params:
            d_opts[k] = v
        else:
            raise ValueError(
                f"The PF-SDM option {k!r} is neither an argument of pfsdm() nor of "
                f"distance_matrix(); known: {sorted(set(p_params) | set(d_params))}."
            )
    return p_opts, d_opts


_PFSDM_KW: dict = {}


_HEAVY = ("contour", "sdf", "mapping", "samples", "disk", "mask_info", "intensity_image")


def _slim(res):
    """A shallow copy without the fields ``distance_matrix`` never reads (a full result pickles
    to ~250 kB: too much to send back from the workers for 1,400 shapes)."""
    out = copy.copy(res)
    for name in _HEAVY:
        if hasattr(out, name):
            object.__setattr__(out, name, None)
    return out


def _pfsdm_one(mask):
    import napari_pfsdm

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return napari_pfsdm.pfsdm(mask, **_PFSDM_KW)


def _pfsdm_one_slim(mask):
    res = _pfsdm_one(mask)
    res.outline  # noqa: B018  (cached before the contour is dropped: the boundary term needs it)
    return _slim(res)


#: Rows added next to "default": the SDF term alone (no boundary term).
OLD_DEFAULT = "invariance=combined,boundary_weight=0"
OUTLINE_ROW = "outline Procrustes (the boundary term alone)"


def run_pfsdm(masks, specs: list[str] | None, processes: int) -> list[Method]:
    try:
        import napari_pfsdm as api

        api.pfsdm, api.distance_matrix  # noqa: B018
    except (ImportError, AttributeError) as exc:
        print(f"  PF-SDM skipped: the core API is not available yet ({exc}).")
        return []
    variants, p_params, d_params = discover_variants(api)
    if specs and specs != ["all"]:
        if "default" in specs and OLD_DEFAULT not in specs and "boundary_weight" in d_params:
            specs = [*specs, OLD_DEFAULT]
        variants = [parse_variant(e) for spec in specs for e in expand_spec(spec)]
    defaults = {**p_params, **d_params}
    print(f"  pfsdm() options: {list(p_params)}")
    print(f"  distance_matrix() options: {list(d_params)}")
    out = []
    results_by_popts: dict = {}
    for opts in variants:
        p_opts, d_opts = split_options(opts, p_params, d_params)
        full_p = {k: p_opts.get(k, p_params[k]) for k in OPTION_VALUES if k in p_params}
        pkey = tuple(sorted({**full_p, **p_opts}.items(), key=lambda kv: kv[0]))
        if pkey not in results_by_popts:
            _PFSDM_KW.clear()
            _PFSDM_KW.update(p_opts)
            res, ms, wall = describe(_pfsdm_one_slim, masks, processes)
            folded = [r.diagnostics.get("folded_fraction", np.nan) for r in res]
            results_by_popts[pkey] = (res, ms, float(np.nanmean(folded)))
            print(f"  pfsdm({dict(pkey) or ''}): {ms:.2f} ms/shape, {wall:.0f} s wall, "
                  f"mean folded fraction {np.nanmean(folded):.3f}")
        res, ms, folded = results_by_popts[pkey]
        try:
            with Stopwatch() as sw:
                D = np.asarray(api.distance_matrix(res, **d_opts), dtype=float)
        except (ValueError, TypeError) as exc:
            print(f"  {variant_name(opts, defaults)} failed: {exc}")
            continue
        s = sw.wall
        out.append(Method(variant_name(opts, defaults), D, ms, s, sw.cpu, extra={"opts": opts},
                          notes=f"mean folded fraction {folded:.3f}"))
        print(f"  {out[-1].name}: all pairs {s:.2f} s")
        core_d = importlib.import_module("napari_pfsdm.core.distances")
        if not opts and hasattr(core_d, "boundary_term"):
            with Stopwatch() as sw:
                DB = core_d.boundary_term(res)
            out.append(Method(OUTLINE_ROW, DB, ms, sw.wall, sw.cpu,
                              notes="full Procrustes, free start point and mirror; "
                                    "core.boundary, ms/shape = the whole PF-SDM"))
            print(f"  {OUTLINE_ROW}: all pairs {sw.wall:.2f} s")
        if not opts and RERANK:
            from napari_pfsdm.analysis.rerank import rerank

            for method in RERANK:
                with Stopwatch() as sw2:
                    R = rerank(D, method)
                out.append(Method(f"PF-SDM defaults + rerank({method!r})", R, ms, s + sw2.wall,
                                  sw.cpu + sw2.cpu, notes=f"re-ranking {sw2.wall:.2f} s"))
                print(f"  {out[-1].name}: re-ranking {sw2.wall:.2f} s")
    return out


#: Re-ranking variants applied to the default distance (``--rerank``).
RERANK: list[str] = []


# =========================================================================== reporting
def score_rows(methods: list[Method], labels, subset_idx) -> list[dict]:
    rows = []
    n = len(labels)
    for m in methods:
        sets = [] if m.subset_only else [("all", np.arange(n))]
        if subset_idx is not None and len(subset_idx):
            sets.append((f"first {len(set(labels[subset_idx]))} classes", subset_idx))
        for set_name, idx in sets:
            if m.subset_only:
                D = m.D
            else:
                D = m.D[np.ix_(idx, idx)]
            lab = labels[idx]
            be = bullseye(D, lab)
            n_pairs = len(idx) * (len(idx) - 1) / 2
            rows.append({
                "method": m.name,
                "shapes": set_name,
                "n": len(idx),
                "bullseye_pct": round(be.score, 2),
                "loo_1nn_pct": round(loo_1nn(D, lab), 2),
                "ms_per_shape": round(m.ms_per_shape, 3),
                "s_all_pairs": round(m.s_pairs, 3),
                "cpu_s_all_pairs": round(m.s_pairs_cpu, 3),
                "us_per_pair": round(1e6 * m.s_pairs / (n * (n - 1) / 2 if not m.subset_only
                                                       else n_pairs), 3),
                "notes": m.notes,
            })
    return rows


def markdown_table(rows: list[dict]) -> str:
    lines = [
        "| method | shapes | bull's-eye % | LOO 1-NN % | CPU ms/shape | s all pairs (wall) "
        "| CPU s all pairs |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['method']} | {r['shapes']} ({r['n']}) | {r['bullseye_pct']:.2f} | "
            f"{r['loo_1nn_pct']:.2f} | {r['ms_per_shape']:.2f} | {r['s_all_pairs']:.2f} | "
            f"{r['cpu_s_all_pairs']:.2f} |"
        )
    return "\n".join(lines)


def write_csv(path: Path, rows: list[dict]) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def per_class_table(methods: list[Method], labels) -> tuple[list[str], dict[str, dict]]:
    classes = sorted(set(labels))
    table = {m.name: bullseye(m.D, labels).per_class for m in methods if not m.subset_only}
    return classes, table


def plot_per_class(path: Path, classes, table, main: str, ref: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    a = np.array([table[main][c] for c in classes])
    b = np.array([table[ref][c] for c in classes])
    order = np.argsort(a, kind="stable")
    y = np.arange(len(classes))
    fig, ax = plt.subplots(figsize=(8, 0.2 * len(classes) + 1.5))
    ax.barh(y - 0.2, a[order], height=0.4, color="tab:blue",
            label=f"{main} (mean {a.mean():.1f} %)")
    ax.barh(y + 0.2, b[order], height=0.4, color="tab:orange",
            label=f"{ref} (mean {b.mean():.1f} %)")
    ax.set_yticks(y, [classes[i] for i in order], fontsize=7)
    ax.set_ylim(-0.7, len(classes) - 0.3)
    ax.set_xlim(0, 100)
    ax.set_xlabel("bull's-eye per class (%)")
    ax.grid(axis="x", alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title("MPEG-7 CE-Shape-1: per-class bull's-eye, sorted by the first method",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_gallery(path: Path, masks, labels, names, D, per_class: dict, title: str,
                 n_classes: int = 6, n_neighbours: int = 10) -> list[str]:
    """Query and its nearest neighbours for the worst and best classes; misses framed red.

    The query shown for a class is its member with the median per-query bull's-eye."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ranked = sorted(per_class, key=lambda c: per_class[c])
    chosen = ranked[:n_classes] + ranked[-n_classes:]
    per_query = bullseye(D, labels).per_query
    cols = n_neighbours + 1
    fig, axes = plt.subplots(len(chosen), cols, figsize=(cols * 0.9 + 0.8, len(chosen) * 1.0 + 0.6))
    for row, cls in enumerate(chosen):
        members = np.flatnonzero(labels == cls)
        q = members[np.argsort(per_query[members], kind="stable")[len(members) // 2]]
        idx = [q, *nearest(D, q, n_neighbours)]
        for col, j in enumerate(idx):
            ax = axes[row, col]
            ax.imshow(masks[j], cmap="gray_r", interpolation="nearest")
            ax.set_xticks([])
            ax.set_yticks([])
            hit = labels[j] == cls
            colour = "black" if col == 0 else ("tab:green" if hit else "red")
            for sp in ax.spines.values():
                sp.set_edgecolor(colour)
                sp.set_linewidth(1.0 if (col == 0 or hit) else 2.5)
            ax.set_title(names[j], fontsize=5, color="black" if hit else "red", pad=1.5)
        axes[row, 0].set_ylabel(f"{cls}\n{per_class[cls]:.0f} %", fontsize=7, rotation=0,
                                ha="right", va="center")
    fig.suptitle(f"{title}: query (left) and its {n_neighbours} nearest; misses framed red.\n"
                 f"Top {n_classes} rows: worst classes; bottom {n_classes}: best.", fontsize=8)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return chosen


# =========================================================================== main
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", nargs="?", type=Path, default=DEFAULT_FOLDER,
                    help="MPEG-7 CE-Shape-1 folder of .gif files (default: %(default)s)")
    ap.add_argument("--subset", type=int, default=20, metavar="N",
                    help="run shape context on the first N classes (sorted names; 0 = skip)")
    ap.add_argument("--variants", nargs="*", default=["all"], metavar="SPEC",
                    help="PF-SDM variants: 'all' (every combination of the core's options), "
                         "'default', 'none', or specs like radii=boundary,invariance=align "
                         "(value * = every value the core accepts)")
    ap.add_argument("--main", default="default", metavar="SPEC",
                    help="the PF-SDM variant drawn in the PNGs (default: the core's defaults)")
    ap.add_argument("--processes", type=int, default=2)
    ap.add_argument("--classes", type=int, default=0, metavar="N",
                    help="quick check: use only the first N classes for everything (0 = all)")
    ap.add_argument("--no-peers", action="store_true", help="skip EFA, GPA and Hu")
    ap.add_argument("--rerank", nargs="*", default=None, metavar="METHOD",
                    help="also re-rank the default distance (napari_pfsdm.rerank); no value: "
                         "every method")
    ap.add_argument("--no-cache", action="store_true", help="recompute the cached masks / SC")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    print(f"load average at start: {os.getloadavg()[0]:.1f} (2 cores shared)")
    import subprocess

    head = subprocess.run(["git", "-C", str(REPO), "describe", "--always", "--dirty"],
                          capture_output=True, text=True).stdout.strip()

    print(f"MPEG-7 folder: {args.folder}")
    masks, labels, names, stats = load_masks(args.folder, use_cache=not args.no_cache)
    print(f"{len(masks)} shapes, {len(set(labels))} classes; {stats['multi']} with several "
          f"components (largest kept), {stats['shrunk']} shrunk to <= {MAX_SIDE} px, "
          f"{stats['split']} split by the shrinking (largest kept), {stats['holes']} with a "
          f"hole closed by the shrinking (filled)")
    classes = sorted(set(labels))
    if args.classes:
        keep = np.isin(labels, classes[: args.classes])
        masks = [m for m, k in zip(masks, keep, strict=True) if k]
        names = [nm for nm, k in zip(names, keep, strict=True) if k]
        labels = labels[keep]
        classes = classes[: args.classes]
        print(f"quick check on the first {args.classes} classes ({len(masks)} shapes)")
    subset_idx = None
    if args.subset > 0:
        keep = set(classes[: args.subset])
        subset_idx = np.flatnonzero([lab in keep for lab in labels])

    methods: list[Method] = []
    if not args.no_peers:
        print("peers:")
        methods += run_peers(masks, args.processes)
    if args.rerank is not None:
        from napari_pfsdm.analysis.rerank import RERANK_METHODS

        RERANK[:] = args.rerank or list(RERANK_METHODS)
    if args.variants != ["none"]:
        print("PF-SDM:")
        methods += run_pfsdm(masks, args.variants, args.processes)
    if subset_idx is not None:
        key = _folder_key(sorted(args.folder.glob("*.gif")))
        methods.append(run_shape_context(masks, subset_idx, args.processes, key,
                                         use_cache=not args.no_cache))

    rows = score_rows(methods, labels, subset_idx)
    table_md = markdown_table(rows)
    print("\n" + table_md)
    print(f"load average at end: {os.getloadavg()[0]:.1f}")
    args.out.mkdir(parents=True, exist_ok=True)
    print(f"core version (at start): git {head or 'unknown'}")
    table_md += f"\n\n(git {head or 'unknown'}; load average {os.getloadavg()[0]:.1f} on 2 cores)"
    (args.out / "mpeg7_results.md").write_text(
        f"`{' '.join(['benchmarks/mpeg7.py', *(argv if argv is not None else sys.argv[1:])])}`"
        f"\n\n{table_md}\n"
    )
    write_csv(args.out / "mpeg7_results.csv", rows)
    classes, table = per_class_table(methods, labels)
    with open(args.out / "mpeg7_per_class.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["class", *table])
        for c in classes:
            w.writerow([c, *(round(table[m][c], 2) for m in table)])

    # the PF-SDM default (or the best available method before the core lands) vs mirror EFA
    full = [m for m in methods if not m.subset_only]
    if not full:
        print(f"wrote {args.out}/mpeg7_results.csv, mpeg7_per_class.csv (no plots)")
        return 0
    main_name = "PF-SDM defaults"
    if args.main != "default":
        main_name = next((m.name for m in full if m.extra.get("opts") == parse_variant(args.main)),
                         args.main)
    main_m = next((m for m in full if m.name == main_name), None)
    if main_m is None:
        main_m = next((m for m in full if m.name.startswith("PF-SDM")), None)
    ref = REF
    if main_m is None:
        main_m = full[0]
    if ref in table:
        plot_per_class(args.out / "mpeg7_per_class.png", classes, table, main_m.name, ref)
    chosen = plot_gallery(args.out / "mpeg7_gallery.png", masks, labels, names, main_m.D,
                          table[main_m.name], main_m.name)
    worst, best = chosen[:6], chosen[6:]
    print(f"\n{main_m.name}: worst classes {', '.join(worst)}; best {', '.join(best)}")
    if ref in table:
        diff = {c: table[main_m.name][c] - table[ref][c] for c in classes}
        order = sorted(diff, key=diff.get)
        print(f"largest losses vs {ref}: "
              + ", ".join(f"{c} {diff[c]:+.0f}" for c in order[:6]))
        print(f"largest gains vs {ref}: "
              + ", ".join(f"{c} {diff[c]:+.0f}" for c in order[::-1][:6]))
    plots = ("mpeg7_per_class.png, " if ref in table else "") + "mpeg7_gallery.png"
    print(f"wrote {args.out}/mpeg7_results.csv, mpeg7_per_class.csv, {plots}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
