"""Feature tables over (frame, label) of a label image or time-lapse."""

from __future__ import annotations

import threading
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from scipy import ndimage as ndi

from ..core.boundary import N_OUTLINE_MODES
from ..core.descriptor import PFSDMResult, pfsdm
from ..core.params import PFSDMParams, as_params
from ..core.table_schema import BASE_COLUMNS, feature_columns, outline_columns
from .tables import failed_rows

__all__ = [
    "ObjectResult",
    "FOLDED_WARNING",
    "count_objects",
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

_BLAS_LOCK = threading.Lock()
_BLAS_STATE: dict[str, Any] = {"users": 0, "limiter": None}


@contextmanager
def _one_blas_thread():
    """Limit BLAS to one thread while objects are computed: one object's matrices are small,
    threads only add overhead and, with several workers, oversubscribe the cores (parallelism
    comes from frames: the dask batch). Reference-counted, so that concurrent threads restore
    the original setting only when the last one leaves."""
    with _BLAS_LOCK:
        if _BLAS_STATE["users"] == 0:
            from threadpoolctl import threadpool_limits

            _BLAS_STATE["limiter"] = threadpool_limits(limits=1, user_api="blas")
        _BLAS_STATE["users"] += 1
    try:
        yield
    finally:
        with _BLAS_LOCK:
            _BLAS_STATE["users"] -= 1
            if _BLAS_STATE["users"] == 0:
                _BLAS_STATE["limiter"].restore_original_limits()


_BASE_COLUMNS = BASE_COLUMNS


@dataclass
class ObjectResult:
    """One object of one frame, as yielded by :func:`iter_objects`.

    Attributes
    ----------
    frame, label : int
    bbox : tuple of slice
        The object's bounding box in the frame (row slice, column slice).
    area : int
        Pixels of the label in the frame.
    centroid : ndarray, shape (2,)
        Pixel centroid (row, col) in the frame.
    result : PFSDMResult or None
        ``None`` when the object could not be described; ``error`` then says why.
    error : str
        Empty when fine.
    intensity_error : str
        Why the intensity could not be described (NaN pixels, no signal) while the shape was:
        ``result`` then has no intensity embedding. Empty when fine.
    """

    frame: int
    label: int
    bbox: tuple[slice, slice]
    area: int
    centroid: np.ndarray
    touches_border: bool
    result: PFSDMResult | None
    error: str = ""
    intensity_error: str = ""


def _validate(labels, intensity) -> tuple[int, bool]:
    shape = tuple(labels.shape)
    if len(shape) not in (2, 3):
        raise ValueError(
            f"Labels must be 2-D (Y, X) or a 3-D time-lapse (T, Y, X); got shape {shape}. "
            "For a 3-D volume or extra channels, pass one 2-D plane or a T×Y×X stack."
        )
    dtype = np.dtype(labels.dtype)
    if not (np.issubdtype(dtype, np.integer) or dtype.kind == "b"):
        raise ValueError(
            f"Labels must be an integer label image (each object one whole number), got dtype "
            f"{dtype}. Convert a segmentation with skimage.measure.label first."
        )
    if intensity is not None and tuple(intensity.shape) != shape:
        raise ValueError(
            f"The intensity image has shape {tuple(intensity.shape)} but the labels have shape "
            f"{shape}: they must cover the same frames and pixels."
        )
    return (shape[0] if len(shape) == 3 else 1), len(shape) == 3


def _frame(array, t: int, timelapse: bool) -> np.ndarray:
    return np.asarray(array[t] if timelapse else array)


def count_objects(labels) -> int:
    """Number of (frame, label) objects in a 2-D or T×Y×X label image (reads every frame)."""
    n_frames, timelapse = _validate(labels, None)
    return int(sum(np.count_nonzero(np.bincount(_frame(labels, t, timelapse).ravel())[1:])
                   for t in range(n_frames)))


def iter_objects(
    labels, intensity=None, *, frames=None, params: PFSDMParams | None = None, **options: Any
) -> Iterator[ObjectResult]:
    """PF-SDM of every object of every frame, one at a time.

    Parameters
    ----------
    labels : array_like of int, shape (Y, X) or (T, Y, X)
        Label image; 0 is background. numpy, dask or zarr arrays: frames are read one at a time.
    intensity : array_like, same shape, optional
    frames : iterable of int, optional
        Frames to process (default all).
    params : PFSDMParams, optional
        The method's options as one record (or give them as keywords).
    **options
        Passed to :func:`~napari_pfsdm.core.descriptor.pfsdm`, checked first by
        :class:`~napari_pfsdm.core.params.PFSDMParams`.

    Yields
    ------
    ObjectResult
        In frame order, then label order. Objects that cannot be described (too small, NaN
        intensity, ...) are yielded with ``result=None`` and the reason in ``error``; a badly
        formed input (wrong dimensions, shapes, dtype) raises ``ValueError`` before anything runs.
        While it runs, BLAS is limited to one thread (the per-object matrices are small).
    """
    n_frames, timelapse = _validate(labels, intensity)
    p = as_params(params, options)  # a bad option fails here, before any work
    with _one_blas_thread():
        yield from _iter_frames(labels, intensity, n_frames, timelapse, frames, p.options())


def _iter_frames(labels, intensity, n_frames, timelapse, frames, options):
    for t in range(n_frames) if frames is None else frames:
        frame = _frame(labels, t, timelapse)
        if frame.dtype == bool:
            frame = frame.astype(np.uint8)
        if frame.size and frame.min() < 0:
            raise ValueError(
                f"Frame {t} has negative labels; labels must be 0 (background) or positive."
            )
        image = None if intensity is None else _frame(intensity, t, timelapse).astype(float)
        boxes = ndi.find_objects(frame)
        for index, box in enumerate(boxes):
            if box is None:
                continue
            label = index + 1
            big = tuple(slice(max(s.start - 1, 0), min(s.stop + 1, n)) for s, n in
                        zip(box, frame.shape, strict=True))
            mask = frame[big] == label
            area = int(mask.sum())
            centroid = np.array(ndi.center_of_mass(mask)) + [big[0].start, big[1].start]
            touches = bool(box[0].start == 0 or box[1].start == 0
                           or box[0].stop == frame.shape[0] or box[1].stop == frame.shape[1])
            res, error, int_error = _describe(mask, None if image is None else image[big],
                                              (big[0].start, big[1].start), options)
            yield ObjectResult(frame=int(t), label=label, bbox=box, area=area, centroid=centroid,
                               touches_border=touches, result=res, error=error,
                               intensity_error=int_error)


def _describe(mask, image, offset, options) -> tuple[PFSDMResult | None, str, str]:
    """pfsdm of one object; an intensity that cannot be described (NaN pixels, no signal)
    costs the intensity features only, never the shape ones."""
    def run(img):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
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
    objects, *, with_intensity: bool = False, params: PFSDMParams | None = None, **options: Any
) -> pd.DataFrame:
    """The feature table of :func:`measure` from objects computed by :func:`iter_objects` with
    the same options (``params`` or keywords; one row per object, in the given order).
    ``objects`` may be a generator: only the rows are kept, not the results."""
    opts = as_params(params, options).record()
    shape_cols = feature_columns(opts["n_radii"], opts["n_fourier"], "shape")
    int_cols = feature_columns(opts["n_radii"], opts["n_fourier"], "intensity") \
        if with_intensity else []
    out_cols = outline_columns(N_OUTLINE_MODES)
    nan_s, nan_i = np.full(len(shape_cols), np.nan), np.full(len(int_cols), np.nan)
    nan_o = np.full(len(out_cols), np.nan)
    base, shape_rows, int_rows, out_rows = [], [], [], []
    for obj in objects:
        res = obj.result
        diag = res.diagnostics if res is not None else {}
        base.append((obj.frame, obj.label, obj.area, obj.centroid[0], obj.centroid[1],
                     obj.touches_border, diag.get("n_components", np.nan),
                     diag.get("n_holes", np.nan), diag.get("folded_fraction", np.nan), obj.error,
                     "; ".join(object_warnings(obj, with_intensity=with_intensity))))
        shape_rows.append(res.embedding.ravel() if res is not None else nan_s)
        out_rows.append(np.column_stack([res.outline.real, res.outline.imag]).ravel()
                        if res is not None else nan_o)
        if int_cols:
            emb = None if res is None else res.intensity_embedding
            int_rows.append(emb.ravel() if emb is not None else nan_i)
    blocks = [pd.DataFrame(base, columns=_BASE_COLUMNS),
              pd.DataFrame(np.array(shape_rows).reshape(-1, len(shape_cols)), columns=shape_cols)]
    if int_cols:
        blocks.append(pd.DataFrame(np.array(int_rows).reshape(-1, len(int_cols)),
                                   columns=int_cols))
    blocks.append(pd.DataFrame(np.array(out_rows).reshape(-1, len(out_cols)), columns=out_cols))
    table = pd.concat(blocks, axis=1)
    table.attrs["pfsdm"] = opts
    return table


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

    def col(name, default):
        return table[name] if name in table.columns else pd.Series(default, index=table.index)

    def n_obj(n: int, verb_one: str, verb_many: str) -> str:
        return f"{n} object {verb_one}" if n == 1 else f"{n} objects {verb_many}"

    parts = []
    border = int(col("touches_border", False).fillna(False).astype(bool).sum())
    if border:
        parts.append(n_obj(border, "touches the border", "touch the border"))
    folded = col("folded_fraction", 0.0).astype(float)
    over = folded[folded > FOLDED_WARNING]
    if len(over) == 1:
        parts.append(f"1 is {100 * float(over.iloc[0]):.0f} % folded")
    elif len(over):
        parts.append(f"{len(over)} are more than {100 * FOLDED_WARNING:.0f} % folded "
                     f"(up to {100 * float(over.max()):.0f} %)")
    holes = int((col("n_holes", 0).fillna(0).astype(float) > 0).sum())
    if holes:
        parts.append(f"{holes} had holes filled")
    pieces = int((col("n_components", 1).fillna(1).astype(float) > 1).sum())
    if pieces:
        parts.append(f"{pieces} {'was' if pieces == 1 else 'were'} in several pieces")
    no_int = int(col("warnings", "").fillna("").astype(str).str.contains(
        "intensity features left empty").sum())
    if no_int:
        parts.append(f"{no_int} {'has' if no_int == 1 else 'have'} no intensity features")
    errors = int(col("error", "").fillna("").astype(str).ne("").sum())
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
        ``movie`` (when present), ``frame``, ``label``, ``reason`` of the others.
    """
    bad = failed_rows(table, channels)
    pos = [b[0] for b in bad]
    keep = np.ones(len(table), bool)
    keep[pos] = False
    measured = table[keep].reset_index(drop=True)
    measured.attrs = dict(table.attrs)
    left = pd.DataFrame({"frame": [b[1] for b in bad], "label": [b[2] for b in bad],
                         "reason": [b[3] for b in bad]})
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
        warnings.warn(f"left out {len(left)} of {len(table)} rows without features ({shown}"
                      f"{'; …' if len(left) > 5 else ''})", UserWarning, stacklevel=2)
    return measured


def measure(
    labels,
    intensity=None,
    *,
    progress: Callable[[int, int | None], None] | None = None,
    params: PFSDMParams | None = None,
    **options: Any,
) -> pd.DataFrame:
    """PF-SDM feature table: one row per (frame, label).

    Parameters
    ----------
    labels : array_like of int, shape (Y, X) or (T, Y, X)
        Label image or time-lapse (numpy, dask or zarr; read one frame at a time).
    intensity : array_like, same shape, optional
        Reporter image; adds ``intensity_rXX_nYY`` columns.
    progress : callable(done, total), optional
        Called after every object; ``total`` is None for lazy (non-numpy) inputs.
    params : PFSDMParams, optional
        The method's options as one record (or give them as keywords).
    **options
        Passed to :func:`~napari_pfsdm.core.descriptor.pfsdm` (``n_fourier``, ``mapping``, ...).

    Returns
    -------
    pandas.DataFrame
        Columns ``frame``, ``label``, ``area`` (pixels), ``centroid_y``, ``centroid_x``
        (pixels), ``touches_border``, ``n_components``, ``n_holes``, ``folded_fraction``,
        ``error`` (empty when fine, otherwise the reason, with NaN features), ``warnings``
        (plain-words reasons to look twice: border contact, folding above
        :data:`FOLDED_WARNING`, holes filled, several pieces, an intensity that could not be
        described, whose features are then NaN while the shape's are kept), then
        ``shape_rXX_nYY`` and, with an intensity, ``intensity_rXX_nYY``, then the outline
        coefficients of the boundary term ``outline_n±KK_re/im`` (64 columns, see
        :mod:`napari_pfsdm.core.table_schema`). ``attrs["pfsdm"]`` holds the options used,
        with the rings' ``radii`` and ``weights``.

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
    counted = progress is not None and isinstance(labels, np.ndarray)
    total = count_objects(labels) if counted else None

    def reporting():
        for done, obj in enumerate(iter_objects(labels, intensity, params=p), start=1):
            yield obj  # consumed row by row: no result is kept
            if progress is not None:
                progress(done, total)

    return table_from_objects(reporting(), with_intensity=intensity is not None, params=p)
