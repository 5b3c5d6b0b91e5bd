"""PF-SDM of one object: contour → SDF → push-forward → Fourier magnitudes (docs/design.md §2)."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from typing import Any

import numpy as np
from scipy import ndimage as ndi

from ..errors import InputError
from .boundary import normalised_modes, outline_coefficients
from .contour import Contour, MaskInfo, extract_contour, prepare_mask
from .elastic_signature import SMOOTHING, outline_signature
from .intensity import intensity_crop
from .medial_axis import skeleton as _skeleton
from .morphometric import magnitude_embedding, mode_weights, ring_radii, ring_weights, spectrum
from .params import OPTIONS, PFSDMParams, as_params, params_of, with_option_keywords
from .pushforward import BijectiveMap, FourierMap, display_turn, make_map
from .sdf import ExactSDF, ViscousSDF, make_sdf

__all__ = ["PFSDMResult", "pfsdm", "render_disk", "render_disks", "DEFAULTS"]

#: Default options of :func:`pfsdm`: those of :data:`~napari_pfsdm.core.params.OPTIONS`
#: (chosen on the benchmarks, see docs/method.md).
DEFAULTS: dict[str, Any] = {o.name: o.default for o in OPTIONS}


@dataclass(eq=False)
class PFSDMResult:
    """Everything :func:`pfsdm` computed for one object (see ``docs/API.md``).

    The ``skeleton`` is computed on first access (it costs more than the embedding).
    """

    contour: Contour
    sdf: ExactSDF | ViscousSDF
    mapping: FourierMap | BijectiveMap
    radii: np.ndarray
    angles: np.ndarray
    weights: np.ndarray
    mode_weights: np.ndarray
    samples: np.ndarray
    disk: np.ndarray
    spectrum: np.ndarray
    embedding: np.ndarray
    diagnostics: dict[str, Any]
    options: dict[str, Any]
    mask_info: MaskInfo = field(repr=False)
    intensity_image: np.ndarray | None = field(default=None, repr=False)
    intensity_disk: np.ndarray | None = None
    intensity_spectrum: np.ndarray | None = None
    intensity_embedding: np.ndarray | None = None

    @cached_property
    def outline(self) -> np.ndarray:
        """Normalised Fourier coefficients of the outline, what the boundary term of the
        distance compares (:func:`napari_pfsdm.core.boundary.outline_coefficients`): the
        harmonic map's own coefficients when that is the map."""
        if self.options["mapping"] == "harmonic" and isinstance(self.mapping, FourierMap):
            return normalised_modes(self.mapping.coefficients)
        return outline_coefficients(self.contour.normalized)

    @cached_property
    def signature(self) -> np.ndarray:
        """The outline signature that the elastic term of the distance compares
        (:func:`napari_pfsdm.core.elastic_signature.outline_signature`, with the result's
        ``elastic_smoothing``): (channels, points)."""
        return outline_signature(self.contour.normalized,
                                 smoothing=self.options.get("elastic_smoothing",
                                                            SMOOTHING))

    @cached_property
    def skeleton(self):
        """The pruned medial axis, in image and disk coordinates (:class:`Skeleton`)."""
        return _skeleton(self)


def _check_intensity(intensity: np.ndarray, mask_shape: tuple[int, ...]) -> np.ndarray:
    intensity = np.asarray(intensity)
    if intensity.shape != mask_shape:
        raise InputError(
            f"The intensity image has shape {intensity.shape} but the mask has shape "
            f"{mask_shape}: they must cover the same pixels."
        )
    if not np.issubdtype(intensity.dtype, np.number) or np.iscomplexobj(intensity):
        raise InputError(f"The intensity image must be real numbers, got dtype {intensity.dtype}.")
    return intensity.astype(np.float64, copy=False)


def _intensity_crop(intensity: np.ndarray, info: MaskInfo) -> np.ndarray:
    """The intensity over the prepared mask's box (edge values repeated past the image),
    divided by the object's mean intensity (:func:`~napari_pfsdm.core.intensity.intensity_crop`)."""
    return intensity_crop(intensity, info.offset, info.mask)


def pfsdm(
    mask: np.ndarray,
    intensity: np.ndarray | None = None,
    *,
    smooth: float = 1.0,
    degree: int = 16,
    grid: int = 48,
    offset: tuple[float, ...] = (0.0, 0.0),
    spacing=None,
    params: PFSDMParams | None = None,
    **options: Any,
):
    """Push-Forward Signed Distance Morphometric of one 2-D object or one 3-D volume.

    A 3-D mask (Z, Y, X) goes to :func:`~napari_pfsdm.core.descriptor3d.pfsdm3d` (docs/design.md
    §6) and returns a :class:`~napari_pfsdm.core.descriptor3d.PFSDM3DResult`; its options are
    ``spacing``, ``n_radii``, ``radii``, ``ring_weighting``, ``mode_exponent``, ``sh_degree``,
    ``surface_weight``, ``ball_map``, ``components``, ``min_area`` (voxels), ``smooth`` and
    ``offset``. The 2-D-only options (``n_fourier``, ``n_angles``, ``sdf``, ``viscosity``,
    ``mapping``, ``normalization``) must stay at their defaults for a volume, and the 3-D-only
    ones for a 2-D mask: a changed value is refused, never ignored.

    The method's options are the keywords of :data:`~napari_pfsdm.core.params.OPTIONS` (the
    signature is generated from it, with the same defaults, ranges and choices); a bad value
    raises :class:`~napari_pfsdm.errors.InputError` in the same words as from ``measure``, the
    command line or a table's record.

    Parameters
    ----------
    mask : array_like of bool, shape (Y, X)
        The object, e.g. ``labels == 3``. Holes are filled; of several pieces the largest is
        kept (``components``); an object touching the image edge is accepted and flagged.
    intensity : array_like, shape (Y, X), optional
        A reporter image over the same pixels; gives ``intensity_embedding`` (normalised by the
        object's mean intensity, so overall brightness does not matter).
    n_fourier : int
        Highest Fourier index N_F kept per ring (the embedding has N_F + 1 columns).
    n_radii, n_angles : int
        Polar sampling of the disk: rings in (0, 1) and equispaced angles (power of 2 best).
    sdf : {"exact", "viscous"}
        ``"exact"``: signed Euclidean distance to the sub-pixel outline (fast; default).
        ``"viscous"``: the paper's regularised distance, smooth across the skeleton, ~25× slower.
    viscosity : float
        ν of the viscous SDF, in units of the object's size (largest centroid distance = 1).
    mapping : {"harmonic", "bijective", "radial"}
        Push-forward map from the disk to the shape. ``"harmonic"`` (arc-length boundary
        correspondence, Poisson extension): fastest, may fold for long bent arms (see
        ``diagnostics["folded_fraction"]``). ``"bijective"``: never folds, ~7× slower; use it
        for snake-like or strongly branched objects. ``"radial"``: the paper's polar-angle map;
        only for star-shaped objects.
    normalization : {"none", "ring"}
        ``"ring"`` scales (c_1 … c_N_F) to unit length on every ring, as in the paper.
    radii : {"uniform", "boundary"} or array_like
        Placement of the rings (``"boundary"`` packs them toward the outline).
    ring_weighting : {"depth", "none", "boundary"}
        Extra weight of each ring in the distance. ``"depth"`` (default) divides by (1 − r)²,
        i.e. compares φ*/(1 − r), which stays of order one up to the outline where φ* → 0;
        ``"boundary"``: 1/(1 − r + 0.05); ``"none"``: the plain ∫ dr of the paper.
    mode_exponent : float
        The distance compares (1 + n)^mode_exponent · |c_n|: 0.25 (default) brings out the fine
        outline; 0 as in the paper.
    components : {"largest", "raise"}
        What to do with an object made of several pieces.
    min_area : int
        Smaller objects raise ``ValueError``.
    smooth : float
        Gaussian smoothing of the outline along its length, in pixels (removes the pixel
        staircase that otherwise changes with the object's orientation).
    degree : int
        Polynomial degree of the ``"radial"`` map.
    grid : int
        Grid resolution (nodes across the object) of the ``"bijective"`` map.
    offset : (float, float)
        Image coordinates of ``mask[0, 0]``, when the mask is a crop of a larger image; all
        image-space outputs (contour, skeleton) are then in the larger image's coordinates.
    spacing : sequence of floats, optional
        Voxel size along Z, Y, X for a 3-D mask. A 2-D mask takes only an isotropic one (the
        descriptor is scale-invariant); anisotropic pixels are refused.
    sh_degree, surface_weight, ball_map
        3-D only (see :func:`~napari_pfsdm.core.descriptor3d.pfsdm3d`).
    params : PFSDMParams, optional
        The options as one checked record, instead of keywords (giving both is refused).

    Returns
    -------
    PFSDMResult, or PFSDM3DResult for a 3-D mask

    Raises
    ------
    ValueError
        Not a 2-D mask, an empty or too small object, a mismatched or NaN intensity, an unknown
        option or a value out of its range (:class:`~napari_pfsdm.errors.InputError`).

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[:96, :96]
    >>> ellipse = ((yy - 48) / 30) ** 2 + ((xx - 48) / 15) ** 2 < 1
    >>> res = pfsdm(ellipse)
    >>> res.embedding.shape
    (16, 11)
    >>> rotated = ((xx - 48) / 30) ** 2 + ((yy - 48) / 15) ** 2 < 1
    >>> bool(np.abs(pfsdm(rotated).embedding - res.embedding).max() < 0.01)
    True
    """
    mask = np.asarray(mask)
    # a bad or unknown option fails here, in plain words
    p = params_of(options) if params is None else as_params(params, options)
    if (options or params is not None) and mask.ndim in (2, 3):  # defaults fit every dimension
        p.check_dimension(mask.ndim)
    radii = np.asarray(p.radii) if isinstance(p.radii, tuple) else p.radii
    if mask.ndim == 3:
        from .descriptor3d import pfsdm3d

        return pfsdm3d(mask, intensity, spacing=spacing, smooth=smooth, params=p,
                       offset=(0.0, 0.0, 0.0) if not any(offset) else offset)
    if spacing is not None:
        sp = np.asarray(spacing, float).ravel()
        if mask.ndim == 2 and (sp.size not in (1, 2) or not np.all(sp == sp[0])):
            raise InputError(
                f"spacing {tuple(sp.tolist())} was given for a 2-D mask: 2-D objects take "
                "square pixels only (the descriptor does not depend on their size). For a 3-D "
                "volume pass the (Z, Y, X) mask itself."
            )
    info = prepare_mask(mask, components=p.components, min_area=p.min_area)
    if intensity is not None:
        intensity = _check_intensity(intensity, mask.shape)
    n_angles, n_fourier = p.n_angles, p.n_fourier
    n_points = n_angles * -(-256 // n_angles)  # the multiple of n_angles from 256 up
    contour = extract_contour(info, n_points=n_points, smooth=smooth)
    nodes = contour.normalized
    phi = make_sdf(p.sdf, nodes, viscosity=p.viscosity)
    exact = phi.exact if isinstance(phi, ViscousSDF) else phi
    pmap = make_map(p.mapping, nodes, exact, degree=degree, grid=grid)

    r, theta, ring_w, mode_w = (a.copy() for a in _sampling(
        p.n_radii, radii if isinstance(radii, str) else tuple(np.ravel(radii).tolist()),
        n_angles, p.ring_weighting, n_fourier, p.mode_exponent))
    if isinstance(pmap, FourierMap):
        samples, jacobian = pmap.polar_and_jacobian(r, n_angles)
    else:
        samples, jacobian = pmap.polar(r, n_angles), None
    disk = phi(samples.reshape(-1, 2)).reshape(len(r), n_angles)
    folded = disk > 0
    if jacobian is not None:
        folded |= jacobian <= 0
    spec = spectrum(disk)
    emb = magnitude_embedding(spec, n_fourier, p.normalization)

    diagnostics = {
        "area": info.area,
        "touches_border": info.touches_border,
        "n_components": info.n_components,
        "n_holes": info.n_holes,
        "folded_fraction": np.count_nonzero(folded) / folded.size,
        "scale": contour.scale,
    }
    result_options = {
        "n_fourier": n_fourier, "n_radii": len(r), "n_angles": n_angles, "sdf": p.sdf,
        "viscosity": p.viscosity, "mapping": p.mapping, "normalization": p.normalization,
        "radii": r.tolist(), "ring_weighting": p.ring_weighting,
        "mode_exponent": p.mode_exponent, "elastic_smoothing": p.elastic_smoothing,
        "smooth": smooth,
    }
    result = PFSDMResult(
        contour=contour, sdf=phi, mapping=pmap, radii=r, angles=theta,
        weights=ring_w, mode_weights=mode_w, samples=samples, disk=disk,
        spectrum=spec, embedding=emb, diagnostics=diagnostics, options=result_options,
        mask_info=info,
    )
    if intensity is not None:
        result.intensity_image = _intensity_crop(intensity, info)
        result.intensity_disk = sample_intensity(result, samples)
        result.intensity_spectrum = spectrum(result.intensity_disk)
        result.intensity_embedding = magnitude_embedding(
            result.intensity_spectrum, n_fourier, p.normalization)
    if any(offset):
        _shift(result, np.asarray(offset, float))
    return result


pfsdm.__signature__ = with_option_keywords(pfsdm)  # type: ignore[attr-defined]


@lru_cache(maxsize=8)
def _sampling(n_radii: int, radii: str | tuple[float, ...], n_angles: int, ring_weighting: str,
              n_fourier: int, mode_exponent: float) -> tuple[np.ndarray, ...]:
    """The rings' radii, the angles, the ring weights and the mode weights of a set of
    options, computed once (read-only; :func:`pfsdm` hands out copies)."""
    r = ring_radii(n_radii, radii if isinstance(radii, str) else np.asarray(radii))
    out = (r, 2 * np.pi * np.arange(n_angles) / n_angles, ring_weights(r, ring_weighting),
           mode_weights(n_fourier, mode_exponent))
    for a in out:
        a.flags.writeable = False
    return out


def _shift(result: PFSDMResult, offset: np.ndarray) -> None:
    """Move a result computed on a crop into the coordinates of the full image."""
    c = result.contour
    result.contour = Contour(points=c.points + offset, center=c.center + offset, scale=c.scale,
                             area=c.area)
    info = result.mask_info
    result.mask_info = MaskInfo(mask=info.mask, offset=info.offset + offset, area=info.area,
                                n_components=info.n_components, n_holes=info.n_holes,
                                touches_border=info.touches_border, outline=info.outline)


def _polar_to_cartesian(polar: np.ndarray, size: int, turn: float = 0.0) -> np.ndarray:
    """Resample (n_r, n_θ) samples at r_i = (i + ½)/n_r, θ_j = 2πj/n_θ onto a size × size image
    of the unit disk (row ↔ u, col ↔ v, NaN outside), the disk turned by ``turn`` radians."""
    n_r, n_t = polar.shape
    c = (np.arange(size) + 0.5) / size * 2 - 1
    u, v = np.meshgrid(c, c, indexing="ij")
    rho = np.hypot(u, v)
    ang = np.mod(np.arctan2(v, u) - turn, 2 * np.pi)
    ri = np.clip(rho * n_r - 0.5, 0, n_r - 1)
    ti = ang / (2 * np.pi) * n_t
    wrapped = np.concatenate([polar, polar[:, :1]], axis=1)
    img = ndi.map_coordinates(wrapped, [ri.ravel(), ti.ravel()], order=1).reshape(size, size)
    img[rho > 1] = np.nan
    return img


def render_disk(result: PFSDMResult, size: int = 128, channel: str = "sdf") -> np.ndarray:
    """The pushed-forward function as a Cartesian image of the unit disk, for display.

    Parameters
    ----------
    result : PFSDMResult
    size : int
        Output is ``size × size``; pixel (i, j) is the disk point u = row, v = column (both
        in [-1, 1]), turned so that the disk shows the object roughly in the image's
        orientation (the turn does not change any descriptor).
    channel : {"sdf", "intensity"}
        The PF-SDF φ* (normalised units, negative inside) or the pushed intensity (relative to
        the object's mean).

    Returns
    -------
    ndarray of float, shape (size, size); NaN outside the disk.
    """
    return render_disks(result, size, (channel,))[channel]


def render_disks(result: PFSDMResult, size: int = 128,
                 channels: tuple[str, ...] = ("sdf", "intensity")) -> dict[str, np.ndarray]:
    """:func:`render_disk` of several channels at once (the map is evaluated once).

    Returns
    -------
    dict
        ``{channel: image}``, for the channels asked for; ``"intensity"`` is left out when the
        result has no intensity.
    """
    for channel in channels:
        if channel not in ("sdf", "intensity"):
            raise InputError(f"channel must be 'sdf' or 'intensity', got {channel!r}.")
    if channels == ("intensity",) and result.intensity_image is None:
        raise InputError("This result has no intensity: pass an intensity image to pfsdm.")
    # about two samples per output pixel along each ring: the SDF evaluation is the cost
    n_r, n_t = max(size // 2, 4), max(64, 2 * size)
    pts = result.mapping.polar((np.arange(n_r) + 0.5) / n_r, n_t)
    # θ = 0 is where the outline's parametrisation starts; turn the disk so that this point
    # shows at its own polar angle around the centroid: the disk then shows the object roughly
    # in the image's orientation.
    turn = display_turn(result)
    out = {}
    for channel in channels:
        if channel == "sdf":
            values = result.sdf(pts.reshape(-1, 2)).reshape(n_r, n_t)
        elif result.intensity_image is not None:
            values = sample_intensity(result, pts)
        else:
            continue
        out[channel] = _polar_to_cartesian(values, size, turn=turn)
    return out


def sample_intensity(result: PFSDMResult, points: np.ndarray) -> np.ndarray:
    """Relative intensity (1 = the object's mean) at normalised shape points (..., 2)."""
    pix = points.reshape(-1, 2) * result.contour.scale + result.contour.center
    pix = pix - result.mask_info.offset
    values = ndi.map_coordinates(result.intensity_image, pix.T, order=1, mode="nearest")
    return values.reshape(points.shape[:-1])
