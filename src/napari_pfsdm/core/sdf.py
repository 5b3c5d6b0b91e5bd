"""Signed distance functions of a closed contour, evaluable at any point with their gradient.

Step 2 of the method (docs/design.md §2.2). Both functions work in the contour's normalised
coordinates and follow the convention φ < 0 inside, φ = 0 on the boundary, φ > 0 outside.

* :class:`ExactSDF` — the Euclidean distance to the sub-pixel polygon, signed. Cheap (a
  nearest-vertex search and two segment projections per point); the nearest point is sought on
  the two edges at the nearest vertex, which is the polygon's distance to within 0.03 pixel
  (measured against all edges on the perturbed five shapes at 256 px). Its gradient jumps
  across the medial axis (the skeleton).
* :class:`ViscousSDF` — the paper's regularised distance: the solution of the viscous Eikonal
  equation |∇φ|² − ν Δ|φ| = 1 with φ = 0 on the boundary. The Hopf–Cole substitution
  |φ| = −ν log w turns it into the linear screened Poisson problem ν² Δw = w, w = 1 on the
  boundary, solved here as a boundary integral: a double-layer potential with the kernel
  K₀(|x − y|/ν)/2π, a second-kind Nyström system on the contour nodes (spectrally accurate for
  smooth outlines), and near the boundary an 8× refined quadrature. It is smooth across the
  skeleton (rounded over a width ~ν) and within ~ν·κ·d of the exact distance elsewhere.
  Inside a disk of radius R the exact solution is w = I₀(ρ/ν)/I₀(R/ν).

Use the exact SDF by default (it is 5–10× cheaper and the benchmarks find no loss); use the
viscous one when you need a φ that is differentiable everywhere (e.g. gradients near the
skeleton), or to reproduce the paper.
"""

from __future__ import annotations

import threading
from functools import lru_cache

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import k1e
from skimage.measure import points_in_poly

from ..errors import InputError
from .choices import SDF_KINDS

__all__ = ["ExactSDF", "ViscousSDF", "make_sdf", "SDF_KINDS"]


#: Points per block of the brute-force nearest-vertex search: a block's distances
#: (256 points × at most 512 vertices, float32) fit one preallocated buffer of 512 KB.
_BLOCK = 256
_SCRATCH = threading.local()


def _scratch(size: int) -> np.ndarray:
    """A float32 buffer of at least ``size`` values, kept per thread: a fresh block-sized
    temporary costs more (allocation and page faults) than the arithmetic done in it."""
    buf = getattr(_SCRATCH, "buf", None)
    if buf is None or buf.size < size:
        buf = _SCRATCH.buf = np.empty(max(size, _BLOCK * ExactSDF.BRUTE_FORCE_VERTICES),
                                      np.float32)
    return buf


@lru_cache(maxsize=16)
def _ring_neighbours(m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For m points on a closed ring (read-only): the next and the previous index of each, the
    indices (2m,) of [previous, self] (the two edges at each vertex), and the indices (6m,)
    into [edge normals, vertex normals] of :attr:`ExactSDF._normal`'s table."""
    i = np.arange(m)
    nxt, prv = np.roll(i, -1), np.roll(i, 1)
    pair = np.concatenate([prv, i])
    normal = np.concatenate([i + m, nxt + m, prv, i, prv + m, i + m])
    for a in (nxt, prv, pair, normal):
        a.flags.writeable = False
    return nxt, prv, pair, normal


class ExactSDF:
    """Signed Euclidean distance to a closed polygon.

    Parameters
    ----------
    polygon : ndarray, shape (M, 2)
        Vertices of a closed, non-self-intersecting polygon (no repeated closing vertex).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    >>> sdf = ExactSDF(np.column_stack([np.cos(t), np.sin(t)]))
    >>> np.round(sdf(np.array([[0.0, 0.0], [2.0, 0.0]])), 3)
    array([-1.,  1.])
    """

    #: Polygons with at most this many vertices find each point's nearest vertex by brute force
    #: in single precision (2–3× faster than the KD-tree for a 256-point contour; a vertex
    #: that ties to 1e-7 may be taken for the nearest, which moves the distance by far less
    #: than the polygon's own approximation of the outline); longer ones use a KD-tree.
    BRUTE_FORCE_VERTICES = 512

    def __init__(self, polygon: np.ndarray) -> None:
        p = self.polygon = np.ascontiguousarray(polygon, dtype=float).reshape(-1, 2)
        m = len(p)
        self._next, self._prev, pair, table = _ring_neighbours(m)
        # points as complex numbers first axis + i·second; edge i runs from vertex i to i + 1
        z = p.view(complex)[:, 0]
        e = z[self._next] - z
        # per vertex k the two edges at it, (k − 1 → k) and (k → k + 1), as _pair[:, 0 or 1, k]:
        # their start a, the edge e and 1/e (t = Re((p − a)/e) is p's position along it)
        own = np.empty((3, m), complex)
        own[0] = z
        own[1] = e
        np.divide(1.0, e, out=own[2])
        self._pair = np.take(own, pair, axis=1).reshape(3, 2, m)
        # outward unit normals for counter-clockwise (−i e/|e|) and at the vertices the
        # bisector of the two edges' normals; conjugated, so that Re(g n̄) = g · n
        normals = np.empty(2 * m, complex)
        normal, vertex = normals[:m], normals[m:]
        np.multiply(e, -1j, out=normal)
        normal /= np.abs(e)
        np.add(normal, normal[self._prev], out=vertex)
        vertex /= np.maximum(np.abs(vertex), 1e-12)
        # the pseudo-normal of the closest point on edge slot s of vertex k, by where it lies
        # along the edge (class 0: at its end, 1: inside, 2: at its start): _normal[c, s, k]
        self._normal = np.conj(normals[table])
        # the sign of the shoelace sum Σ x_i y_(i+1) − x_(i+1) y_i = Σ Im(z̄_i e_i)
        self._orientation = -1.0 if np.vdot(z, e).imag < 0 else 1.0
        if m <= self.BRUTE_FORCE_VERTICES:
            # relative to the polygon's mean, so that single precision holds in any units
            self._origin = np.add.reduce(p, axis=0) / m
            p32 = np.empty((m, 2), np.float32)  # p − origin in double, rounded once
            np.subtract(p, self._origin, out=p32, casting="same_kind")
            # [x, y, 1] · [−2q_x, −2q_y, |q|²] = |p − q|² − |p|²: one product per block
            self._rhs32 = np.empty((3, m), np.float32)
            np.multiply(p32.T, -2.0, out=self._rhs32[:2])
            self._rhs32[2] = (p32 ** 2).sum(axis=1)
            self._tree = None
        else:
            self._tree = cKDTree(p)

    def closest_points(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Closest boundary point of each query point.

        Returns
        -------
        closest : ndarray, shape (K, 2)
        distance : ndarray, shape (K,)
            Unsigned distance.
        arc : ndarray, shape (K,)
            Position of the closest point along the polygon, in vertex units (0 … M).
        """
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        c, d, _, edge, t = self._closest(pts, full=True)
        return c, d, np.mod(edge + t, len(self.polygon))

    def _nearest_vertex(self, pts: np.ndarray) -> np.ndarray:
        """Index of each point's nearest polygon vertex."""
        if self._tree is not None:
            return self._tree.query(pts)[1]
        n = len(pts)
        m = len(self.polygon)
        k = np.empty(n, np.intp)
        # blocks of 256 points: OpenBLAS runs such small products on one thread (threads would
        # burn twice the CPU time for nothing, measured), in one reused buffer
        buf = _scratch(_BLOCK * m)
        # rows x, y, 1 relative to the origin, in single precision (one cast of contiguous rows)
        p32 = np.empty((3, n), np.float32)
        np.subtract(pts.T, self._origin[:, None], out=p32[:2], casting="same_kind")
        p32[2] = 1.0
        for i in range(0, n, _BLOCK):
            block = p32[:, i:i + _BLOCK].T
            d = buf[:len(block) * m].reshape(len(block), m)
            np.matmul(block, self._rhs32, out=d)
            np.argmin(d, axis=1, out=k[i:i + len(block)])
        return k

    def _closest(self, pts: np.ndarray, full: bool = False):
        """Closest points (K, 2) (None unless ``full``), unsigned distances, which points are
        inside, and (None unless ``full``) the edge of each closest point and the position
        t ∈ [0, 1] along it."""
        k = self._nearest_vertex(pts)
        zp = np.ascontiguousarray(pts).view(complex)[:, 0]
        # the two edges at the nearest vertex, (prev → k) and (k → next), as rows 0 and 1
        a, e, inv = np.take(self._pair, k, axis=2)  # (C-contiguous, unlike [:, :, k])
        g = zp - a
        t = np.maximum((g * inv).real, 0.0)  # clipped to [0, 1]
        np.minimum(t, 1.0, out=t)
        c = t * e
        c += a
        np.subtract(zp, c, out=g)
        d = np.abs(g)
        # the second edge wins only when strictly nearer (as a sequential scan would keep it)
        pick = d[1] < d[0]
        t, d, g = np.where(pick, t[1], t[0]), np.where(pick, d[1], d[0]), np.where(
            pick, g[1], g[0])
        # the pseudo-normal at the closest point: the edge's normal, or at a vertex the
        # bisector of its two edges' normals; its side gives the sign exactly
        m = len(self.polygon)
        where = np.add(t < 1, t <= 0, dtype=np.intp)  # 0: t = 1, 1: inside, 2: t = 0
        where *= 2
        where += pick
        where *= m
        where += k
        g *= self._normal[where]
        inside = g.real > 0 if self._orientation < 0 else g.real < 0
        if not full:
            return None, d, inside, None, None
        closest = np.where(pick, c[1], c[0])
        return closest.view(float).reshape(-1, 2), d, inside, np.where(pick, k, self._prev[k]), t

    def _signed(self, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        c, d, inside, _, _ = self._closest(pts, full=True)
        return c, d, np.where(inside, -1.0, 1.0)

    def inside(self, points: np.ndarray) -> np.ndarray:
        """Boolean: which points lie inside the polygon."""
        return points_in_poly(np.asarray(points, float).reshape(-1, 2), self.polygon)

    def __call__(self, points: np.ndarray) -> np.ndarray:
        """Signed distance at ``points`` (K, 2): negative inside."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        _, d, inside, _, _ = self._closest(pts)
        return np.negative(d, out=d, where=inside)

    def gradient(self, points: np.ndarray) -> np.ndarray:
        """Gradient ∇φ at ``points`` (K, 2): the unit vector away from the closest point,
        pointing outward; undefined (returned as 0) on the boundary itself."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        c, d, sign = self._signed(pts)
        with np.errstate(invalid="ignore", divide="ignore"):
            g = sign[:, None] * (pts - c) / d[:, None]
        return np.nan_to_num(g)


def _spectral_geometry(nodes: np.ndarray, refine: int = 1):
    """Nodes, outward normals, quadrature weights and curvature of a smooth closed curve given
    by equispaced samples, optionally refined by trigonometric interpolation."""
    m = len(nodes)
    coef = np.fft.fft(nodes[:, 0] + 1j * nodes[:, 1])
    n_fine = m * refine
    pad = np.zeros(n_fine, complex)
    pad[: m // 2] = coef[: m // 2]
    pad[n_fine - (m - m // 2):] = coef[m // 2:]
    kf = np.fft.fftfreq(n_fine, 1.0 / n_fine)
    z = np.fft.ifft(pad) * refine
    dz = np.fft.ifft(1j * kf * pad) * refine
    ddz = np.fft.ifft(-(kf**2) * pad) * refine
    speed = np.abs(dz)
    tangent = dz / speed
    normal = np.column_stack([tangent.imag, -tangent.real])
    curvature = (dz.real * ddz.imag - dz.imag * ddz.real) / speed**3
    weights = speed * 2 * np.pi / n_fine
    return np.column_stack([z.real, z.imag]), normal, weights, curvature


def _double_layer(targets: np.ndarray, nodes: np.ndarray, normals: np.ndarray,
                  weights: np.ndarray, k: float, shift: np.ndarray | None = None) -> np.ndarray:
    """Matrix of the double-layer kernel (k/2π) K₁(k r) (x − y)·n_y / r · w_y, rows scaled by
    exp(k · shift) to stay in floating-point range."""
    diff = targets[:, None, :] - nodes[None, :, :]
    r = np.sqrt(np.einsum("ijk,ijk->ij", diff, diff))
    r = np.maximum(r, 1e-300)
    e = r if shift is None else r - shift[:, None]
    return (k / (2 * np.pi)) * k1e(k * r) * np.exp(-k * e) * (
        np.einsum("ijk,jk->ij", diff, normals) / r) * weights[None, :]


class ViscousSDF:
    """Viscous (regularised) signed distance of a smooth closed curve.

    Parameters
    ----------
    nodes : ndarray, shape (M, 2)
        Counter-clockwise curve, equispaced in arc length (a :class:`Contour`'s ``normalized``).
    viscosity : float
        ν, in the contour's normalised units (1 = the largest centroid distance). The skeleton is
        rounded over a width ~ν; 0.05 by default.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 2 * np.pi, 128, endpoint=False)
    >>> sdf = ViscousSDF(np.column_stack([np.cos(t), np.sin(t)]), viscosity=0.1)
    >>> from scipy.special import i0e
    >>> rho = 0.5; expected = 0.1 * (np.log(i0e(rho / 0.1) / i0e(1 / 0.1)) + (rho - 1) / 0.1)
    >>> bool(abs(sdf(np.array([[rho, 0.0]]))[0] - expected) < 1e-5)  # 5e-6 at 128 nodes
    True
    """

    def __init__(self, nodes: np.ndarray, viscosity: float = 0.05, refine: int = 8) -> None:
        if not viscosity > 0:
            raise InputError(f"viscosity must be positive, got {viscosity}.")
        self.nu = float(viscosity)
        self.k = 1.0 / self.nu
        self.exact = ExactSDF(nodes)
        pts, normal, w, kappa = _spectral_geometry(np.asarray(nodes, float))
        self._coarse = (pts, normal, w)
        self.h = float(w.max())
        a = _double_layer(pts, pts, normal, w, self.k)
        np.fill_diagonal(a, -kappa * w / (4 * np.pi))
        eye = 0.5 * np.eye(len(pts))
        one = np.ones(len(pts))
        self._mu_in = np.linalg.solve(a - eye, one)
        self._mu_out = np.linalg.solve(a + eye, one)
        self._refine = refine
        self._fine = None

    def _fine_geometry(self):
        if self._fine is None:
            pts, normal, w, _ = _spectral_geometry(self._coarse[0], self._refine)
            n = len(self._coarse[0])

            def upsample(mu):
                c = np.fft.fft(mu)
                pad = np.zeros(n * self._refine, complex)
                pad[: n // 2] = c[: n // 2]
                pad[len(pad) - (n - n // 2):] = c[n // 2:]
                return np.real(np.fft.ifft(pad)) * self._refine

            self._fine = (pts, normal, w, upsample(self._mu_in), upsample(self._mu_out))
        return self._fine

    def _log_w(self, pts: np.ndarray, d: np.ndarray, inside: np.ndarray) -> np.ndarray:
        """log w at points at distance d from the boundary, by the coarse or refined rule."""
        out = np.empty(len(pts))
        near = d < 3 * self.h
        for sel, (nodes, normal, w, mu_in, mu_out) in (
            (~near, (*self._coarse, self._mu_in, self._mu_out)),
            (near, self._fine_geometry() if near.any() else (None,) * 5),
        ):
            if not sel.any():
                continue
            for side, mu in ((inside, mu_in), (~inside, mu_out)):
                s = sel & side
                if s.any():
                    val = _double_layer(pts[s], nodes, normal, w, self.k, shift=d[s]) @ mu
                    # val ≈ 1 for a resolved quadrature; a non-positive value means the point
                    # is where the polygon and the smooth curve disagree (a sharp corner): use
                    # the exact distance there rather than log(0)
                    ok = val > 1e-12
                    out[s] = np.where(ok, np.log(np.where(ok, val, 1.0)), 0.0) - self.k * d[s]
        return out

    def __call__(self, points: np.ndarray) -> np.ndarray:
        """Viscous signed distance at ``points`` (K, 2): negative inside."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        _, d, inside, _, _ = self.exact._closest(pts)
        phi = np.where(inside, -d, d)
        # Within a fraction of the refined node spacing the quadrature is not resolved; there
        # the viscous and exact distances agree to O(d·ν·κ), far below the sampling error.
        far = d > 0.5 * self.h / self._refine
        if far.any():
            lw = self._log_w(pts[far], d[far], inside[far])
            phi[far] = np.where(inside[far], self.nu * lw, -self.nu * lw)
        return phi

    def gradient(self, points: np.ndarray, step: float = 1e-4) -> np.ndarray:
        """∇φ at ``points`` (K, 2) by central differences of the (smooth) viscous φ."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        g = np.empty_like(pts)
        for axis in range(2):
            e = np.zeros(2)
            e[axis] = step
            g[:, axis] = (self(pts + e) - self(pts - e)) / (2 * step)
        return g


def make_sdf(kind: str, nodes: np.ndarray, viscosity: float = 0.05) -> ExactSDF | ViscousSDF:
    """Build the SDF named ``kind`` ("exact" or "viscous") of a normalised contour."""
    if kind == "exact":
        return ExactSDF(nodes)
    if kind == "viscous":
        return ViscousSDF(nodes, viscosity=viscosity)
    raise InputError(f"sdf must be one of {SDF_KINDS}, got {kind!r}.")
