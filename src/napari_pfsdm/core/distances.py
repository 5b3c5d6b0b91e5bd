"""PF-SDM distances between objects (docs/design.md §2.6, §2.9), for two or thousands at once.

The default distance has two terms (docs/design.md §2.9):

    D(S₁, S₂) = d_SDF(S₁, S₂) + λ · d_B(S₁, S₂),   λ = :data:`BOUNDARY_WEIGHT` = 1.

d_SDF compares the pushed-forward SDFs: d_SDF² = ∫₀¹ ‖e₁(r) − e₂(r)‖² dr + w_I ∫₀¹ ‖i₁(r) −
i₂(r)‖² dr, by the quadrature weights of the rings (the paper's d is its square, same
ranking). d_B (:mod:`napari_pfsdm.core.boundary`) compares what φ∘X drops: where the map X
puts the values, i.e. X on the unit circle, the outline in arc length; it is the full
Procrustes distance of the two outlines with free start point and mirror, in [0, 1].
``boundary_weight=0`` gives the SDF term alone.

An elastic outline term is opt-in (``elastic_weight`` μ > 0, :mod:`napari_pfsdm.core.elastic`):
D + μ · d_E, d_E the mean L1 cost per point of the best elastic correspondence between the
two outlines' multi-scale signatures (dynamic programming over start point, mirror and local
stretching). It needs the signatures (results, or a table measured with them) and costs
about 3 times the default distance's time for all pairs on 2 cores, 5 times on one
(docs/benchmarks.md).

Three ways to remove rotation and reflection from the SDF term (``invariance``):

``"magnitude"``
    Compare the magnitudes |c_n(r)| (the embedding). Fast (one matrix product for all pairs).
``"align"``
    Keep the complex c_n(r) and minimise the distance over every rotation (cyclic shift in θ)
    and over the reflection θ → −θ, all shifts at once by an FFT cross-correlation. It keeps the
    phase relation between rings and between modes that magnitudes discard; always ≥ the
    magnitude distance. Needs results (a table holds magnitudes only).
``"combined"``
    The sum of the two (72.5 % bull's-eye on MPEG-7 without the boundary term).

The default is ``"magnitude"`` plus the boundary term (79.5 % on MPEG-7, docs/benchmarks.md):
with d_B, aligning the SDF phases adds nothing measurable (79.7 %) and costs most of the time,
and a feature table holds what it needs (magnitudes and outline coefficients).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from . import distances3d
from .boundary import boundary_distance_matrix
from .elastic import elastic_distance_matrix
from .embeddings import Embeddings
from .params import option
from .threads import blas_threads_by

__all__ = [
    "BOUNDARY_WEIGHT",
    "ELASTIC_WEIGHT",
    "INVARIANCES",
    "RECOMMENDED_ELASTIC_WEIGHT",
    "boundary_term",
    "channel_arrays",
    "check_boundary_weight",
    "check_elastic_weight",
    "check_weight",
    "elastic_term",
    "distance",
    "distance_matrix",
    "Embeddings",
    "magnitude_features",
    "no_boundary_in_3d",
    "no_elastic_in_3d",
    "weighted_features",
]

INVARIANCES = ("combined", "magnitude", "align")

#: λ, the weight of the boundary term d_B in the default distance, declared with its range in
#: the option record (``core.params.WEIGHT_OPTIONS``). d_B (a sine, in [0, 1]) and
#: the default magnitude SDF distance have similar spreads on real and synthetic outlines
#: (median off-diagonal values: MPEG-7 0.29 and 0.42; five-shape benchmark 0.30 and 0.25);
#: λ = 1 is the best or within 0.1 point of the best on MPEG-7 (λ = 0.75, 1, 1.25: 79.4,
#: 79.5, 79.5 % bull's-eye) and beats GPA's silhouette on the five-shape benchmark. A fixed
#: number, so that a distance never depends on the other objects of a collection.
BOUNDARY_WEIGHT = option("boundary_weight").default

#: μ, the weight of the elastic outline term d_E (:mod:`.elastic`) in the default distance:
#: 0, the term is opt-in (MPEG-7 and its leave-classes-out study in docs/benchmarks.md give
#: the weight that retrieves best, ``RECOMMENDED_ELASTIC_WEIGHT``).
ELASTIC_WEIGHT = option("elastic_weight").default
#: The weight of d_E chosen by leave-classes-out cross-validation on MPEG-7
#: (``benchmarks/mpeg7_elastic.py``, docs/benchmarks.md).
RECOMMENDED_ELASTIC_WEIGHT = 0.375


def magnitude_features(emb: np.ndarray, weights: np.ndarray, modes: np.ndarray) -> np.ndarray:
    return (emb * np.sqrt(weights)[None, :, None] * modes[None, None, :]).reshape(len(emb), -1)


@blas_threads_by(lambda a, b: 2.0 * a.size * len(b))
def _sq_euclidean(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    aa = np.einsum("ij,ij->i", a, a)
    bb = np.einsum("ij,ij->i", b, b)
    g = a @ b.T  # in place from here: n × n temporaries dominate the memory for many objects
    g *= -2.0
    g += aa[:, None]
    g += bb[None, :]
    return np.maximum(g, 0.0, out=g)


def _n_shifts(n_modes: int) -> int:
    """Angles at which :func:`_align_sq` samples the correlation of ``n_modes`` modes."""
    return max(64, 8 * n_modes)


def _align_flops(spec: list[np.ndarray], weights: list[np.ndarray], chunk: int) -> float:
    """Operations of :func:`_align_sq`'s largest products: a chunk's rings' cross terms, or its
    correlations times the angles' basis."""
    n, n_rings, k = spec[0].shape
    rows = min(chunk, n)
    return max(8.0 * rows * n_rings * n, 4.0 * rows * n * k * _n_shifts(k))


@blas_threads_by(_align_flops)
def _align_sq(spec: list[np.ndarray], weights: list[np.ndarray], chunk: int) -> np.ndarray:
    """Squared aligned distance for all pairs: min over rotations and the reflection of the
    weighted L2 distance of complex spectra (n, R, K), summed over channels.

    d²(s) = ‖a‖² + ‖b‖² − 2 C(s) with C(s) = Re Σ_m X_m e^{ims}, X_m = Σ_r w_r a_rm conj(b_rm)
    (a reflection conjugates b). C is sampled at max(64, 8K) angles by a real matrix product and
    its best sample refined by a parabola. The (i, j) and (j, i) estimates (single precision,
    computed apart) are averaged, so that the matrix is exactly symmetric.
    """
    n, _, k = spec[0].shape
    n_shift = _n_shifts(k)
    m = np.arange(k)
    ang = np.outer(m, 2 * np.pi * np.arange(n_shift) / n_shift)
    # single precision: twice the speed of the matrix products, errors ~1e-7 of ‖a‖‖b‖
    basis = np.vstack([np.cos(ang), -np.sin(ang)]).astype(np.float32)  # Re(X e^{ims})
    norms = sum(np.einsum("irk,r->i", np.abs(s) ** 2, w)
                for s, w in zip(spec, weights, strict=True))
    flat = [np.ascontiguousarray((s * np.sqrt(w)[None, :, None]).transpose(2, 0, 1),
                                 dtype=np.complex64)
            for s, w in zip(spec, weights, strict=True)]  # (K, n, R)
    out = np.empty((n, n))
    for i0 in range(0, n, chunk):
        i1 = min(i0 + chunk, n)
        best = np.full((i1 - i0, n), -np.inf)
        for mirror in (False, True):
            cross = np.zeros((i1 - i0, n, k), np.complex64)
            for f in flat:
                other = f if mirror else np.conj(f)
                for mode in range(k):
                    cross[:, :, mode] += f[mode, i0:i1] @ other[mode].T
            corr = np.concatenate([cross.real, cross.imag], axis=2) @ basis
            best = np.maximum(best, _parabolic_peak(corr))
        out[i0:i1] = np.maximum(norms[i0:i1, None] + norms[None, :] - 2 * best, 0.0)
    out += out.T
    out *= 0.5
    return out


def _parabolic_peak(corr: np.ndarray) -> np.ndarray:
    """Maximum over the last axis of a periodic sampled function, refined by the parabola
    through the best sample and its two neighbours (so the angle is not quantised)."""
    j = corr.argmax(axis=-1)[..., None]
    n = corr.shape[-1]
    c0 = np.take_along_axis(corr, j, -1)[..., 0]
    cm = np.take_along_axis(corr, (j - 1) % n, -1)[..., 0]
    cp = np.take_along_axis(corr, (j + 1) % n, -1)[..., 0]
    curv = 2 * c0 - cm - cp
    with np.errstate(invalid="ignore", divide="ignore"):
        lift = np.where(curv > 0, (cp - cm) ** 2 / (8 * curv), 0.0)
    return c0 + np.minimum(lift, np.abs(c0 - np.minimum(cm, cp)))


def _from_results(items, channel: str):
    attr = "embedding" if channel == "shape" else "intensity_embedding"
    if any(getattr(r, attr) is None for r in items):
        raise InputError("intensity_weight > 0 needs results computed with an intensity.")
    emb = np.stack([getattr(r, attr) for r in items])
    return emb, items[0].weights, items[0].mode_weights


def channel_arrays(items, channel: str):
    """``(embeddings, ring weights, mode weights)`` of one channel (``"shape"`` or
    ``"intensity"``) of results or :class:`Embeddings`."""
    if isinstance(items, Embeddings):
        return items.channel(channel)
    return _from_results(list(items), channel)


def weighted_features(items, channel: str = "shape") -> np.ndarray:
    """Flat feature vectors (n, n_radii × (n_fourier + 1)) scaled by the ring and mode weights,
    so that their Euclidean distances are the PF-SDM (magnitude) distances; use them for PCA
    or any Euclidean method. ``items``: results or :class:`Embeddings` (for a table, see
    :func:`napari_pfsdm.weighted_features`). For 3-D results the surface term is one more row
    (:mod:`.distances3d`): (n, (n_radii + 1) × (sh_degree + 1))."""
    if not isinstance(items, Embeddings) and not hasattr(items, "columns"):
        items = list(items)
        if items and distances3d.is_3d(items):
            items = distances3d.embeddings_3d(items, with_intensity=channel == "intensity")
    return magnitude_features(*channel_arrays(items, channel))


def distance_matrix(
    items,
    intensity_weight: float = 0.0,
    *,
    invariance: str | None = None,
    boundary_weight: float | None = None,
    elastic_weight: float | None = None,
    chunk: int = 128,
) -> np.ndarray:
    """All pairwise PF-SDM distances.

    Parameters
    ----------
    items : sequence of PFSDMResult, or Embeddings
        The objects, computed with the same options (rings, N_F). A feature table goes through
        :func:`napari_pfsdm.distance_matrix`, which turns it into :class:`Embeddings`.
    intensity_weight : float
        Weight w_I of the intensity term (0: shape only).
    invariance : {"combined", "magnitude", "align"}, optional
        How rotation and reflection are removed from the SDF term (module docstring).
        Default ``"magnitude"``; the others need results (a table holds magnitudes only).
    boundary_weight : float, optional
        λ, the weight of the boundary term d_B; default :data:`BOUNDARY_WEIGHT` (1). 0: the
        SDF term alone (with ``invariance="combined"``: 72.5 % bull's-eye on MPEG-7, against
        79.5 % for the default).
    elastic_weight : float, optional
        μ, the weight of the elastic outline term d_E (module docstring); default
        :data:`ELASTIC_WEIGHT` (0: off). :data:`RECOMMENDED_ELASTIC_WEIGHT` is the weight
        chosen on MPEG-7 by leave-classes-out cross-validation.
    chunk : int
        Rows computed at once by ``"align"`` (about chunk × n × 120 float32 numbers at once;
        5,000 objects with the combined distance peak at 1.2 GiB in all, measured).

    Returns
    -------
    ndarray, shape (n, n)
        Symmetric, zero diagonal.

    Raises
    ------
    TypeError
        A table (use :func:`napari_pfsdm.distance_matrix`).

    Examples
    --------
    >>> import numpy as np
    >>> from napari_pfsdm import pfsdm
    >>> yy, xx = np.mgrid[:64, :64]
    >>> disk = (yy - 32) ** 2 + (xx - 32) ** 2 < 20 ** 2
    >>> bar = (abs(yy - 32) < 8) & (abs(xx - 32) < 25)
    >>> d = distance_matrix([pfsdm(disk), pfsdm(bar), pfsdm(disk.T)])
    >>> bool(d[0, 2] < 0.02 * d[0, 1])
    True
    """
    if not isinstance(items, Embeddings) and not hasattr(items, "columns"):

        items = list(items)
        if items and distances3d.is_3d(items):
            distances3d.check_invariance_3d(invariance)
            items = distances3d.embeddings_3d(items, with_intensity=bool(intensity_weight))
            invariance = "magnitude"
            boundary_weight = no_boundary_in_3d(boundary_weight)
            elastic_weight = no_elastic_in_3d(elastic_weight)
    if hasattr(items, "columns"):
        raise TypeError(
            "core.distances.distance_matrix takes results or Embeddings; for a feature table use "
            "napari_pfsdm.distance_matrix (napari_pfsdm.analysis.tables), which reads its options"
        )
    arrays = isinstance(items, Embeddings)
    if invariance is None:
        invariance = "magnitude"
    boundary_weight = check_boundary_weight(boundary_weight)
    intensity_weight = check_weight("intensity_weight", intensity_weight)
    elastic_weight = check_elastic_weight(elastic_weight)
    if invariance not in INVARIANCES:
        raise InputError(f"invariance must be one of {INVARIANCES}, got {invariance!r}.")
    channels = ["shape"] + (["intensity"] if intensity_weight else [])
    if arrays:
        if invariance != "magnitude":
            raise InputError(
                f"invariance={invariance!r} needs the complex spectra of pfsdm results; a table "
                "holds magnitudes only. Use invariance='magnitude' for tables."
            )
        embs = [items.channel(c) for c in channels]
    else:
        items = list(items)
        if not items:
            return np.zeros((0, 0))
        embs = [_from_results(items, c) for c in channels]
    scale = [1.0, float(intensity_weight)]
    d_mag = d_align = None
    if invariance in ("magnitude", "combined"):
        d_mag = None
        for (emb, w, mw), s in zip(embs, scale[: len(embs)], strict=True):
            f = magnitude_features(emb, w, mw)
            sq = _sq_euclidean(f, f)
            if d_mag is None:
                d_mag = sq if s == 1.0 else sq * s
            else:
                sq *= s
                d_mag += sq
        d_mag = np.sqrt(d_mag, out=d_mag)
    if invariance in ("align", "combined"):
        n_f = embs[0][0].shape[2]
        spec = [np.stack([r.spectrum[:, :n_f] for r in items]) * embs[0][2]]
        if intensity_weight:
            spec.append(np.stack([r.intensity_spectrum[:, :n_f] for r in items]) * embs[0][2])
        wts = [embs[0][1] * s for s in scale[: len(spec)]]
        d_align = _align_sq(spec, wts, chunk)
        d_align = np.sqrt(d_align, out=d_align)
    if invariance == "magnitude":
        out = d_mag
    elif invariance == "align":
        out = d_align
    else:
        out = d_mag
        out += d_align
        del d_align
    if boundary_weight:
        out += boundary_weight * boundary_term(items)
    if elastic_weight:
        out += elastic_weight * elastic_term(items)
    np.fill_diagonal(out, np.where(np.isnan(np.diag(out)), np.nan, 0.0))
    return out


def distance(a, b, intensity_weight: float = 0.0, *, invariance: str | None = None,
             boundary_weight: float | None = None,
             elastic_weight: float | None = None) -> float:
    """PF-SDM distance between two results (see :func:`distance_matrix`); equal to
    ``distance_matrix([a, b, ...])[0, 1]`` (to ~1e-12: no term depends on the other objects)."""
    return float(distance_matrix([a, b], intensity_weight, invariance=invariance,
                                 boundary_weight=boundary_weight,
                                 elastic_weight=elastic_weight)[0, 1])


# --------------------------------------------------------------------------- boundary term
def no_boundary_in_3d(weight: float | None) -> float:
    """3-D objects have no outline: their surface term (``surface_weight``) plays that part."""
    if weight:
        raise InputError("boundary_weight is for 2-D outlines; 3-D objects have their surface "
                         "term instead (the surface_weight option of pfsdm / measure).")
    return 0.0


def check_weight(name: str, weight: float) -> float:
    """A weight of the distance checked by its record (``core.params.WEIGHT_OPTIONS``: from 0
    to ``MAX_WEIGHT``, where every distance stays finite)."""
    return float(option(name).check(weight))


def check_boundary_weight(weight: float | None) -> float:
    """λ as given, checked by its record; :data:`BOUNDARY_WEIGHT` for None."""
    if weight is None:
        return BOUNDARY_WEIGHT
    return check_weight("boundary_weight", weight)


def outlines_of(items) -> np.ndarray:
    """The outline coefficients (n, 2K) of results or :class:`Embeddings`, for the boundary
    term; ``ValueError`` when embeddings carry none."""
    if isinstance(items, Embeddings):
        if items.outline is None:
            raise InputError(
                "The default distance has a boundary term, which needs the objects' outline "
                "coefficients, and these embeddings carry none (a table measured before the "
                "boundary term has no outline_* columns). Measure again, or pass "
                "boundary_weight=0 for the SDF term alone.")
        return np.asarray(items.outline)
    return np.stack([r.outline for r in items])


def boundary_term(items) -> np.ndarray:
    """d_B for all pairs of results or :class:`Embeddings` (:mod:`napari_pfsdm.core.boundary`)."""
    return boundary_distance_matrix(outlines_of(items))


# --------------------------------------------------------------------------- elastic term
def no_elastic_in_3d(weight: float | None) -> float:
    """3-D objects have no outline signature: a non-zero elastic weight is refused."""
    if weight:
        raise InputError("elastic_weight is for 2-D outlines; 3-D objects have their surface "
                         "term instead (the surface_weight option of pfsdm / measure).")
    return 0.0


def check_elastic_weight(weight: float | None) -> float:
    """μ as given, checked by its record; :data:`ELASTIC_WEIGHT` (0: off) for None."""
    if weight is None:
        return ELASTIC_WEIGHT
    return check_weight("elastic_weight", weight)


#: What a user is told when the elastic term meets objects without their outline signatures.
NO_SIGNATURES = ("the elastic outline term (elastic_weight > 0) compares the objects' outline "
                 "signatures, and these objects have none (a table has its elastic_* columns "
                 "only when measured with elastic_signature='table'): measure again with it "
                 "(the plugin: More options; pfsdm measure --elastic-signature table), or "
                 "leave the term off")


def signatures_of(items) -> np.ndarray:
    """The outline signatures (n, channels, points) of results or :class:`Embeddings`, for the
    elastic term; ``ValueError`` when embeddings carry none."""
    if isinstance(items, Embeddings):
        if items.signature is None:
            raise InputError(NO_SIGNATURES)
        return np.asarray(items.signature)
    return np.stack([r.signature for r in items])


def elastic_term(items) -> np.ndarray:
    """d_E for all pairs of results or :class:`Embeddings` (:mod:`napari_pfsdm.core.elastic`)."""
    return elastic_distance_matrix(signatures_of(items))
