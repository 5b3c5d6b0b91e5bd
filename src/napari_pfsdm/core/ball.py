"""Maps from the unit ball to a 3-D object (docs/design.md §6.3).

``"radial"`` (default): the ball point r·ω (0 ≤ r ≤ 1, ω a unit direction)
goes to c + r R(ω) ω, where c is the object's centroid and R(ω) the distance from c to the
**outermost** crossing of the surface along ω. For a star-shaped object (every ray from c
leaves the object once) this is one-to-one and sends the sphere onto the surface. A ray that
crosses the surface more than once (a peanut's waist seen from its middle, a bent arm, an
object whose centroid lies outside it) still ends at the outermost crossing, but the samples
between its crossings lie outside the object; both are reported, as in 2-D:
``crossing_fraction`` (share of the sphere's solid angle whose ray crosses more than once) and
the descriptor's ``folded_fraction`` (share of the ball's samples that land outside).

``"harmonic"`` (:class:`HarmonicBallMap`): the streamlines of the potential of a point source
at the centroid (the deepest voxel when the centroid lies outside) that vanishes on the surface.
Streamlines never cross, so nothing folds but the discretisation's error near the surface (a C
shape whose centroid lies outside: 2.6 % of samples, against 75 % for the radial map); a sphere's
map is the radial one. About twice the radial map's cost (a sparse solve on ~40 nodes across).

The radial map's rays are followed through the smoothed mask of
:class:`~.volume_sdf.SurfaceSDF` in steps of half the finest voxel, the last crossing refined by
linear interpolation.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .choices import BALL_MAPS
from .volume_sdf import SurfaceSDF

__all__ = ["BALL_MAPS", "HarmonicBallMap", "RadialBallMap", "make_ball_map"]


class RadialBallMap:
    """The radial map from the unit ball to an object, centred on its centroid.

    Parameters
    ----------
    surface : SurfaceSDF
        The object (its smoothed mask is what the rays follow).
    center : ndarray, shape (3,), optional
        Physical crop coordinates of the ball's centre (default the surface's centroid).
    """

    def __init__(self, surface: SurfaceSDF, center: np.ndarray | None = None) -> None:
        self.surface = surface
        self.center = np.asarray(surface.center if center is None else center, float)
        extent = (np.array(surface.field.shape) - 1) * surface.spacing
        corners = np.array(np.meshgrid(*[[0.0, e] for e in extent], indexing="ij")).reshape(3, -1).T
        self._t_max = float(np.linalg.norm(corners - self.center, axis=1).max())
        self._step = 0.5 * float(surface.spacing.min())

    def rays(self, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Outermost surface distance R(ω) and number of exits along each direction.

        Parameters
        ----------
        directions : ndarray, shape (..., 3)
            Unit vectors (z, y, x).

        Returns
        -------
        radius : ndarray, shape (...)
            Physical distance from the centre to the outermost crossing (0 when the ray never
            meets the object).
        crossings : ndarray of int, shape (...)
            How many times the ray leaves the object, plus one if it starts outside (a
            star-shaped object seen from its centre gives 1 everywhere).
        """
        dirs = np.asarray(directions, float)
        flat = dirs.reshape(-1, 3)
        t = np.arange(0.0, self._t_max + self._step, self._step)
        out_r = np.empty(len(flat))
        out_n = np.empty(len(flat), int)
        chunk = max(1, 400_000 // len(t))
        for i in range(0, len(flat), chunk):
            d = flat[i:i + chunk]
            pts = self.center[None, None, :] + t[None, :, None] * d[:, None, :]
            v = self.surface.field_at(pts.reshape(-1, 3)).reshape(len(d), len(t)) - 0.5
            inside = v > 0
            exits = (inside[:, :-1] & ~inside[:, 1:]).sum(axis=1) + (~inside[:, 0])
            has = inside.any(axis=1)
            last = np.where(has, len(t) - 1 - np.argmax(inside[:, ::-1], axis=1), 0)
            nxt = np.minimum(last + 1, len(t) - 1)
            rows = np.arange(len(d))
            v0, v1 = v[rows, last], v[rows, nxt]
            frac = np.where(v0 - v1 > 0, v0 / np.where(v0 - v1 > 0, v0 - v1, 1.0), 0.0)
            out_r[i:i + chunk] = np.where(has, t[last] + np.clip(frac, 0, 1) * self._step, 0.0)
            out_n[i:i + chunk] = np.where(has, exits, 0)
        return out_r.reshape(dirs.shape[:-1]), out_n.reshape(dirs.shape[:-1])

    def points(self, radii: np.ndarray, directions: np.ndarray,
               radius: np.ndarray | None = None) -> np.ndarray:
        """Object points (physical crop coordinates) of the ball points r·ω.

        Returns
        -------
        ndarray, shape (len(radii), *directions.shape[:-1], 3)
        """
        dirs = np.asarray(directions, float)
        if radius is None:
            radius = self.rays(dirs)[0]
        r = np.asarray(radii, float).reshape((-1,) + (1,) * (dirs.ndim - 1))
        return self.center + (r * radius)[..., None] * dirs


def make_ball_map(kind: str, surface: SurfaceSDF, scale: float = 1.0
                  ) -> RadialBallMap | HarmonicBallMap:
    """The ball map named ``kind`` (one of :data:`BALL_MAPS`); ``scale`` is the object's
    equal-volume radius (the harmonic map's ρ ends there)."""
    if kind == "radial":
        return RadialBallMap(surface)
    if kind == "harmonic":
        return HarmonicBallMap(surface, scale)
    raise InputError(f"ball_map must be one of {', '.join(BALL_MAPS)}; got {kind!r}.")


class HarmonicBallMap:
    """A ball map that never folds: the streamlines of the potential of a point source at the
    object's centre, which vanishes on the surface (docs/design.md §6.3).

    φ = 1/(4π|x − c|) + h(x), with h harmonic inside the object and φ = 0 on the surface
    (h = −1/(4π|x − c|) there; solved on a grid of about ``grid`` nodes across the object).
    Every streamline of −∇φ leaves the source and reaches the surface, and two never cross, so
    the ball point r·ω goes to the point of the streamline that starts in direction ω where
    ρ = 1/(4πφ + 1/s) equals r·s (s the equal-volume radius; ρ = |x − c| for a sphere, whose
    map is then the radial one, and ρ = s exactly on the surface). A streamline's share of the
    sphere is its share of the source's flux: thin protrusions get few directions.

    Parameters
    ----------
    surface : SurfaceSDF
    scale : float
        The equal-volume radius s (physical).
    grid : int
        Nodes of the potential's grid along the object's longest side.
    steps : int
        Integration steps (midpoint rule in ρ) from the centre to the surface.
    """

    def __init__(self, surface: SurfaceSDF, scale: float, grid: int = 40,
                 steps: int = 48) -> None:
        from scipy import ndimage as ndi
        from scipy.sparse import csr_matrix
        from scipy.sparse.linalg import bicgstab

        self.surface = surface
        self.scale = float(scale)
        self.steps = int(steps)
        c = np.asarray(surface.center, float)
        if not surface.inside(c[None])[0]:  # a C-shape: start from the deepest voxel
            inside = surface.field > 0.5
            depth = ndi.distance_transform_edt(inside, sampling=surface.spacing)
            c = np.array(np.unravel_index(np.argmax(depth), depth.shape)) * surface.spacing
        self.center = c
        extent = (np.array(surface.field.shape) - 1) * surface.spacing
        h = float(extent.max()) / grid
        axes = [np.arange(0.0, e + h, h) for e in extent]
        pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
        level = surface.field_at(pts.reshape(-1, 3)).reshape(pts.shape[:-1]) - 0.5
        inside = level > 0
        index = -np.ones(inside.shape, int)
        index[inside] = np.arange(int(inside.sum()))
        n = int(inside.sum())
        ii = np.argwhere(inside)
        # Shortley–Weller: an arm that leaves the object ends on the surface (the 0.5 level,
        # linearly interpolated), where h = −G
        arms = {}
        for axis in range(3):
            for step in (-1, 1):
                nb = ii.copy()
                nb[:, axis] += step
                ok = (nb[:, axis] >= 0) & (nb[:, axis] < inside.shape[axis])
                nbc = np.clip(nb, 0, np.array(inside.shape) - 1)
                nb_in = ok & inside[nbc[:, 0], nbc[:, 1], nbc[:, 2]]
                l0 = level[ii[:, 0], ii[:, 1], ii[:, 2]]
                l1 = np.where(ok, level[nbc[:, 0], nbc[:, 1], nbc[:, 2]], -0.5)
                t = np.where(nb_in, 1.0, np.clip(l0 / np.maximum(l0 - l1, 1e-12), 0.05, 1.0))
                arms[axis, step] = (t, nb_in, nbc)
        rows, cols, vals = [], [], []
        diag = np.zeros(n)
        rhs = np.zeros(n)
        for axis in range(3):
            for step in (-1, 1):
                t, nb_in, nbc = arms[axis, step]
                other = arms[axis, -step][0]
                a = 2.0 / (t * (t + other))  # × 1/h², dropped throughout
                diag += a
                sel = np.flatnonzero(nb_in)
                rows.append(sel)
                cols.append(index[nbc[sel, 0], nbc[sel, 1], nbc[sel, 2]])
                vals.append(-a[sel])
                out = np.flatnonzero(~nb_in)
                e = np.zeros(3)
                e[axis] = step * h
                crossing = ii[out] * h + t[out, None] * e
                g = 1.0 / (4 * np.pi * np.maximum(np.linalg.norm(crossing - c, axis=1), 1e-9))
                rhs[out] += a[out] * (-g)
        rows.append(np.arange(n))
        cols.append(np.arange(n))
        vals.append(diag)
        lap = csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(n, n))
        sol, _ = bicgstab(lap, rhs, rtol=1e-9, maxiter=4000)
        hgrid = np.zeros(inside.shape)
        hgrid[inside] = sol
        # outside the object, extend h by its nearest inside value (gradients at the rim)
        _, near = ndi.distance_transform_edt(~inside, return_indices=True)
        hgrid = hgrid[tuple(near)]
        self._h = hgrid
        self._grad = [np.gradient(hgrid, h, axis=a) for a in range(3)]
        self._h_step = h
        self.h_center = float(self._interp(self._h, c[None])[0])

    def _interp(self, values: np.ndarray, points: np.ndarray) -> np.ndarray:
        from scipy import ndimage as ndi

        return ndi.map_coordinates(values, (points / self._h_step).T, order=1, mode="nearest")

    def _velocity(self, x: np.ndarray) -> np.ndarray:
        """dx/dρ = (∇φ / |∇φ|²) · (−1 / (4πρ²)), ρ = 1/(4πφ + 1/s)."""
        d = x - self.center
        r = np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
        grad = -d / (4 * np.pi * r**3) + np.column_stack([self._interp(g, x)
                                                          for g in self._grad])
        phi = 1 / (4 * np.pi * r[:, 0]) + self._interp(self._h, x)
        rho = 1 / (4 * np.pi * phi + 1 / self.scale)
        g2 = np.maximum(np.einsum("ij,ij->i", grad, grad), 1e-300)
        return grad / g2[:, None] * (-1 / (4 * np.pi * rho**2))[:, None]

    def points(self, radii: np.ndarray, directions: np.ndarray,
               radius: np.ndarray | None = None) -> np.ndarray:
        """Object points (physical crop coordinates) of the ball points r·ω, by following the
        streamlines (``radius`` is ignored; kept for the radial map's signature)."""
        dirs = np.asarray(directions, float)
        flat = dirs.reshape(-1, 3)
        r = np.sort(np.asarray(radii, float).ravel())
        targets = r * self.scale
        # start close to the source, where φ ≈ 1/(4π|x − c|) + h(c): ρ0 for a step of ε
        eps = 0.25 * self._h_step
        x = self.center + eps * flat
        rho0 = 1 / (1 / eps + 4 * np.pi * self.h_center + 1 / self.scale)
        out = np.empty((len(r), len(flat), 3))
        grid_rho = np.concatenate([[rho0], np.linspace(rho0, self.scale, self.steps + 1)[1:]])
        grid_rho = np.unique(np.concatenate([grid_rho, targets[targets > rho0]]))
        k = 0
        for t in targets[targets <= rho0]:  # shells inside the start: straight from the source
            out[k] = self.center + (t / rho0) * eps * flat
            k += 1
        for a, b in zip(grid_rho[:-1], grid_rho[1:], strict=True):
            mid = x + 0.5 * (b - a) * self._velocity(x)
            x = x + (b - a) * self._velocity(mid)
            while k < len(r) and np.isclose(b, targets[k]):
                out[k] = x
                k += 1
        order = np.argsort(np.argsort(np.asarray(radii, float).ravel()))
        return out[order].reshape((len(r),) + dirs.shape[:-1] + (3,))

    def rays(self, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance from the centre to where each streamline meets the surface, and 1 (a
        streamline crosses the surface once)."""
        end = self.points([1.0], directions)[0]
        return np.linalg.norm(end - self.center, axis=-1), np.ones(end.shape[:-1], int)
