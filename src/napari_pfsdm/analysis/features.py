"""Feature tables over (frame, label) of a label image or time-lapse."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from ..core.boundary import N_OUTLINE_MODES
from ..core.descriptor import PFSDMResult, pfsdm
from ..core.elastic_signature import N_CHANNELS, N_SIGNATURE_POINTS
from ..core.midline import midline_columns
from ..core.params import PFSDMParams, as_params, with_option_keywords
from ..core.pieces import quietly
from ..core.table_options import carry_options, set_options
from ..core.table_schema import (
    BASE_COLUMNS,
    TRACK_COLUMN,
    base_columns,
    feature_columns,
    outline_columns,
    signature_columns,
    table_feature_columns,
)
from ..core.volume_sdf import check_spacing
from ..errors import InputError
from .classic import classic_columns, classic_measures, midline_measures
from .label_images import (
    check_arrays,
    check_frames,
    count_objects,
    crop_of,
    frame_at,
    object_boxes,
    resolve_axes,
    voxel_spacing,
)
from .tables import failed_rows
from .threads import one_blas_thread

__all__ = [
    "ObjectResult",
    "FOLDED_WARNING",
    "describe_object",
    "drop_failed",
    "feature_columns",
    "iter_objects",
    "measure",
    "object_warnings",
    "resolved_options",
    "split_failed",
    "table_from_objects",
    "warnings_summary",
]

#: A row's ``warnings`` mention folding above this fraction of disk samples (5 %): the map
#: then leaves the object there, and the features describe the object less faithfully.
FOLDED_WARNING = 0.05


_BASE_COLUMNS = BASE_COLUMNS


@dataclass
class ObjectResult:
    """One object of one frame, as yielded by :func:`iter_objects`.

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
        The classic measures of the labelled pixels (:mod:`napari_pfsdm.analysis.classic`,
        scikit-image's regionprops), with the reporter's when there is an image.
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


def iter_objects(
    labels, intensity=None, *, axes: str | None = None, spacing=None, frames=None,
    params: PFSDMParams | None = None, **options: Any
) -> Iterator[ObjectResult]:
    """PF-SDM of every object of every frame, one at a time.

    Parameters
    ----------
    labels : array_like of int, shape (Y, X), (T, Y, X), (Z, Y, X) or (T, Z, Y, X)
        Label image; 0 is background. numpy, dask or zarr arrays: frames are read one at a time.
    intensity : array_like, same shape, optional
    axes : {"yx", "tyx", "zyx", "tzyx"}, optional
        Which axes the labels have; default ``"yx"`` for 2-D and ``"tyx"`` for 3-D arrays (a
        Z-stack must say ``"zyx"``); a 4-D array must say.
    spacing : 3 floats, optional
        Voxel size along Z, Y, X of 3-D objects (default 1, 1, 1); 2-D frames take none.
    frames : iterable of int, optional
        Frames to process (default all). A negative index counts from the end as in Python
        (``-1``: the last frame) and is reported as the frame it is (``n_frames - 1``); a
        frame outside the movie, one given twice, or one that is not a whole number is
        refused (``InputError``).
    params : PFSDMParams, optional
        The method's options as one record (or give them as keywords).
    **options
        The method's options (:data:`~napari_pfsdm.core.params.OPTIONS`: the signature shows
        them with their defaults), checked first by
        :class:`~napari_pfsdm.core.params.PFSDMParams`.

    Yields
    ------
    ObjectResult
        In frame order, then label order. Objects that cannot be described (too small, NaN
        intensity, ...) are yielded with ``result=None`` and the reason in ``error``; a badly
        formed input (wrong dimensions, shapes, dtype) raises ``ValueError`` before anything runs.
        While it runs, BLAS is limited to one thread (the per-object matrices are small).
    """
    n_frames, timelapse, axes = check_arrays(labels, intensity, axes)
    voxel = voxel_spacing(axes, spacing)
    p = as_params(params, options)  # a bad option fails here, before any work
    p.check_dimension(3 if "z" in axes else 2)
    opts = _pfsdm_options(p)
    if voxel is not None:
        opts["spacing"] = voxel
    frames = None if frames is None else check_frames(frames, n_frames if timelapse else 1)
    with one_blas_thread():
        yield from _iter_frames(labels, intensity, n_frames, timelapse, frames, opts)


iter_objects.__signature__ = with_option_keywords(iter_objects)  # type: ignore[attr-defined]


def _iter_frames(labels, intensity, n_frames, timelapse, frames, options):
    for t in range(n_frames) if frames is None else frames:
        frame = frame_at(labels, t, timelapse)
        if frame.dtype == bool:
            frame = frame.astype(np.uint8)
        if frame.size and frame.min() < 0:
            raise InputError(
                f"Frame {t} has negative labels; labels must be 0 (background) or positive."
            )
        image = None if intensity is None else frame_at(intensity, t, timelapse).astype(float)
        for label, box in object_boxes(frame):
            yield _object_in_frame(frame, image, int(t), label, box, options)


def _object_in_frame(frame, image, t: int, label: int, box, options) -> ObjectResult:
    """The :class:`ObjectResult` of ``label`` in one frame, 2-D or 3-D (``box``: its
    bounding box)."""
    big = crop_of(box, frame.shape)
    return _object_in_crop(frame[big], None if image is None else image[big], t, label, box,
                           big, frame.shape, options)


def _object_in_crop(labels_crop, crop, t: int, label: int, box, big, shape,
                    options) -> ObjectResult:
    """What :func:`_object_in_frame` computes, from the object's crop alone: ``labels_crop``
    and ``crop`` (the reporter, or None) are the frame's and the image's pixels in ``big``
    (:func:`crop_of` of ``box`` in a frame of ``shape``). A worker process is sent the crops
    of the objects of one large frame, not the frame for each task."""
    mask = labels_crop == label
    start = [s.start for s in big]
    where = np.nonzero(mask)  # the centre of mass, as ndimage's (exact sums of whole numbers)
    area = len(where[0])
    centroid = np.array([w.sum() / area for w in where]) + start
    touches = any(s.start == 0 or s.stop == n for s, n in zip(box, shape, strict=True))
    res, error, int_error = _describe(mask, crop, tuple(start), options)
    measures = classic_measures(mask, crop, spacing=options.get("spacing"))
    bins = options.get("profile_bins", _BINS)
    if bins:  # 0: no midline measures
        measures.update(midline_measures(res, crop, offset=tuple(start), bins=bins,
                                         anterior=options.get("anterior", _ANTERIOR)))
    return ObjectResult(frame=int(t), label=int(label), bbox=box, area=area, centroid=centroid,
                        touches_border=touches, result=res, error=error,
                        intensity_error=int_error, measures=measures)


def describe_object(
    labels, intensity, frame: int, label: int, *, params: PFSDMParams | None = None,
    box: tuple[slice, ...] | None = None, axes: str | None = None, spacing=None,
) -> ObjectResult:
    """The full :class:`ObjectResult` of one (frame, label), exactly as :func:`iter_objects`
    computes it (same crop, same options): for pictures of one object after :func:`measure`.

    Parameters
    ----------
    labels, intensity, axes, spacing
        As for :func:`iter_objects`; only ``frame`` is read.
    frame, label : int
        The object (``frame`` is ignored without a time axis).
    params : PFSDMParams, optional
        The options of the run the object belongs to.
    box : tuple of slice, optional
        Its bounding box in the frame, if known (saves a search of the frame).

    Raises
    ------
    KeyError
        When ``label`` is not in that frame.
    """
    n_frames, timelapse, axes = check_arrays(labels, intensity, axes)
    voxel = voxel_spacing(axes, spacing)
    p = as_params(params, {})
    opts = _pfsdm_options(p)
    if voxel is not None:
        opts["spacing"] = voxel
    t = int(frame) if timelapse else 0
    if not 0 <= t < n_frames:
        raise KeyError(f"frame {frame} is not in the labels ({n_frames} frames)")
    plane = frame_at(labels, t, timelapse)
    if plane.dtype == bool:
        plane = plane.astype(np.uint8)
    if box is None:
        where = np.nonzero(plane == label)
        if where[0].size == 0:
            raise KeyError(f"label {label} is not in frame {frame}")
        box = tuple(slice(int(w.min()), int(w.max()) + 1) for w in where)
    big = crop_of(box, plane.shape)
    crop = None if intensity is None else frame_at(intensity, t, timelapse)[big].astype(float)
    with one_blas_thread():
        return _object_in_crop(plane[big], crop, t, int(label), box, big, plane.shape, opts)


#: The midline's options at their defaults (``options`` holds none when all are).
_BINS, _ANTERIOR = PFSDMParams().profile_bins, PFSDMParams().anterior  # type: ignore


def _pfsdm_options(p: PFSDMParams) -> dict[str, Any]:
    """The keywords ``pfsdm`` is called with for ``p``: none at the defaults (``pfsdm`` then
    skips checking the same fourteen values again for every object)."""
    return {} if p == PFSDMParams() else p.options()


def _describe(mask, image, offset, options) -> tuple[PFSDMResult | None, str, str]:
    """pfsdm of one object; an intensity that cannot be described (NaN pixels, no signal)
    costs the intensity features only, never the shape ones."""
    def run(img):
        with quietly():  # the pieces are counted in the table (n_components)
            return pfsdm(mask, img, offset=offset, **options)

    try:
        return run(image), "", ""
    except _OBJECT_ERRORS as exc:
        if image is None:
            return None, _reason(exc), ""
        try:
            res = run(None)
        except _OBJECT_ERRORS:
            return None, _reason(exc), ""
        return res, "", _reason(exc)


#: Errors that cost one object its features, never the whole run: ValueError for what the
#: method refuses (too small, NaN intensity, ...), RuntimeError for numerical failures such as
#: a degenerate Delaunay triangulation (scipy's QhullError) in the bijective map,
#: ArithmeticError for overflows.
_OBJECT_ERRORS = (ValueError, RuntimeError, ArithmeticError)


def _reason(exc: BaseException) -> str:
    """The row's ``error`` text: the message of a ValueError (written for users), the type and
    first line of anything else (a numerical failure)."""
    if isinstance(exc, ValueError):
        return str(exc)
    first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return f"numerical failure ({type(exc).__name__}{': ' + first if first else ''})"


def resolved_options(**options: Any) -> dict[str, Any]:
    """The options a :func:`pfsdm` call would use, with the rings' radii and weights: the
    record a table carries (:meth:`PFSDMParams.record`)."""
    return PFSDMParams.from_options(options).record()


def table_from_objects(
    objects, *, with_intensity: bool = False, params: PFSDMParams | None = None,
    axes: str | None = None, spacing=None, **options: Any
) -> pd.DataFrame:
    """The feature table of :func:`measure` from objects computed by :func:`iter_objects` with
    the same options (``params`` or keywords; one row per object, in the given order) and the
    same ``axes`` and ``spacing`` (recorded in the options; no ``axes``: 2-D objects, not
    recorded).
    ``objects`` may be a generator: only the rows are kept, not the results."""
    ndim = 3 if axes and "z" in axes else 2
    opts = as_params(params, options).record(ndim)
    if axes is not None:
        opts["axes"] = axes
    if ndim == 3:
        opts["spacing"] = check_spacing(spacing, 3).tolist()
    shape_cols = table_feature_columns(opts, "shape")
    int_cols = table_feature_columns(opts, "intensity") if with_intensity else []
    # the outline's coefficients (boundary term of the distance): outlines in 2-D only
    out_cols = outline_columns(N_OUTLINE_MODES) if ndim == 2 else []
    # the outline signature (elastic term of the distance), 2-D only
    sig_cols = signature_columns(N_CHANNELS, N_SIGNATURE_POINTS) \
        if ndim == 2 and opts.get("elastic_signature") == "table" else []
    nan_s, nan_i = np.full(len(shape_cols), np.nan), np.full(len(int_cols), np.nan)
    nan_o, nan_e = np.full(len(out_cols), np.nan), np.full(len(sig_cols), np.nan)
    classic_cols = classic_columns(ndim, with_intensity)  # regionprops (analysis.classic)
    # the object's own axis (core.midline), after the classic measures (profile_bins > 0)
    if int(opts["profile_bins"]):
        classic_cols += midline_columns(int(opts["profile_bins"]), with_intensity)
    base, classic_rows, shape_rows, int_rows, out_rows, sig_rows = [], [], [], [], [], []
    for obj in objects:
        classic_rows.append([obj.measures.get(c, np.nan) for c in classic_cols])
        res = obj.result
        diag = res.diagnostics if res is not None else {}
        extra = (diag.get("crossing_fraction", np.nan),) if ndim == 3 else ()
        base.append((obj.frame, obj.label, obj.area, *obj.centroid, obj.touches_border,
                     diag.get("n_components", np.nan), diag.get("n_holes", np.nan),
                     diag.get("folded_fraction", np.nan), *extra, obj.error,
                     "; ".join(object_warnings(obj, with_intensity=with_intensity))))
        if res is None:
            shape_rows.append(nan_s)
        elif ndim == 3:
            shape_rows.append(np.concatenate([res.embedding.ravel(), res.surface_embedding]))
        else:
            shape_rows.append(res.embedding.ravel())
        if out_cols:
            out_rows.append(np.column_stack([res.outline.real, res.outline.imag]).ravel()
                            if res is not None else nan_o)
        if sig_cols:
            sig_rows.append(res.signature.ravel() if res is not None else nan_e)
        if int_cols:
            emb = None if res is None else res.intensity_embedding
            int_rows.append(emb.ravel() if emb is not None else nan_i)
    blocks = [pd.DataFrame(base, columns=base_columns(ndim)),
              pd.DataFrame(_stack_rows(classic_rows, len(classic_cols), float),
                           columns=classic_cols),
              pd.DataFrame(_stack_rows(shape_rows, len(shape_cols)), columns=shape_cols)]
    if int_cols:
        blocks.append(pd.DataFrame(_stack_rows(int_rows, len(int_cols)), columns=int_cols))
    if out_cols:
        blocks.append(pd.DataFrame(_stack_rows(out_rows, len(out_cols)), columns=out_cols))
    if sig_cols:
        blocks.append(pd.DataFrame(_stack_rows(sig_rows, len(sig_cols)), columns=sig_cols))
    table = pd.concat(blocks, axis=1)
    set_options(table, opts)
    return table


#: Rows per piece of :func:`_stack_rows`.
STACK_PIECE_ROWS = 2048


def _stack_rows(rows: list, width: int, dtype=None) -> np.ndarray:
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


def warnings_summary(table: pd.DataFrame) -> str:
    """One line on the suspect and failed objects of a table, or "" when there are none.

    Examples
    --------
    >>> import pandas as pd
    >>> t = pd.DataFrame({"error": ["", "", "too small"], "touches_border": [True, True, False],
    ...                   "folded_fraction": [0.29, 0.0, float("nan")], "n_holes": [0, 2, 0],
    ...                   "n_components": [1, 1, 1], "warnings": ["w", "w", ""]})
    >>> for part in warnings_summary(t).split("; "):
    ...     print(part)
    1 object has no features (see the error column)
    2 objects touch the border, 1 is 29 % folded, 1 had holes filled: see the warnings column
    """
    if len(table) == 0:
        return ""

    n = len(table)

    def numbers(name: str, missing: float) -> np.ndarray:  # NaN (and no column) → missing
        if name not in table.columns:
            return np.full(n, missing)
        values = pd.to_numeric(table[name], errors="coerce").to_numpy(float, na_value=np.nan)
        return np.where(np.isnan(values), missing, values)

    def texts(name: str) -> list[str]:
        return [] if name not in table.columns else \
            [str(v) for v in table[name].to_numpy() if isinstance(v, str) and v]

    def n_obj(n: int, verb_one: str, verb_many: str) -> str:
        return f"{n} object {verb_one}" if n == 1 else f"{n} objects {verb_many}"

    parts = []
    border = int((numbers("touches_border", 0.0) != 0).sum())
    if border:
        parts.append(n_obj(border, "touches the border", "touch the border"))
    folded = numbers("folded_fraction", 0.0)
    over = folded[folded > FOLDED_WARNING]
    if len(over) == 1:
        parts.append(f"1 is {100 * float(over[0]):.0f} % folded")
    elif len(over):
        parts.append(f"{len(over)} are more than {100 * FOLDED_WARNING:.0f} % folded "
                     f"(up to {100 * float(over.max()):.0f} %)")
    holes = int((numbers("n_holes", 0.0) > 0).sum())
    if holes:
        parts.append(f"{holes} had holes filled")
    pieces = int((numbers("n_components", 1.0) > 1).sum())
    if pieces:
        parts.append(f"{pieces} {'was' if pieces == 1 else 'were'} in several pieces")
    no_int = sum("intensity features left empty" in w for w in texts("warnings"))
    if no_int:
        parts.append(f"{no_int} {'has' if no_int == 1 else 'have'} no intensity features")
    errors = len(texts("error"))
    head = (n_obj(errors, "has no features", "have no features") + " (see the error column)"
            if errors else "")
    tail = ", ".join(parts) + ": see the warnings column" if parts else ""
    return "; ".join(p for p in (head, tail) if p)


def split_failed(
    table: pd.DataFrame, channels: tuple[str, ...] | list[str] = ("shape",)
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Split a feature table into rows that have ``channels`` features and rows that do not.

    Returns
    -------
    measured : DataFrame
        The rows with features (index reset, ``attrs`` kept).
    left_out : DataFrame
        ``movie`` (when present), ``frame``, ``label``, ``track_id`` (when present),
        ``reason`` of the others.
    """
    bad = failed_rows(table, channels)
    pos = [b[0] for b in bad]
    keep = np.ones(len(table), bool)
    keep[pos] = False
    measured = carry_options(table, table[keep].reset_index(drop=True))
    left = pd.DataFrame({"frame": [b[1] for b in bad], "label": [b[2] for b in bad],
                         "reason": [b[3] for b in bad]})
    if TRACK_COLUMN in table.columns:
        left.insert(2, TRACK_COLUMN, table[TRACK_COLUMN].to_numpy()[pos] if pos else [])
    if "movie" in table.columns:
        left.insert(0, "movie", table["movie"].to_numpy()[pos] if pos else [])
    return measured, left


def drop_failed(table: pd.DataFrame, *, intensity: bool = False) -> pd.DataFrame:
    """The rows of a feature table that have features, warning which rows were left out.

    Parameters
    ----------
    table : DataFrame
        From :func:`measure` or :func:`napari_pfsdm.read_table`.
    intensity : bool
        Also leave out rows without intensity features (for distances with an intensity
        weight).

    Returns
    -------
    DataFrame
        The measured rows, index reset, options kept; use it for distances and PCA so that
        rows and matrix entries stay in step.
    """
    measured, left = split_failed(table, ("shape", "intensity") if intensity else ("shape",))
    if len(left):
        shown = "; ".join(f"frame {r.frame} label {r.label}: {r.reason}"
                          for r in left.head(5).itertuples())
        warnings.warn(f"left out {len(left)} of {len(table)} rows (no features, or left out "
                      f"by the options: {shown}"
                      f"{'; …' if len(left) > 5 else ''})", UserWarning, stacklevel=2)
    return measured


def measure(
    labels,
    intensity=None,
    *,
    axes: str | None = None,
    spacing=None,
    progress: Callable[[int, int | None], None] | None = None,
    params: PFSDMParams | None = None,
    **options: Any,
) -> pd.DataFrame:
    """PF-SDM feature table: one row per (frame, label).

    Parameters
    ----------
    labels : array_like of int, shape (Y, X), (T, Y, X), (Z, Y, X) or (T, Z, Y, X)
        Label image, volume or time-lapse (numpy, dask or zarr; read one frame at a time).
    intensity : array_like, same shape, optional
        Reporter image; adds ``intensity_rXX_nYY`` columns.
    axes : {"yx", "tyx", "zyx", "tzyx"}, optional
        Which axes ``labels`` has. Default: ``"yx"`` for 2-D and ``"tyx"`` (a time-lapse of
        2-D frames) for 3-D arrays, so a Z-stack must say ``axes="zyx"``; a 4-D array must say
        ``"tzyx"`` (refused otherwise). Recorded in ``attrs["pfsdm"]["axes"]``.
    spacing : 3 floats, optional
        Voxel size along Z, Y, X for 3-D objects (e.g. ``(2.0, 0.5, 0.5)``); recorded in
        ``attrs["pfsdm"]["spacing"]``. 2-D frames take none.
    progress : callable(done, total), optional
        Called after every object; ``total`` is None for lazy (non-numpy) inputs.
    params : PFSDMParams, optional
        The method's options as one record (or give them as keywords).
    **options
        The method's options (``n_fourier``, ``mapping``, ...: one keyword per
        :data:`~napari_pfsdm.core.params.OPTIONS` entry, shown in the signature with its
        default), checked before any work as :func:`~napari_pfsdm.core.descriptor.pfsdm`
        checks them.

    Returns
    -------
    pandas.DataFrame
        Columns ``frame``, ``label``, ``area`` (pixels), ``centroid_y``, ``centroid_x``
        (pixels), ``touches_border``, ``n_components``, ``n_holes``, ``folded_fraction``,
        ``error`` (empty when fine, otherwise the reason, with NaN features), ``warnings``
        (plain-words reasons to look twice: border contact, folding above
        :data:`FOLDED_WARNING`, holes filled, several pieces, an intensity that could not be
        described, whose features are then NaN while the shape's are kept), the classic
        measures (:mod:`napari_pfsdm.analysis.classic`), the midline's ``midline_length``,
        ``width_mean``, ``width_max``, ``width_bXX`` and, with an intensity, ``reporter_bXX``,
        ``polarity_angle_image``, ``polarity_angle_midline`` (:mod:`napari_pfsdm.core.midline`:
        pixels, degrees; NaN for 3-D objects), then
        ``shape_rXX_nYY`` and, with an intensity, ``intensity_rXX_nYY``, then the outline
        coefficients of the boundary term ``outline_n±KK_re/im`` (64 columns) and the outline
        signature of the elastic term ``elastic_cC_pPP`` (448 columns), see
        :mod:`napari_pfsdm.core.table_schema`. ``attrs["pfsdm"]`` holds the options used,
        with the rings' ``radii`` and ``weights``, and ``axes``.
        3-D objects: ``volume`` (voxels) instead of ``area``, ``centroid_z``, and
        ``crossing_fraction`` (rays from the centroid crossing the surface more than once), then
        ``shape_rXX_lYY`` (shell, SH degree), ``surface_lYY`` and ``intensity_rXX_lYY``
        (``core.table_schema``), without outline or signature columns.

    Examples
    --------
    >>> import numpy as np
    >>> labels = np.zeros((3, 64, 64), int)
    >>> labels[:, 10:30, 10:40] = 1
    >>> labels[:, 40:60, 20:35] = 2
    >>> table = measure(labels)
    >>> len(table), list(table.columns[:3])
    (6, ['frame', 'label', 'area'])
    """
    p = as_params(params, options)  # before counting: a bad option fails at once
    axes = resolve_axes(tuple(labels.shape), axes)
    voxel = voxel_spacing(axes, spacing)
    p.check_dimension(3 if "z" in axes else 2)
    counted = progress is not None and isinstance(labels, np.ndarray)
    total = count_objects(labels, axes) if counted else None

    def reporting():
        for done, obj in enumerate(iter_objects(labels, intensity, axes=axes, spacing=voxel,
                                                params=p), start=1):
            yield obj  # consumed row by row: no result is kept
            if progress is not None:
                progress(done, total)

    return table_from_objects(reporting(), with_intensity=intensity is not None, params=p,
                              axes=axes, spacing=voxel)


measure.__signature__ = with_option_keywords(measure)  # type: ignore[attr-defined]
