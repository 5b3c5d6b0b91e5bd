"""Synthetic gastruloid-like time-lapses: shape and a Brachyury-like reporter.

Each object is a movie of a growing 2-D "gastruloid": a near-spherical aggregate that breaks
symmetry into an ovoid/teardrop and then either elongates along **one** body axis (the
single-axis class) or grows **two or three** protrusions (the multi-axes class). A
Brachyury-like reporter is expressed almost uniformly at first and then polarises towards the
future posterior pole(s) *before* the shape changes: the molecular asymmetry precedes the shape
asymmetry, as observed in mouse gastruloids (the paper's Fig. 2).

Time is normalised: ``s = t / (n_frames - 1)`` runs from 0 (first frame) to 1 (last frame), so
that a 6-frame movie spans the same development as a 25-frame one. Lengths are relative to the
object's body radius ``R`` and ``R`` is relative to the frame size, so the generator works at any
resolution.

Model, per object (all random draws from one ``numpy.random.Generator`` seeded by ``seed``):

* **Body**: an ellipse of radius ``R(s) = R0 (1 + (growth - 1) s)``, ``R0 = radius * size``,
  aspect ratio ``ellipticity`` in a random direction (the same distribution for both classes:
  the early frames are genuinely ambiguous), shrinking by up to 15 % as axes elongate.
* **Axes**: tapered round cones (a "teardrop" that lengthens into a body axis) from the body
  centre along a random direction, slightly bent, smoothly united with the body. The primary
  axis starts at ``shape_onset`` and reaches ``axis_length * R0`` at ``s = 1``. Multi-axes
  objects get 2 (probability ``p_two_axes``) or 3 axes at least ``min_separation_deg`` apart;
  the extra ones start ``secondary_delay`` later and are ``secondary_length`` times as long.
* **Boundary noise**: a smooth random field (correlation length ``0.3 R0``, amplitude
  ``boundary_noise * R0`` pixels) added to the signed distance before thresholding; most of it
  is fixed per object, a little changes every frame.
* **Reporter**: a uniform level (with multiplicative texture ``texture``) that gives way,
  from ``polarisation_onset`` over ``polarisation_duration``, to Gaussian poles (width
  ``pole_width * R``) that ride on the tips of the axes. Multi-axes objects get one pole per
  axis (the secondary ones with strength ``secondary_pole``); single-axis objects get, with
  probability ``decoy_probability``, a transient weak second pole (strength ``decoy_pole``)
  that fades again: it makes intensity at intermediate times imperfect evidence.
* **Imaging**: the reporter is multiplied by the slightly blurred mask and a random gain
  (``gain``), a background ``background`` is added, then Gaussian noise ``imaging_noise``.

Labels are one connected, hole-free component per object and frame.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
from scipy import ndimage as ndi

from ..errors import InputError

__all__ = [
    "GastruloidParams",
    "GastruloidSet",
    "make_gastruloids",
    "make_timelapse_montage",
]


@dataclass(frozen=True)
class GastruloidParams:
    """Parameters of the generator; every ``(low, high)`` pair is a uniform range.

    See the module docstring for the model; lengths are in units of the body radius ``R0``
    unless stated, times in normalised movie time ``s`` in [0, 1].
    """

    radius: tuple[float, float] = (0.1, 0.13)  #: body radius R0 / frame size
    growth: tuple[float, float] = (1.05, 1.25)  #: R(1) / R(0)
    ellipticity: tuple[float, float] = (1.0, 1.18)  #: early aspect ratio, both classes
    shape_onset: tuple[float, float] = (0.1, 0.28)  #: start of the primary axis
    axis_length: tuple[float, float] = (1.9, 2.8)  #: primary axis length at s = 1
    tip_radius: tuple[float, float] = (0.3, 0.5)  #: axis tip radius
    bend: tuple[float, float] = (-0.12, 0.12)  #: axis curvature x = k y^2 / R0
    p_two_axes: float = 0.7  #: multi-axes: probability of 2 (else 3) axes
    min_separation_deg: float = 75.0  #: minimal angle between two axes
    secondary_delay: tuple[float, float] = (0.0, 0.15)  #: extra onset of axes 2, 3
    secondary_length: tuple[float, float] = (0.5, 0.95)  #: relative to the primary
    boundary_noise: float = 0.05  #: amplitude of the boundary noise, in R0
    polarisation_onset: tuple[float, float] = (0.02, 0.15)  #: reporter starts to polarise
    polarisation_duration: tuple[float, float] = (0.1, 0.25)
    pole_width: float = 0.55  #: Gaussian width of a pole, in R
    secondary_pole: tuple[float, float] = (0.35, 1.0)  #: multi-axes: extra poles' strength
    decoy_probability: float = 0.35  #: single-axis: chance of a transient second pole
    decoy_pole: tuple[float, float] = (0.15, 0.5)  #: its strength
    texture: float = 0.25  #: std of the multiplicative reporter texture
    gain: tuple[float, float] = (0.6, 1.4)  #: overall brightness of the reporter
    background: float = 0.03  #: background level of the intensity image
    imaging_noise: float = 0.03  #: std of the additive Gaussian imaging noise


@dataclass
class GastruloidSet:
    """A set of one-object movies from :func:`make_gastruloids`.

    Attributes
    ----------
    labels : ndarray, uint16, (n_objects, T, Y, X)
        One object per movie, label 1, background 0.
    intensity : ndarray, float32, (n_objects, T, Y, X)
        The reporter image of each movie.
    multi_axis : ndarray, bool, (n_objects,)
        True for the multi-axes class.
    params : dict
        ``"generator"``: the :class:`GastruloidParams` as a dict, ``"seed"``, and ``"objects"``:
        one dict per object with its drawn parameters (axis angles, onsets, ...).
    """

    labels: np.ndarray
    intensity: np.ndarray
    multi_axis: np.ndarray
    params: dict = field(default_factory=dict)

    @property
    def groups(self) -> list[str]:
        """Class name of each object: ``"multi-axes"`` or ``"single-axis"``."""
        return ["multi-axes" if m else "single-axis" for m in self.multi_axis]


def _smoothstep(x: np.ndarray | float) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _smooth_min(a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    """Polynomial smooth minimum (a smooth union of two signed distances)."""
    h = np.maximum(k - np.abs(a - b), 0.0) / k
    return np.minimum(a, b) - h * h * k * 0.25


def _round_cone(x: np.ndarray, y: np.ndarray, r1: float, r2: float, h: float) -> np.ndarray:
    """Signed distance to a 2-D tapered capsule from (0, 0), radius r1, to (0, h), radius r2."""
    x = np.abs(x)
    b = (r1 - r2) / h
    a = np.sqrt(max(1.0 - b * b, 1e-12))
    k = -b * x + a * y
    d_mid = a * x + b * y - r1
    d_base = np.hypot(x, y) - r1
    d_tip = np.hypot(x, y - h) - r2
    return np.where(k < 0.0, d_base, np.where(k > a * h, d_tip, d_mid))


def _noise_field(rng: np.random.Generator, shape: tuple[int, int], sigma: float) -> np.ndarray:
    """Smooth Gaussian random field with unit standard deviation."""
    f = ndi.gaussian_filter(rng.standard_normal(shape), sigma, mode="wrap")
    return f / (f.std() + 1e-12)


def _draw_angles(rng: np.random.Generator, n: int, min_sep: float) -> np.ndarray:
    """n directions (radians), pairwise at least ``min_sep`` apart on the circle."""
    for _ in range(1000):
        ang = rng.uniform(0.0, 2.0 * np.pi, n)
        diff = np.abs((ang[:, None] - ang[None, :] + np.pi) % (2.0 * np.pi) - np.pi)
        diff[np.diag_indices(n)] = np.inf
        if diff.min() >= min_sep:
            return ang
    base = rng.uniform(0.0, 2.0 * np.pi)  # fall back on evenly spread axes
    return base + 2.0 * np.pi * np.arange(n) / n


def _draw_object(rng: np.random.Generator, p: GastruloidParams, multi: bool, size: int) -> dict:
    """All random parameters of one object (no pixels yet)."""
    u = rng.uniform
    r0 = u(*p.radius) * size
    n_axes = (2 if rng.random() < p.p_two_axes else 3) if multi else 1
    angles = _draw_angles(rng, n_axes, np.deg2rad(p.min_separation_deg))
    onset0 = u(*p.shape_onset)
    onsets = [onset0] + [min(onset0 + u(*p.secondary_delay), 0.9) for _ in range(n_axes - 1)]
    len0 = u(*p.axis_length)
    lengths = [len0] + [len0 * u(*p.secondary_length) for _ in range(n_axes - 1)]
    pol_on = u(*p.polarisation_onset)
    pol_dur = u(*p.polarisation_duration)
    poles = [1.0] + [u(*p.secondary_pole) for _ in range(n_axes - 1)]
    decoy = None
    if not multi and rng.random() < p.decoy_probability:
        # the decoy sits away from the real axis
        ang = angles[0] + np.sign(rng.standard_normal()) * rng.uniform(np.pi / 2, np.pi)
        decoy = {"angle": float(ang), "strength": float(u(*p.decoy_pole))}
    return {
        "multi_axis": bool(multi),
        "n_axes": n_axes,
        "r0": float(r0),
        "growth": float(u(*p.growth)),
        "ellipticity": float(u(*p.ellipticity)),
        "ellipse_angle": float(u(0.0, np.pi)),
        "angles": [float(a) for a in angles],
        "onsets": [float(o) for o in onsets],
        "lengths": [float(v) for v in lengths],
        "tip_radii": [float(u(*p.tip_radius)) for _ in range(n_axes)],
        "bends": [float(u(*p.bend)) for _ in range(n_axes)],
        "polarisation_onset": float(pol_on),
        "polarisation_duration": float(pol_dur),
        "pole_strengths": [float(v) for v in poles],
        "decoy": decoy,
        "gain": float(u(*p.gain)),
    }


def _extent(obj: dict) -> tuple[float, float, float, float]:
    """Conservative (min_y, max_y, min_x, max_x) of the object around its centre, in pixels."""
    r0 = obj["r0"]
    rmax = r0 * obj["growth"] * np.sqrt(obj["ellipticity"]) * 1.1 + 2.0
    ys, xs = [-rmax, rmax], [-rmax, rmax]
    for ang, length, tip, bend in zip(
        obj["angles"], obj["lengths"], obj["tip_radii"], obj["bends"], strict=True
    ):
        h = length * r0
        side = abs(bend) * h * h / r0
        margin = tip * r0 * 1.1 + 0.3 * r0 + 2.0  # tip radius, smooth union, noise
        for across in (side, -side, 0.0):
            ty = h * np.sin(ang) + across * np.cos(ang)
            tx = h * np.cos(ang) - across * np.sin(ang)
            ys.extend([ty - margin, ty + margin])
            xs.extend([tx - margin, tx + margin])
    return min(ys), max(ys), min(xs), max(xs)


def _render_movie(
    rng: np.random.Generator,
    obj: dict,
    p: GastruloidParams,
    shape: tuple[int, int],
    n_frames: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Pixels of one object's movie: (T, Y, X) bool mask and float32 reporter image."""
    ny, nx = shape
    for _ in range(5):  # shrink objects whose fully grown axes would not fit in the frame
        y0, y1, x0, x1 = _extent(obj)
        fit = min((ny - 4.0) / (y1 - y0), (nx - 4.0) / (x1 - x0))
        if fit >= 1.0:
            break
        obj["r0"] *= fit * 0.97
    r0 = obj["r0"]
    y0, y1, x0, x1 = _extent(obj)
    lo_y, hi_y = -y0 + 1.0, ny - 2.0 - y1
    lo_x, hi_x = -x0 + 1.0, nx - 2.0 - x1
    cy = rng.uniform(lo_y, hi_y) if hi_y > lo_y else (lo_y + hi_y) / 2.0
    cx = rng.uniform(lo_x, hi_x) if hi_x > lo_x else (lo_x + hi_x) / 2.0
    obj["center"] = [float(cy), float(cx)]

    yy, xx = np.mgrid[0:ny, 0:nx].astype(np.float64)
    qy, qx = yy - cy, xx - cx
    corr = max(0.3 * r0, 1.0)
    fixed_noise = _noise_field(rng, shape, corr)
    texture = 1.0 + p.texture * _noise_field(rng, shape, max(0.25 * r0, 1.0))
    noise_amp = p.boundary_noise * r0

    ca, sa = np.cos(obj["ellipse_angle"]), np.sin(obj["ellipse_angle"])
    ex, ey = qx * ca + qy * sa, -qx * sa + qy * ca
    sq_e = np.sqrt(obj["ellipticity"])

    masks = np.zeros((n_frames, ny, nx), dtype=bool)
    images = np.zeros((n_frames, ny, nx), dtype=np.float32)
    base_level = 0.35
    for t in range(n_frames):
        s = t / (n_frames - 1) if n_frames > 1 else 0.0
        progress = [
            _smoothstep((s - on) / max(1.0 - on, 1e-6)) for on in obj["onsets"]
        ]
        radius = r0 * (1.0 + (obj["growth"] - 1.0) * s) * (1.0 - 0.15 * max(progress))
        # the early ovoid relaxes as the axes take over
        e = 1.0 + (sq_e - 1.0) * (1.0 - max(progress))
        sdf = (np.hypot(ex / e, ey * e) - radius) * (1.0 / e)
        tips = []
        for ang, on_prog, length, tip, bend in zip(
            obj["angles"], progress, obj["lengths"], obj["tip_radii"], obj["bends"],
            strict=True,
        ):
            ux, uy = np.cos(ang), np.sin(ang)
            along = qx * ux + qy * uy
            across = -qx * uy + qy * ux
            h = length * r0 * on_prog
            r1 = 0.9 * radius
            r2 = r1 + (tip * r0 - r1) * on_prog  # a bulge that tapers into a tip
            tips.append((cy + 0.85 * (h + 0.6 * radius) * uy, cx + 0.85 * (h + 0.6 * radius) * ux))
            if h <= abs(r1 - r2) + 0.5:
                continue
            across = across - bend * np.clip(along, 0.0, None) ** 2 / r0
            sdf = _smooth_min(sdf, _round_cone(across, along, r1, r2, h), 0.35 * radius)
        step_noise = _noise_field(rng, shape, corr)
        sdf = sdf + noise_amp * (0.85 * fixed_noise + 0.5 * step_noise)
        mask = sdf < 0.0
        lab, n = ndi.label(mask)
        if n > 1:
            sizes = np.bincount(lab.ravel())
            sizes[0] = 0
            mask = lab == int(np.argmax(sizes))
        mask = ndi.binary_fill_holes(mask)
        masks[t] = mask

        # reporter: uniform level that polarises towards the (future) tips
        pol = float(_smoothstep((s - obj["polarisation_onset"]) / obj["polarisation_duration"]))
        width2 = 2.0 * (p.pole_width * radius) ** 2
        field_ = np.full(shape, base_level * (1.0 - 0.6 * pol))
        for (ty, tx), strength in zip(tips, obj["pole_strengths"], strict=True):
            field_ += pol * strength * np.exp(-((yy - ty) ** 2 + (xx - tx) ** 2) / width2)
        if obj["decoy"] is not None:
            fade = 1.0 - float(_smoothstep((s - obj["polarisation_onset"] - 0.3) / 0.25))
            d_ang = obj["decoy"]["angle"]
            ty, tx = cy + 0.7 * radius * np.sin(d_ang), cx + 0.7 * radius * np.cos(d_ang)
            field_ += (
                pol * fade * obj["decoy"]["strength"]
                * np.exp(-((yy - ty) ** 2 + (xx - tx) ** 2) / width2)
            )
        soft_mask = ndi.gaussian_filter(mask.astype(np.float64), 1.0)
        img = obj["gain"] * field_ * np.clip(texture, 0.2, None) * soft_mask + p.background
        img += p.imaging_noise * rng.standard_normal(shape)
        images[t] = np.clip(img, 0.0, None)
    return masks, images


def _check(n_objects: int, n_frames: int, size: int, multi_fraction: float) -> None:
    if n_objects < 1:
        raise InputError(f"n_objects must be at least 1, got {n_objects}.")
    if n_frames < 1:
        raise InputError(f"n_frames must be at least 1, got {n_frames}.")
    if size < 32:
        raise InputError(f"size must be at least 32 pixels, got {size}: objects would vanish.")
    if not 0.0 <= multi_fraction <= 1.0:
        raise InputError(f"multi_fraction must be in [0, 1], got {multi_fraction}.")


def _class_flags(rng: np.random.Generator, n: int, multi_fraction: float) -> np.ndarray:
    """Exactly round(n * multi_fraction) multi-axes objects, in random order."""
    n_multi = int(round(n * multi_fraction))
    flags = np.zeros(n, dtype=bool)
    flags[:n_multi] = True
    return rng.permutation(flags)


def make_gastruloids(
    n_objects: int = 78,
    n_frames: int = 25,
    size: int = 128,
    multi_fraction: float = 0.15,
    seed: int = 0,
    params: GastruloidParams | None = None,
) -> GastruloidSet:
    """Synthetic gastruloid movies, one object per movie (the paper's data set layout).

    Parameters
    ----------
    n_objects : int
        Number of movies (the paper: 78).
    n_frames : int
        Frames per movie (the paper: 25); development is spread over them (see module notes).
    size : int
        Frame side in pixels (frames are ``size`` x ``size``).
    multi_fraction : float
        Fraction of multi-axes objects; exactly ``round(n_objects * multi_fraction)`` of them
        (the paper: 13 of 78, about 0.17).
    seed : int
        Seed of the random generator: the same seed gives the same arrays.
    params : GastruloidParams, optional
        Model parameters; the defaults are documented in the module docstring.

    Returns
    -------
    GastruloidSet
        ``labels`` (n_objects, T, Y, X) uint16 with label 1, ``intensity`` float32 of the same
        shape, ``multi_axis`` (n_objects,) bool, ``params`` (the drawn parameters).
    """
    _check(n_objects, n_frames, size, multi_fraction)
    p = params or GastruloidParams()
    rng = np.random.default_rng(seed)
    flags = _class_flags(rng, n_objects, multi_fraction)
    labels = np.zeros((n_objects, n_frames, size, size), dtype=np.uint16)
    intensity = np.zeros((n_objects, n_frames, size, size), dtype=np.float32)
    objects = []
    for i, multi in enumerate(flags):
        obj = _draw_object(rng, p, bool(multi), size)
        masks, images = _render_movie(rng, obj, p, (size, size), n_frames)
        labels[i] = masks
        intensity[i] = images
        objects.append(obj)
    return GastruloidSet(
        labels=labels,
        intensity=intensity,
        multi_axis=flags,
        params={"generator": asdict(p), "seed": seed, "objects": objects},
    )


def make_timelapse_montage(
    n_objects: int = 6,
    n_frames: int = 12,
    size: int = 256,
    seed: int = 0,
    multi_fraction: float = 1.0 / 3.0,
    params: GastruloidParams | None = None,
) -> tuple[np.ndarray, np.ndarray, dict[int, str]]:
    """Several gastruloids per frame, on a grid, for the napari sample data and demos.

    Parameters
    ----------
    n_objects : int
        Number of objects (label ids 1 ... n_objects, stable over time).
    n_frames : int
        Number of frames.
    size : int
        Frame side in pixels; each object lives in its own grid cell.
    seed : int
        Seed of the random generator.
    multi_fraction : float
        Fraction of multi-axes objects (at least one of each class when n_objects >= 2).
    params : GastruloidParams, optional
        Model parameters.

    Returns
    -------
    labels : ndarray, uint16, (T, Y, X)
    intensity : ndarray, float32, (T, Y, X)
    groups : dict
        label id → ``"single-axis"`` or ``"multi-axes"``.
    """
    _check(n_objects, n_frames, size, multi_fraction)
    p = params or GastruloidParams()
    rng = np.random.default_rng(seed)
    flags = _class_flags(rng, n_objects, multi_fraction)
    if n_objects >= 2 and not flags.any():
        flags[rng.integers(n_objects)] = True
    if n_objects >= 2 and flags.all():
        flags[rng.integers(n_objects)] = False
    n_cols = int(np.ceil(np.sqrt(n_objects)))
    n_rows = int(np.ceil(n_objects / n_cols))
    cell = size // max(n_cols, n_rows)
    if cell < 32:
        raise InputError(
            f"size={size} is too small for {n_objects} objects (cells of {cell} px); "
            "use a larger size or fewer objects."
        )
    labels = np.zeros((n_frames, size, size), dtype=np.uint16)
    intensity = np.full((n_frames, size, size), p.background, dtype=np.float32)
    intensity += (p.imaging_noise * rng.standard_normal(intensity.shape)).astype(np.float32)
    np.clip(intensity, 0.0, None, out=intensity)
    groups: dict[int, str] = {}
    off_y = (size - n_rows * cell) // 2
    off_x = (size - n_cols * cell) // 2
    for i, multi in enumerate(flags):
        obj = _draw_object(rng, p, bool(multi), cell)
        masks, images = _render_movie(rng, obj, p, (cell, cell), n_frames)
        r, c = divmod(i, n_cols)
        ys, xs = off_y + r * cell, off_x + c * cell
        sl = np.s_[:, ys : ys + cell, xs : xs + cell]
        labels[sl][masks] = i + 1
        intensity[sl] = images
        groups[i + 1] = "multi-axes" if multi else "single-axis"
    return labels, intensity, groups
