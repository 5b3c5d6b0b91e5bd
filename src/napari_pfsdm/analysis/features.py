"""Feature tables over (frame, label) of a label image or time-lapse."""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pandas as pd

from ..core import units
from ..core.params import PFSDMParams, as_params, with_option_keywords
from ..core.table_options import carry_options, set_options, table_options
from ..core.table_schema import TRACK_COLUMN, feature_columns
from ..core.threads import one_blas_thread
from ..core.units import check_times
from ..errors import InputError
from .label_images import (
    check_arrays,
    check_frames,
    count_objects,
    frame_at,
    voxel_spacing,
)
from .measuring import (
    FOLDED_WARNING,
    ObjectMeasurer,
    ObjectResult,
    check_frame_ids,
    object_warnings,
)
from .physical import add_times
from .tables import failed_rows

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
    measurer = ObjectMeasurer.of(p, ndim=3 if "z" in axes else 2,
                                 with_intensity=intensity is not None, axes=axes, spacing=voxel)
    frames = None if frames is None else check_frames(frames, n_frames if timelapse else 1)
    yield from measure_frames(measurer, labels, intensity,
                              range(n_frames) if frames is None else frames, timelapse)


iter_objects.__signature__ = with_option_keywords(iter_objects)  # type: ignore[attr-defined]


#: Objects measured under one BLAS limit by :func:`measure_frames` (progress moves by at most
#: this many objects at a time).
BLAS_BATCH = 32


def measure_frames(measurer: ObjectMeasurer, labels, intensity, frames, timelapse: bool
                   ) -> Iterator[ObjectResult]:
    """Every object of ``frames`` of the labels (and the reporter), measured by ``measurer``
    one crop at a time, in frame then label order, on one BLAS thread.

    The BLAS limit is taken for :data:`BLAS_BATCH` objects at a time and never held across a
    ``yield``: a caller that stops early, or computes between two objects, has the machine's
    BLAS threads (setting the limit costs about a millisecond, so not once per object)."""
    for t in frames:
        frame = check_frame_ids(frame_at(labels, t, timelapse), t)
        image = None if intensity is None else frame_at(intensity, t, timelapse)
        crops = iter(measurer.crops(frame, image, int(t)))
        while batch := list(itertools.islice(crops, BLAS_BATCH)):
            with one_blas_thread():
                results = [measurer.measure(crop) for crop in batch]
            yield from results


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
    measurer = ObjectMeasurer.of(as_params(params, {}), ndim=3 if "z" in axes else 2,
                                 with_intensity=intensity is not None, axes=axes, spacing=voxel)
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
    image = None if intensity is None else frame_at(intensity, t, timelapse)
    with one_blas_thread():
        return measurer.measure(measurer.crop(plane, image, t, int(label), box))


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
    p = as_params(params, options)
    measurer = ObjectMeasurer.of(p, ndim=3 if axes and "z" in axes else 2,
                                 with_intensity=with_intensity, axes=axes, spacing=spacing)
    return with_leave_out(measurer.table(objects), p)


def with_leave_out(table: pd.DataFrame, params: PFSDMParams) -> pd.DataFrame:
    """``table`` (measured by an :class:`~napari_pfsdm.analysis.measuring.ObjectMeasurer`,
    whose record has the leave-out options at their defaults) with the leave-out options of
    ``params`` in its record, where shape spaces read them
    (:func:`~napari_pfsdm.core.params.leave_out_of`)."""
    if params.leave_out() != PFSDMParams().leave_out():
        set_options(table, {**table_options(table), **params.leave_out()})
    return table


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
    times: Any = None,
    time_unit: str | None = None,
    pixel_size: Any = None,
    space_unit: str | None = None,
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
    times : sequence of float, optional
        Each frame's time, in frame order (uneven, or repeated for a time imaged twice, as
        the experiment was): the table gets a ``time`` column after ``frame``, and
        ``time_unit`` in its record. Without it, time is the frame.
    time_unit : str, optional
        Their unit (``"day"``, ``"h"``, ``"min"``, ``"s"``; :data:`~napari_pfsdm.core.units.
        TIMES`).
    pixel_size : float or sequence of float, optional
        The physical size of a pixel (one number: square pixels), or of a voxel (Z, Y, X,
        for 3-D objects: then also their ``spacing``): sizes (areas, volumes, lengths,
        widths, perimeters, midline measures) are then in ``space_unit``, not pixels; shape
        features stay unitless. Recorded as ``pixel_size`` and ``space_unit``.
    space_unit : str, optional
        Its unit (default ``"µm"``; :data:`~napari_pfsdm.core.units.LENGTHS`).
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
    n_frames, timelapse, axes = check_arrays(labels, intensity, axes)
    volume = "z" in axes
    measurer = ObjectMeasurer.of(
        p, ndim=3 if volume else 2, with_intensity=intensity is not None, axes=axes,
        spacing=voxel_spacing(axes, spacing) if pixel_size is None or not volume else spacing,
        pixel_size=pixel_size, space_unit=space_unit)
    if times is not None:
        times = check_times(times, n_frames if timelapse else 1)
        time_unit = units.time_unit(time_unit)[0] if time_unit else None
    elif time_unit is not None:
        raise InputError(f"a time unit ({time_unit}) was given without times: give each "
                         "frame's time too (times=[...])")
    counted = progress is not None and isinstance(labels, np.ndarray)
    total = count_objects(labels, axes) if counted else None

    def reporting():
        objects = measure_frames(measurer, labels, intensity, range(n_frames), timelapse)
        for done, obj in enumerate(objects, start=1):
            yield obj  # consumed row by row: no result is kept
            if progress is not None:
                progress(done, total)

    table = with_leave_out(measurer.table(reporting()), p)
    return table if times is None else add_times(table, times, time_unit)


measure.__signature__ = with_option_keywords(measure)  # type: ignore[attr-defined]
