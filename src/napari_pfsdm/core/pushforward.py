"""Push-forward maps X: unit disk → shape (docs/design.md §2.3).

Every map sends the unit circle onto the object's outline and the disk's interior into the
object, in the contour's normalised coordinates; a point of the disk is a complex number
``u + iv`` and a point of the shape ``row + i col``. Three maps are offered:

``"harmonic"``
    Boundary correspondence by normalised arc length (θ = 2π s / L), extended into the disk by
    the Poisson integral: the Fourier series of the outline with each mode n damped by r^|n|.
    O(M log M), smooth, the cheapest. For strongly non-convex shapes (long bent arms) it can
    fold: some disk points land outside the shape (``folded_fraction`` reports how many).
``"bijective"``
    The harmonic map in the other direction, shape → disk, with the same boundary
    correspondence, solved on a grid inside the shape (Shortley–Weller finite differences) and
    inverted by linear interpolation. By the Radó–Kneser–Choquet theorem it is one-to-one for any
    simply connected shape, so nothing folds; about 10× the cost of ``"harmonic"``.
``"radial"``
    The paper's construction: each boundary point goes to the point of the unit circle at its
    polar angle around the centroid; the correspondence is fitted by least squares with a
    polynomial of degree ``degree`` (on the circle, polynomials in (x, y) of degree m — the paper's
    Chebyshev basis — are exactly the trigonometric polynomials of degree m), then extended
    harmonically. Valid for star-shaped objects only; kept to compare with the paper.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy import sparse
from scipy.interpolate import LinearNDInterpolator
from scipy.sparse.linalg import splu
from scipy.spatial import Delaunay, cKDTree

from ..errors import InputError
from . import fourier
from .choices import MAPPINGS
from .sdf import ExactSDF

__all__ = ["MAPPINGS", "FourierMap", "BijectiveMap", "display_turn", "make_map", "push_to_disk"]


def _as_complex(points: np.ndarray) -> np.ndarray:
    points = np.asarray(points, float)
    if points.ndim == 2 and points.shape[1] == 2 and points.flags.c_contiguous:
        return points.view(complex)[:, 0]  # the same numbers, without the arithmetic
    return points[..., 0] + 1j * points[..., 1]


def _as_real(z: np.ndarray) -> np.ndarray:
    return np.stack([z.real, z.imag], axis=-1)


class FourierMap:
    """A harmonic map of the disk given by the Fourier coefficients of its boundary values:
    X(r, θ) = Σ_n a_n r^|n| e^{inθ}.

    Parameters
    ----------
    coefficients : ndarray of complex, shape (M,)
        a_n in ``numpy.fft.fftfreq(M, 1/M)`` order.
    """

    def __init__(self, coefficients: np.ndarray) -> None:
        self.coefficients = np.asarray(coefficients, complex)
        self._n = _mode_numbers(len(self.coefficients))

    def _damping(self, radii: np.ndarray) -> np.ndarray:
        """r^|n| on the rings: (n_r, M)."""
        return np.asarray(radii, float)[:, None] ** np.abs(self._n)[None, :]

    def polar(self, radii: np.ndarray, n_angles: int) -> np.ndarray:
        """Shape points at the polar grid (radii × θ_j = 2πj/n_angles): (n_r, n_angles, 2)."""
        return self._polar(self._damping(radii), n_angles)

    def _polar(self, damp: np.ndarray, n_angles: int) -> np.ndarray:
        m = len(self.coefficients)
        if m % n_angles == 0:
            return _as_real(_on_angles(self.coefficients[None, :] * damp, n_angles))
        theta = 2 * np.pi * np.arange(n_angles) / n_angles
        basis = np.exp(1j * np.outer(self._n, theta))
        return _as_real((self.coefficients[None, :] * damp) @ basis)

    def jacobian_sign(self, radii: np.ndarray, n_angles: int) -> np.ndarray:
        """det ∂X/∂(r, θ) at the polar grid: positive where the map preserves orientation.
        Needs ``n_angles`` to divide the number of coefficients."""
        return self._jacobian(np.asarray(radii, float), self._damping(radii), n_angles)

    def _jacobian(self, r: np.ndarray, damp: np.ndarray, n_angles: int) -> np.ndarray:
        # ∂X/∂r = Σ |n| a_n r^(|n|-1) e^{inθ} (r > 0 on every ring); ∂X/∂θ = Σ i n a_n r^|n| e^{inθ}
        x_r = _on_angles(self.coefficients * np.abs(self._n) * damp / r[:, None], n_angles)
        x_t = _on_angles(self.coefficients * 1j * self._n * damp, n_angles)
        return np.imag(np.conj(x_r) * x_t)

    def polar_and_jacobian(self, radii: np.ndarray,
                           n_angles: int) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`polar` and :meth:`jacobian_sign` at once (one product with the rings' cached
        factors r^|n|, |n| r^(|n|-1) and n r^|n|, one inverse FFT)."""
        m = len(self.coefficients)
        if m % n_angles:
            damp = self._damping(radii)
            return self._polar(damp, n_angles), self._jacobian(np.asarray(radii, float), damp,
                                                              n_angles)
        factors = _ring_factors(tuple(np.asarray(radii, float).tolist()), m)
        # _on_angles(coefficients · factors): the modes folded onto n_angles by two real
        # products summed over the folds (the same sums, without the (3, n_r, m) product)
        rows = factors.shape[0] * factors.shape[1]
        folds = factors.reshape(rows, m // n_angles, n_angles)
        c = self.coefficients.reshape(m // n_angles, n_angles)
        folded = np.empty((rows, n_angles), complex)
        folded.real = np.einsum("rgj,gj->rj", folds, np.ascontiguousarray(c.real))
        folded.imag = np.einsum("rgj,gj->rj", folds, np.ascontiguousarray(c.imag))
        # (norm="forward": the inverse transform unscaled, i.e. ifft · n_angles)
        z = fourier.ifft(folded, norm="forward").reshape(*factors.shape[:2], n_angles)
        # det = Im(conj(∂X/∂r) · ∂X/∂θ) with ∂X/∂θ = i Σ n a_n r^|n| e^{inθ}
        x_r, x_t = z[1], z[2]
        jacobian = x_r.real * x_t.real
        jacobian += x_r.imag * x_t.imag
        # the shape points (n_r, n_angles, 2): the complex samples' own memory, as pairs
        return z[0].view(float).reshape(*z.shape[1:], 2), jacobian

    def __call__(self, uv: np.ndarray, chunk: int = 2048) -> np.ndarray:
        """Shape points of arbitrary disk points ``uv`` (K, 2)."""
        uv = np.asarray(uv, float).reshape(-1, 2)
        r, theta = np.hypot(uv[:, 0], uv[:, 1]), np.arctan2(uv[:, 1], uv[:, 0])
        out = np.empty(len(uv), complex)
        for i in range(0, len(uv), chunk):
            basis = (r[i : i + chunk, None] ** np.abs(self._n)
                     * np.exp(1j * theta[i : i + chunk, None] * self._n))
            out[i : i + chunk] = basis @ self.coefficients
        return _as_real(out)

    def boundary(self, theta: np.ndarray) -> np.ndarray:
        """Outline points X(1, θ) at angles ``theta`` (K,), by linear interpolation between
        the boundary samples."""
        m = len(self.coefficients)
        nodes = np.fft.ifft(self.coefficients) * m
        grid = 2 * np.pi * np.arange(m + 1) / m
        closed = np.append(nodes, nodes[:1])
        t = np.mod(theta, 2 * np.pi)
        return np.column_stack([np.interp(t, grid, closed.real), np.interp(t, grid, closed.imag)])


@lru_cache(maxsize=32)
def _mode_numbers(m: int) -> np.ndarray:
    """The mode number n of each of m coefficients in ``fftfreq`` order (read-only)."""
    n = np.rint(np.fft.fftfreq(m, 1.0 / m)).astype(int)
    n.flags.writeable = False
    return n


@lru_cache(maxsize=32)
def _ring_factors(radii: tuple[float, ...], m: int) -> np.ndarray:
    """(3, n_r, m), read-only: r^|n| (the damping of :class:`FourierMap`), |n| r^(|n|-1) (for
    ∂X/∂r) and n r^|n| (for ∂X/∂θ, without its factor i) on the rings, for m modes."""
    n = _mode_numbers(m)
    r = np.asarray(radii, float)[:, None]
    damp = r ** np.abs(n)[None, :]
    out = np.stack([damp, np.abs(n) * damp / r, n * damp])
    out.flags.writeable = False
    return out


def _on_angles(coefficients: np.ndarray, n_angles: int) -> np.ndarray:
    """Σ_n c_n e^{inθ_j} at θ_j = 2πj/n_angles, for coefficients (..., M) in ``fftfreq`` order
    with M a multiple of n_angles: the modes are folded onto n_angles first (e^{inθ_j} depends
    on n mod n_angles only), so the inverse FFT is n_angles long, not M."""
    m = coefficients.shape[-1]
    folded = coefficients.reshape(*coefficients.shape[:-1], m // n_angles, n_angles).sum(axis=-2)
    return np.fft.ifft(folded, axis=-1, norm="forward")  # ifft · n_angles


def harmonic_map(nodes: np.ndarray) -> FourierMap:
    """Arc-length harmonic map of an equispaced, counter-clockwise contour (M, 2)."""
    z = _as_complex(nodes)
    return FourierMap(fourier.fft(z, norm="forward"))  # fft / M


def radial_map(nodes: np.ndarray, degree: int = 16) -> FourierMap:
    """The paper's map: boundary point ↦ its polar angle, fitted with a degree-``degree``
    polynomial deformation, harmonically extended."""
    z = _as_complex(nodes)
    m = len(z)
    degree = int(min(degree, (m - 1) // 2))
    n = np.arange(-degree, degree + 1)
    alpha = np.angle(z)
    design = np.exp(1j * alpha[:, None] * n[None, :])
    coef, *_ = np.linalg.lstsq(design, z, rcond=None)
    full = np.zeros(m, complex)
    full[n % m] = coef
    return FourierMap(full)


class BijectiveMap:
    """Inverse of the discrete harmonic map shape → disk (one-to-one for simply connected shapes).

    Parameters
    ----------
    nodes : ndarray, shape (M, 2)
        Normalised counter-clockwise contour, equispaced in arc length.
    sdf : ExactSDF
        Its exact signed distance (gives the boundary crossings of grid edges).
    grid : int
        Grid nodes across the normalised square [-1, 1]² (spacing 2/grid).
    """

    def __init__(self, nodes: np.ndarray, sdf: ExactSDF, grid: int = 48) -> None:
        m = len(nodes)
        self._boundary = harmonic_map(nodes)
        h = 2.0 / grid
        lo, hi = nodes.min(axis=0) - h, nodes.max(axis=0) + h
        ax0 = np.arange(lo[0], hi[0] + h, h)
        ax1 = np.arange(lo[1], hi[1] + h, h)
        g0, g1 = np.meshgrid(ax0, ax1, indexing="ij")
        pts = np.column_stack([g0.ravel(), g1.ravel()])
        phi = sdf(pts).reshape(g0.shape)
        inside = phi < 0
        index = -np.ones(g0.shape, int)
        index[inside] = np.arange(inside.sum())
        n_in = int(inside.sum())
        ii, jj = np.nonzero(inside)
        rows, cols, vals = [], [], []
        rhs = np.zeros(n_in, complex)
        diag = np.zeros(n_in)
        cross_pts, cross_row, cross_coef = [], [], []
        for axis in (0, 1):
            arms = {}
            for step in (-1, 1):
                ni, nj = ii + step * (axis == 0), jj + step * (axis == 1)
                nb_in = inside[ni, nj]  # grid has a one-node margin, indices stay valid
                t = np.ones(n_in)
                out = ~nb_in
                p_phi, q_phi = phi[ii[out], jj[out]], phi[ni[out], nj[out]]
                t[out] = np.clip(p_phi / (p_phi - q_phi), 1e-3, 1.0)
                arms[step] = (t * h, nb_in, ni, nj, out)
            for step in (-1, 1):
                arm, nb_in, ni, nj, out = arms[step]
                opp = arms[-step][0]
                a = 2.0 / ((arm + opp) * arm)
                diag -= a
                rows.append(np.nonzero(nb_in)[0])
                cols.append(index[ni[nb_in], nj[nb_in]])
                vals.append(a[nb_in])
                e = np.zeros(2)
                e[axis] = step
                p = np.column_stack([ax0[ii[out]], ax1[jj[out]]])
                cross_pts.append(p + arm[out, None] * e)
                cross_row.append(np.nonzero(out)[0])
                cross_coef.append(a[out])
        cross_pts = np.vstack(cross_pts)
        _, _, arc = sdf.closest_points(cross_pts)
        values = np.exp(2j * np.pi * arc / m)
        np.add.at(rhs, np.concatenate(cross_row), -np.concatenate(cross_coef) * values)
        lap = sparse.csc_matrix(
            (np.concatenate([*vals, diag]),
             (np.concatenate([*rows, np.arange(n_in)]), np.concatenate([*cols, np.arange(n_in)]))),
            shape=(n_in, n_in),
        )
        lu = splu(lap)
        disk = lu.solve(rhs.real) + 1j * lu.solve(rhs.imag)
        shape_pts = np.column_stack([ax0[ii], ax1[jj]])
        theta = 2 * np.pi * np.arange(m) / m
        self.grid_points = shape_pts
        self.grid_disk = _as_real(disk)
        self.n_grid = n_in
        disk_all = np.vstack([self.grid_disk, np.column_stack([np.cos(theta), np.sin(theta)])])
        shape_all = np.vstack([shape_pts, nodes])
        self._interp = LinearNDInterpolator(Delaunay(disk_all), shape_all)
        self._rim = np.cos(np.pi / m)
        self._inverse_tree = cKDTree(shape_all)
        self._inverse_values = disk_all

    def __call__(self, uv: np.ndarray) -> np.ndarray:
        """Shape points of disk points ``uv`` (K, 2)."""
        uv = np.asarray(uv, float).reshape(-1, 2)
        out = np.full(uv.shape, np.nan)
        # the triangulation's hull is the polygon of the boundary nodes: points beyond it (a
        # sliver at r > cos(π/M)) would send qhull into a brute-force search; they lie on the
        # outline to within (π/M)²/2
        rim = np.hypot(uv[:, 0], uv[:, 1]) >= self._rim
        out[~rim] = self._interp(uv[~rim])
        bad = rim | np.isnan(out[:, 0])
        if bad.any():
            out[bad] = self._boundary.boundary(np.arctan2(uv[bad, 1], uv[bad, 0]))
        return out

    def polar(self, radii: np.ndarray, n_angles: int) -> np.ndarray:
        """Shape points at the polar grid: (n_r, n_angles, 2)."""
        theta = 2 * np.pi * np.arange(n_angles) / n_angles
        r = np.asarray(radii, float)[:, None]
        uv = np.stack([r * np.cos(theta), r * np.sin(theta)], axis=-1)
        return self(uv.reshape(-1, 2)).reshape(len(radii), n_angles, 2)


def make_map(kind: str, nodes: np.ndarray, sdf: ExactSDF, *, degree: int = 16,
             grid: int = 48) -> FourierMap | BijectiveMap:
    """Build the push-forward map named ``kind`` (one of :data:`MAPPINGS`)."""
    if kind == "harmonic":
        return harmonic_map(nodes)
    if kind == "radial":
        return radial_map(nodes, degree=degree)
    if kind == "bijective":
        return BijectiveMap(nodes, sdf, grid=grid)
    raise InputError(f"mapping must be one of {MAPPINGS}, got {kind!r}.")


def display_turn(result) -> float:
    """Angle (radians) by which :func:`~napari_pfsdm.core.descriptor.render_disk` turns the disk:
    the polar angle of the outline's start point (θ = 0) around the centroid. ``result`` is a
    :class:`~napari_pfsdm.core.descriptor.PFSDMResult` (anything with ``contour.normalized``)."""
    start = result.contour.normalized[0]
    return float(np.arctan2(start[1], start[0]))


def push_to_disk(result, shape_points: np.ndarray, n_r: int = 64, n_t: int = 256) -> np.ndarray:
    """Approximate inverse of the push-forward map: for each normalised shape point (k, 2), the
    disk point (u, v) whose image under ``result.mapping`` is nearest (on an n_r × n_t polar
    grid), in the turned frame of :func:`display_turn`."""
    if len(shape_points) == 0:
        return np.zeros((0, 2))
    r = (np.arange(n_r) + 0.5) / n_r
    theta = 2 * np.pi * np.arange(n_t) / n_t
    images = result.mapping.polar(r, n_t).reshape(-1, 2)
    _, k = cKDTree(images).query(shape_points)
    rr, tt = np.divmod(k, n_t)
    angle = theta[tt] + display_turn(result)
    return np.column_stack([r[rr] * np.cos(angle), r[rr] * np.sin(angle)])
