"""Synthetic 3-D objects that volume, inertia and sphericity cannot tell apart.

Twelve classes of blobs in normalised units (the equal-volume radius is about 1), each copy
with a random rotation, an optional mirror image, a random scale and a smooth random surface
perturbation, rasterised into a boolean volume (voxel centre inside, optionally with an
anisotropic ``spacing``):

* six **moment-hard** classes whose inertia is isotropic (bumps or dents on the vertices of a
  regular tetrahedron, octahedron, cube, icosahedron; so the inertia eigenvalue ratios are all
  1 and only sphericity differs, by little);
* six **anisotropic** classes: two opposite bumps (a line), three bumps on a triangle, four on
  a square, two bumps at a right angle, a prolate ellipsoid, a peanut (two merged balls).

:data:`NON_STAR` adds four classes that are not star-shaped from their centroid (which lies
outside three of them): tube arcs of 270° and 180°, a cup (a thick hemispherical shell) and a
U-bend, to compare ball maps where the radial one folds.

Examples
--------
>>> vols, labels, names = make_volume_set(n_per_class=1, size=32, seed=0)
>>> len(vols), vols[0].shape, vols[0].dtype, len(names)
(12, (32, 32, 32), dtype('bool'), 12)
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import InputError

__all__ = ["VOLUME_CLASSES", "MOMENT_HARD", "NON_STAR", "blob_volume", "make_volume_set",
           "random_rotation"]


def _normalise(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


_PHI = (1 + 5 ** 0.5) / 2
_TETRA = _normalise([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]])
_OCTA = _normalise(np.vstack([np.eye(3), -np.eye(3)]))
_CUBE = _normalise(np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T)
_ICOSA = _normalise([[0, s1, s2 * _PHI] for s1 in (-1, 1) for s2 in (-1, 1)]
                    + [[s1, s2 * _PHI, 0] for s1 in (-1, 1) for s2 in (-1, 1)]
                    + [[s2 * _PHI, 0, s1] for s1 in (-1, 1) for s2 in (-1, 1)])
_LINE = _normalise([[1, 0, 0], [-1, 0, 0]])
_TRI = _normalise([[np.cos(a), np.sin(a), 0] for a in 2 * np.pi * np.arange(3) / 3])
_SQUARE = _normalise([[np.cos(a), np.sin(a), 0] for a in 2 * np.pi * np.arange(4) / 4])
_ELL = _normalise([[1, 0, 0], [0, 1, 0]])


def _bumps(centres: np.ndarray, height: float, width: float) -> Callable[[np.ndarray], np.ndarray]:
    """R(ω) = 1 + height Σ_k exp(−(1 − ω·b_k) / width²)."""
    def radius(u: np.ndarray) -> np.ndarray:
        return 1.0 + height * np.exp(-(1.0 - u @ centres.T) / width**2).sum(axis=-1)
    return radius


#: name -> (radial function of a unit direction, or None for an implicit shape; moment-hard)
_CLASSES: dict[str, tuple[Callable | None, bool]] = {
    "tetrahedron": (_bumps(_TETRA, 0.45, 0.35), True),
    "octahedron": (_bumps(_OCTA, 0.35, 0.3), True),
    "cube": (_bumps(_CUBE, 0.3, 0.28), True),
    "icosahedron": (_bumps(_ICOSA, 0.2, 0.22), True),
    "octahedron_dents": (_bumps(_OCTA, -0.25, 0.35), True),
    "tetrahedron_sharp": (_bumps(_TETRA, 0.35, 0.2), True),
    "line": (_bumps(_LINE, 0.5, 0.35), False),
    "triangle": (_bumps(_TRI, 0.45, 0.35), False),
    "square": (_bumps(_SQUARE, 0.4, 0.32), False),
    "elbow": (_bumps(_ELL, 0.5, 0.35), False),
    "prolate": (None, False),
    "peanut": (None, False),
}
VOLUME_CLASSES: tuple[str, ...] = tuple(_CLASSES)
MOMENT_HARD: tuple[str, ...] = tuple(k for k, (_, hard) in _CLASSES.items() if hard)
NON_STAR: tuple[str, ...] = ("arc270", "arc180", "cup", "ubend")


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random rotation matrix (3, 3), from a random unit quaternion."""
    q = _normalise(rng.normal(size=4))
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def _tube_arc(q: np.ndarray, angle: float) -> np.ndarray:
    ring = np.hypot(np.hypot(q[..., 1], q[..., 2]) - 0.65, q[..., 0]) - 0.3
    outside_arc = np.abs(np.arctan2(q[..., 1], q[..., 2])) > angle / 2
    return np.where(outside_arc, 1.0, ring)


def _implicit(name: str, q: np.ndarray) -> np.ndarray:
    """Inside-ness f(q) < 0 of the implicit classes (normalised coordinates)."""
    if name == "arc270":
        return _tube_arc(q, 1.5 * np.pi)
    if name == "arc180":
        return _tube_arc(q, np.pi)
    if name == "cup":
        r = np.linalg.norm(q, axis=-1)
        return np.where(q[..., 0] < 0.2, np.maximum(r - 1.0, 0.55 - r), 1.0)
    if name == "ubend":
        bend = np.where(q[..., 2] >= 0,
                        np.hypot(np.hypot(q[..., 1], q[..., 2]) - 0.5, q[..., 0]) - 0.28, 1.0)
        legs = np.where((q[..., 2] < 0) & (q[..., 2] > -0.8),
                        np.hypot(q[..., 0], np.abs(q[..., 1]) - 0.5) - 0.28, 1.0)
        return np.minimum(bend, legs)
    if name == "prolate":
        return np.linalg.norm(q / np.array([1.55, 0.8, 0.8]), axis=-1) - 1.0
    # peanut: the smooth union of two unit-ish balls along the first axis
    a = np.array([0.6, 0.0, 0.0])
    d1 = np.linalg.norm(q - a, axis=-1) - 0.75
    d2 = np.linalg.norm(q + a, axis=-1) - 0.75
    k = 0.15
    h = np.clip(0.5 + 0.5 * (d2 - d1) / k, 0, 1)
    return d2 * (1 - h) + d1 * h - k * h * (1 - h)


def blob_volume(
    name: str,
    *,
    size: int | tuple[int, int, int] = 64,
    radius: float = 20.0,
    rotation: np.ndarray | None = None,
    mirror: bool = False,
    spacing=(1.0, 1.0, 1.0),
    noise: float = 0.0,
    rng: np.random.Generator | None = None,
) -> np.ndarray:
    """One object of class ``name`` as a boolean volume.

    Parameters
    ----------
    name : str
        One of :data:`VOLUME_CLASSES`.
    size : int or (int, int, int)
        Voxels per axis.
    radius : float
        Physical size of one normalised unit (≈ the equal-volume radius).
    rotation : ndarray (3, 3), optional
        Applied to the object (default none).
    mirror : bool
        Mirror the object (x → −x in its own frame) before rotating it.
    spacing : 3 floats
        Voxel size (z, y, x); the object keeps its physical shape.
    noise : float
        Amplitude of a smooth random surface perturbation (normalised units, e.g. 0.04).
    rng : numpy Generator, optional
        For the perturbation (and nothing else).
    """
    if name not in _CLASSES and name not in NON_STAR:
        raise InputError(f"Unknown class {name!r}; the classes are "
                         f"{', '.join(VOLUME_CLASSES + NON_STAR)}.")
    shape = (size,) * 3 if np.isscalar(size) else tuple(size)
    spacing = np.asarray(spacing, float)
    centre = (np.array(shape) - 1) / 2 * spacing
    grid = np.stack(np.meshgrid(*[np.arange(n) * s for n, s in zip(shape, spacing, strict=True)],
                                indexing="ij"), axis=-1) - centre
    rot = np.eye(3) if rotation is None else np.asarray(rotation, float)
    q = grid @ rot / radius  # rot.T applied to each point: back into the object's frame
    if mirror:
        q[..., 2] = -q[..., 2]
    norm = np.linalg.norm(q, axis=-1)
    u = q / np.maximum(norm, 1e-12)[..., None]
    pert = np.zeros(shape)
    if noise:
        rng = np.random.default_rng() if rng is None else rng
        dirs = _normalise(rng.normal(size=(24, 3)))
        amp = rng.uniform(-1, 1, 24) * noise
        pert = (np.exp(-(1.0 - u @ dirs.T) / 0.35**2) * amp).sum(axis=-1)
    func, _ = _CLASSES.get(name, (None, False))
    if func is None:
        return _implicit(name, q) - pert * np.minimum(norm, 1.0) < 0
    return norm < func(u) + pert


def make_volume_set(
    n_per_class: int = 8,
    *,
    size: int = 64,
    seed: int = 0,
    noise: float = 0.04,
    scale_range: tuple[float, float] = (0.8, 1.2),
    spacing=(1.0, 1.0, 1.0),
    classes: tuple[str, ...] = VOLUME_CLASSES,
) -> tuple[list[np.ndarray], np.ndarray, list[str]]:
    """``n_per_class`` copies of each class: random rotation, mirror (half of them), scale and
    surface noise; the unit of the object is ``size / 4.4`` finest voxels (times the scale),
    so that the longest class stays inside the volume.

    Returns
    -------
    volumes : list of ndarray of bool
    labels : ndarray of int
    names : list of str
        The class names (``names[labels[i]]``).
    """
    rng = np.random.default_rng(seed)
    vols, labels = [], []
    for k, name in enumerate(classes):
        for i in range(n_per_class):
            vols.append(blob_volume(
                name, size=size, radius=size / 4.4 * rng.uniform(*scale_range) * min(spacing),
                rotation=random_rotation(rng), mirror=bool(i % 2), spacing=spacing,
                noise=noise, rng=rng))
            labels.append(k)
    return vols, np.asarray(labels), list(classes)
