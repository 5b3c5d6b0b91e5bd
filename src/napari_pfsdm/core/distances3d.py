"""PF-SDM distances between 3-D objects (docs/design.md §6.5), through the 2-D machinery.

d(S₁, S₂)² = Σ_r w_r Σ_l m_l² (e₁(r, l) − e₂(r, l))² + w_S Σ_l m_l² (s₁(l) − s₂(l))²
           (+ w_I × the same over the intensity shells),

with e(r, l) = √P_l(r) the shells' spherical-harmonic power, s(l) that of the outer surface's
radial function (``surface_embedding``), w_r the shell weights, m_l = (1 + l)^α and w_S the
``surface_weight``. The surface is stacked as one more "shell" of weight w_S, so that the
magnitude distance of :mod:`.distances` computes it unchanged; the intensity gets a zero row
there. There is nothing to align: the power per degree is already rotation- and
mirror-invariant, so ``invariance`` can only be ``"magnitude"``.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .embeddings import Embeddings

__all__ = ["embeddings_3d", "is_3d", "check_invariance_3d", "stack_3d"]


def is_3d(items) -> bool:
    """True when ``items`` is a non-empty sequence of 3-D results (mixing 2-D and 3-D results
    is refused in plain words)."""
    if isinstance(items, Embeddings) or hasattr(items, "columns"):
        return False
    items = list(items)
    dims = {getattr(r, "ndim", 2) for r in items}
    if len(dims) > 1:
        raise InputError("The results mix 2-D and 3-D objects; their descriptors cannot be "
                         "compared. Compare 2-D and 3-D objects separately.")
    return dims == {3}


def check_invariance_3d(invariance: str | None) -> None:
    """3-D results are compared by their invariant SH power; ``"align"`` is 2-D only."""
    if invariance not in (None, "magnitude"):
        raise InputError(
            f"invariance={invariance!r} is for 2-D results (it aligns Fourier phases over "
            "rotations); 3-D results are compared by their spherical-harmonic power, which is "
            "rotation- and mirror-invariant already. Use invariance='magnitude' (the default)."
        )


def stack_3d(shells: np.ndarray, surface: np.ndarray | None) -> np.ndarray:
    """(n, R, L + 1) shells and (n, L + 1) surface → (n, R + 1, L + 1); a missing surface (the
    intensity channel) is a zero row."""
    shells = np.asarray(shells, float)
    extra = np.zeros_like(shells[:, :1]) if surface is None else np.asarray(surface,
                                                                            float)[:, None, :]
    return np.concatenate([shells, extra], axis=1)


def embeddings_3d(results, with_intensity: bool = False) -> Embeddings:
    """The :class:`~.distances.Embeddings` of 3-D results: shells plus the surface row.

    Raises
    ------
    ValueError
        Results computed with different options (shells, degree or weights), or
        ``with_intensity`` without intensity embeddings.
    """
    results = list(results)
    first = results[0]
    for r in results[1:]:
        if (r.embedding.shape != first.embedding.shape
                or not np.allclose(r.weights, first.weights)
                or not np.allclose(r.mode_weights, first.mode_weights)
                or r.surface_weight != first.surface_weight):
            raise InputError("The 3-D results were computed with different options (shells, "
                             "sh_degree or weights); compute them all with the same options.")
    shape = stack_3d(np.stack([r.embedding for r in results]),
                     np.stack([r.surface_embedding for r in results]))
    intensity = None
    if with_intensity:
        if any(r.intensity_embedding is None for r in results):
            raise InputError("intensity_weight > 0 needs results computed with an intensity.")
        intensity = stack_3d(np.stack([r.intensity_embedding for r in results]), None)
    weights = np.append(first.weights, first.surface_weight)
    return Embeddings(shape=shape, weights=weights, mode_weights=first.mode_weights,
                      intensity=intensity)
