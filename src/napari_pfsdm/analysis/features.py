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

from ..core.descriptor import DEFAULTS, PFSDMResult, pfsdm
from ..core.morphometric import mode_weights, ring_radii, ring_weights

__all__ = [
    "ObjectResult",
    "count_objects",
    "feature_columns",
    "iter_objects",
    "measure",
    "resolved_options",
    "table_from_objects",
]

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


_BASE_COLUMNS = ["frame", "label", "area", "centroid_y", "centroid_x", "touches_border",
                 "n_components", "n_holes", "folded_fraction", "error"]


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
    """

    frame: int
    label: int
    bbox: tuple[slice, slice]
    area: int
    centroid: np.ndarray
    touches_border: bool
    result: PFSDMResult | None
    error: str = ""


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


def iter_objects(labels, intensity=None, *, frames=None, **options: Any) -> Iterator[ObjectResult]:
    """PF-SDM of every object of every frame, one at a time.

    Parameters
    ----------
    labels : array_like of int, shape (Y, X) or (T, Y, X)
        Label image; 0 is background. numpy, dask or zarr arrays: frames are read one at a time.
    intensity : array_like, same shape, optional
    frames : iterable of int, optional
        Frames to process (default all).
    **options
        Passed to :func:`~napari_pfsdm.core.descriptor.pfsdm`.

    Yields
    ------
    ObjectResult
        In frame order, then label order. Objects that cannot be described (too small, NaN
        intensity, ...) are yielded with ``result=None`` and the reason in ``error``; a badly
        formed input (wrong dimensions, shapes, dtype) raises ``ValueError`` before anything runs.
        While it runs, BLAS is limited to one thread (the per-object matrices are small).
    """
    n_frames, timelapse = _validate(labels, intensity)
    with _one_blas_thread():
        yield from _iter_frames(labels, intensity, n_frames, timelapse, frames, options)


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
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", UserWarning)
                    res = pfsdm(mask, None if image is None else image[big],
                                offset=(big[0].start, big[1].start), **options)
                error = ""
            except ValueError as exc:
                res, error = None, str(exc)
            yield ObjectResult(frame=int(t), label=label, bbox=box, area=area, centroid=centroid,
                               touches_border=touches, result=res, error=error)


def feature_columns(n_radii: int, n_fourier: int, channel: str = "shape") -> list[str]:
    """Column names ``{channel}_rXX_nYY`` (ring-major), as in :func:`measure`'s table."""
    return [f"{channel}_r{r:02d}_n{n:02d}" for r in range(n_radii) for n in range(n_fourier + 1)]


def resolved_options(**options: Any) -> dict[str, Any]:
    """The options a :func:`pfsdm` call would use, with the rings' radii and weights."""
    opts = {**DEFAULTS, **options}
    r = ring_radii(opts["n_radii"], opts["radii"])
    opts["radii"] = r.tolist()
    opts["n_radii"] = len(r)
    opts["weights"] = ring_weights(r, opts["ring_weighting"]).tolist()
    opts["mode_weights"] = mode_weights(opts["n_fourier"], opts["mode_exponent"]).tolist()
    return opts


def table_from_objects(objects, *, with_intensity: bool = False, **options: Any) -> pd.DataFrame:
    """The feature table of :func:`measure` from objects computed by :func:`iter_objects` with
    the same ``options`` (one row per object, in the given order). ``objects`` may be a
    generator: only the rows are kept, not the results."""
    opts = resolved_options(**options)
    shape_cols = feature_columns(opts["n_radii"], opts["n_fourier"], "shape")
    int_cols = feature_columns(opts["n_radii"], opts["n_fourier"], "intensity") \
        if with_intensity else []
    nan_s, nan_i = np.full(len(shape_cols), np.nan), np.full(len(int_cols), np.nan)
    base, shape_rows, int_rows = [], [], []
    for obj in objects:
        res = obj.result
        diag = res.diagnostics if res is not None else {}
        base.append((obj.frame, obj.label, obj.area, obj.centroid[0], obj.centroid[1],
                     obj.touches_border, diag.get("n_components", np.nan),
                     diag.get("n_holes", np.nan), diag.get("folded_fraction", np.nan), obj.error))
        shape_rows.append(res.embedding.ravel() if res is not None else nan_s)
        if int_cols:
            emb = None if res is None else res.intensity_embedding
            int_rows.append(emb.ravel() if emb is not None else nan_i)
    blocks = [pd.DataFrame(base, columns=_BASE_COLUMNS),
              pd.DataFrame(np.array(shape_rows).reshape(-1, len(shape_cols)), columns=shape_cols)]
    if int_cols:
        blocks.append(pd.DataFrame(np.array(int_rows).reshape(-1, len(int_cols)),
                                   columns=int_cols))
    table = pd.concat(blocks, axis=1)
    table.attrs["pfsdm"] = opts
    return table


def measure(
    labels,
    intensity=None,
    *,
    progress: Callable[[int, int | None], None] | None = None,
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
    **options
        Passed to :func:`~napari_pfsdm.core.descriptor.pfsdm` (``n_fourier``, ``mapping``, ...).

    Returns
    -------
    pandas.DataFrame
        Columns ``frame``, ``label``, ``area`` (pixels), ``centroid_y``, ``centroid_x``
        (pixels), ``touches_border``, ``n_components``, ``n_holes``, ``folded_fraction``,
        ``error`` (empty when fine, otherwise the reason, with NaN features), then
        ``shape_rXX_nYY`` and, with an intensity, ``intensity_rXX_nYY``. ``attrs["pfsdm"]``
        holds the options used, with the rings' ``radii`` and ``weights``.

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
    counted = progress is not None and isinstance(labels, np.ndarray)
    total = count_objects(labels) if counted else None

    def reporting():
        for done, obj in enumerate(iter_objects(labels, intensity, **options), start=1):
            yield obj  # consumed row by row: no result is kept
            if progress is not None:
                progress(done, total)

    return table_from_objects(reporting(), with_intensity=intensity is not None, **options)
