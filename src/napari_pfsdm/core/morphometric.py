"""The morphometric: ring-by-ring Fourier magnitudes of a function sampled on the unit disk.

Step 4 of the method (docs/design.md §2.4–2.5). A function f(r, θ) on the disk (the PF-SDF, or a
pushed intensity) is sampled on ``n_radii`` rings × ``n_angles`` equispaced angles; an FFT along θ
gives c_n(r). A rotation of the object shifts θ and multiplies c_n by a phase, a reflection
conjugates it: the magnitudes |c_n(r)| are invariant to both.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from . import fourier

__all__ = [
    "RADII_PLACEMENTS",
    "NORMALIZATIONS",
    "RING_WEIGHTINGS",
    "mode_weights",
    "ring_radii",
    "ring_weights",
    "spectrum",
    "magnitude_embedding",
]

RADII_PLACEMENTS = ("uniform", "boundary")
NORMALIZATIONS = ("none", "ring")
RING_WEIGHTINGS = ("none", "boundary", "depth")


def ring_radii(n_radii: int, placement: str | np.ndarray = "uniform") -> np.ndarray:
    """Radii of the sampling rings in (0, 1).

    Parameters
    ----------
    n_radii : int
        Number of rings.
    placement : {"uniform", "boundary"} or array_like
        ``"uniform"``: r_i = (i + ½)/N (the paper). ``"boundary"``: r_i = 1 − ((i + ½)/N)²,
        denser toward the outline, where the harmonic extension keeps the boundary's detail (it
        damps Fourier mode k by r^|k|). An array gives the radii explicitly.

    Returns
    -------
    ndarray, shape (n_radii,), increasing.

    Examples
    --------
    >>> ring_radii(4)
    array([0.125, 0.375, 0.625, 0.875])
    """
    if not isinstance(placement, str):
        r = np.sort(np.asarray(placement, float).ravel())
        if r.size == 0 or r[0] <= 0 or r[-1] >= 1:
            raise InputError("Explicit radii must lie strictly between 0 and 1.")
        return r
    if n_radii < 1:
        raise InputError(f"n_radii must be at least 1, got {n_radii}.")
    t = (np.arange(n_radii) + 0.5) / n_radii
    if placement == "uniform":
        return t
    if placement == "boundary":
        return np.sort(1.0 - t**2)
    raise InputError(f"radii must be one of {RADII_PLACEMENTS} or an array, got {placement!r}.")


def ring_weights(radii: np.ndarray, weighting: str = "none") -> np.ndarray:
    """Quadrature weights of ∫₀¹ … dr at the given radii, times an optional ring weighting.

    Each ring gets the width of its cell (midpoints between neighbours, 0 and 1 at the ends), so
    that Σ w_i f(r_i) ≈ ∫₀¹ f(r) dr for any placement. ``weighting="boundary"`` multiplies by
    1/(1 − r + 0.05), emphasising the rings that see the outline. ``weighting="depth"``
    multiplies by 1/(1 − r)²: the distance then compares φ*/(1 − r), the PF-SDF relative to the
    depth of the ring in a disk, which stays of order one up to the outline (where φ* → 0).
    """
    r = np.asarray(radii, float)
    edges = np.concatenate([[0.0], 0.5 * (r[1:] + r[:-1]), [1.0]])
    w = np.diff(edges)
    if weighting == "boundary":
        w = w / (1.0 - r + 0.05)
    elif weighting == "depth":
        w = w / (1.0 - r) ** 2
    elif weighting != "none":
        raise InputError(f"ring_weighting must be one of {RING_WEIGHTINGS}, got {weighting!r}.")
    return w


def mode_weights(n_fourier: int, exponent: float = 0.0) -> np.ndarray:
    """Factor (1 + n)^exponent applied to Fourier index n = 0 … n_fourier before comparing.

    A positive exponent brings out the higher modes, which carry the fine outline that tells
    compact shapes apart (the harmonic extension damps them by r^n); 0 compares the magnitudes
    as they are (the paper). The benchmarks' numbers for 0, 0.25 and 0.5 are in docs/method.md.
    """
    if not np.isfinite(exponent) or exponent < 0:
        raise InputError(f"mode_exponent must be a number >= 0, got {exponent!r}.")
    return (1.0 + np.arange(n_fourier + 1, dtype=float)) ** float(exponent)


def spectrum(samples: np.ndarray) -> np.ndarray:
    """c_n(r) for n = 0 … n_angles/2 of samples (n_radii, n_angles): ``rfft / n_angles``
    (the division done inside the transform)."""
    return fourier.rfft(samples, norm="forward")


def magnitude_embedding(
    spec: np.ndarray, n_fourier: int, normalization: str = "none"
) -> np.ndarray:
    """|c_n(r)| for n = 0 … n_fourier, optionally normalised ring by ring.

    Parameters
    ----------
    spec : ndarray of complex, shape (n_radii, K)
        From :func:`spectrum`, K > n_fourier.
    n_fourier : int
        Highest Fourier index kept, N_F.
    normalization : {"none", "ring"}
        ``"none"`` keeps the magnitudes in the units of the function (for the PF-SDF: normalised
        lengths, so a thicker object has a larger c_0). ``"ring"`` is the paper's choice: at each
        radius (c_1 … c_N_F) is scaled to unit length (c_0 is kept). It discards how
        non-circular each ring is and is unstable for near-circular objects, whose c_n≥1 are
        all ≈ 0 — measured in ``benchmarks/synthetic.py``.

    Returns
    -------
    ndarray, shape (n_radii, n_fourier + 1)
    """
    if n_fourier >= spec.shape[-1]:
        raise InputError(
            f"n_fourier={n_fourier} needs more than {2 * n_fourier} angles; raise n_angles."
        )
    emb = np.abs(spec[..., : n_fourier + 1])
    if normalization == "ring":
        norm = np.linalg.norm(emb[..., 1:], axis=-1, keepdims=True)
        emb = emb.copy()
        emb[..., 1:] /= np.maximum(norm, 1e-12)
    elif normalization != "none":
        raise InputError(f"normalization must be one of {NORMALIZATIONS}, got {normalization!r}.")
    return emb
