"""What a label image holds: its axes, its frames and the objects in each frame.

Checked before any object is measured, in plain words: the axis order (:func:`resolve_axes`,
:data:`AXES`), a colour image given as labels (:func:`refuse_colour`), an array without
pixels, labels that are not whole numbers, a reporter of another shape (:func:`check_arrays`),
frames asked for that the movie does not have (:func:`check_frames`), the voxel size of 3-D
objects (:func:`voxel_spacing`). Then the objects: their ids (:func:`present_ids`), bounding
boxes (:func:`object_boxes`) and crops (:func:`crop_of`), found in time and memory that follow
the pixels, whatever the ids; :func:`count_objects` is the package's one count of them.
Whether labels are those a table was measured from is checked by content, frame by frame
(:func:`frame_objects`: ids, pixel counts, centroids; :func:`check_labels_match`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import ndimage as ndi

from ..core.volume_sdf import check_spacing
from ..errors import InputError

__all__ = ["AXES", "check_arrays", "check_frames", "check_labels_match", "count_objects",
           "crop_of", "frame_at", "frame_objects", "looks_like_colour", "object_boxes",
           "present_ids", "raw_image_reason", "refuse_colour", "refuse_not_labels",
           "reporter_channels",
           "refuse_zero_size", "resolve_axes", "voxel_spacing"]


#: The axis orders a label image may have (docs/design.md §5, "axes"): ``t`` time, ``z``, ``y``,
#: ``x`` space. A 2-D array is ``"yx"`` and a 3-D one ``"tyx"`` unless ``axes`` says otherwise;
#: a 4-D array must say (``"tzyx"``).
AXES = ("yx", "tyx", "zyx", "tzyx")


def resolve_axes(shape: tuple[int, ...], axes: str | None = None) -> str:
    """The axis order of a label image of ``shape``: ``axes`` checked against it, or the
    documented default (2-D: ``"yx"``, 3-D: ``"tyx"``, the time-lapse of 2-D frames this
    package always took); a 4-D array without ``axes`` is refused, never guessed.

    Examples
    --------
    >>> resolve_axes((10, 64, 64)), resolve_axes((10, 64, 64), "zyx")
    ('tyx', 'zyx')
    """
    ndim = len(shape)
    if axes is None:
        refuse_colour(shape)
        if ndim == 2:
            return "yx"
        if ndim == 3:
            return "tyx"
        if ndim == 4:
            raise InputError(
                f"The labels have 4 dimensions {tuple(shape)}: say which axes they are, e.g. "
                "axes='tzyx' for a time-lapse of Z-stacks (in the command line: --axes tzyx)."
            )
        raise InputError(
            f"Labels must be 2-D (Y, X), 3-D (T, Y, X or Z, Y, X) or 4-D (T, Z, Y, X); got shape "
            f"{tuple(shape)}. For extra channels, pass one channel."
        )
    axes = str(axes).lower()
    if axes not in AXES:
        raise InputError(f"axes must be one of {', '.join(AXES)} (t time, z y x space); got "
                         f"{axes!r}.")
    if len(axes) != ndim:
        raise InputError(f"axes={axes!r} names {len(axes)} axes but the labels have {ndim} "
                         f"dimensions {tuple(shape)}.")
    return axes


def looks_like_colour(shape: tuple[int, ...]) -> bool:
    """Whether an array of ``shape`` looks like a colour image: 3 or 4 samples (RGB, RGBA) on
    its last axis, after an axis of at least 8 pixels (``(Y, X, 3)``, ``(T, Y, X, 4)``).

    Judged by the axes, never by the number of frames: a ``(3, Y, X)`` time-lapse is not one.

    Examples
    --------
    >>> looks_like_colour((64, 64, 3)), looks_like_colour((3, 64, 64))
    (True, False)
    """
    return len(shape) in (3, 4) and shape[-1] in (3, 4) and shape[-2] >= 8


def refuse_colour(shape: tuple[int, ...], what: str = "The labels") -> None:
    """Raise, in plain words, for labels (or a reporter) that look like a colour image
    (:func:`looks_like_colour`) when no ``axes`` were given: the command line refuses them
    too. Saying ``axes`` (e.g. ``"tyx"``) takes the array as it is."""
    if looks_like_colour(tuple(shape)):
        raise InputError(
            f"{what} have shape {tuple(shape)}: {shape[-1]} values per pixel on the last axis, "
            "which looks like a colour (RGB/RGBA) image, not a label image. Give the "
            "segmentation with one whole number per object (0 = background), or one channel "
            "(e.g. image[..., 0]); if the last axis really is the image's width, say "
            f"axes='{'tyx' if len(shape) == 3 else 'tzyx'}'."
        )


def voxel_spacing(axes: str, spacing) -> np.ndarray | None:
    """The voxel size of a 3-D axis order (None for 2-D, where only square pixels exist)."""
    if "z" in axes:
        return check_spacing(spacing, 3)
    if spacing is not None:
        sp = np.asarray(spacing, float).ravel()
        if sp.size not in (1, 2) or not np.all(sp == sp[0]):
            raise InputError(
                f"spacing {tuple(sp.tolist())} was given for 2-D frames (axes={axes!r}); 2-D "
                "objects take square pixels only. If the first axis is Z, say axes='zyx'."
            )
    return None


def refuse_zero_size(shape: tuple[int, ...], what: str = "The labels") -> None:
    """Raise, in plain words, for an array with no pixels (a 0-frame movie, a 0-wide image)."""
    if any(int(n) == 0 for n in shape):
        raise InputError(
            f"{what} {'have' if what.startswith('The ') else 'has'} shape "
            f"{tuple(int(n) for n in shape)}: no pixels (an axis of length "
            "0), so there is nothing to measure. Check that the file was written completely "
            "and holds the segmentation."
        )


#: Ids up to this many times a frame's pixels get their bounding boxes from a table indexed
#: by id (:func:`scipy.ndimage.find_objects`); larger ids are renumbered first.
_DIRECT_IDS_PER_PIXEL = 2


def _as_counts(flat: np.ndarray) -> np.ndarray:
    """An integer array numpy's ``bincount`` and ``find_objects`` take (bool and uint64 too)."""
    return flat.astype(np.intp, copy=False) if flat.dtype.kind in "bu" and (
        flat.dtype.itemsize >= np.dtype(np.intp).itemsize or flat.dtype == bool) else flat


def _small_ids(frame: np.ndarray) -> bool:
    """Whether the ids of ``frame`` (non-negative, not empty) are small enough for a table
    indexed by id: memory then stays proportional to the frame, whatever the largest id."""
    return int(frame.max()) <= _DIRECT_IDS_PER_PIXEL * frame.size + 1024


def present_ids(frame: np.ndarray) -> np.ndarray:
    """The object ids (> 0) in a frame, sorted; time and memory proportional to its pixels,
    whatever the ids (up to 2**63 - 1 in int64/uint64, 2**32 - 1 in uint32).

    Examples
    --------
    >>> present_ids(np.array([[0, 7], [10**12, 7]], np.int64)).tolist()
    [7, 1000000000000]
    """
    flat = np.asarray(frame).ravel()
    if flat.size == 0:
        return np.zeros(0, np.int64)
    if _small_ids(flat):
        present = np.flatnonzero(np.bincount(_as_counts(flat)))
    else:
        present = np.unique(flat)
    present = present[present > 0]
    return present.astype(np.int64) if not len(present) or int(present[-1]) < 2**63 \
        else present


def object_boxes(frame: np.ndarray) -> list[tuple[int, tuple[slice, ...]]]:
    """``(label, bounding box)`` of every object of a frame, in label order.

    :func:`scipy.ndimage.find_objects` keeps one entry per possible id, from 1 to the largest:
    one object of id 10**8 would cost 10**8 entries (seconds and gigabytes), and ids near 2**63
    overflow. Frames whose largest id is more than a few times their number of pixels are
    renumbered (``numpy.unique``) first, so time and memory follow the pixels and the number
    of objects, never the ids.

    Examples
    --------
    >>> frame = np.zeros((4, 5), np.uint64)
    >>> frame[1:3, 2:4] = 2**63 - 1
    >>> object_boxes(frame)
    [(9223372036854775807, (slice(1, 3, None), slice(2, 4, None)))]
    """
    frame = np.asarray(frame)
    if frame.size == 0 or not frame.any():
        return []
    if _small_ids(frame):
        boxes = ndi.find_objects(_as_counts(frame))
        return [(i + 1, box) for i, box in enumerate(boxes) if box is not None]
    ids, inverse = np.unique(frame, return_inverse=True)
    background = int(ids[0]) == 0
    compact = inverse.reshape(frame.shape).astype(np.intp) + (0 if background else 1)
    labels = ids[1:] if background else ids
    return [(int(lab), box) for lab, box in
            zip(labels, ndi.find_objects(compact), strict=True)]


def check_arrays(labels, intensity, axes: str | None = None,
                 where: str = "The labels") -> tuple[int, bool, str]:
    """Labels (and a reporter of the same shape) checked as :func:`measure` takes them:
    ``(number of frames, whether it is a time-lapse, the axis order)``; plain words for
    anything else (:class:`~napari_pfsdm.errors.InputError`), a raw image or negative ids in
    a few of its frames included (:func:`refuse_not_labels`)."""
    shape = tuple(labels.shape)
    axes = resolve_axes(shape, axes)
    refuse_zero_size(shape)
    dtype = np.dtype(labels.dtype)
    if not (np.issubdtype(dtype, np.integer) or dtype.kind == "b"):
        raise InputError(
            f"Labels must be an integer label image (each object one whole number), got dtype "
            f"{dtype}. Convert a segmentation with skimage.measure.label first."
        )
    if intensity is not None and tuple(intensity.shape) != shape:
        if tuple(intensity.shape[:-1]) == shape and intensity.shape[-1] in (3, 4):
            refuse_colour(tuple(intensity.shape), "The intensity image and its labels")
        raise InputError(
            f"The intensity image has shape {tuple(intensity.shape)} but the labels have shape "
            f"{shape}: they must cover the same frames and pixels."
        )
    timelapse = axes.startswith("t")
    refuse_not_labels(labels, axes, where)
    return (shape[0] if timelapse else 1), timelapse, axes


#: A frame whose values lie in more separate patches than this per value, with at least
#: :data:`RAW_MIN_VALUES` values, is a raw image, not labels: a segmentation has one patch per
#: object, or a few (an object in pieces); a microscope image scatters each value over hundreds
#: (tests/test_faults_files3.py: 3,500 nuclei 1.02 patches per id, a tessellation 1.0; 16-bit
#: and 8-bit images 50 to 1,800).
RAW_PATCHES_PER_VALUE = 8
RAW_MIN_VALUES = 16
#: Pixels of a frame looked at (its centre), at most: the check costs ~0.1 s.
RAW_SAMPLE = 2048 * 2048


def raw_image_reason(frame: np.ndarray) -> str | None:
    """Why a frame of "labels" is a raw image, in words, or None when it looks like labels
    (:data:`RAW_PATCHES_PER_VALUE`). Its centre is looked at, at most :data:`RAW_SAMPLE`
    pixels.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> raw = rng.poisson(100, (64, 64)).astype(np.uint16)
    >>> raw_image_reason(raw).split(" patches")[0] + " patches"
    '68 different values lie in 3,670 separate patches'
    >>> labels = np.zeros((64, 64), np.uint16); labels[:32], labels[40:] = 1, 2
    >>> raw_image_reason(labels) is None
    True
    """
    from skimage.measure import label as patches

    frame = np.asarray(frame)
    if frame.dtype == bool or frame.size == 0:
        return None
    side = int(RAW_SAMPLE ** (1 / frame.ndim))
    crop = tuple(slice(max(0, (n - side) // 2), max(0, (n - side) // 2) + side)
                 for n in frame.shape)
    frame = frame[crop]
    values = len(present_ids(frame)) if frame.min() >= 0 else len(np.unique(frame))
    if values < RAW_MIN_VALUES:
        return None
    n = int(patches(frame, background=0, connectivity=frame.ndim).max())
    if n < RAW_PATCHES_PER_VALUE * values:
        return None
    return (f"{values:,} different values lie in {n:,} separate patches, {n / values:.0f} "
            "per value, where a segmentation has one patch (or a few) per object")


def _frames_to_check(n_frames: int) -> list[int]:
    return sorted({0, n_frames // 2, n_frames - 1})


def refuse_not_labels(labels, axes: str, where: str = "The labels") -> None:
    """Refuse, before any work, labels whose first, middle or last frame holds negative ids or
    is a raw image (:func:`raw_image_reason`), naming ``where`` and saying what to give."""
    timelapse = axes.startswith("t")
    n_frames = int(labels.shape[0]) if timelapse else 1
    for t in _frames_to_check(n_frames):
        frame = frame_at(labels, t, timelapse)
        if frame.dtype == bool or not frame.size:
            continue
        at = f" (frame {t})" if timelapse else ""
        low = frame.min()
        if low < 0:
            raise InputError(
                f"{where} hold{'s' if not where.startswith('The ') else ''} negative values"
                f"{at}, down to {int(low)}: labels are 0 (background) and whole numbers from 1, "
                "one per object. If negative values mark the background, set them to 0 "
                "(labels[labels < 0] = 0); if the ids are shifted, relabel them "
                "(skimage.measure.label)")
        reason = raw_image_reason(frame)
        if reason:
            raise InputError(
                f"{where} look{'s' if not where.startswith('The ') else ''} like a raw image, "
                f"not a label image{at}: {reason}. Give the segmentation (one whole number "
                "per object, 0 = background), not the raw image")


#: Largest number of channels a reporter's extra axis may have to be read by channel.
MAX_CHANNELS = 16


def reporter_channels(image_shape: tuple, labels_shape: tuple, rgb: bool = False,
                      axis: bool = False):
    """How an image of ``image_shape`` can be the reporter of labels of ``labels_shape``: the
    one rule of the napari plugin's reporter choices and of ``pfsdm measure
    --reporter-channel``.

    Returns ``[None]`` (the image as it is), the list of its channels (an image with one
    more axis, of at most :data:`MAX_CHANNELS` entries, that is the labels' grid without it),
    or None (it does not fit). With ``axis=True``: the channel axis (None without one).

    >>> movie = (5, 64, 64)
    >>> reporter_channels(movie, movie), reporter_channels((5, 2, 64, 64), movie)
    ([None], [0, 1])
    >>> reporter_channels((5, 2, 64, 64), movie, axis=True), reporter_channels((64, 64), movie)
    (1, None)
    """
    image_shape, labels_shape = tuple(image_shape), tuple(labels_shape)
    if rgb:
        return None
    if image_shape == labels_shape:
        return None if axis else [None]
    if len(image_shape) == len(labels_shape) + 1:
        for k in range(len(image_shape) - 2):  # a channel axis is never Y or X
            if image_shape[:k] + image_shape[k + 1:] == labels_shape \
                    and image_shape[k] <= MAX_CHANNELS:
                return k if axis else list(range(image_shape[k]))
    return None


def frame_at(array, t: int, timelapse: bool) -> np.ndarray:
    """Frame ``t`` of a time-lapse (the array itself otherwise), read into memory."""
    return np.asarray(array[t] if timelapse else array)


def count_objects(labels, axes: str | None = None) -> int:
    """Number of (frame, label) objects in a label image, one frame at a time (numpy, dask
    and zarr arrays); ``axes`` as :func:`measure`. The one count of the package: the plugin's
    progress total too.

    Raises
    ------
    InputError
        Labels that are not whole numbers, or that hold negative values.

    Examples
    --------
    >>> labels = np.zeros((2, 8, 8), np.uint8)
    >>> labels[0, :2, :2], labels[0, 5:, 5:], labels[1, 3:5, 3:5] = 1, 4, 4
    >>> count_objects(labels)
    3
    """
    n_frames, timelapse, _ = check_arrays(labels, None, axes)
    n = 0
    for t in range(n_frames):
        a = frame_at(labels, t, timelapse).ravel()
        if a.dtype == bool:
            a = a.astype(np.uint8)
        if a.size and a.min() < 0:
            raise InputError("The labels have negative values; labels must be 0 (background) "
                             "or positive whole numbers.")
        n += len(present_ids(a))
    return n


def check_frames(frames: Any, n_frames: int) -> list[int]:
    """Frame indices given to the API as the frames they are: whole numbers, negative ones
    counted from the end (``-1`` is ``n_frames - 1``), each once, inside the movie.

    Examples
    --------
    >>> check_frames([0, -1], 5)
    [0, 4]
    """
    if isinstance(frames, int | np.integer):
        frames = [frames]
    out: list[int] = []
    for f in np.asarray(list(frames), dtype=object).ravel():
        if isinstance(f, bool | np.bool_) or not isinstance(f, int | np.integer):
            if not (isinstance(f, float | np.floating) and float(f).is_integer()):
                raise InputError(f"frames must be whole numbers (frame indices); got {f!r}.")
        t = int(f)
        if not -n_frames <= t < n_frames:
            raise InputError(f"frame {t} is not in the movie: it has {n_frames} frame"
                             f"{'s' if n_frames != 1 else ''} (0 to {n_frames - 1}, or -1 for "
                             "the last).")
        t %= n_frames
        if t in out:
            raise InputError(f"frame {t} is given twice in frames (its objects would be "
                             "counted twice); give each frame once.")
        out.append(t)
    return out


def crop_of(box, shape) -> tuple[slice, ...]:
    """The crop an object is measured in: its bounding box ``box`` one pixel wider on every
    side, within a frame of ``shape``."""
    return tuple(slice(max(s.start - 1, 0), min(s.stop + 1, n)) for s, n in
                 zip(box, shape, strict=True))


def frame_objects(frame: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The objects of one frame as a table reports them: ``(ids, pixel counts, centroids)``
    (centroids as the mean pixel coordinates, one row per id, one column per axis), in time
    and memory that follow the pixels, whatever the ids.

    Examples
    --------
    >>> f = np.zeros((4, 6), np.uint16); f[0:2, 0:2] = 7; f[3, 3:6] = 2
    >>> ids, n, c = frame_objects(f)
    >>> ids.tolist(), n.tolist(), c.tolist()
    ([2, 7], [3, 4], [[3.0, 4.0], [0.5, 0.5]])
    """
    frame = np.asarray(frame)
    if frame.dtype == bool:
        frame = frame.astype(np.uint8)
    flat = frame.ravel()
    if flat.size == 0 or not flat.any():
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, frame.ndim))
    if _small_ids(flat):
        index = _as_counts(flat)
        ids = None
    else:
        ids, index = np.unique(flat, return_inverse=True)
        index = index.ravel()
    counts = np.bincount(index)
    sums = []
    for axis, n in enumerate(frame.shape):
        shape = [1] * frame.ndim
        shape[axis] = n
        coord = np.broadcast_to(np.arange(n, dtype=float).reshape(shape), frame.shape).ravel()
        sums.append(np.bincount(index, weights=coord, minlength=len(counts)))
    all_ids = np.arange(len(counts)) if ids is None else ids
    keep = (counts > 0) & (all_ids != 0)
    centroids = np.stack(sums, axis=1)[keep] / counts[keep, None]
    return all_ids[keep], counts[keep], centroids


def _has_physical_units(table) -> bool:
    """Whether a table's sizes may be in physical units (its options record a pixel or voxel
    size other than 1): then sizes are a constant multiple of pixel counts."""
    opts = getattr(table, "attrs", {}).get("pfsdm") or {}
    for key in ("pixel_size", "spacing"):
        value = opts.get(key)
        if value is not None and not np.allclose(np.asarray(value, float), 1.0):
            return True
    return False


def check_labels_match(labels, table, where: str = "the labels",
                       movie: str | None = None) -> None:
    """Refuse, in plain words, labels that are not the segmentation ``table`` was measured
    from: every row's object must be in its frame of ``labels`` with the row's size (``area``
    or ``volume``, pixel counts or a constant multiple of them, as a pixel size gives) and,
    in pixel units, its centroid. Objects of the labels that the table lacks are allowed (rows
    left out of a table). Each frame the table names is read once.

    Parameters
    ----------
    labels : array_like
        One image or volume, or a movie (time first), numpy, dask or zarr.
    table : pandas.DataFrame
        Rows of one movie (``frame``, ``label`` and ``area`` or ``volume``; centroids when
        it has them).
    where : str
        The labels' name (a file), for the message.
    movie : str, optional
        The movie's name in the table, for the message.

    Raises
    ------
    InputError
        Naming the first objects that differ, the frames, and what to do.
    """
    size_col = "area" if "area" in table.columns else "volume"
    if size_col not in table.columns or not len(table):
        return
    axes = [c for c in ("centroid_z", "centroid_y", "centroid_x") if c in table.columns]
    ndim = getattr(labels, "ndim", np.ndim(labels))
    obj_ndim = 3 if "volume" in table.columns or "centroid_z" in table.columns else 2
    movie_like = ndim == obj_ndim + 1
    bad: list[str] = []
    bad_frames: set[int] = set()
    ratios: list[np.ndarray] = []
    cents: list[tuple[np.ndarray, np.ndarray]] = []
    n_frames = int(labels.shape[0]) if movie_like else 1
    for t, rows in table.groupby("frame", sort=True):
        if not (isinstance(t, int | np.integer) and 0 <= t < n_frames):
            bad.append(f"frame {t} is not in the labels ({n_frames} frame"
                       f"{'s' if n_frames > 1 else ''})")
            bad_frames.add(-1)
            continue
        t = int(t)
        image = np.asarray(labels[t]) if movie_like else np.asarray(labels)
        ids, counts, centroids = frame_objects(image)
        pos = {int(i): k for k, i in enumerate(ids.tolist())}
        for row in rows.itertuples(index=False):
            lab = int(row.label)
            size = float(getattr(row, size_col))
            k = pos.get(lab)
            if k is None:
                bad.append(f"frame {t}: label {lab} is not there")
                bad_frames.add(t)
                continue
            if np.isfinite(size):
                ratios.append(np.array([size / counts[k], counts[k], t, lab], float))
            if axes and len(axes) == centroids.shape[1]:
                cents.append((np.array([getattr(row, a) for a in axes], float),
                              np.append(centroids[k], [t, lab])))
    if ratios:
        r = np.array(ratios)
        scale = float(np.median(r[:, 0])) if _has_physical_units(table) else 1.0
        off = np.abs(r[:, 0] - scale) > 1e-6 * abs(scale)
        for ratio, n, t, lab in r[off][:3]:
            bad.append(f"frame {int(t)}: label {int(lab)} has {int(n):,} pixels there, "
                       f"{size_col} {ratio * n:g} in the table")
        bad_frames.update(int(t) for t in r[off, 2])
        if abs(scale - 1.0) <= 1e-9 and cents and not off.any():
            for want, got in cents:
                if np.nanmax(np.abs(want - got[:-2])) > 1e-6:
                    t, lab = int(got[-2]), int(got[-1])
                    at = ", ".join(a.split("_")[1] for a in axes)
                    bad.append(f"frame {t}: label {lab} is centred at {at} = "
                               f"{', '.join(f'{v:.1f}' for v in got[:-2])} there, "
                               f"{', '.join(f'{v:.1f}' for v in want)} in the table")
                    bad_frames.add(t)
    if bad:
        from_ = f" of {movie}" if movie else ""
        more = f" (objects differ in {len(bad_frames)} frame{'s' if len(bad_frames) > 1 else ''})"
        raise InputError(
            f"{where} is not the segmentation the table{from_} was measured from: "
            f"{'; '.join(bad[:3])}{more}. Give the label movie the table was measured from "
            "(the same file, not another segmentation of the same images)")
