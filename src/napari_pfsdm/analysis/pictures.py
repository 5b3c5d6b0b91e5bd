"""Pictures of one measured object: its SDF, its pushed-forward disk, its skeleton (no Qt).

What the napari plugin shows for the selected object, as plain arrays, so that a script can make
the same pictures: :func:`object_pictures` describes the object again with the options and crop of
its run (exactly what its table row measured) and returns an :class:`ObjectPictures` (2-D) or a
:class:`VolumePictures` (3-D).

Examples
--------
>>> import numpy as np
>>> from napari_pfsdm.core.params import PFSDMParams
>>> labels = np.zeros((64, 64), np.uint8)
>>> labels[16:48, 20:44] = 3
>>> pics = object_pictures(labels, None, 0, 3, params=PFSDMParams(), axes="yx", size=32)
>>> pics.disk.shape, pics.sdf.shape
((32, 32), (32, 32))
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core.params import PFSDMParams

__all__ = ["ObjectPictures", "VolumePictures", "object_pictures", "object_midline",
           "disk_pixels", "sdf_square", "SHELL_RADII"]

#: Margin around an object's bounding box (fraction of its larger side) in the SDF picture.
SDF_MARGIN = 0.25
#: Profile pieces of the midline drawn for a run measured without midline measures.
PICTURE_BINS = 10
#: The shells of the unit ball shown for a 3-D object.
SHELL_RADII = (0.25, 0.5, 0.75, 0.95)


@dataclass
class ObjectPictures:
    """The pictures of one 2-D object.

    Attributes
    ----------
    frame, label : int
    disk : ndarray (S, S)
        Pushed-forward SDF (units of the object's size, negative inside; NaN outside the disk).
    intensity_disk : ndarray (S, S) or None
        Pushed-forward reporter relative to the object's mean (None without a reporter).
    sdf : ndarray (S, S)
        The SDF in pixels (negative inside) on a square around the object, sample ``(i, j)`` at
        frame position ``sdf_corner + (i, j) * sdf_step``.
    sdf_corner : (float, float)
    sdf_step : float
    outline : ndarray (K, 2)
        The outline in frame pixels ``(row, col)``, closed.
    skeleton_image, skeleton_disk : list of ndarray (k, 2)
        The skeleton's branches: frame pixels, and pixels of the disk picture.
    notes : list of str
        Why a part is missing, in plain words.
    midline : Midline or None
        The object's own axis (:func:`object_midline`), when asked for.
    """

    frame: int
    label: int
    disk: np.ndarray
    intensity_disk: np.ndarray | None
    sdf: np.ndarray
    sdf_corner: tuple[float, float]
    sdf_step: float
    outline: np.ndarray
    skeleton_image: list = field(default_factory=list)
    skeleton_disk: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    midline: Any = None


@dataclass
class VolumePictures:
    """The pictures of one 3-D object.

    Attributes
    ----------
    frame, label : int
    shells : ndarray (k, n_lat, n_lon)
        The pushed-forward SDF on :data:`SHELL_RADII` of the unit ball, as maps of directions
        (rows: polar angle from the +z pole; columns: longitude).
    intensity_shells : ndarray or None
        The reporter on the same shells (1 = the object's mean).
    surface : (verts, faces, values)
        The surface in voxels (z, y, x) of the stack; each vertex's distance from the centre
        relative to the sphere of the same volume (1 = on it).
    """

    frame: int
    label: int
    shells: np.ndarray
    intensity_shells: np.ndarray | None
    surface: tuple
    notes: list = field(default_factory=list)


def disk_pixels(uv: np.ndarray, size: int) -> np.ndarray:
    """Pixel ``(row, col)`` of unit-disk points ``(u, v)`` in a ``size`` × ``size`` picture of
    :func:`napari_pfsdm.render_disk` (u along rows, pixel centres at ``(i + 0.5) / size * 2 - 1``).

    >>> disk_pixels(np.array([[-1.0, 1.0]]), 4).tolist()
    [[-0.5, 3.5]]
    """
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    return (uv + 1.0) * 0.5 * size - 0.5


def sdf_square(result, bbox: tuple[slice, slice], size: int
               ) -> tuple[tuple[float, float], float, np.ndarray]:
    """The object's SDF in pixels on a ``size`` × ``size`` grid over a square around its box.

    Returns ``((row0, col0), step, values)``: sample ``(i, j)`` lies at frame position
    ``(row0 + i * step, col0 + j * step)``.
    """
    r0, r1, c0, c1 = bbox[0].start, bbox[0].stop, bbox[1].start, bbox[1].stop
    side = max(r1 - r0, c1 - c0) * (1 + 2 * SDF_MARGIN) + 4
    step = side / size
    cy, cx = (r0 + r1 - 1) / 2, (c0 + c1 - 1) / 2
    row0, col0 = cy - (size - 1) / 2 * step, cx - (size - 1) / 2 * step
    grid = np.arange(size) * step
    rr, cc = np.meshgrid(row0 + grid, col0 + grid, indexing="ij")
    pts = np.stack([rr.ravel(), cc.ravel()], axis=1)
    contour = result.contour
    normalized = (pts - np.asarray(contour.center, float)) / float(contour.scale)
    values = np.asarray(result.sdf(normalized), dtype=float) * float(contour.scale)
    return (float(row0), float(col0)), float(step), values.reshape(size, size).astype(np.float32)


def _volume_pictures(res, frame: int, label: int) -> VolumePictures:
    from ..core.descriptor3d import shell_maps, surface_mesh

    shells = shell_maps(res, SHELL_RADII, n_lat=48, n_lon=96)[0].astype(np.float32)
    ishells = None
    if getattr(res, "intensity_image", None) is not None:
        ishells = shell_maps(res, SHELL_RADII, n_lat=48, n_lon=96,
                             channel="intensity")[0].astype(np.float32)
    verts, faces, values = surface_mesh(res, channel="radius")
    return VolumePictures(frame=frame, label=int(label), shells=shells, intensity_shells=ishells,
                          surface=(verts.astype(np.float32), faces.astype(np.int32),
                                   values.astype(np.float32)))


def object_pictures(labels, intensity, frame: int, label: int, *, params: PFSDMParams,
                    axes: str, spacing=None, box=None, size: int = 128,
                    skeleton_samples: int | None = 512, midline: bool = False
                    ) -> ObjectPictures | VolumePictures:
    """The pictures of the object ``label`` in ``frame``, made with its run's options.

    Parameters
    ----------
    labels, intensity : array-like
        The measured arrays (``intensity`` may be None), with axes ``axes``.
    frame, label : int
        The object (``frame`` is ignored without a time axis).
    params : PFSDMParams
        The run's options.
    axes : str
        ``"yx"``, ``"tyx"``, ``"zyx"`` or ``"tzyx"``.
    spacing : tuple of float, optional
        Voxel size (z, y, x) of Z-stacks.
    box : tuple of slice, optional
        The object's bounding box in its frame, when known.
    size : int
        Side of the disk and SDF pictures, in samples.
    skeleton_samples : int or None
        The skeleton is traced with at most this many samples along the longer side of the
        object's box (``samples_across`` of :func:`napari_pfsdm.core.medial_axis.skeleton`):
        a big object's skeleton then costs about what a 512-pixel one does and lies within
        about a grid step of the one traced at every pixel. None traces every pixel. The
        default is :data:`~napari_pfsdm.core.medial_axis.SAMPLES_ACROSS`, the result's own.
    midline : bool
        Also the object's midline (:func:`object_midline`, 2-D objects), as its row measured
        it; a note says why when it cannot be traced.

    Raises
    ------
    KeyError
        When there is no such object.
    ValueError
        When the object has no features (the reason, in words).
    """
    from ..analysis.features import describe_object
    from ..core.descriptor import render_disks

    where = {"axes": axes}
    if "z" in axes and spacing is not None:
        where["spacing"] = spacing
    t = int(frame) if axes.startswith("t") else 0
    obj = describe_object(labels, intensity, t, int(label), params=params, box=box, **where)
    res = obj.result
    if res is None:
        raise ValueError(obj.error or "the object could not be described")
    if "z" in axes:
        return _volume_pictures(res, t, label)
    disks = render_disks(res, size=size)
    idisk = disks["intensity"].astype(np.float32) if "intensity" in disks else None
    corner, step, sdf = sdf_square(res, obj.bbox, size)
    outline = np.asarray(res.contour.points, float)
    notes: list[str] = []
    sk_img: list = []
    sk_disk: list = []
    try:
        from ..core.medial_axis import SAMPLES_ACROSS, skeleton

        if skeleton_samples == SAMPLES_ACROSS:
            sk = res.skeleton  # the result's own (cached) skeleton
        else:
            sk = skeleton(res, samples_across=skeleton_samples)
        sk_img = [p.astype(np.float32) for p in sk.paths("image")]
        sk_disk = [disk_pixels(p, size).astype(np.float32) for p in sk.paths("disk")]
    except Exception as err:  # noqa: BLE001 - the other pictures are still worth showing
        notes.append(f"no skeleton ({type(err).__name__}: {err})")
    axis = None
    if midline:
        try:
            axis = object_midline(labels, intensity, frame, label, params=params, axes=axes,
                                  box=box)
        except Exception as err:  # noqa: BLE001 - the other pictures are still worth showing
            notes.append(f"no midline ({type(err).__name__}: {err})")
    return ObjectPictures(frame=t, label=int(label), disk=disks["sdf"].astype(np.float32),
                          intensity_disk=idisk, sdf=sdf, sdf_corner=corner, sdf_step=step,
                          outline=np.vstack([outline, outline[:1]]).astype(np.float32),
                          skeleton_image=sk_img, skeleton_disk=sk_disk, notes=notes,
                          midline=axis)


def object_midline(labels, intensity, frame: int, label: int, *, params: PFSDMParams,
                   axes: str, box=None):
    """The midline of the object ``label`` in ``frame``, as its table row measured it, for
    drawing (:class:`~napari_pfsdm.core.midline.Midline`).

    The same object (:func:`~napari_pfsdm.analysis.features.describe_object`: the run's crop
    and options), the same reporter pixels and the same ``profile_bins`` and ``anterior``, so
    ``object_midline(...).columns()`` equals the row's midline columns. Draw
    ``.points`` (image ``(row, col)`` pixels, anterior end first, both ends on the outline) as
    a path, ``.points[0]`` as the anterior end, ``.cross_sections()`` (one segment per bin,
    outline to outline) as lines, and ``.width`` against ``.arc`` (or ``.width_bins``, and
    ``.reporter_bins`` with a reporter) as profiles.

    Parameters
    ----------
    labels, intensity, frame, label, params, axes, box
        As for :func:`object_pictures`.

    Raises
    ------
    KeyError
        When there is no such object.
    ValueError
        When the object has no features, or is 3-D (the midline is measured on 2-D objects).

    Examples
    --------
    >>> labels = np.zeros((64, 96), np.uint8)
    >>> yy, xx = np.mgrid[:64, :96]
    >>> labels[((yy - 32) / 20) ** 2 + ((xx - 48) / 40) ** 2 <= 1] = 2
    >>> m = object_midline(labels, None, 0, 2, params=PFSDMParams(), axes="yx")
    >>> round(m.length), m.points.shape, m.cross_sections().shape
    (80, (101, 2), (10, 2, 2))
    """
    from ..core.midline import midline
    from .features import describe_object
    from .label_images import crop_of

    if "z" in axes:
        raise ValueError("the midline is measured on 2-D objects only")
    t = int(frame) if axes.startswith("t") else 0
    obj = describe_object(labels, intensity, t, int(label), params=params, box=box, axes=axes)
    if obj.result is None:
        raise ValueError(obj.error or "the object could not be described")
    big = crop_of(obj.bbox, tuple(labels.shape[-2:]))
    crop = None
    if intensity is not None:
        plane = intensity[t] if axes.startswith("t") else intensity
        crop = np.asarray(plane[big], float)
    return midline(obj.result, crop, bins=params.profile_bins or PICTURE_BINS,
                   anterior=params.anterior,
                   intensity_offset=tuple(float(s.start) for s in big))
