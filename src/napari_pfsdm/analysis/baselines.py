"""Classic morphometrics the PF-SDM is compared with: EFA and Procrustes (GPA).

- **EFA** (elliptic Fourier analysis, Kuhl & Giardina 1982): the normalised coefficients of
  the first 10 harmonics of the outline (``pyefd.elliptic_fourier_descriptors(...,
  normalize=True)``), compared by Euclidean distance. The normalisation removes translation,
  scale, rotation and the start point up to a two-fold ambiguity each (the direction and the
  end of the first harmonic's major axis): :func:`efa_descriptors` fixes the first and
  :func:`efa_distance_matrix` minimises over the second (``canonical=False,
  resolve_start=False`` gives the raw ``pyefd`` behaviour). Reflection is not removed.
- **Mirror-aware EFA**: the same, with the distance minimised over the outline and its mirror
  image.
- **GPA** (Procrustes on landmarks, as in the paper): ``n_points`` points equally spaced in arc
  length on the EFA-reconstructed outline; the full Procrustes distance between two such
  configurations, minimised over translation, scale, rotation, the cyclic start point and
  reflection (computed for all pairs at once by FFT cross-correlation).

The outline is the longest marching-squares contour (``skimage.measure.find_contours`` at level
½) of the mask padded by one pixel, oriented counter-clockwise.

``pyefd`` is an optional dependency (extras ``bench`` and ``testing``); it is imported only
when these functions run.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from skimage.measure import find_contours

from ..core.contour import signed_area
from ..errors import InputError

__all__ = [
    "mask_contour",
    "efa_descriptors",
    "efa_distance_matrix",
    "efa_outlines",
    "gpa_distance_matrix",
    "procrustes_distance_matrix",
]


def _pyefd():
    try:
        import pyefd
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise ImportError(
            "The EFA and GPA baselines need the optional package 'pyefd'. Install it with "
            "`pip install 'napari-pfsdm[bench]'` (or `pip install pyefd`)."
        ) from err
    return pyefd


def mask_contour(mask: np.ndarray) -> np.ndarray:
    """Outer sub-pixel outline of a mask, counter-clockwise, in image ``(row, col)`` pixels.

    Parameters
    ----------
    mask : array_like of bool, shape (Y, X)

    Returns
    -------
    ndarray, shape (K, 2)
        Closed outline without the repeated end point.
    """
    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise InputError(f"Expected a 2-D mask, got an array of shape {mask.shape}.")
    if not mask.any():
        raise InputError("The mask is empty: there is no outline to describe.")
    padded = np.pad(mask.astype(np.float32), 1)
    contour = max(find_contours(padded, 0.5), key=len)[:-1] - 1.0
    if signed_area(contour) < 0:
        contour = contour[::-1]
    return contour


def _as_contours(items: Sequence[np.ndarray], contours: bool) -> list[np.ndarray]:
    if contours:
        return [np.asarray(c, float) for c in items]
    return [mask_contour(m) for m in items]


def efa_descriptors(
    masks: Sequence[np.ndarray],
    *,
    order: int = 10,
    mirror: bool = False,
    canonical: bool = True,
    contours: bool = False,
) -> np.ndarray:
    """Normalised elliptic Fourier descriptors of each object.

    Parameters
    ----------
    masks : sequence of ndarray
        Boolean masks (or outlines with ``contours=True``).
    order : int
        Number of harmonics.
    mirror : bool
        Describe the mirror images of the outlines instead (column axis flipped, orientation
        kept counter-clockwise).
    canonical : bool
        Rotate by 180° where needed so that ``a_1 = +1``. ``pyefd``'s normalisation aligns the
        first harmonic's major axis but leaves its direction (a rotation by π, which negates
        every coefficient) to chance; this removes that. The other half of the ambiguity, the
        start point at either end of the major axis (which negates the even harmonics), is
        handled by :func:`efa_distance_matrix`.
    contours : bool
        ``masks`` are already ``(K, 2)`` outlines.

    Returns
    -------
    ndarray, shape (n, 4 * order)
        Flattened ``(a_n, b_n, c_n, d_n)`` per harmonic, normalised as ``pyefd`` does
        (``a_1 = ±1``, ``b_1 = c_1 = 0``).
    """
    pyefd = _pyefd()
    out = np.empty((len(masks), 4 * order))
    for i, c in enumerate(_as_contours(masks, contours)):
        if mirror:
            c = (c * np.array([1.0, -1.0]))[::-1]
        out[i] = pyefd.elliptic_fourier_descriptors(c, order=order, normalize=True).ravel()
    if canonical:
        out *= np.where(out[:, :1] < 0, -1.0, 1.0)
    return out


def _even_flip(desc: np.ndarray) -> np.ndarray:
    """Descriptors of the same outline started at the other end of the major axis."""
    order = desc.shape[1] // 4
    sign = np.repeat(np.where(np.arange(1, order + 1) % 2 == 0, -1.0, 1.0), 4)
    return desc * sign


def _pairwise_euclidean(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d2 = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T
    return np.sqrt(np.clip(d2, 0.0, None))


def efa_distance_matrix(
    masks: Sequence[np.ndarray] | None = None,
    *,
    order: int = 10,
    mirror_aware: bool = False,
    resolve_start: bool = True,
    descriptors: np.ndarray | None = None,
    mirrored: np.ndarray | None = None,
    contours: bool = False,
) -> np.ndarray:
    """Pairwise Euclidean distances between normalised EFA descriptors.

    Parameters
    ----------
    masks : sequence of ndarray, optional
        Boolean masks (or outlines with ``contours=True``); not needed when ``descriptors``
        (and, for ``mirror_aware``, ``mirrored``) are given.
    order : int
        Number of harmonics (the paper: 10).
    mirror_aware : bool
        Take for each pair the smaller of the distances to the other outline and to its mirror
        image, which makes EFA reflection invariant.
    resolve_start : bool
        Also minimise over the two start points that the normalisation cannot tell apart (the
        two ends of the first harmonic's major axis: even harmonics change sign). Without it
        (and with ``canonical=False`` descriptors) this is plain ``pyefd`` normalised EFA,
        whose distance jumps when a rotation of the object flips either choice.
    descriptors, mirrored : ndarray, optional
        Precomputed :func:`efa_descriptors` (``mirror=False`` and ``mirror=True``).
    contours : bool
        ``masks`` are already outlines.

    Returns
    -------
    ndarray, shape (n, n)
        Symmetric, zero diagonal.
    """
    if descriptors is None:
        if masks is None:
            raise InputError("Give the masks or their precomputed EFA descriptors.")
        descriptors = efa_descriptors(masks, order=order, contours=contours)
    others = [descriptors]
    if mirror_aware:
        if mirrored is None:
            if masks is None:
                raise InputError("mirror_aware needs the masks or the mirrored descriptors.")
            mirrored = efa_descriptors(masks, order=order, mirror=True, contours=contours)
        others.append(mirrored)
    if resolve_start:
        others += [_even_flip(o) for o in others]
    dist = np.min([_pairwise_euclidean(descriptors, o) for o in others], axis=0)
    dist = np.minimum(dist, dist.T)
    np.fill_diagonal(dist, 0.0)
    return dist


def efa_outlines(
    masks: Sequence[np.ndarray],
    *,
    order: int = 10,
    n_points: int = 100,
    contours: bool = False,
) -> np.ndarray:
    """Outlines reconstructed from the (unnormalised) EFA, ``n_points`` equidistant points each.

    Parameters
    ----------
    masks : sequence of ndarray
        Boolean masks (or outlines with ``contours=True``).
    order : int
        Number of harmonics of the reconstruction.
    n_points : int
        Points per outline, equally spaced in arc length along the reconstruction.
    contours : bool
        ``masks`` are already outlines.

    Returns
    -------
    ndarray, shape (n, n_points, 2)
        Counter-clockwise ``(row, col)`` points in the image's pixel frame.
    """
    pyefd = _pyefd()
    out = np.empty((len(masks), n_points, 2))
    for i, c in enumerate(_as_contours(masks, contours)):
        coeffs = pyefd.elliptic_fourier_descriptors(c, order=order, normalize=False)
        locus = pyefd.calculate_dc_coefficients(c)
        dense = pyefd.reconstruct_contour(coeffs, locus=locus, num_points=8 * n_points)
        dense = dense[:-1] if np.allclose(dense[0], dense[-1]) else dense
        out[i] = _resample_closed(dense, n_points)
    return out


def _resample_closed(points: np.ndarray, n: int) -> np.ndarray:
    closed = np.vstack([points, points[:1]])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])
    t = np.linspace(0.0, s[-1], n, endpoint=False)
    return np.column_stack([np.interp(t, s, closed[:, 0]), np.interp(t, s, closed[:, 1])])


def procrustes_distance_matrix(
    outlines: np.ndarray,
    *,
    reflection: bool = True,
    chunk: int = 256,
) -> np.ndarray:
    """Full Procrustes distance between closed landmark outlines, best start point and mirror.

    Each outline (``n_points`` landmarks, counter-clockwise) is centred and scaled to unit
    size, as a complex vector ``z``. For two outlines the full Procrustes distance after the
    optimal rotation and scaling is ``sqrt(1 - |<z1, z2>|²)``; it is minimised over all cyclic
    shifts of the landmarks (the start point is arbitrary) and, with ``reflection``, over the
    mirror image of ``z2`` (conjugated and traversed backwards, to stay counter-clockwise).

    Parameters
    ----------
    outlines : ndarray, shape (n, n_points, 2)
    reflection : bool
        Also allow the mirror image.
    chunk : int
        Rows computed at once (memory ``chunk × n × n_points`` complex numbers).

    Returns
    -------
    ndarray, shape (n, n)
        Symmetric, zero diagonal, values in ``[0, 1]``.
    """
    outlines = np.asarray(outlines, float)
    if outlines.ndim != 3 or outlines.shape[2] != 2:
        raise InputError(f"Expected outlines of shape (n, n_points, 2), got {outlines.shape}.")
    z = outlines[..., 1] + 1j * outlines[..., 0]
    z = z - z.mean(axis=1, keepdims=True)
    z = z / np.linalg.norm(z, axis=1, keepdims=True)
    fz = np.fft.fft(z, axis=1)
    candidates = [fz]
    if reflection:
        candidates.append(np.fft.fft(np.conj(z[:, ::-1]), axis=1))
    n = len(z)
    best = np.zeros((n, n))
    for start in range(0, n, chunk):
        rows = fz[start : start + chunk, None, :]
        for fc in candidates:
            # corr[i, j, k] = sum_m z_j[m + k] conj(z_i[m]) for all cyclic shifts k.
            corr = np.fft.ifft(np.conj(rows) * fc[None, :, :], axis=2)
            best[start : start + chunk] = np.maximum(
                best[start : start + chunk], np.abs(corr).max(axis=2)
            )
    dist = np.sqrt(np.clip(1.0 - best**2, 0.0, None))
    dist = 0.5 * (dist + dist.T)
    np.fill_diagonal(dist, 0.0)
    return dist


def gpa_distance_matrix(
    masks: Sequence[np.ndarray] | None = None,
    *,
    order: int = 10,
    n_points: int = 100,
    reflection: bool = True,
    outlines: np.ndarray | None = None,
    contours: bool = False,
) -> np.ndarray:
    """Procrustes distances on equidistant points of the EFA-reconstructed outlines.

    The paper's GPA baseline: ``n_points`` landmarks sampled on the ``order``-harmonic EFA
    reconstruction of each outline (:func:`efa_outlines`), compared by
    :func:`procrustes_distance_matrix`.

    Parameters
    ----------
    masks : sequence of ndarray, optional
        Boolean masks (or outlines with ``contours=True``); not needed with ``outlines``.
    order, n_points : int
        EFA harmonics and landmarks per outline.
    reflection : bool
        Minimise over mirror images too.
    outlines : ndarray, shape (n, n_points, 2), optional
        Precomputed :func:`efa_outlines`.
    contours : bool
        ``masks`` are already outlines.

    Returns
    -------
    ndarray, shape (n, n)
    """
    if outlines is None:
        if masks is None:
            raise InputError("Give the masks or their precomputed EFA outlines.")
        outlines = efa_outlines(masks, order=order, n_points=n_points, contours=contours)
    return procrustes_distance_matrix(outlines, reflection=reflection)
