"""Thin and fine shapes: exterior SDF, multi-scale viscosity, bijective map
for folded objects only — prototyped against the default distance in the same run.

Run from the repository root (one process; heavy: ~20 min the first time, seconds once the
per-shape descriptors are cached in a temporary folder outside the repository)::

    PYTHONPATH=src /work/bin/heavy .venv/bin/python benchmarks/thin_shapes.py
    PYTHONPATH=src .venv/bin/python benchmarks/thin_shapes.py --classes 5 --no-viscous  # quick

Data: MPEG-7 CE-Shape-1 through ``benchmarks/mpeg7.py``'s loader and preprocessing (imported,
not copied), plus a synthetic proxy for "subtle outline detail among similar, pre-aligned
shapes" (:func:`fine_detail_set`; what it is and is not is in its docstring).

The variants (nothing in ``napari_pfsdm.core`` is changed; every variant is built here from the
default result's own pieces: its contour, exact SDF, harmonic map samples, weights):

``default``
    ``napari_pfsdm.distance_matrix(results)``: D = d_SDF (ring magnitudes) + λ d_B, λ = 1,
    rebuilt here from the stored embeddings and outlines (checked equal to the library's on
    the first shapes, to 1e-9).
``exterior normal``
    The SDF sampled *outside* the object on the outline's parallel curves: at the outline point
    X(1, θ) moved by t along the outward normal, g_t(θ) = φ(X(1, θ) + t n(θ)) / t, for
    t = 0.025, 0.05, 0.1, 0.2, 0.4 (normalised units, largest centroid distance = 1). g_t = 1
    exactly where the offset curve at distance t is still the level set φ = t (a convex
    outline: g ≡ 1, no information); it drops below 1 where the normal meets the exterior
    medial axis (a concavity, a gap between two parts: the turns of a coil, the teeth of a
    crown) and below 0 where it re-enters the object. These are the exterior analogue of the
    interior rings (the interior is the harmonic map's image; the exterior has no such map,
    see below), sampled in arc length like d_B, so a rotation, start point or mirror only
    moves θ: their Fourier magnitudes (modes 0–10, weighted (1 + n)^0.25, each ring 1/5) are
    appended to the magnitude term as extra rings with weight μ:
    D = sqrt(d_SDF² + μ² d_ext²) + d_B.
``exterior scaled``
    The same on scaled copies of the outline about the centroid, r X(1, θ), r = 1.05 … 1.8,
    g = φ / ((r − 1) |X|). Kept to compare: scaling follows the polar angle, not the
    outline, so in a deep concavity the copy lands inside the object for reasons of
    position, not of shape.
    (Not used: the harmonic map's own continuation Σ a_n r^|n| e^{inθ} past r = 1 multiplies
    mode n by r^n — the outline's pixel noise at n ≈ 100 by 10^8 at r = 1.2 — and the bounded
    exterior harmonic extension Σ a_n r^-|n| e^{inθ} collapses onto the centroid.)
``viscous ν``
    The viscous SDF (``core.sdf.ViscousSDF``, as ``pfsdm(sdf="viscous", viscosity=ν)``) at the
    default map's samples, ν = 0.05 and 0.2, alone, or as scales with the exact SDF (ν → 0):
    D = sqrt(mean over scales of d_SDF,ν²) + d_B (the mean keeps λ = 1's balance).
``bijective if folded > τ``
    ``pfsdm(mask, mapping="bijective")`` for the objects whose harmonic map's
    ``diagnostics["folded_fraction"]`` exceeds τ, the harmonic map for the rest; same d_B.

Outputs in ``benchmarks/out/``: ``thin_shapes.csv`` (one row per variant and shape set, the
per-class bull's-eye of the thin and finely detailed classes, :data:`NAMED`, as columns),
``thin_shapes.md`` (the table with the command line) and ``thin_shapes.png`` (per-class bars
and score against cost).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one thread: the machine is shared (before numpy is imported)

import argparse  # noqa: E402
import hashlib  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "examples"))  # the paper's reproductions

import mpeg7  # noqa: E402
import mpeg7_peers as peers  # noqa: E402
from napari_pfsdm.analysis.retrieval import bullseye, loo_1nn  # noqa: E402
from napari_pfsdm.core.boundary import boundary_distance_matrix  # noqa: E402
from napari_pfsdm.core.morphometric import magnitude_embedding, mode_weights, spectrum  # noqa: E402
from napari_pfsdm.core.sdf import ViscousSDF  # noqa: E402

CACHE = mpeg7.CACHE_DIR / "thin_shapes"
VERSION = "v1"
OFFSETS = np.array([0.025, 0.05, 0.1, 0.2, 0.4])  # exterior parallel curves, normalised units
SCALES = np.array([1.05, 1.1, 1.2, 1.4, 1.8])  # exterior scaled copies
NORMAL_MODES = 32  # the normal is taken from the outline's modes |n| <= 32 (pixel noise off)
VISCOSITIES = (0.05, 0.2)
TAUS = (0.2, 0.3, 0.4, 0.5)
MUS = (0.5, 1.0, 2.0)
NAMED = ("spring", "crown", "Comma", "Misk", "watch", "device4", "device6", "device9")
N_FOURIER = 10
#: Bull's-eye of a random ranking with 10 classes of 20: (1 + 39 · 19/199) / 20.
CHANCE = 100 * (1 + 39 * 19 / 199) / 20


# =========================================================================== per shape
def outward_normals(nodes: np.ndarray, keep: int = NORMAL_MODES) -> np.ndarray:
    """Unit outward normals (M, 2) of a counter-clockwise closed curve sampled in arc length,
    from its Fourier series truncated to |n| <= ``keep`` (the convention of core.sdf)."""
    z = nodes[:, 0] + 1j * nodes[:, 1]
    m = len(z)
    n = np.fft.fftfreq(m, 1.0 / m)
    c = np.fft.fft(z)
    c[np.abs(n) > keep] = 0
    dz = np.fft.ifft(1j * n * c)
    t = dz / np.maximum(np.abs(dz), 1e-12)
    return np.column_stack([t.imag, -t.real])


def exterior_profiles(sdf, nodes: np.ndarray, offsets: np.ndarray = OFFSETS,
                      keep: int = NORMAL_MODES) -> tuple[np.ndarray, np.ndarray]:
    """g on the parallel curves (len(offsets), M) and on the scaled copies (len(SCALES), M)."""
    normal = outward_normals(nodes, keep)
    offsets = np.asarray(offsets, float)
    pts = nodes[None] + offsets[:, None, None] * normal[None]
    g_normal = sdf(pts.reshape(-1, 2)).reshape(len(offsets), -1) / offsets[:, None]
    rho = np.maximum(np.hypot(nodes[:, 0], nodes[:, 1]), 1e-6)
    pts = SCALES[:, None, None] * nodes[None]
    g_scaled = (sdf(pts.reshape(-1, 2)).reshape(len(SCALES), -1)
                / ((SCALES[:, None] - 1) * rho[None]))
    return g_normal, g_scaled


def base_features(mask: np.ndarray) -> dict:
    """The default result's embedding and outline, the exterior profiles' magnitudes and the
    bijective map's embedding, with the CPU seconds of each step."""
    from napari_pfsdm import pfsdm

    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.process_time()
        res = pfsdm(mask)
        _ = res.outline
        out["t_default"] = time.process_time() - t0
        t0 = time.process_time()
        g_normal, g_scaled = exterior_profiles(res.sdf, res.contour.normalized)
        out["ext_normal"] = magnitude_embedding(spectrum(g_normal), N_FOURIER)
        out["ext_scaled"] = magnitude_embedding(spectrum(g_scaled), N_FOURIER)
        out["t_exterior"] = (time.process_time() - t0) / 2  # the two kinds cost the same
        t0 = time.process_time()
        bij = pfsdm(mask, mapping="bijective")
        out["t_bijective"] = time.process_time() - t0
    out["emb"] = res.embedding
    out["outline"] = res.outline
    out["folded"] = res.diagnostics["folded_fraction"]
    out["emb_bij"] = bij.embedding
    out["folded_bij"] = bij.diagnostics["folded_fraction"]
    out["weights"] = res.weights
    out["mode_weights"] = res.mode_weights
    return out


#: Other choices of the exterior rings, to see how much the score depends on them.
SENSITIVITY = {
    "offsets x0.5": (OFFSETS / 2, NORMAL_MODES),
    "offsets x2": (OFFSETS * 2, NORMAL_MODES),
    "offsets 0.05, 0.1, 0.2": (np.array([0.05, 0.1, 0.2]), NORMAL_MODES),
    "normal from 16 modes": (OFFSETS, 16),
    "normal from 64 modes": (OFFSETS, 64),
}


def exterior_sensitivity(mask: np.ndarray) -> dict:
    """The exterior parallel-curve magnitudes for every choice in :data:`SENSITIVITY`."""
    from napari_pfsdm import pfsdm

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pfsdm(mask)
    out = {}
    for i, (offsets, keep) in enumerate(SENSITIVITY.values()):
        g, _ = exterior_profiles(res.sdf, res.contour.normalized, offsets, keep)
        out[f"s{i}"] = magnitude_embedding(spectrum(g), N_FOURIER)
    return out


def exterior_invariance(masks: list[np.ndarray], n: int = 20) -> str:
    """Exterior and interior (SDF) ring magnitudes of a mask against its copy turned by 90°,
    its mirror image and its copy turned by 30° (resampled: the pixels change): the largest and
    median distance to the copy, relative to the median distance between different masks."""
    from skimage.transform import rotate

    from napari_pfsdm import pfsdm

    def feats(m):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = pfsdm(m)
        g, _ = exterior_profiles(r.sdf, r.contour.normalized)
        return magnitude_embedding(spectrum(g), N_FOURIER), r

    idx = np.linspace(0, len(masks) - 1, n).astype(int)
    pairs = [feats(masks[i]) for i in idx]
    e = np.stack([p[0] for p in pairs])
    w, mw = pairs[0][1].weights, pairs[0][1].mode_weights
    f = np.stack([p[1].embedding for p in pairs])
    typical = {"exterior": np.median(np.sqrt(ext_sq(e))[np.triu_indices(n, 1)]),
               "SDF": np.median(np.sqrt(sdf_sq(f, w, mw))[np.triu_indices(n, 1)])}
    moves = {"turned 90°": np.rot90, "mirrored": lambda m: m[:, ::-1],
             "turned 30°": lambda m: rotate(m.astype(float), 30, resize=True, order=1) > 0.5}
    lines = [f"invariance on {n} MPEG-7 masks (distance to the moved copy / median distance "
             "between different masks; largest, median):"]
    for name, move in moves.items():
        d = {"exterior": [], "SDF": []}
        for k, i in enumerate(idx):
            e2, r2 = feats(np.pad(move(masks[i]), 4))
            d["exterior"].append(np.sqrt(ext_sq(np.stack([e[k], e2]))[0, 1]))
            d["SDF"].append(np.sqrt(sdf_sq(np.stack([f[k], r2.embedding]), w, mw))[0, 1])
        lines.append(f"  {name}: " + "; ".join(
            f"{t} rings {max(v) / typical[t]:.3f}, {np.median(v) / typical[t]:.3f}"
            for t, v in d.items()))
    return "\n".join(lines)


def viscous_features(mask: np.ndarray, nu: float) -> dict:
    """The viscous SDF's ring magnitudes at the default (harmonic) map's samples."""
    from napari_pfsdm import pfsdm

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pfsdm(mask)
        t0 = time.process_time()
        v = ViscousSDF(res.contour.normalized, viscosity=nu)
        disk = v(res.samples.reshape(-1, 2)).reshape(res.disk.shape)
        t = time.process_time() - t0
    return {"emb": magnitude_embedding(spectrum(disk), N_FOURIER), "t": t}


def _key(masks: list[np.ndarray], tag: str) -> str:
    h = hashlib.sha256(f"{VERSION}-{tag}".encode())
    for m in masks:
        h.update(np.packbits(m).tobytes())
        h.update(str(m.shape).encode())
    return h.hexdigest()[:16]


def cached(fn, masks: list[np.ndarray], tag: str, label: str) -> dict[str, np.ndarray]:
    """Stack ``fn(mask)`` over the masks (one process), cached in a temporary .npz."""
    CACHE.mkdir(parents=True, exist_ok=True)
    path = CACHE / f"{tag}_{_key(masks, tag)}.npz"
    if path.exists():
        print(f"  {label}: read from the cache {path}")
        return dict(np.load(path))
    t0 = time.perf_counter()
    rows = []
    for i, m in enumerate(masks):
        rows.append(fn(m))
        if (i + 1) % 200 == 0:
            print(f"    {label}: {i + 1}/{len(masks)}, {time.perf_counter() - t0:.0f} s",
                  flush=True)
    out = {k: np.stack([np.asarray(r[k]) for r in rows]) for k in rows[0]}
    np.savez(path, **out)
    print(f"  {label}: {len(masks)} shapes in {time.perf_counter() - t0:.0f} s wall")
    return out


# =========================================================================== distances
def _sq(f: np.ndarray) -> np.ndarray:
    aa = np.einsum("ij,ij->i", f, f)
    return np.maximum(aa[:, None] + aa[None, :] - 2 * f @ f.T, 0.0)


def sdf_sq(emb: np.ndarray, weights: np.ndarray, modes: np.ndarray) -> np.ndarray:
    """Squared magnitude SDF distances, as core.distances (ring and mode weights)."""
    f = (emb * np.sqrt(weights)[None, :, None] * modes[None, None, :]).reshape(len(emb), -1)
    return _sq(f)


def ext_sq(emb: np.ndarray) -> np.ndarray:
    """Squared exterior-ring distances: mode weights (1 + n)^0.25, each ring 1/K."""
    k = emb.shape[1]
    return sdf_sq(emb, np.full(k, 1.0 / k), mode_weights(N_FOURIER, 0.25))


def _finish(D: np.ndarray) -> np.ndarray:
    np.fill_diagonal(D, 0.0)
    return D


def variant_matrices(base: dict, visc: dict[float, dict], d_b: np.ndarray) -> dict:
    """name -> (D, extra CPU seconds per shape over the default descriptor)."""
    w, mw = base["weights"][0], base["mode_weights"][0]
    sq0 = sdf_sq(base["emb"], w, mw)
    out = {
        "default (SDF + boundary)": (np.sqrt(sq0) + d_b, 0.0),
        "SDF term alone": (np.sqrt(sq0), 0.0),
        "boundary term alone": (d_b.copy(), 0.0),
    }
    t_ext = float(base["t_exterior"].mean())
    for kind in ("normal", "scaled"):
        sqe = ext_sq(base[f"ext_{kind}"])
        for mu in MUS if kind == "normal" else (1.0,):
            out[f"exterior {kind}, mu={mu:g}"] = (np.sqrt(sq0 + mu**2 * sqe) + d_b, t_ext)
        if kind == "normal":
            out["exterior normal alone"] = (np.sqrt(sqe), t_ext)
    sq_v = {nu: sdf_sq(v["emb"], w, mw) for nu, v in visc.items()}
    t_v = {nu: float(v["t"].mean()) for nu, v in visc.items()}
    for nu, s in sq_v.items():
        out[f"viscous nu={nu:g} (replaces exact)"] = (np.sqrt(s) + d_b, t_v[nu])
    for name, emb in base.get("sensitivity", {}).items():
        out[f"exterior normal, mu=1, {name}"] = (np.sqrt(sq0 + ext_sq(emb)) + d_b, t_ext)
    if len(sq_v) >= 2:
        out[f"viscous scales {'+'.join(f'{nu:g}' for nu in sq_v)}"] = (
            np.sqrt(sum(sq_v.values()) / len(sq_v)) + d_b, sum(t_v.values()))
    if sq_v:
        out[f"exact + viscous {'+'.join(f'{nu:g}' for nu in sq_v)}"] = (
            np.sqrt((sq0 + sum(sq_v.values())) / (1 + len(sq_v))) + d_b, sum(t_v.values()))
    if "emb_bij" in base:
        t_bij = base["t_bijective"]
        for tau in (*TAUS, 0.0):
            sel = base["folded"] > tau
            emb = np.where(sel[:, None, None], base["emb_bij"], base["emb"])
            name = (f"bijective if folded > {tau:g} ({sel.sum()} objects)" if tau
                    else "bijective for every object")
            # the harmonic result is computed first (it tells which objects fold)
            out[name] = (np.sqrt(sdf_sq(emb, w, mw)) + d_b,
                         float((t_bij * sel).mean()) if tau else float(t_bij.mean()))
    return {k: (_finish(D), t) for k, (D, t) in out.items()}


# =========================================================================== scoring
def score(matrices: dict, labels: np.ndarray, t_default: float, shapes: str,
          classes: tuple[str, ...]) -> list[dict]:
    rows = []
    for name, (D, extra) in matrices.items():
        be = bullseye(D, labels)
        row = {"variant": name, "shapes": shapes, "n": len(labels),
               "bullseye_pct": round(be.score, 2), "loo_1nn_pct": round(loo_1nn(D, labels), 2),
               "ms_per_shape": round(1e3 * (t_default + extra), 2),
               "cost_ratio": round((t_default + extra) / t_default, 2)}
        for c in classes:
            row[c] = round(be.per_class.get(c, float("nan")), 1)
        rows.append(row)
    return rows


def markdown(rows: list[dict], classes: tuple[str, ...]) -> str:
    head = ("| variant | bull's-eye % | 1-NN % | cost × default | "
            + " | ".join(classes) + " |")
    lines = [head, "|" + "---|" * (4 + len(classes))]
    for r in rows:
        lines.append(f"| {r['variant']} | {r['bullseye_pct']:.2f} | {r['loo_1nn_pct']:.2f} | "
                     f"{r['cost_ratio']:.2f} | "
                     + " | ".join(f"{r[c]:.0f}" for c in classes) + " |")
    return "\n".join(lines)


def held_out_choice(matrices: dict, labels: np.ndarray) -> str:
    """Choose the exterior-ring variant (μ, offsets, normal) on half of the classes, score it
    on the other half against the default there: is the gain more than the choice?"""
    classes = np.array(sorted(set(labels)))
    lines = ["exterior rings chosen on half of the classes, scored on the other half "
             "(bull's-eye %, default -> chosen):"]
    candidates = [k for k in matrices if k.startswith("exterior normal,")]
    for name, half in (("even classes", classes[::2]), ("odd classes", classes[1::2])):
        fit = np.isin(labels, half)
        test = ~fit

        def be(key, sel):
            D = matrices[key][0]
            return bullseye(D[np.ix_(sel, sel)], labels[sel]).score

        best = max(candidates, key=lambda k: be(k, fit))
        d0, d1 = be("default (SDF + boundary)", test), be(best, test)
        lines.append(f"  chosen on the {name}: {best!r}; on the others {d0:.2f} -> {d1:.2f} "
                     f"({d1 - d0:+.2f})")
    return "\n".join(lines)


def reranked(matrices: dict, labels: np.ndarray) -> str:
    """Does the exterior rings' gain survive the collection-level re-ranking?"""
    from napari_pfsdm.analysis.rerank import rerank

    lines = ["with rerank(D) (diffusion, the library's default):"]
    for key in ("default (SDF + boundary)", "exterior normal, mu=1"):
        R = rerank(matrices[key][0])
        lines.append(f"  {key}: bull's-eye {bullseye(R, labels).score:.2f} %, "
                     f"1-NN {loo_1nn(R, labels):.2f} %")
    return "\n".join(lines)


def comparability(base: dict, sq0_nn: np.ndarray) -> str:
    """How far one object's harmonic and bijective SDF terms are, against the distance to its
    nearest other object (harmonic): can the two kinds be mixed in one collection?"""
    w, mw = base["weights"][0], base["mode_weights"][0]
    f = lambda e: (e * np.sqrt(w)[None, :, None] * mw[None, None, :]).reshape(len(e), -1)  # noqa: E731
    self_d = np.linalg.norm(f(base["emb"]) - f(base["emb_bij"]), axis=1)
    ratio = self_d / np.maximum(sq0_nn, 1e-12)
    folded = base["folded"]
    lines = []
    for lo, hi in ((0, 0.05), (0.05, 0.2), (0.2, 0.4), (0.4, 1.01)):
        sel = (folded >= lo) & (folded < hi)
        if sel.any():
            lines.append(f"folded fraction [{lo:g}, {hi:g}): {sel.sum()} objects, "
                         f"d_SDF(harmonic, bijective) of the same object / its nearest-"
                         f"neighbour d_SDF: median {np.median(ratio[sel]):.2f}, "
                         f"> 1 for {100 * np.mean(ratio[sel] > 1):.0f} %")
    return "\n".join(lines)


# =========================================================================== synthetic proxy
def fine_detail_set(fine: float, n_classes: int = 10, per_class: int = 20, size: int = 160,
                    seed: int = 0) -> tuple[list[np.ndarray], np.ndarray]:
    """Smooth, similar, pre-aligned outlines whose classes differ only by fine detail.

    Every object is one wing-like base outline (an ellipse of aspect 0.4 with a fixed,
    asymmetric low-mode deformation), in the same orientation (±3°), size ±5 %. Class k adds
    its own fine radial detail — modes 8–16 with random phases, RMS ``fine`` (in units of
    the mean radius). Each member adds its own coarse variation — modes 2–4, RMS 0.03 —
    which is the nuisance: it is larger than the class signal for ``fine`` < 0.03. Rasterised
    at ``size`` px.

    What it is: a test of whether a descriptor ranks fine outline detail above coarse
    within-class variation among pre-aligned shapes, the situation of insect wings. What it is
    not: wings (no venation, no landmarks, no real biological variation; the class signal is
    a random band-limited pattern, which is a lucky case for Fourier-based outlines).
    """
    from skimage.draw import polygon

    rng = np.random.default_rng(seed)
    t = np.linspace(0, 2 * np.pi, 720, endpoint=False)

    def band(lo, hi, rms, r):
        m = np.arange(lo, hi + 1)
        a = r.normal(size=len(m)) / np.sqrt(len(m))
        ph = r.uniform(0, 2 * np.pi, len(m))
        f = (a[:, None] * np.cos(m[:, None] * t[None] + ph[:, None])).sum(0)
        return rms * f / np.sqrt(np.mean(f**2))

    base = 1 + band(2, 3, 0.06, np.random.default_rng(1000 + seed))
    class_detail = [band(8, 16, fine, rng) for _ in range(n_classes)]
    masks, labels = [], []
    for k in range(n_classes):
        for _ in range(per_class):
            rad = base + class_detail[k] + band(2, 4, 0.03, rng)
            ang = np.deg2rad(rng.uniform(-3, 3))
            s = 0.42 * size * rng.uniform(0.95, 1.05)
            x, y = rad * np.cos(t), 0.4 * rad * np.sin(t)
            xr = x * np.cos(ang) - y * np.sin(ang)
            yr = x * np.sin(ang) + y * np.cos(ang)
            m = np.zeros((size, size), bool)
            rr, cc = polygon(size / 2 + s * yr, size / 2 + s * xr, m.shape)
            m[rr, cc] = True
            masks.append(m)
            labels.append(f"c{k}")
    return masks, np.array(labels)


def five_shapes(viscous: bool) -> list[dict]:
    """The five-shape benchmark's sets (random rotation, reflection, scale; exact and
    perturbed copies): silhouette and 1-NN, to see the exterior rings on data that took no
    part in choosing them."""
    from synthetic_five_shapes import build_set, scores

    rows = []
    for set_name in ("exact", "perturbed"):
        masks, labels, _ = build_set(set_name)
        name = f"five shapes, {set_name}"
        _, mats, _, _ = run_set(masks, labels, name, viscous, False, ())
        for variant, (D, _) in mats.items():
            sil, nn = scores(D, labels)
            rows.append({"shapes": name, "variant": variant, "silhouette": sil, "loo_1nn": nn})
    return rows


def peers_matrices(masks: list[np.ndarray]) -> dict:
    """EFA (resolved, mirror-aware) and GPA, as in benchmarks/mpeg7.py; cost ratio unknown."""
    efa = [peers.efa_resolved_descriptor(m) for m in masks]
    gpa = [peers.gpa_descriptor(m) for m in masks]
    return {"EFA resolved mirror-aware (peer)": (peers.efa_resolved_distances(
                efa, mirror_aware=True), np.nan),
            "GPA (peer)": (peers.gpa_distances(gpa), np.nan),
            "pre-aligned overlap 1 - IoU (peer)": (overlap_distances(masks), np.nan)}


def overlap_distances(masks: list[np.ndarray], grid: int = 128) -> np.ndarray:
    """1 − IoU of the masks centred on their centroid and scaled to the same area, in the
    image's orientation: a distance that uses the pre-alignment (no rotation search)."""
    from scipy import ndimage as ndi

    c = (np.arange(grid) + 0.5) / grid * 2 - 1
    u, v = np.meshgrid(c, c, indexing="ij")
    flat = []
    for m in masks:
        rows, cols = np.nonzero(m)
        half = 1.25 * np.sqrt(len(rows))  # the grid spans 2.5 sqrt(area): room for aspect 0.3
        coords = [rows.mean() + u * half, cols.mean() + v * half]
        flat.append(ndi.map_coordinates(m.astype(float), coords, order=1).ravel() > 0.5)
    X = np.array(flat, float)
    inter = X @ X.T
    area = X.sum(1)
    union = area[:, None] + area[None, :] - inter
    return _finish(1.0 - inter / np.maximum(union, 1.0))


# =========================================================================== plot
def plot(path: Path, rows: list[dict], classes: tuple[str, ...], shown: list[str],
         synth_rows: list[dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(14, 6.5),
                                  gridspec_kw={"width_ratios": [1.7, 1]})
    by = {r["variant"]: r for r in rows if r["shapes"] == "MPEG-7"}
    shown = [s for s in shown if s in by]
    y = np.arange(len(classes))
    h = 0.8 / len(shown)
    for j, name in enumerate(shown):
        vals = [by[name][c] for c in classes]
        ax.barh(y + (j - (len(shown) - 1) / 2) * h, vals, height=h,
                label=f"{name} ({by[name]['bullseye_pct']:.1f} %)")
    ax.set_yticks(y, classes, fontsize=8)
    ax.invert_yaxis()
    ax.set_xlim(0, 100)
    ax.set_xlabel("bull's-eye per class (%)")
    ax.grid(axis="x", alpha=0.3)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2)
    ax.set_title("MPEG-7: thin and finely detailed classes and the default's worst", fontsize=9)
    for k, r in enumerate(rows):
        if r["shapes"] != "MPEG-7" or "alone" in r["variant"]:
            continue
        ax2.scatter(r["cost_ratio"], r["bullseye_pct"], s=18,
                    color="tab:red" if r["variant"].startswith("default") else "tab:blue")
        label = (r["variant"].replace("bijective if folded", "bij. if folded")
                 .replace(" (replaces exact)", "").replace("exterior normal, mu=1, ", "ext. "))
        label = label.split(" (")[0]
        ax2.annotate(label, (r["cost_ratio"], r["bullseye_pct"]), fontsize=6,
                     xytext=(3, 2 - 9 * (k % 2) * r["variant"].startswith("bij")),
                     textcoords="offset points")
    ax2.set_xscale("log")
    ax2.set_xlabel("CPU cost per shape / default's (same run, log)")
    ax2.set_ylabel("MPEG-7 bull's-eye (%)")
    ax2.grid(alpha=0.3)
    title = "overall score against cost"
    if synth_rows:
        best = max(synth_rows, key=lambda r: r["bullseye_pct"])
        dflt = next(r for r in synth_rows if r["variant"].startswith("default"))
        title += (f"\nfine-detail proxy: default {dflt['bullseye_pct']:.0f} %, best "
                  f"{best['variant']} {best['bullseye_pct']:.0f} % (chance {CHANCE:.1f} %)")
    ax2.set_title(title, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# =========================================================================== main
def check_anchor(masks, labels, D_default) -> float:
    """Max |difference| of the rebuilt default against napari_pfsdm.distance_matrix."""
    import napari_pfsdm as api

    idx = np.arange(min(30, len(masks)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = [api.pfsdm(masks[i]) for i in idx]
    D = api.distance_matrix(res)
    return float(np.abs(D - D_default[np.ix_(idx, idx)]).max())


def run_set(masks, labels, shapes: str, viscous: bool, bijective: bool, classes) -> tuple:
    tag = "mpeg7" if shapes == "MPEG-7" else shapes.replace(" ", "_")
    base = cached(base_features, masks, f"base_{tag}", f"{shapes}: default + exterior + "
                  "bijective")
    if not bijective:
        base.pop("emb_bij")
    if shapes == "MPEG-7":
        sens = cached(exterior_sensitivity, masks, f"sens_{tag}", f"{shapes}: exterior choices")
        base["sensitivity"] = {name: sens[f"s{i}"] for i, name in enumerate(SENSITIVITY)}
    visc = {}
    if viscous:
        for nu in VISCOSITIES:
            visc[nu] = cached(lambda m, nu=nu: viscous_features(m, nu), masks,
                              f"visc{nu:g}_{tag}", f"{shapes}: viscous nu={nu:g}")
    t0 = time.perf_counter()
    d_b = boundary_distance_matrix(base["outline"])
    print(f"  boundary term, all pairs: {time.perf_counter() - t0:.1f} s")
    mats = variant_matrices(base, visc, d_b)
    t_def = float(base["t_default"].mean())
    print(f"  default descriptor: {1e3 * t_def:.2f} CPU ms/shape; exterior profiles "
          f"{1e3 * base['t_exterior'].mean():.2f}; bijective map "
          f"{1e3 * base['t_bijective'].mean():.1f}; viscous "
          + ", ".join(f"nu={nu:g} {1e3 * v['t'].mean():.0f}" for nu, v in visc.items()))
    return base, mats, t_def, d_b


def _mean(values: np.ndarray, sel: np.ndarray) -> float:
    return float(values[sel].mean()) if sel.any() else float("nan")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", nargs="?", type=Path, default=mpeg7.DEFAULT_FOLDER)
    ap.add_argument("--classes", type=int, default=0, help="first N classes only (0 = all)")
    ap.add_argument("--no-viscous", action="store_true", help="skip the (slow) viscous SDF")
    ap.add_argument("--no-synthetic", action="store_true")
    ap.add_argument("--out", type=Path, default=mpeg7.OUT)
    args = ap.parse_args(argv)
    head = subprocess.run(["git", "-C", str(HERE.parent), "describe", "--always", "--dirty"],
                          capture_output=True, text=True).stdout.strip()
    print(f"git {head}; load average {os.getloadavg()[0]:.1f}; one process, one thread")
    masks, labels, names, _ = mpeg7.load_masks(args.folder)
    if args.classes:
        keep = np.isin(labels, sorted(set(labels))[: args.classes])
        masks = [m for m, k in zip(masks, keep, strict=True) if k]
        labels = labels[keep]
    print(f"MPEG-7: {len(masks)} shapes")
    base, mats, t_def, d_b = run_set(masks, labels, "MPEG-7", not args.no_viscous, True, NAMED)
    err = check_anchor(masks, labels, mats["default (SDF + boundary)"][0])
    print(f"  rebuilt default vs napari_pfsdm.distance_matrix (30 shapes): max |diff| {err:.1e}")
    default_pc = bullseye(mats["default (SDF + boundary)"][0], labels).per_class
    worst = tuple(c for c in sorted(default_pc, key=default_pc.get) if c not in NAMED)[:6]
    classes = (*[c for c in NAMED if c in default_pc], *worst)
    rows = score(mats, labels, t_def, "MPEG-7", classes)
    sq0 = np.sqrt(sdf_sq(base["emb"], base["weights"][0], base["mode_weights"][0]))
    np.fill_diagonal(sq0, np.inf)
    comp = comparability(base, sq0.min(axis=1))
    ff = base["folded"]
    fold_txt = (f"folded fraction (harmonic): mean {ff.mean():.3f}, > 0.2: {np.sum(ff > 0.2)}, "
                f"> 0.3: {np.sum(ff > 0.3)}, > 0.4: {np.sum(ff > 0.4)}; spring mean "
                f"{_mean(ff, labels == 'spring'):.2f}; bijective: mean "
                f"{base['folded_bij'].mean():.3f}, spring "
                f"{_mean(base['folded_bij'], labels == 'spring'):.2f}")
    print(fold_txt)
    print(comp)
    invariance = exterior_invariance(masks)
    print(invariance)
    if not args.classes:
        invariance += "\n\n" + held_out_choice(mats, labels) + "\n\n" + reranked(mats, labels)
        print(invariance.split("\n\n", 1)[1])

    synth_rows = []
    if not args.no_synthetic:
        for fine in (0.01, 0.02):
            sm, sl = fine_detail_set(fine)
            name = f"fine-detail proxy {fine:g}"
            _, smats, st, _ = run_set(sm, sl, name, not args.no_viscous, False, ())
            smats.update(peers_matrices(sm))
            r = score(smats, sl, st, name, ())
            synth_rows += r
    five_rows = [] if args.no_synthetic else five_shapes(not args.no_viscous)
    table = markdown(rows, classes)
    print("\n" + table)
    if synth_rows:
        print()
        for r in synth_rows:
            print(f"{r['shapes']}: {r['variant']}: bull's-eye {r['bullseye_pct']:.1f} %, "
                  f"1-NN {r['loo_1nn_pct']:.1f} %")
    args.out.mkdir(parents=True, exist_ok=True)
    all_rows = rows + [{**r, **dict.fromkeys(classes, "")} for r in synth_rows]
    mpeg7.write_csv(args.out / "thin_shapes.csv", all_rows)
    synth_md = "\n".join(f"| {r['shapes']} | {r['variant']} | {r['bullseye_pct']:.1f} | "
                         f"{r['loo_1nn_pct']:.1f} |" for r in synth_rows)
    cmd = " ".join(["benchmarks/thin_shapes.py", *(argv if argv is not None else sys.argv[1:])])
    five_md = "\n".join(f"| {r['shapes']} | {r['variant']} | {r['silhouette']:.3f} | "
                        f"{r['loo_1nn']:.3f} |" for r in five_rows)
    for r in five_rows:
        print(f"{r['shapes']}: {r['variant']}: silhouette {r['silhouette']:.3f}, "
              f"1-NN {r['loo_1nn']:.3f}")
    (args.out / "thin_shapes.md").write_text(
        f"`{cmd}` (git {head}, load average {os.getloadavg()[0]:.1f})\n\n{table}\n\n{fold_txt}\n\n"
        f"{comp}\n\n{invariance}\n\n| set | variant | bull's-eye % | 1-NN % |\n|---|---|---|---|\n"
        f"{synth_md}\n\n| set | variant | silhouette | 1-NN |\n|---|---|---|---|\n{five_md}\n")
    shown = ["default (SDF + boundary)", "exterior normal, mu=1", "exterior scaled, mu=1",
             "exact + viscous 0.05+0.2",
             next((r["variant"] for r in rows
                   if r["variant"].startswith("bijective if folded > 0.3")), "")]
    plot(args.out / "thin_shapes.png", rows, classes, shown, [
        r for r in synth_rows if r["shapes"].endswith("0.02")])
    print(f"wrote {args.out}/thin_shapes.csv, thin_shapes.md, thin_shapes.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
