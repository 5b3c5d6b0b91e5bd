"""The analysis behind the widget, as plain arrays (no Qt, no napari).

The widget runs :func:`run_analysis` in a worker thread. It walks the objects with
:func:`napari_pfsdm.iter_objects`, yields ``(done, total, frame, label)`` after each object so that
the GUI can show progress and stop early, and finally returns an :class:`AnalysisOutput` whose
arrays are ready to be handed to napari layers: the GUI thread only adds layers.
"""

from __future__ import annotations

from collections.abc import Generator
from dataclasses import dataclass, field, replace
from types import SimpleNamespace

import numpy as np
import pandas as pd

from ..analysis.reduction import mds_coordinates
from ..analysis.reduction import pca_scores as _pca
from ..core.params import PFSDMParams
from ..core.table_schema import BASE_COLUMNS as _BASE_COLUMNS
from ..core.table_schema import has_channel

#: Largest side length (pixels) of one rendered unit disk.
DISK_SIZE = 96
#: Budget of disk pixels over all (object, frame) slots: many objects get smaller disks.
DISK_PIXEL_BUDGET = 40_000_000
#: The columns before the features, as in :func:`napari_pfsdm.measure`.
BASE_COLUMNS = _BASE_COLUMNS
#: Margin around an object's bounding box (fraction of its larger side) for the SDF patch.
SDF_MARGIN = 0.25


@dataclass
class AnalysisOutput:
    """Everything one run produced, as arrays in the Labels layer's data coordinates.

    Attributes
    ----------
    table
        One row per (frame, label): the feature table of :func:`napari_pfsdm.measure`.
    options
        The options of the run (``table.attrs["pfsdm"]`` plus the widget's own).
    objects
        ``(frame, label)`` of every object, in the order of the disk stack's object axis
        (sorted by label, then frame).
    object_labels
        Sorted distinct labels; index ``o`` of the disk stack's first axis is ``object_labels[o]``.
    time_lapse
        True when the labels were (T, Y, X).
    disk, intensity_disk
        (O, T, S, S) float32 stacks of the pushed-forward SDF / intensity (NaN outside the
        disk and where an object is absent); ``(O, S, S)`` for a 2-D image.
        ``intensity_disk`` is None without an intensity image.
    disk_skeleton
        Same shape as ``disk``: the skeleton pushed onto the disk (value = label).
    skeleton
        Same shape as the labels: the skeleton of every object in image space (value = label).
    sdf_patches
        ``{(frame, label): (row0, col0, patch)}``: the SDF (pixels, negative inside) on the object's
        bounding box plus a margin.
    pca
        ``{"shape": scores, "intensity": scores}``: DataFrames with ``frame``, ``label``,
        ``PC1``... and ``attrs["explained_variance_ratio"]``.
    skeleton_errors
        ``{(frame, label): reason}`` for objects whose skeleton could not be drawn (their
        features are kept; the widget says how many).
    """

    table: pd.DataFrame
    options: dict
    objects: list[tuple[int, int]]
    object_labels: np.ndarray
    time_lapse: bool
    disk: np.ndarray
    intensity_disk: np.ndarray | None
    disk_skeleton: np.ndarray
    skeleton: np.ndarray
    sdf_patches: dict = field(default_factory=dict)
    pca: dict = field(default_factory=dict)
    skeleton_errors: dict = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return self.skeleton.shape[0] if self.time_lapse else 1

    def object_index(self, label: int) -> int | None:
        """Index of ``label`` on the disk stack's object axis (None if absent)."""
        idx = int(np.searchsorted(self.object_labels, label))
        if idx < len(self.object_labels) and self.object_labels[idx] == label:
            return idx
        return None

    def sdf_window(self, label: int) -> tuple[np.ndarray, tuple[int, int]]:
        """SDF of ``label`` on the union of its patches over time: (array, (row0, col0)).

        The array is (T, h, w) for a time-lapse ((h, w) for a 2-D image), NaN where the object
        is absent; ``(row0, col0)`` is its top-left pixel in the frame. Memory stays small for
        large frames and long movies.
        """
        items = [(f, p) for (f, lab), p in self.sdf_patches.items() if lab == label]
        if not items:
            shape = (self.n_frames, 1, 1) if self.time_lapse else (1, 1)
            return np.full(shape, np.nan, dtype=np.float32), (0, 0)
        r0 = min(p[0] for _, p in items)
        c0 = min(p[1] for _, p in items)
        r1 = max(p[0] + p[2].shape[0] for _, p in items)
        c1 = max(p[1] + p[2].shape[1] for _, p in items)
        out = np.full((self.n_frames, r1 - r0, c1 - c0), np.nan, dtype=np.float32)
        for frame, (pr, pc, patch) in items:
            h, w = patch.shape
            out[frame, pr - r0:pr - r0 + h, pc - c0:pc - c0 + w] = patch
        return (out if self.time_lapse else out[0]), (r0, c0)

    def sdf_stack(self, label: int) -> np.ndarray:
        """SDF of ``label`` in every frame, shaped like the labels (NaN away from the object)."""
        out = np.full(self.skeleton.shape, np.nan, dtype=np.float32)
        frames = out if self.time_lapse else out[None]
        for (frame, lab), (r0, c0, patch) in self.sdf_patches.items():
            if lab == label:
                h, w = patch.shape
                frames[frame, r0:r0 + h, c0:c0 + w] = patch
        return out


def validate_layers_data(labels: np.ndarray, intensity: np.ndarray | None) -> None:
    """Refuse label/intensity combinations the analysis cannot use.

    Raises
    ------
    ValueError
        With a sentence saying what is wrong and what to do.
    """
    if labels.ndim not in (2, 3):
        raise ValueError(
            f"The Labels layer has {labels.ndim} dimensions {tuple(labels.shape)}; PF-SDM needs a "
            "2-D image (Y, X) or a time-lapse (T, Y, X). Split channels or z first."
        )
    if not np.issubdtype(np.dtype(labels.dtype), np.integer) and labels.dtype != bool:
        raise ValueError("The Labels layer must hold integer labels (one number per object).")
    if intensity is not None and tuple(intensity.shape) != tuple(labels.shape):
        raise ValueError(
            f"The Image layer's shape {tuple(intensity.shape)} does not match the Labels layer's "
            f"{tuple(labels.shape)}: choose an image recorded on the same grid, or none."
        )


def list_objects(labels) -> list[tuple[int, int]]:
    """``(frame, label)`` of every object, frame by frame (dask arrays: one frame at a time)."""
    frames = [labels] if labels.ndim == 2 else (labels[t] for t in range(labels.shape[0]))
    out = []
    for t, frame in enumerate(frames):
        labs = np.unique(np.asarray(frame))
        out.extend((t, int(lab)) for lab in labs if lab != 0)
    return out


def _rasterize(points: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Integer (row, col) of ``points`` that fall inside ``shape``."""
    if points is None or len(points) == 0:
        return np.zeros(0, int), np.zeros(0, int)
    rc = np.rint(np.asarray(points, dtype=float)).astype(int)
    ok = (rc[:, 0] >= 0) & (rc[:, 0] < shape[0]) & (rc[:, 1] >= 0) & (rc[:, 1] < shape[1])
    return rc[ok, 0], rc[ok, 1]


def disk_pixels(uv: np.ndarray, size: int) -> np.ndarray:
    """Pixel (row, col) of unit-disk points (u, v) in a :func:`render_disk` image of ``size``.

    ``render_disk`` puts u along the rows and v along the columns, pixel centres at
    ``(i + 0.5) / size * 2 - 1``.
    """
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    return (uv + 1.0) * 0.5 * size - 0.5


def sdf_patch(result, bbox, frame_shape: tuple[int, int]):
    """The object's SDF in pixels on its bounding box plus a margin.

    ``bbox`` is ``(row slice, col slice)`` in the frame; the result's contour is in frame pixels.
    Returns ``(row0, col0, patch)``.
    """
    r0, r1, c0, c1 = bbox[0].start, bbox[0].stop, bbox[1].start, bbox[1].stop
    m = int(np.ceil(SDF_MARGIN * max(r1 - r0, c1 - c0))) + 2
    r0, c0 = max(r0 - m, 0), max(c0 - m, 0)
    r1, c1 = min(r1 + m, frame_shape[0]), min(c1 + m, frame_shape[1])
    rr, cc = np.mgrid[r0:r1, c0:c1]
    pts = np.stack([rr.ravel(), cc.ravel()], axis=1).astype(float)
    contour = result.contour
    normalized = (pts - np.asarray(contour.center, float)) / float(contour.scale)
    values = np.asarray(result.sdf(normalized), dtype=float) * float(contour.scale)
    return r0, c0, values.reshape(r1 - r0, c1 - c0).astype(np.float32)


def pca_scores(table: pd.DataFrame, channel: str = "shape", n_components: int = 5) -> pd.DataFrame:
    """The widget's PCA: :func:`napari_pfsdm.analysis.reduction.pca_scores` (the command line's
    too), with the plot's column names ``frame``, ``label``, ``PC1``… and
    ``attrs["explained_variance_ratio"]``; no PC columns with fewer than two measured rows."""
    empty = pd.DataFrame({"frame": pd.Series(dtype=int), "label": pd.Series(dtype=int)})
    empty.attrs["explained_variance_ratio"] = []
    if not has_channel(table.columns, channel):
        return empty
    try:
        scores, ratios = _pca(table, channel, n_components)
    except ValueError:  # fewer than two measured rows
        return empty
    out = scores[["frame", "label"]].copy()
    for col in scores.columns:
        if col.startswith(f"{channel}_PC"):
            out[col[len(channel) + 1:]] = scores[col].to_numpy()
    out.attrs["explained_variance_ratio"] = [float(r) for r in ratios]
    return out


#: The widget's MDS is the package's one MDS.
classical_mds = mds_coordinates


def _rows_only(obj):
    """The object with only what its table row needs (embeddings, diagnostics): the full
    result (SDF, map, skeleton, disks) of every object is not kept for the whole run."""
    res = obj.result
    if res is None:
        return obj
    light = SimpleNamespace(diagnostics=res.diagnostics, embedding=res.embedding,
                            intensity_embedding=res.intensity_embedding, outline=res.outline)
    return replace(obj, result=light)


def disk_size_for(n_slots: int, largest: int = DISK_SIZE) -> int:
    """Disk side so that ``n_slots`` (object × frame) disks stay within the pixel budget."""
    side = int(np.sqrt(DISK_PIXEL_BUDGET / max(n_slots, 1)))
    return int(np.clip(side, 24, largest))


def run_analysis(
    labels,
    intensity=None,
    options: PFSDMParams | dict | None = None,
    disk_size: int | None = None,
) -> Generator[tuple[int, int, int, int], None, AnalysisOutput]:
    """Analyse every (frame, label) object; a generator for worker threads.

    ``options`` is the method's :class:`~napari_pfsdm.core.params.PFSDMParams` (or the same
    as a dict of keywords). Yields ``(done, total, frame, label)`` after each object; returns an
    :class:`AnalysisOutput`. Closing the generator (or the worker stopping at a yield) stops the
    work and keeps nothing.
    """
    from ..analysis.features import iter_objects, table_from_objects
    from ..core.descriptor import render_disk

    params = (options if isinstance(options, PFSDMParams)
              else PFSDMParams.from_options(dict(options or {})))
    validate_layers_data(labels, intensity)
    time_lapse = labels.ndim == 3
    n_frames = labels.shape[0] if time_lapse else 1
    frame_shape = tuple(labels.shape[-2:])
    objects = list_objects(labels)
    if not objects:
        raise ValueError("The Labels layer has no objects (all pixels are 0): paint or load a "
                         "segmentation first.")
    total = len(objects)
    object_labels = np.unique([lab for _, lab in objects])
    n_obj = len(object_labels)
    if disk_size is None:
        # rendering evaluates the SDF at ~size²/2 points: cheaper disks for the costly options
        costly = params.sdf == "viscous" or params.mapping == "bijective"
        disk_size = disk_size_for(n_obj * n_frames, largest=64 if costly else DISK_SIZE)
    disk = np.full((n_obj, n_frames, disk_size, disk_size), np.nan, dtype=np.float32)
    idisk = disk.copy() if intensity is not None else None
    label_dtype = np.min_scalar_type(int(object_labels.max()))
    dskel = np.zeros(disk.shape, dtype=label_dtype)
    skel = np.zeros((n_frames, *frame_shape), dtype=label_dtype)
    patches: dict = {}
    skeleton_errors: dict = {}
    collected = []
    done = 0
    for obj in iter_objects(labels, intensity, params=params):
        collected.append(_rows_only(obj))  # the table needs rows, not the whole results
        frame, label = int(obj.frame), int(obj.label)
        res = obj.result
        if res is not None and not obj.error:
            o = int(np.searchsorted(object_labels, label))
            disk[o, frame] = render_disk(res, size=disk_size)
            if idisk is not None and getattr(res, "intensity_disk", None) is not None:
                idisk[o, frame] = render_disk(res, size=disk_size, channel="intensity")
            try:
                sk = res.skeleton
                rr, cc = _rasterize(np.asarray(sk.points), frame_shape)
                skel[frame, rr, cc] = label
                rr, cc = _rasterize(disk_pixels(sk.disk_points, disk_size), (disk_size,) * 2)
                dskel[o, frame, rr, cc] = label
            except Exception as err:  # noqa: BLE001 - must not lose the features: recorded
                skeleton_errors[(frame, label)] = f"{type(err).__name__}: {err}"
            patches[(frame, label)] = sdf_patch(res, obj.bbox, frame_shape)
        done += 1
        yield done, total, frame, label
    table = table_from_objects(collected, with_intensity=intensity is not None, params=params)
    pca = {"shape": pca_scores(table, "shape")}
    if intensity is not None:
        pca["intensity"] = pca_scores(table, "intensity")
    opts = dict(table.attrs.get("pfsdm") or params.record())
    if not time_lapse:
        disk, dskel, skel = disk[:, 0], dskel[:, 0], skel[0]
        idisk = idisk[:, 0] if idisk is not None else None
    return AnalysisOutput(
        table=table, options=opts, objects=[(f, lab) for f, lab in objects],
        object_labels=object_labels, time_lapse=time_lapse, disk=disk, intensity_disk=idisk,
        disk_skeleton=dskel, skeleton=skel, sdf_patches=patches, pca=pca,
        skeleton_errors=skeleton_errors,
    )
