"""The per-object step of every measuring path: one object's crop in, one table row out.

:class:`ObjectMeasurer` is built from the typed option record (:class:`~napari_pfsdm.core.
params.PFSDMParams`), the objects' dimension and whether there is a reporter. It owns

- :meth:`~ObjectMeasurer.crop`: an object's pixels cut from its frame with a margin
  (:class:`Crop`, what a worker process is sent for an object of a frame split between tasks);
- :meth:`~ObjectMeasurer.measure`: the crop's :class:`ObjectResult` (the PF-SDM descriptor and
  every per-object measure of :data:`MEASURES`);
- :attr:`~ObjectMeasurer.columns` and :meth:`~ObjectMeasurer.table`: the table's columns, in
  order, and the rows of measured objects.

``pf.measure``, the plugin's Run (the process pool of :mod:`~napari_pfsdm.analysis.parallel`),
dask's tasks and the batch (:mod:`napari_pfsdm.batch.tasks`) all build one measurer and send it
to their workers as it is (it pickles); the options that only choose which objects enter a shape
space (:data:`~napari_pfsdm.core.params.LEAVE_OUT_OPTIONS`) are not part of it
(:meth:`~napari_pfsdm.core.params.PFSDMParams.measured`): they act where the shape space is
built, and changing them measures nothing again.

**A new per-object measure** is one :class:`Measure` in :data:`MEASURES`: the function that
computes it from an :class:`ObjectView` and the declaration of its columns (name, meaning in
plain words, unit), from which the table's columns, the glossary
(:mod:`napari_pfsdm.analysis.glossary`) and docs/columns.md follow.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field, replace
from functools import cached_property
from types import SimpleNamespace
from typing import Any

import numpy as np
import pandas as pd

from ..core import units
from ..core.boundary import N_OUTLINE_MODES
from ..core.columns import BASE_2D, BASE_3D, Column, Family
from ..core.descriptor import PFSDMResult, pfsdm
from ..core.elastic_signature import N_CHANNELS, N_SIGNATURE_POINTS
from ..core.midline import midline_columns
from ..core.params import PFSDMParams
from ..core.pieces import quietly
from ..core.table_options import set_options
from ..core.table_schema import (
    outline_columns,
    signature_columns,
    table_feature_columns,
)
from ..core.units import check_pixel_size
from ..core.volume_sdf import check_spacing
from ..errors import InputError
from . import classic
from .label_images import crop_of, object_boxes

__all__ = [
    "FOLDED_WARNING",
    "MEASURES",
    "Crop",
    "Measure",
    "ObjectMeasurer",
    "ObjectResult",
    "ObjectView",
    "light",
    "object_warnings",
]

#: A row's ``warnings`` mention folding above this fraction of disk samples (5 %): the map
#: then leaves the object there, and the features describe the object less faithfully.
FOLDED_WARNING = 0.05


@dataclass
class ObjectResult:
    """One object of one frame, measured.

    Attributes
    ----------
    frame, label : int
    bbox : tuple of slice
        The object's bounding box in the frame (row slice, column slice; 3-D: z, row, col).
    area : int
        Pixels (3-D: voxels) of the label in the frame.
    centroid : ndarray, shape (2,) or (3,)
        Pixel centroid (row, col) in the frame; 3-D: voxel centroid (z, row, col).
    result : PFSDMResult, PFSDM3DResult or None
        ``None`` when the object could not be described; ``error`` then says why.
    error : str
        Empty when fine.
    intensity_error : str
        Why the intensity could not be described (NaN pixels, no signal) while the shape was:
        ``result`` then has no intensity embedding. Empty when fine.
    measures : dict
        The values of the per-object measures (:data:`MEASURES`) by column name.
    """

    frame: int
    label: int
    bbox: tuple[slice, ...]
    area: int
    centroid: np.ndarray
    touches_border: bool
    result: PFSDMResult | None
    error: str = ""
    intensity_error: str = ""
    measures: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Crop:
    """One object's pixels, cut from its frame with a margin (:func:`~napari_pfsdm.analysis.
    label_images.crop_of`).

    Attributes
    ----------
    frame, label : int
    box : tuple of slice
        The object's bounding box in the frame.
    origin : tuple of int
        Where the crop starts in the frame.
    labels : ndarray
        The frame's labels in the crop (every label there, not only the object's).
    image : ndarray or None
        The reporter's pixels in the crop, in the image's own dtype.
    touches_border : bool
        Whether the object's box reaches an edge of the frame.
    """

    frame: int
    label: int
    box: tuple[slice, ...]
    origin: tuple[int, ...]
    labels: np.ndarray
    image: np.ndarray | None
    touches_border: bool

    def detached(self) -> Crop:
        """The crop with its own copy of its pixels, not a view of the frame (to be sent to
        another process without the frame)."""
        return replace(self, labels=np.array(self.labels),
                       image=None if self.image is None else np.array(self.image))


@dataclass(frozen=True)
class ObjectView:
    """What a :class:`Measure` computes from: the object's mask (its labelled pixels, every
    piece and hole as segmented), the reporter on the same pixels (float, or None), its PF-SDM
    result (None when it has no features), where the crop starts in the frame (``offset``),
    and the measurer (its options, ``spacing`` of voxels for 3-D objects)."""

    mask: np.ndarray
    image: np.ndarray | None
    result: Any
    offset: tuple[int, ...]
    measurer: ObjectMeasurer


@dataclass(frozen=True)
class Measure:
    """One per-object measure.

    Attributes
    ----------
    name : str
    declares : tuple of Column or Family
        Its columns: name, meaning in plain words, unit (the glossary and docs/columns.md).
    columns : callable(ObjectMeasurer) -> list of str
        The names it fills for a measurer, in the table's order.
    compute : callable(ObjectView) -> dict
        The value of each of those columns for one object (missing names are NaN).
    applies : callable(ObjectMeasurer) -> bool
        Whether a measurer computes it (e.g. 2-D objects only, with a reporter only).
    """

    name: str
    declares: tuple[Column | Family, ...]
    columns: Callable[[ObjectMeasurer], list[str]]
    compute: Callable[[ObjectView], dict]
    applies: Callable[[ObjectMeasurer], bool]


# --------------------------------------------------------------------------- the measures
def _shape_2d(view: ObjectView) -> dict:
    return classic.shape_measures(view.mask)


def _shape_3d(view: ObjectView) -> dict:
    return classic.shape_measures(view.mask, spacing=view.measurer.spacing)


def _reporter(view: ObjectView) -> dict:
    return classic.reporter_measures(view.mask, view.image)


def _midline(view: ObjectView) -> dict:
    p = view.measurer.params
    return classic.midline_measures(view.result, view.image, offset=view.offset,
                                    bins=p.profile_bins, anterior=p.anterior)


def _shape_2d_columns(m: ObjectMeasurer) -> list[str]:
    return list(classic.SHAPE_MEASURES_2D)


def _shape_3d_columns(m: ObjectMeasurer) -> list[str]:
    return list(classic.SHAPE_MEASURES_3D)


def _reporter_columns(m: ObjectMeasurer) -> list[str]:
    return list(classic.REPORTER_MEASURES)


def _midline_columns(m: ObjectMeasurer) -> list[str]:
    return midline_columns(m.params.profile_bins, m.with_intensity)


def _in_2d(m: ObjectMeasurer) -> bool:
    return m.ndim == 2


def _in_3d(m: ObjectMeasurer) -> bool:
    return m.ndim == 3


def _with_reporter(m: ObjectMeasurer) -> bool:
    return m.with_intensity


def _with_midline(m: ObjectMeasurer) -> bool:
    return m.ndim == 2 and m.params.profile_bins > 0


#: The per-object measures, in the table's order (after the base columns, before the
#: features). Their functions are module-level, so that a measurer pickles by reference.
MEASURES: tuple[Measure, ...] = (
    Measure("shape (2-D)", classic.SHAPE_COLUMNS_2D, _shape_2d_columns, _shape_2d, _in_2d),
    Measure("shape (3-D)", classic.SHAPE_COLUMNS_3D, _shape_3d_columns, _shape_3d, _in_3d),
    Measure("reporter", classic.REPORTER_COLUMNS, _reporter_columns, _reporter,
            _with_reporter),
    Measure("midline", classic.MIDLINE_COLUMNS, _midline_columns, _midline, _with_midline),
)


# --------------------------------------------------------------------------- the measurer
@dataclass(frozen=True)
class ObjectMeasurer:
    """Measures objects one crop at a time, as every path of the package does.

    Build it with :meth:`of` (from the option record). It pickles: the process pool and dask
    send it to their workers with the crops.

    Attributes
    ----------
    params : PFSDMParams
        What is measured (:meth:`~napari_pfsdm.core.params.PFSDMParams.measured`: the options
        that only leave objects out of shape spaces at their defaults).
    ndim : {2, 3}
    with_intensity : bool
    axes : str or None
        The labels' axes, for the table's record (None: 2-D objects, not recorded).
    spacing : tuple of 3 floats or None
        Voxel size (Z, Y, X) of 3-D objects.
    measures : tuple of Measure
        The measures of :data:`MEASURES` that apply.
    pixel_size : tuple of float or None
        The physical size of a pixel (Y, X), or of a voxel (Z, Y, X: then also ``spacing``),
        in ``space_unit``: the table's sizes (columns of unit ``length``, ``area``,
        ``volume``) are then in that unit, not in pixels.
    space_unit : str or None
    """

    params: PFSDMParams
    ndim: int = 2
    with_intensity: bool = False
    axes: str | None = None
    spacing: tuple[float, ...] | None = None
    measures: tuple[Measure, ...] = ()
    pixel_size: tuple[float, ...] | None = None
    space_unit: str | None = None

    @classmethod
    def of(cls, params: PFSDMParams, *, ndim: int = 2, with_intensity: bool = False,
           axes: str | None = None, spacing: Any = None, pixel_size: Any = None,
           space_unit: str | None = None) -> ObjectMeasurer:
        """The measurer of ``params`` for ``ndim``-D objects (``spacing``: their voxel size,
        3-D only; default 1, 1, 1, or ``pixel_size``), with or without a reporter; with a
        ``pixel_size`` (one number, or one per axis) and its ``space_unit`` (µm when not
        given), the table's sizes are physical."""
        if ndim not in (2, 3):
            raise ValueError(f"ndim must be 2 or 3, got {ndim!r}")
        params.check_dimension(ndim)
        size, unit = None, None
        if pixel_size is not None:
            size = check_pixel_size(pixel_size, ndim)
            unit = units.space_unit(space_unit or "µm")[0]
            if ndim == 3:
                given = None if spacing is None else tuple(check_spacing(spacing, 3).tolist())
                if given is not None and given != size:
                    raise InputError(
                        f"spacing {given} and pixel size {size} differ: give the voxel size "
                        "once (the pixel size, in its unit)")
                spacing = size
        elif space_unit is not None:
            raise InputError(f"a space unit ({space_unit}) was given without a pixel size: "
                             "give the pixel size too (e.g. --pixel-size 0.65)")
        voxel = tuple(check_spacing(spacing, 3).tolist()) if ndim == 3 else None
        base = cls(params.measured(), ndim, bool(with_intensity), axes, voxel, (), size, unit)
        measures = tuple(m for m in MEASURES if m.applies(base))
        return replace(base, measures=measures)

    # ----------------------------------------------------------------- what it writes
    def record(self) -> dict[str, Any]:
        """The table's options (``attrs["pfsdm"]``, the sidecar): the record of what is
        measured, the labels' ``axes`` and, for 3-D objects, the voxel ``spacing``."""
        out = self.params.record(self.ndim)
        if self.axes is not None:
            out["axes"] = self.axes
        if self.ndim == 3:
            out["spacing"] = list(self.spacing)
        if self.pixel_size is not None:
            out["pixel_size"] = list(self.pixel_size)
            out["space_unit"] = self.space_unit
        return out

    @cached_property
    def size_factors(self) -> dict[str, float]:
        """What each size column is multiplied by to be in the physical unit (none without a
        pixel size): lengths by the pixel's side, areas by its area, volumes by the voxel's
        (3-D lengths are already physical: scikit-image measures them with the spacing)."""
        if self.pixel_size is None:
            return {}
        kinds = column_units(self)
        if self.ndim == 2:
            side = self.pixel_size[0]
            factor = {"length": side, "area": side * side}
        else:
            factor = {"volume": float(np.prod(self.pixel_size))}
        return {c: factor[k] for c, k in kinds.items() if k in factor}

    @cached_property
    def families(self) -> dict[str, list[str]]:
        """The table's columns by kind, in order: ``base``, ``measures`` (the per-object
        measures), ``shape``, ``intensity`` (features), ``outline`` (the boundary term's
        coefficients, 2-D) and ``signature`` (the elastic term's, when the options ask)."""
        rec = self.record()
        two_d = self.ndim == 2
        return {
            "base": ["frame", "label", *(c.name for c in (BASE_2D if two_d else BASE_3D))],
            "measures": [c for m in self.measures for c in m.columns(self)],
            "shape": table_feature_columns(rec, "shape"),
            "intensity": table_feature_columns(rec, "intensity") if self.with_intensity else [],
            "outline": outline_columns(N_OUTLINE_MODES) if two_d else [],
            "signature": signature_columns(N_CHANNELS, N_SIGNATURE_POINTS)
            if two_d and self.params.elastic_signature == "table" else [],
        }

    @property
    def columns(self) -> list[str]:
        """Every column of the table, in order."""
        return [c for cols in self.families.values() for c in cols]

    # ----------------------------------------------------------------- objects
    def crop(self, frame: np.ndarray, image: np.ndarray | None, t: int, label: int,
             box: tuple[slice, ...]) -> Crop:
        """The :class:`Crop` of ``label`` (bounding box ``box``) in ``frame`` (and the
        reporter ``image``, or None) of frame number ``t``."""
        big = crop_of(box, frame.shape)
        touches = any(s.start == 0 or s.stop == n for s, n in zip(box, frame.shape,
                                                                  strict=True))
        return Crop(int(t), int(label), box, tuple(int(s.start) for s in big), frame[big],
                    None if image is None else image[big], touches)

    def crops(self, frame: np.ndarray, image: np.ndarray | None, t: int,
              labels: Iterable[int] | None = None) -> Iterator[Crop]:
        """The crops of a frame's objects in label order (``labels``: only these)."""
        if frame.dtype == bool:
            frame = frame.astype(np.uint8)
        boxes = object_boxes(frame)
        if labels is not None:
            wanted = {int(x) for x in labels}
            boxes = [(lab, box) for lab, box in boxes if lab in wanted]
        for label, box in boxes:
            yield self.crop(frame, image, t, label, box)

    def measure(self, crop: Crop) -> ObjectResult:
        """The :class:`ObjectResult` of one crop: the descriptor and every measure."""
        mask = crop.labels == crop.label
        where = np.nonzero(mask)  # the centre of mass, as ndimage's (exact sums of integers)
        area = len(where[0])
        centroid = np.array([w.sum() / area for w in where]) + crop.origin
        image = None if crop.image is None else crop.image.astype(float)
        res, error, int_error = self._describe(mask, image, crop.origin)
        view = ObjectView(mask, image, res, crop.origin, self)
        values: dict = {}
        for m in self.measures:
            values.update(m.compute(view))
        return ObjectResult(frame=crop.frame, label=crop.label, bbox=crop.box, area=area,
                            centroid=centroid, touches_border=crop.touches_border, result=res,
                            error=error, intensity_error=int_error, measures=values)

    def _describe(self, mask: np.ndarray, image: np.ndarray | None, offset: tuple[int, ...]
                  ) -> tuple[Any, str, str]:
        """pfsdm of one object; an intensity that cannot be described (NaN pixels, no signal)
        costs the intensity features only, never the shape ones."""
        def run(img):
            with quietly():  # the pieces are counted in the table (n_components)
                return pfsdm(mask, img, offset=offset, spacing=self.spacing,
                             params=self.params)

        try:
            return run(image), "", ""
        except OBJECT_ERRORS as exc:
            if image is None:
                return None, reason(exc), ""
            try:
                res = run(None)
            except OBJECT_ERRORS:
                return None, reason(exc), ""
            return res, "", reason(exc)

    # ----------------------------------------------------------------- rows
    def table(self, objects: Iterable[ObjectResult]) -> pd.DataFrame:
        """The table rows of ``objects`` (measured by this measurer, in the given order; a
        generator is consumed row by row, only the rows kept), its options in
        ``attrs["pfsdm"]`` (:meth:`record`)."""
        fam = self.families
        nan = {k: np.full(len(v), np.nan) for k, v in fam.items()}
        three_d = self.ndim == 3
        rows: dict[str, list] = {k: [] for k in fam}
        for obj in objects:
            rows["measures"].append([obj.measures.get(c, np.nan) for c in fam["measures"]])
            res = obj.result
            diag = res.diagnostics if res is not None else {}
            extra = (diag.get("crossing_fraction", np.nan),) if three_d else ()
            rows["base"].append((obj.frame, obj.label, obj.area, *obj.centroid,
                                 obj.touches_border, diag.get("n_components", np.nan),
                                 diag.get("n_holes", np.nan),
                                 diag.get("folded_fraction", np.nan), *extra, obj.error,
                                 "; ".join(object_warnings(
                                     obj, with_intensity=self.with_intensity))))
            if res is None:
                rows["shape"].append(nan["shape"])
            elif three_d:
                rows["shape"].append(np.concatenate([res.embedding.ravel(),
                                                     res.surface_embedding]))
            else:
                rows["shape"].append(res.embedding.ravel())
            if fam["outline"]:
                rows["outline"].append(
                    np.column_stack([res.outline.real, res.outline.imag]).ravel()
                    if res is not None else nan["outline"])
            if fam["signature"]:
                rows["signature"].append(res.signature.ravel() if res is not None
                                         else nan["signature"])
            if fam["intensity"]:
                emb = None if res is None else res.intensity_embedding
                rows["intensity"].append(emb.ravel() if emb is not None
                                         else nan["intensity"])
        blocks = [pd.DataFrame(rows["base"], columns=fam["base"]),
                  pd.DataFrame(stack_rows(rows["measures"], len(fam["measures"]), float),
                               columns=fam["measures"]),
                  pd.DataFrame(stack_rows(rows["shape"], len(fam["shape"])),
                               columns=fam["shape"])]
        for kind in ("intensity", "outline", "signature"):
            if fam[kind]:
                blocks.append(pd.DataFrame(stack_rows(rows[kind], len(fam[kind])),
                                           columns=fam[kind]))
        table = pd.concat(blocks, axis=1)
        for column, factor in self.size_factors.items():
            table[column] = table[column].astype(float) * factor
        set_options(table, self.record())
        return table


#: Errors that cost one object its features, never the whole run: ValueError for what the
#: method refuses (too small, NaN intensity, ...), RuntimeError for numerical failures such as
#: a degenerate Delaunay triangulation (scipy's QhullError) in the bijective map,
#: ArithmeticError for overflows.
OBJECT_ERRORS = (ValueError, RuntimeError, ArithmeticError)


def column_units(measurer: ObjectMeasurer) -> dict[str, str]:
    """The unit kind (:data:`~napari_pfsdm.core.columns.UNITS`) of each column of a
    measurer's table that has one, from the columns' declarations."""
    declared: list[Column | Family] = [*(BASE_2D if measurer.ndim == 2 else BASE_3D)]
    for m in measurer.measures:
        declared += list(m.declares)
    out = {}
    for name in measurer.columns:
        for d in declared:
            if (d.name == name) if isinstance(d, Column) else d.match(name) is not None:
                if d.unit:
                    out[name] = d.unit
                break
    return out


def reason(exc: BaseException) -> str:
    """The row's ``error`` text: the message of a ValueError (written for users), the type and
    first line of anything else (a numerical failure)."""
    if isinstance(exc, ValueError):
        return str(exc)
    first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return f"numerical failure ({type(exc).__name__}{': ' + first if first else ''})"


def light(obj: ObjectResult) -> ObjectResult:
    """What a table row needs of one object: the object with a light result (embeddings and
    diagnostics only: the SDF, map and skeleton of every object are not kept for a whole
    run, nor sent back by a worker process)."""
    res = obj.result
    if res is None:
        return obj
    kept = SimpleNamespace(diagnostics=res.diagnostics, embedding=res.embedding,
                           intensity_embedding=res.intensity_embedding,
                           surface_embedding=getattr(res, "surface_embedding", None),
                           outline=getattr(res, "outline", None),
                           signature=getattr(res, "signature", None))
    return ObjectResult(frame=obj.frame, label=obj.label, bbox=obj.bbox, area=obj.area,
                        centroid=obj.centroid, touches_border=obj.touches_border,
                        result=kept, error=obj.error, intensity_error=obj.intensity_error,
                        measures=obj.measures)


#: Rows per piece of :func:`stack_rows`.
STACK_PIECE_ROWS = 2048


def stack_rows(rows: list, width: int, dtype=None) -> np.ndarray:
    """``np.array(rows).reshape(-1, width)``, piece by piece.

    One ``np.array`` over 50,000 rows holds the interpreter lock for ~175 ms; the viewer's
    Run does this in a worker thread, and the viewer froze as long. Pieces of
    :data:`STACK_PIECE_ROWS` rows let the GUI thread in between; the values and the dtype
    are those of ``np.array(rows)``.
    """
    if dtype is None:
        dtype = np.result_type(*{np.asarray(r).dtype for r in rows}) if rows else float
    out = np.empty((len(rows), width), dtype=dtype)
    for i in range(0, len(rows), STACK_PIECE_ROWS):
        out[i:i + STACK_PIECE_ROWS] = rows[i:i + STACK_PIECE_ROWS]
    return out


def object_warnings(obj: ObjectResult, *, with_intensity: bool = False) -> list[str]:
    """Plain-words reasons to look at an object twice (the table's ``warnings`` column).

    Border contact (the object may be cut by the image edge), folding above
    :data:`FOLDED_WARNING`, holes filled, several pieces (the largest was kept) and an
    intensity that could not be described.
    """
    out = []
    if obj.touches_border:
        out.append("touches the image border (may be cut off)")
    diag = obj.result.diagnostics if obj.result is not None else {}
    folded = diag.get("folded_fraction", 0.0)
    if folded is not None and np.isfinite(folded) and folded > FOLDED_WARNING:
        if "crossing_fraction" in diag:
            out.append(f"{100 * folded:.1f} % of ball samples fold (the object is not "
                       "star-shaped from its centroid; the radial map leaves it there)")
        else:
            out.append(f"{100 * folded:.1f} % of disk samples fold (try mapping='bijective')")
    n_holes = int(diag.get("n_holes", 0) or 0)
    if n_holes:
        out.append(f"{n_holes} hole{'s' if n_holes > 1 else ''} filled")
    n_comp = int(diag.get("n_components", 1) or 1)
    if n_comp > 1:
        out.append(f"{n_comp} pieces, the largest kept")
    if with_intensity and obj.intensity_error:
        out.append(f"intensity features left empty: {obj.intensity_error}")
    return out


def check_frame_ids(frame: np.ndarray, t: int) -> np.ndarray:
    """``frame`` as labels (a boolean mask as 0/1), refused with negative labels."""
    if frame.dtype == bool:
        frame = frame.astype(np.uint8)
    if frame.size and frame.min() < 0:
        raise InputError(
            f"Frame {t} has negative labels; labels must be 0 (background) or positive.")
    return frame
