"""The peers measured beside PF-SDM in ``benchmarks/mpeg7.py``: EFA, GPA, Hu moments, shape context.

Each method is a per-shape *descriptor* (contour extraction included, so that its time is
comparable with PF-SDM's) and a *distance matrix* over a list of descriptors. Masks are the
preprocessed, padded boolean masks of ``mpeg7.py`` (the object does not touch the border).

* EFA: elliptic Fourier analysis (Kuhl & Giardina 1982) with ``pyefd``, 10 harmonics,
  ``normalize=True`` (rotation, scale and start-point normalised), the three constant
  coefficients dropped, Euclidean distance: plain pyefd, as a user would run it (the figure
  usually quoted for it). The outline is the marching-squares contour
  (``skimage.measure.find_contours`` at 0.5), the same kind of contour PF-SDM uses.
* mirror-aware EFA: the same, with the distance the minimum over the second outline and its
  mirror image (EFA is not reflection invariant; MPEG-7 classes hold mirrored members).
* resolved EFA: the project's own EFA baseline (``napari_pfsdm.analysis.baselines``, also
  used by the five-shape benchmark): the same pyefd descriptors with the two 180°
  ambiguities of the normalisation (direction of the first major axis; start point at either
  end of it) removed. Plain and mirror-aware.
* GPA: Procrustes analysis of 64 points equidistant in arc length on the 10-harmonic EFA
  reconstruction; full Procrustes distance minimised over the start point (all cyclic shifts
  at once by FFT) and over reflection.
* Hu: OpenCV ``cv2.matchShapes`` with ``CONTOURS_MATCH_I1`` on the ``cv2.findContours``
  outline; computed vectorised from the seven Hu moments exactly as OpenCV does (checked
  against ``cv2.matchShapes`` in :func:`check_hu_against_opencv`).
* shape context: OpenCV (opencv-contrib) ``cv2.createShapeContextDistanceExtractor()`` with its
  default settings on 100 points taken evenly along the ``cv2.findContours`` outline.
  Slow (~10 ms per pair), so the benchmark runs it on a subset; d(i, j) is computed once for
  i < j and used for both orders.
"""

from __future__ import annotations

import numpy as np

N_HARMONICS = 10
N_GPA_POINTS = 64
N_SC_POINTS = 100


# --------------------------------------------------------------------------- contours
def outline_subpixel(mask: np.ndarray) -> np.ndarray:
    """Longest marching-squares contour of a padded mask, (M, 2) in (x, y) = (col, row)."""
    from skimage.measure import find_contours

    contours = find_contours(mask.astype(np.float32), 0.5)
    c = max(contours, key=len)
    if np.allclose(c[0], c[-1]):
        c = c[:-1]
    return np.ascontiguousarray(c[:, ::-1])


def outline_opencv(mask: np.ndarray) -> np.ndarray:
    """Largest external ``cv2.findContours`` outline (CHAIN_APPROX_NONE), (M, 1, 2) int32."""
    import cv2

    contours, _ = cv2.findContours(
        mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE
    )
    return max(contours, key=cv2.contourArea)


# --------------------------------------------------------------------------- EFA
def efa_descriptor(mask: np.ndarray) -> np.ndarray:
    """(2, 37) normalised EFA of the outline and of its mirror image (row 1).

    The mirror image x -> -x negates the x coefficients (a_n, b_n); both are then normalised
    by ``pyefd.normalize_efd``, so the mirror costs no second contour or transform."""
    from pyefd import elliptic_fourier_descriptors, normalize_efd

    xy = outline_subpixel(mask)
    coeffs = elliptic_fourier_descriptors(xy, order=N_HARMONICS, normalize=False)
    mirrored = coeffs * np.array([-1.0, -1.0, 1.0, 1.0])
    return np.asarray([normalize_efd(c).ravel()[3:] for c in (coeffs, mirrored)])


def _pairwise_euclidean(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    sq = (A * A).sum(1)[:, None] + (B * B).sum(1)[None, :] - 2.0 * A @ B.T
    return np.sqrt(np.maximum(sq, 0.0))


def efa_distances(descs: list[np.ndarray], *, mirror_aware: bool) -> np.ndarray:
    """(n, n) Euclidean distances of normalised EFA; with ``mirror_aware`` the minimum over
    the second shape and its mirror image (symmetrised by the minimum of both orders)."""
    X = np.stack([d[0] for d in descs])
    D = _pairwise_euclidean(X, X)
    if mirror_aware:
        Xm = np.stack([d[1] for d in descs])
        Dm = _pairwise_euclidean(X, Xm)
        D = np.minimum(D, np.minimum(Dm, Dm.T))
    np.fill_diagonal(D, 0.0)
    return D


# --------------------------------------------------------------------------- resolved EFA
def efa_resolved_descriptor(mask: np.ndarray) -> np.ndarray:
    """(2, 40) EFA of the project's baselines (``napari_pfsdm.analysis.baselines``): pyefd's
    normalisation with its 180° ambiguity removed (``a_1 = +1``), and of the mirror image."""
    from napari_pfsdm.analysis.baselines import efa_descriptors

    return np.vstack([efa_descriptors([mask]), efa_descriptors([mask], mirror=True)])


def efa_resolved_distances(descs: list[np.ndarray], *, mirror_aware: bool) -> np.ndarray:
    """(n, n) ``baselines.efa_distance_matrix``: also minimised over the two start points
    that the normalisation cannot tell apart (the even harmonics change sign)."""
    from napari_pfsdm.analysis.baselines import efa_distance_matrix

    X = np.stack([d[0] for d in descs])
    Xm = np.stack([d[1] for d in descs])
    return efa_distance_matrix(descriptors=X, mirrored=Xm, mirror_aware=mirror_aware)


# --------------------------------------------------------------------------- GPA
def _resample_closed(xy: np.ndarray, n: int) -> np.ndarray:
    closed = np.vstack([xy, xy[:1]])
    seg = np.hypot(*np.diff(closed, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    t = np.linspace(0.0, s[-1], n, endpoint=False)
    return np.column_stack([np.interp(t, s, closed[:, 0]), np.interp(t, s, closed[:, 1])])


def gpa_descriptor(mask: np.ndarray) -> np.ndarray:
    """(64,) complex: centred, unit-norm, counter-clockwise points of the EFA reconstruction."""
    from pyefd import elliptic_fourier_descriptors, reconstruct_contour

    xy = outline_subpixel(mask)
    coeffs = elliptic_fourier_descriptors(xy, order=N_HARMONICS, normalize=False)
    dense = reconstruct_contour(coeffs, locus=(0.0, 0.0), num_points=8 * N_GPA_POINTS)
    pts = _resample_closed(dense, N_GPA_POINTS)
    z = pts[:, 0] + 1j * pts[:, 1]
    z = z - z.mean()
    area2 = np.sum(z.real * np.roll(z.imag, -1) - np.roll(z.real, -1) * z.imag)
    if area2 < 0:  # make every outline counter-clockwise
        z = z[::-1]
    return z / np.linalg.norm(z)


def gpa_distances(descs: list[np.ndarray], chunk: int = 64) -> np.ndarray:
    """(n, n) full Procrustes distances sqrt(1 − max |<z, shift(w)>|²), the maximum over all
    cyclic shifts of ``w`` (start point) and over ``w`` and its mirror image."""
    Z = np.stack(descs)
    # mirror image of a counter-clockwise outline, made counter-clockwise again
    W = np.conj(Z[:, ::-1])
    FZ = np.fft.fft(Z, axis=1)
    FZc = np.conj(FZ)
    FW = np.fft.fft(W, axis=1)
    n = len(descs)
    best = np.zeros((n, n))
    for start in range(0, n, chunk):
        sl = slice(start, start + chunk)
        # circular cross-correlation of every row block with all rows: ifft(conj(F z) * F w)
        for F in (FZ, FW):
            corr = np.fft.ifft(FZc[sl, None, :] * F[None, :, :], axis=2)
            best[sl] = np.maximum(best[sl], np.abs(corr).max(axis=2))
    D = np.sqrt(np.clip(1.0 - best**2, 0.0, None))
    D = np.minimum(D, D.T)
    np.fill_diagonal(D, 0.0)
    return D


# --------------------------------------------------------------------------- Hu / matchShapes
def hu_descriptor(mask: np.ndarray) -> np.ndarray:
    """(7,) Hu moments of the ``cv2.findContours`` outline (what ``cv2.matchShapes`` uses)."""
    import cv2

    return cv2.HuMoments(cv2.moments(outline_opencv(mask))).ravel()


def hu_distances(descs: list[np.ndarray]) -> np.ndarray:
    """(n, n) ``cv2.matchShapes(..., CONTOURS_MATCH_I1)``: Σ |1/m_A − 1/m_B| with
    m = sign(h) log10 |h|, over the moments where both |h| > 1e-5 (as in OpenCV)."""
    H = np.stack(descs)
    eps = 1e-5
    valid = np.abs(H) > eps
    with np.errstate(divide="ignore", invalid="ignore"):
        m = 1.0 / (np.sign(H) * np.log10(np.abs(H)))
    m = np.where(valid, m, 0.0)
    both = valid[:, None, :] & valid[None, :, :]
    D = np.where(both, np.abs(m[:, None, :] - m[None, :, :]), 0.0).sum(axis=2)
    np.fill_diagonal(D, 0.0)
    return D


def check_hu_against_opencv(masks: list[np.ndarray], D: np.ndarray, n_pairs: int = 50) -> float:
    """Largest absolute difference between :func:`hu_distances` and ``cv2.matchShapes``
    on ``n_pairs`` random pairs."""
    import cv2

    rng = np.random.default_rng(1)
    worst = 0.0
    for _ in range(n_pairs):
        i, j = rng.choice(len(masks), 2, replace=False)
        ref = cv2.matchShapes(
            outline_opencv(masks[i]), outline_opencv(masks[j]), cv2.CONTOURS_MATCH_I1, 0
        )
        worst = max(worst, abs(ref - D[i, j]))
    return worst


# --------------------------------------------------------------------------- shape context
def sc_descriptor(mask: np.ndarray) -> np.ndarray:
    """(100, 1, 2) float32 points taken evenly along the ``cv2.findContours`` outline."""
    c = outline_opencv(mask)
    idx = np.linspace(0, len(c), N_SC_POINTS, endpoint=False).astype(int)
    return np.ascontiguousarray(c[idx].astype(np.float32))


_SC = {}


def _sc_rows(i):
    """Worker: distances of shape i to shapes j > i (one extractor per process)."""
    import cv2

    pts = _SC["pts"]
    if "x" not in _SC:
        _SC["x"] = cv2.createShapeContextDistanceExtractor()
    ext = _SC["x"]
    out = np.zeros(len(pts))
    for j in range(i + 1, len(pts)):
        out[j] = ext.computeDistance(pts[i], pts[j])
    return i, out


def sc_distances(descs: list[np.ndarray], processes: int = 2, progress=None) -> np.ndarray:
    """(n, n) OpenCV shape-context distances; d(i, j) computed for i < j and mirrored."""
    import multiprocessing as mp

    n = len(descs)
    D = np.zeros((n, n))
    # interleave long and short rows so both workers stay busy
    order = [i for pair in zip(range(n), range(n - 1, -1, -1), strict=True) for i in pair][:n]
    jobs = order
    _SC.clear()
    _SC["pts"] = descs  # inherited by the forked workers
    if processes > 1:
        with mp.get_context("fork").Pool(processes) as pool:
            for done, (i, row) in enumerate(pool.imap_unordered(_sc_rows, jobs), 1):
                D[i] = row
                if progress:
                    progress(done, n)
    else:
        for done, job in enumerate(jobs, 1):
            i, row = _sc_rows(job)
            D[i] = row
            if progress:
                progress(done, n)
    D = np.triu(D, 1)
    return D + D.T
