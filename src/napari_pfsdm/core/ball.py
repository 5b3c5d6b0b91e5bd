"""Maps from the unit ball to a 3-D object (docs/design.md §6.3).

``"radial"`` (the one map offered so far): the ball point r·ω (0 ≤ r ≤ 1, ω a unit direction)
goes to c + r R(ω) ω, where c is the object's centroid and R(ω) the distance from c to the
**outermost** crossing of the surface along ω. For a star-shaped object (every ray from c
leaves the object once) this is one-to-one and sends the sphere onto the surface. A ray that
crosses the surface more than once (a peanut's waist seen from its middle, a bent arm, an
object whose centroid lies outside it) still ends at the outermost crossing, but the samples
between its crossings lie outside the object; both are reported, as in 2-D:
``crossing_fraction`` (share of the sphere's solid angle whose ray crosses more than once) and
the descriptor's ``folded_fraction`` (share of the ball's samples that land outside).

The rays are followed through the smoothed mask of :class:`~.volume_sdf.SurfaceSDF` in steps
of half the finest voxel, the last crossing refined by linear interpolation.
"""

from __future__ import annotations

import numpy as np

from .volume_sdf import SurfaceSDF

__all__ = ["BALL_MAPS", "RadialBallMap", "make_ball_map"]

BALL_MAPS = ("radial",)


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


def make_ball_map(kind: str, surface: SurfaceSDF) -> RadialBallMap:
    """The ball map named ``kind`` (one of :data:`BALL_MAPS`)."""
    if kind == "radial":
        return RadialBallMap(surface)
    raise ValueError(f"ball_map must be one of {', '.join(BALL_MAPS)}; got {kind!r}.")
