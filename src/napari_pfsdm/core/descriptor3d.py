"""PF-SDM of one 3-D object: surface → SDF → ball map → per-shell spherical-harmonic power
(docs/design.md §6), and what a viewer needs to show it (shells as sphere maps, the surface).

The 3-D counterpart of :mod:`.descriptor`: the pushed-forward SDF φ*(r, ω) = φ(X(r ω)) / s is
sampled on shells r_i × the directions of a Gauss–Legendre grid, and each shell's
spherical-harmonic power P_l(r_i) (:mod:`.sph_harm`) is the rotation- and mirror-invariant
counterpart of the ring's |c_n(r)|: ``embedding[i, l] = √P_l(r_i)``. The scale s is the radius of
the sphere of equal volume (steadier than the largest radius, which one protrusion changes).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy import ndimage as ndi

from ..errors import InputError
from .ball import HarmonicBallMap, RadialBallMap, make_ball_map
from .intensity import intensity_crop
from .morphometric import mode_weights, ring_radii, ring_weights
from .params import OPTIONS, PFSDMParams, params_of, with_option_keywords
from .sph_harm import SphereGrid, power_spectrum, sh_analysis, sphere_grid
from .volume_sdf import SurfaceSDF, VolumeInfo, prepare_volume

__all__ = ["PFSDM3DResult", "pfsdm3d", "shell_maps", "surface_mesh", "DEFAULTS_3D"]

#: Defaults of the 3-D-only options (from core.params.OPTIONS, like all of pfsdm3d's method
#: options).
DEFAULTS_3D: dict[str, Any] = {o.name: o.default for o in OPTIONS if o.dims == "3d"}



@dataclass(eq=False)
class PFSDM3DResult:
    """Everything :func:`pfsdm3d` computed for one 3-D object (see ``docs/API.md``).

    Attributes
    ----------
    surface : SurfaceSDF
        The smoothed surface and its signed distance (physical crop coordinates).
    mapping : RadialBallMap or HarmonicBallMap
        The map from the unit ball to the object.
    grid : SphereGrid
        The directions sampled on every shell.
    radii : ndarray, shape (n_radii,)
        Shell radii in (0, 1).
    radius : ndarray, shape (n_lat, n_lon)
        R(ω): physical distance from the centre to the outermost surface crossing (harmonic
        map: to where the streamline that starts in direction ω meets the surface).
    ball : ndarray, shape (n_radii, n_lat, n_lon)
        The pushed-forward SDF φ*(r, ω), in units of the scale (negative inside).
    power : ndarray, shape (n_radii, sh_degree + 1)
        P_l(r) per shell.
    embedding : ndarray, shape (n_radii, sh_degree + 1)
        √P_l(r): the invariant features (the table's ``shape_rXX_lYY`` columns).
    surface_embedding : ndarray, shape (sh_degree + 1,)
        √P_l of R(ω) / scale − 1 (the outer surface alone; the surface baseline).
    weights, mode_weights : ndarray
        Shell quadrature weights (with the ring weighting) and per-degree factors (1 + l)^α of
        the distance.
    surface_weight : float
        Weight of ``surface_embedding`` in the distance.
    diagnostics : dict
        ``volume`` (voxels), ``physical_volume``, ``scale``, ``touches_border``,
        ``n_components``, ``n_holes``, ``folded_fraction`` (ball samples outside the object),
        ``crossing_fraction`` (solid angle of rays that cross the surface more than once).
    options : dict
    volume_info : VolumeInfo
    """

    surface: SurfaceSDF = field(repr=False)
    mapping: RadialBallMap | HarmonicBallMap = field(repr=False)
    grid: SphereGrid = field(repr=False)
    radii: np.ndarray = field(repr=False)
    radius: np.ndarray = field(repr=False)
    ball: np.ndarray = field(repr=False)
    power: np.ndarray = field(repr=False)
    embedding: np.ndarray = field(repr=False)
    surface_embedding: np.ndarray = field(repr=False)
    weights: np.ndarray = field(repr=False)
    mode_weights: np.ndarray = field(repr=False)
    surface_weight: float
    diagnostics: dict[str, Any]
    options: dict[str, Any] = field(repr=False)
    volume_info: VolumeInfo = field(repr=False)
    intensity_image: np.ndarray | None = field(default=None, repr=False)
    intensity_ball: np.ndarray | None = field(default=None, repr=False)
    intensity_embedding: np.ndarray | None = field(default=None, repr=False)

    ndim = 3

    @property
    def scale(self) -> float:
        """Physical units per normalised unit (the equal-volume sphere's radius)."""
        return float(self.diagnostics["scale"])

    @property
    def spacing(self) -> np.ndarray:
        return self.volume_info.spacing

    @property
    def center(self) -> np.ndarray:
        """The centroid in voxel coordinates (z, y, x) of the input volume."""
        return self.mapping.center / self.spacing + self.volume_info.offset


def _intensity_crop(intensity: np.ndarray, info: VolumeInfo) -> np.ndarray:
    """The intensity over the prepared mask's box (edge values repeated past the image),
    divided by the object's mean intensity (:func:`~napari_pfsdm.core.intensity.intensity_crop`)."""
    return intensity_crop(intensity, info.offset, info.mask)


def _sample(image: np.ndarray, points: np.ndarray, spacing: np.ndarray) -> np.ndarray:
    idx = (points.reshape(-1, 3) / spacing).T
    return ndi.map_coordinates(image, idx, order=1, mode="nearest").reshape(points.shape[:-1])


def pfsdm3d(
    mask: np.ndarray,
    intensity: np.ndarray | None = None,
    *,
    spacing=None,
    smooth: float = 1.0,
    offset=(0.0, 0.0, 0.0),
    params: PFSDMParams | None = None,
    **options: Any,
) -> PFSDM3DResult:
    """Push-Forward Signed Distance Morphometric of one 3-D object.

    Parameters
    ----------
    mask : array_like of bool, shape (Z, Y, X)
        The object (``labels == id``). Cavities are filled; of several pieces the largest is
        kept; an object touching the volume's faces is accepted and flagged.
    intensity : array_like, shape (Z, Y, X), optional
        A reporter volume over the same voxels (normalised by the object's mean).
    spacing : sequence of 3 floats, optional
        Voxel size along Z, Y, X (e.g. ``(2.0, 0.5, 0.5)`` µm); default isotropic 1. Distances
        are physical; the descriptor is scale-invariant (divided by the equal-volume radius).
    params : PFSDMParams, optional
        The options as one record; or give them as keywords (``**options``).
    **options
        The options of :data:`~napari_pfsdm.core.params.OPTIONS` that apply to volumes (the
        signature is generated from the record, with its defaults, ranges and words; a
        2-D-only option set to another value is refused): ``n_radii``, ``radii``,
        ``ring_weighting``, ``mode_exponent`` (shells and their weights, as the rings of the
        2-D :func:`~.descriptor.pfsdm`); ``sh_degree`` (the highest spherical-harmonic degree L
        per shell: the embedding has L + 1 columns); ``ball_map`` (the map from the ball to the
        object, :mod:`.ball`: ``"radial"``, rays from the centroid to the outermost surface
        crossing, for star-shaped objects; ``"harmonic"``, streamlines of a point source's
        potential, never folds, about twice the cost); ``surface_weight`` (weight of the
        surface term, the SH power of R(ω)/scale − 1, next to the shells', docs/design.md
        §6.5); ``components`` (several pieces: keep the largest or refuse); ``min_area``
        (smaller objects, in voxels, are refused: the same setting, and default, as for 2-D
        objects).
    smooth : float
        Gaussian smoothing of the mask before the surface, in finest-voxel widths.
    offset : 3 floats
        Voxel index (z, y, x) of ``mask[0, 0, 0]`` when the mask is a crop of a larger volume;
        :func:`surface_mesh` and ``center`` are then in the larger volume's voxels.

    Returns
    -------
    PFSDM3DResult

    Examples
    --------
    >>> import numpy as np
    >>> zz, yy, xx = np.mgrid[:40, :40, :40] - 19.5
    >>> res = pfsdm3d(zz**2 + yy**2 + xx**2 < 15**2, n_radii=4, sh_degree=4)
    >>> res.embedding.shape
    (4, 5)
    >>> bool(res.embedding[:, 1:].max() < 0.02 * res.embedding[:, 0].min())  # a sphere: l = 0
    True
    """
    mask = np.asarray(mask)
    # the options checked as from any other door (core.params; same messages)
    p = params if params is not None else params_of(options)
    p.check_dimension(3)
    radii = np.asarray(p.radii) if isinstance(p.radii, tuple) else p.radii
    n_radii, ring_weighting, mode_exponent = p.n_radii, p.ring_weighting, p.mode_exponent
    ball_map, components = p.ball_map, p.components
    info = prepare_volume(mask, spacing, components=components, min_volume=p.min_area)
    if intensity is not None:
        intensity = np.asarray(intensity)
        if intensity.shape != mask.shape:
            raise InputError(f"The intensity volume has shape {intensity.shape} but the mask "
                             f"has shape {mask.shape}: they must cover the same voxels.")
        if not np.issubdtype(intensity.dtype, np.number) or np.iscomplexobj(intensity):
            raise InputError(f"The intensity must be real numbers, got dtype {intensity.dtype}.")
    sh_degree, surface_weight = p.sh_degree, p.surface_weight
    surface = SurfaceSDF(info, smooth=smooth)
    if not surface.volume > 0:
        raise InputError("The object has no inside after smoothing (it is thinner than a voxel "
                         "everywhere); it cannot be described in 3-D.")
    scale = float((3 * surface.volume / (4 * np.pi)) ** (1 / 3))
    pmap = make_ball_map(ball_map, surface, scale)
    grid = sphere_grid(sh_degree)
    radius, crossings = pmap.rays(grid.directions)
    r = ring_radii(n_radii, radii)
    pts = pmap.points(r, grid.directions, radius)  # (n_r, lat, lon, 3)
    ball = surface(pts.reshape(-1, 3)).reshape(pts.shape[:-1]) / scale
    power = power_spectrum(sh_analysis(ball, grid))
    surf_power = power_spectrum(sh_analysis(radius / scale - 1.0, grid))
    solid = grid.solid_angle / (4 * np.pi)
    diagnostics = {
        "volume": info.volume,
        "physical_volume": surface.volume,
        "scale": scale,
        "touches_border": info.touches_border,
        "n_components": info.n_components,
        "n_holes": info.n_holes,
        "folded_fraction": float(((ball > 0) * solid[None]).sum() / len(r)),
        "crossing_fraction": float((solid * (crossings > 1)).sum()),
    }
    options = {
        "ndim": 3, "spacing": info.spacing.tolist(), "n_radii": len(r), "radii": r.tolist(),
        "ring_weighting": ring_weighting, "mode_exponent": float(mode_exponent),
        "sh_degree": sh_degree, "ball_map": ball_map, "surface_weight": float(surface_weight),
        "smooth": smooth,
    }
    result = PFSDM3DResult(
        surface=surface, mapping=pmap, grid=grid, radii=r, radius=radius, ball=ball, power=power,
        embedding=np.sqrt(power), surface_embedding=np.sqrt(surf_power),
        weights=ring_weights(r, ring_weighting),
        mode_weights=mode_weights(sh_degree, mode_exponent), surface_weight=float(surface_weight),
        diagnostics=diagnostics, options=options, volume_info=info,
    )
    if intensity is not None:
        result.intensity_image = _intensity_crop(intensity, info)
        result.intensity_ball = _sample(result.intensity_image, pts, info.spacing)
        result.intensity_embedding = np.sqrt(power_spectrum(sh_analysis(result.intensity_ball,
                                                                        grid)))
    if any(offset):
        result.volume_info = replace(info, offset=info.offset + np.asarray(offset, float))
    return result



pfsdm3d.__signature__ = with_option_keywords(pfsdm3d)  # type: ignore[attr-defined]

def shell_maps(
    result: PFSDM3DResult,
    radii=(0.25, 0.5, 0.75, 0.95),
    *,
    n_lat: int = 64,
    n_lon: int = 128,
    channel: str = "sdf",
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A few shells of the pushed-forward function as latitude × longitude images, for display.

    Parameters
    ----------
    result : PFSDM3DResult
    radii : sequence of float in [0, 1]
        The shells to show.
    n_lat, n_lon : int
        Image size: rows are polar angles θ from 0 (the +z pole) to π at pixel centres, columns
        longitudes φ from 0 to 2π (φ measured from +x towards +y).
    channel : {"sdf", "intensity"}
        φ* (units of the scale, negative inside) or the intensity (relative to the object's
        mean).

    Returns
    -------
    images : ndarray, shape (len(radii), n_lat, n_lon)
    theta, phi : ndarray, shapes (n_lat,), (n_lon,)
        The pixel centres' angles (radians).
    """
    if channel not in ("sdf", "intensity"):
        raise InputError(f"channel must be 'sdf' or 'intensity', got {channel!r}.")
    if channel == "intensity" and result.intensity_image is None:
        raise InputError("This result has no intensity: pass an intensity volume to pfsdm.")
    r = np.asarray(radii, float).ravel()
    if r.size == 0 or r.min() < 0 or r.max() > 1:
        raise InputError("Shell radii must lie in [0, 1].")
    theta = (np.arange(n_lat) + 0.5) * np.pi / n_lat
    phi = (np.arange(n_lon) + 0.5) * 2 * np.pi / n_lon
    st = np.sin(theta)[:, None]
    dirs = np.stack([np.repeat(np.cos(theta)[:, None], n_lon, 1), st * np.sin(phi)[None],
                     st * np.cos(phi)[None]], axis=-1)
    pts = result.mapping.points(r, dirs)
    if channel == "sdf":
        values = result.surface(pts.reshape(-1, 3)).reshape(pts.shape[:-1]) / result.scale
    else:
        values = _sample(result.intensity_image, pts, result.spacing)
    return values, theta, phi


def surface_mesh(
    result: PFSDM3DResult,
    *,
    channel: str = "radius",
    shell: float = 0.5,
    coordinates: str = "voxel",
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The object's surface as a triangle mesh with one value per vertex, for display.

    Parameters
    ----------
    result : PFSDM3DResult
    channel : {"radius", "sdf", "intensity"}
        The value per vertex: ``"radius"`` R(ω)/scale of the vertex's direction ω from the
        centroid (1 = the equal-volume sphere; the surface term); ``"sdf"`` the pushed-forward
        SDF φ*(``shell``, ω) under the vertex (how deep the object is along that ray);
        ``"intensity"`` the relative intensity just inside the vertex (half a finest voxel).
    shell : float in [0, 1]
        The shell of ``channel="sdf"``.
    coordinates : {"voxel", "physical"}
        Vertex coordinates (z, y, x) in voxels of the input volume (what napari's Surface layer
        takes, with ``scale=spacing``) or in physical units (voxel × spacing).

    Returns
    -------
    verts : ndarray of float, shape (V, 3)
    faces : ndarray of int, shape (F, 3)
    values : ndarray of float, shape (V,)
    """
    if channel not in ("radius", "sdf", "intensity"):
        raise InputError(f"channel must be 'radius', 'sdf' or 'intensity', got {channel!r}.")
    if coordinates not in ("voxel", "physical"):
        raise InputError(f"coordinates must be 'voxel' or 'physical', got {coordinates!r}.")
    s = result.surface
    rel = s.verts - result.mapping.center
    dirs = rel / np.maximum(np.linalg.norm(rel, axis=1, keepdims=True), 1e-12)
    if channel == "radius":
        values = result.mapping.rays(dirs)[0] / result.scale
    elif channel == "sdf":
        pts = result.mapping.points([shell], dirs)[0]
        values = s(pts) / result.scale
    else:
        if result.intensity_image is None:
            raise InputError("This result has no intensity: pass an intensity volume to pfsdm.")
        inward = s.verts - 0.5 * result.spacing.min() * s.normals
        values = _sample(result.intensity_image, inward, result.spacing)
    verts = s.verts / result.spacing + result.volume_info.offset
    if coordinates == "physical":
        verts = verts * result.spacing
    return verts, s.faces.copy(), np.asarray(values, float)
