"""Reading label and intensity movies from disk, lazily.

Supported inputs (each one movie, 2-D ``(Y, X)`` or 3-D ``(T, Y, X)``):

- TIFF files (``.tif``, ``.tiff``, incl. ImageJ and OME-TIFF), read with tifffile;
- Zarr arrays (v2 or v3), e.g. ``movie.zarr`` or ``store.zarr/labels``;
- multiscale OME-Zarr images: the full-resolution level (the finest ``scale``, whichever its
  place in ``datasets``) is used, the axes as the metadata names and orders them, singleton
  channel / z axes dropped.

What a file declares is obeyed or refused: a TIFF cut short or whose pages do not match its
metadata, a TIFF of several series without ``series=``, an OME-Zarr level the metadata lists
but the store lacks, axes in another order than t, z, y, x are refused in plain words
(:class:`~napari_pfsdm.errors.InputError`), never read as a shorter or different movie.

:func:`open_movie` returns a dask array whose chunks are read only when needed, inside the
worker that needs them (the file is re-opened there, so nothing big travels through the
scheduler); a reader notices a file replaced under it (:mod:`.fingerprint`). Which movies
to read, and their pairing with reporters, is :mod:`.movies`' job.

Its length (about 650 lines) is two readers, TIFF and Zarr/OME-Zarr, each with the checks of
what its file declares; they share the frame access (``_Frames``) and the messages, which a
split by format would have to import back and forth.
"""

from __future__ import annotations

import logging
import os
import re
import threading
import weakref
from pathlib import Path
from typing import Any

import dask.array as da
import numpy as np

from ..errors import InputError
from .fingerprint import file_identity, store_files
from .movies import is_tiff, is_zarr

__all__ = ["check_labels", "missing_chunks", "missing_frames", "missing_warning", "movie_source",
           "open_movie", "refuse_missing_chunks"]


class _Frames:
    """Picklable, lazily opened view of a movie as a (T, Y, X) or (Y, X) array.

    Only the path travels when pickled; the file is (re)opened on first access in each
    process. ``axes`` maps the stored array onto the output: for each stored axis either
    ``None`` (kept) or an integer index (a dropped singleton axis such as c or z).
    """

    def __init__(self, path: str, shape: tuple[int, ...], dtype: np.dtype, drop: tuple):
        self.path = path
        self.shape = shape
        self.dtype = np.dtype(dtype)
        self.ndim = len(shape)
        self._drop = drop
        self._handle: Any = None
        #: what identifies the content that ``shape`` and ``dtype`` describe (file_identity)
        self.identity = file_identity(path, getattr(self, "component", ""))

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_handle"] = None
        return state

    def _open(self) -> Any:  # pragma: no cover - overridden
        raise NotImplementedError

    def __getitem__(self, key: Any) -> np.ndarray:
        if not isinstance(key, tuple):
            key = (key,)
        key = key + (slice(None),) * (self.ndim - len(key))
        full: list[Any] = []
        it = iter(key)
        for d in self._drop:
            full.append(next(it) if d is None else d)
        try:
            if self._handle is None:
                self._handle = self._cached_open()
            return np.asarray(self._handle[tuple(full)])
        except ImportError as exc:
            if _codec_missing(exc):
                raise InputError(_codec_words(self.path, exc)) from exc
            raise
        except MemoryError as exc:
            size = int(np.prod(self.shape[1:], dtype=np.int64)) * self.dtype.itemsize
            raise InputError(
                f"reading {self.path} needs more memory than this machine has free (one frame "
                f"is {size / 2**20:.0f} MiB); use fewer workers (--workers 1), measure on a "
                "machine with more memory, or cut the frames into smaller images") from exc
        except Exception as exc:  # noqa: BLE001 - any reader error: name the file
            if _codec_missing(exc):  # not damaged: a decoder this install lacks
                raise InputError(_codec_words(self.path, exc)) from exc
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
            raise InputError(
                f"cannot read {self.path}: the file seems damaged or truncated "
                f"({type(exc).__name__}{': ' + first if first else ''}); copy or export it "
                "again"
            ) from exc

    def _cache_key(self) -> tuple:
        return (type(self).__name__, self.path, getattr(self, "component", None),
                getattr(self, "series", None), self.identity)

    def _cached_open(self) -> Any:
        """Open once per process: tasks unpickled in a worker re-use the open array.

        The cache is keyed by the file's identity as well as its path, so a movie replaced on
        disk (a new file under the old name, as an atomic save makes) is opened anew; one
        changed after :func:`open_movie` looked at it (its shape may differ) is refused.
        """
        now = file_identity(self.path, getattr(self, "component", ""))
        if now != self.identity:
            raise InputError(
                f"{self.path} changed on disk after it was opened (replaced or rewritten "
                "while pfsdm was reading it); wait until it is written completely and run "
                "again")
        key = self._cache_key()
        handle = _OPEN.get(key)
        if handle is None:
            handle = self._open()
            if len(_OPEN) >= 16:
                _OPEN.pop(next(iter(_OPEN)))
            _OPEN[key] = handle
        return handle


#: Arrays opened in this process, by (kind, path, component/series, file_identity).
_OPEN: dict[tuple, Any] = {}


def missing_chunks(arr: Any, folder: str | os.PathLike, t_axis: int | None) -> dict[int, int]:
    """Chunk (or shard) files of a Zarr array that are not on disk, counted per frame.

    Zarr reads a missing chunk as the array's fill value without a word: a frame whose file
    was lost in a copy would look empty. (Zarr also leaves out chunks that hold only the fill
    value when it writes them, so a missing chunk may be an empty one; only the user knows.)

    Parameters
    ----------
    arr : zarr.Array
    folder : path
        The array's own folder (the store's, or a group's array inside it).
    t_axis : int or None
        The stored axis that is time (None: one frame, frame 0).

    Returns
    -------
    dict
        ``{frame: number of missing chunk files}``, only frames that miss some.
    """
    import itertools

    block = getattr(arr, "shards", None) or arr.chunks
    grid = [-(-int(n) // int(c)) for n, c in zip(arr.shape, block, strict=True)]
    present = store_files(folder)
    missing: dict[int, int] = {}
    for coords in itertools.product(*(range(g) for g in grid)):
        if arr.metadata.encode_chunk_key(coords) not in present:
            t0 = 0 if t_axis is None else coords[t_axis] * int(block[t_axis])
            t1 = 1 if t_axis is None else min(t0 + int(block[t_axis]), int(arr.shape[t_axis]))
            for t in range(t0, t1):
                missing[t] = missing.get(t, 0) + 1
    return missing


def _codec_missing(exc: BaseException) -> bool:
    """Whether reading failed for want of a decoder (tifffile's "requires the 'imagecodecs'
    package", or a codec's module missing), not because the file is damaged."""
    text = str(exc)
    return "imagecodecs" in text or getattr(exc, "name", None) in ("imagecodecs", "compression")


def _first_words(what: Any) -> str:
    """An error's own words (a KeyError's without the quotes its str() adds)."""
    if isinstance(what, BaseException) and what.args and isinstance(what.args[0], str):
        return what.args[0]
    return str(what)


def _codec_words(path: Any, what: Any) -> str:
    return (f"{path} is compressed in a way that needs the imagecodecs package to read "
            f"({_first_words(what)}), and it is not installed here: pip install "
            "imagecodecs (a dependency of napari-pfsdm: this install is incomplete). The file "
            "itself is not damaged")


class _ZarrFrames(_Frames):
    def __init__(self, path: str, component: str, shape, dtype, drop):
        self.component = component  # before __init__: part of the file's identity
        super().__init__(path, shape, dtype, drop)

    def _open(self) -> Any:
        import zarr

        return zarr.open_array(self.path, path=self.component or None, mode="r")


class _TiffFrames(_Frames):
    def __init__(self, path: str, series: int, shape, dtype, drop):
        super().__init__(path, shape, dtype, drop)
        self.series = series

    def _open(self) -> Any:
        import tifffile

        try:
            import zarr
        except ImportError as exc:  # a dependency: only a broken install lacks it
            raise ImportError(
                "reading TIFF movies frame by frame needs the zarr package, a dependency of "
                "napari-pfsdm that is missing here: pip install zarr"
            ) from exc

        store = tifffile.imread(self.path, aszarr=True, series=self.series, level=0)
        return zarr.open_array(store, mode="r")


_AXIS_NAMES = {"t": "time", "z": "z-slices", "c": "channels", "s": "colour samples (RGB)",
               "y": "height", "x": "width"}


def _axes_message(where: str, shape: tuple[int, ...], axes: list[str], bad: str) -> str:
    """Plain words for a movie with an axis pfsdm cannot take (z, channels, RGB samples)."""
    dims = ", ".join(f"{n} {_AXIS_NAMES.get(a, a + ' (unknown axis)')}"
                     for a, n in zip(axes, shape, strict=True))
    what = {"s": "it looks like a colour (RGB) image, not a label image: save the "
                 "segmentation with one whole number per object, 0 = background",
            "z": "for 3-D objects say so with --axes zyx (a Z-stack) or --axes tzyx (a "
                 "time-lapse of Z-stacks); for 2-D objects give one z-plane per file",
            "c": "give the segmentation of one channel per file"}.get(
        bad, "give a 2-D image (Y, X) or a time-lapse (T, Y, X) per file")
    return f"{where} has {len(shape)} dimensions ({dims}); {what}"


def _channel_index(channel: int | None, n: int, where: str) -> int:
    """The reporter's channel to read from an axis of ``n`` channels, or the words to say
    which (``--reporter-channel``)."""
    if channel is None:
        raise InputError(
            f"{where} has {n} channels: say which one is the reporter with --reporter-channel "
            f"N (0 to {n - 1}; reporter_channel=N in Python), as the napari plugin offers "
            "each channel of such an image")
    if not 0 <= channel < n:
        raise InputError(f"--reporter-channel {channel}: {where} has {n} channels; give one "
                         f"from 0 to {n - 1}")
    return int(channel)


def _drop_axes(shape: tuple[int, ...], axes: list[str] | None, where: str,
               keep_z: bool = False, channel: int | None = None,
               like: tuple[int, ...] | None = None) -> tuple:
    """Decide which stored axes to keep to obtain (T, Y, X) or (Y, X); with ``keep_z`` (the
    user said the objects are 3-D) also (T, Z, Y, X) or (Z, Y, X). A reporter (``like``: the
    shape of its labels) may have one axis of channels more, named ``c`` by its metadata or
    found by shape as the plugin finds it (``analysis.label_images.reporter_channels``):
    ``channel`` of it is read."""
    drop = _drop_stored_axes(shape, axes, where, keep_z, channel, like)
    if like is not None and channel is not None and not any(
            d == channel and n > 1 for d, n in zip(drop, shape, strict=True)):
        raise InputError(f"--reporter-channel {channel}: {where} has no axis of channels (its "
                         f"shape {tuple(shape)} is its labels'); leave --reporter-channel out")
    return drop


def _drop_stored_axes(shape: tuple[int, ...], axes: list[str] | None, where: str,
                      keep_z: bool, channel: int | None,
                      like: tuple[int, ...] | None) -> tuple:
    ndim = len(shape)
    kept = ("t", "z", "y", "x") if keep_z else ("t", "y", "x")
    sizes = (2, 3, 4) if keep_z else (2, 3)
    if axes is not None and len(axes) != ndim:
        raise InputError(
            f"{where} has {ndim} dimensions {shape} but its metadata names {len(axes)} axes "
            f"({', '.join(map(str, axes))}): the file is inconsistent, so which axis is time "
            "cannot be known; write it again with its axes")
    if axes is not None:
        axes = [a.lower() for a in axes]
        drop: list[int | None] = []
        for a, n in zip(axes, shape, strict=True):
            if a in kept:
                drop.append(None)
            elif n == 1:
                drop.append(0)
            elif a == "c" and like is not None:  # a reporter's channels: one of them
                drop.append(_channel_index(channel, n, where))
            else:
                raise InputError(_axes_message(where, shape, axes, a))
        names = [a for a, d in zip(axes, drop, strict=True) if d is None]
        order = "".join(a for a in "tzyx" if a in names)
        if len(set(names)) != len(names) or "".join(names) != order or not {"y", "x"} <= set(
                names):
            raise InputError(
                f"{where} stores its axes in the order {', '.join(axes)} (as its metadata "
                f"says); pfsdm reads {', '.join(order or 'yx')} in the order t, z, y, x with y "
                "and x both present: save it with its axes in that order (e.g. numpy's "
                "moveaxis, or 'Re-order Hyperstack' in Fiji)")
        if drop.count(None) in sizes:
            return tuple(drop)
    if like is not None and ndim == len(like) + 1:  # a channel axis found by shape
        from ..analysis.label_images import MAX_CHANNELS, reporter_channels

        k = reporter_channels(shape, like, axis=True)
        if k is not None:
            fits = [j for j in range(ndim - 2) if shape[:j] + shape[j + 1:] == tuple(like)
                    and shape[j] <= MAX_CHANNELS]
            if len(fits) > 1:  # axes of one size: which is time cannot be known
                raise InputError(
                    f"{where} has shape {tuple(shape)} and its file does not name its axes: "
                    f"axis {fits[0]} or axis {fits[1]} could be its channels. Save it with its "
                    "axes named (an ImageJ hyperstack or an OME-TIFF, T C Y X), or one file "
                    "per channel")
            found: list[int | None] = [None] * ndim
            found[k] = _channel_index(channel, shape[k], where)
            return tuple(found)
    # No usable axis names: drop leading singleton axes until 3-D (4-D with keep_z).
    drop = [None] * ndim
    i = 0
    while ndim - i > max(sizes) and shape[i] == 1:
        drop[i] = 0
        i += 1
    if drop.count(None) not in sizes:
        raise InputError(
            f"{where} has shape {shape}; expected a 2-D image (Y, X) or a time-lapse (T, Y, X)"
            + (", a Z-stack (Z, Y, X) or a time-lapse of Z-stacks (T, Z, Y, X)" if keep_z
               else " (for 3-D objects say --axes zyx or tzyx)")
        )
    return tuple(drop)


def _scale(dataset: dict) -> list[float] | None:
    """The ``scale`` of an OME-Zarr dataset's coordinate transformations (None: none given);
    one that is not positive numbers is refused."""
    for t in dataset.get("coordinateTransformations") or ():
        if isinstance(t, dict) and t.get("type") == "scale":
            try:
                scale = [float(v) for v in t["scale"]]
            except (KeyError, TypeError, ValueError):
                scale = []
            if not scale or not all(np.isfinite(v) and v > 0 for v in scale):
                raise InputError(
                    f"the OME-Zarr level {dataset.get('path')!r} has the scale "
                    f"{t.get('scale')!r}, not positive numbers (one per axis); write the "
                    "store again")
            return scale
    return None


def _ome_level(path: Path, group: Any, multiscales: list) -> tuple[str, list[str] | None]:
    """The full-resolution level of an OME-Zarr image and its axis names, as its metadata
    declares them: the level of the finest ``scale`` along every axis (not the first listed),
    every declared level present, one image per group."""
    if not isinstance(multiscales, list) or not multiscales:
        raise InputError(f"{path}: its OME-Zarr 'multiscales' metadata is empty or not a list; "
                         "write the store again")
    if len(multiscales) > 1:
        names = ", ".join(str(m.get("name", i)) for i, m in enumerate(multiscales))
        raise InputError(
            f"{path} holds {len(multiscales)} OME-Zarr images ({names}) in one group; pfsdm "
            "reads one movie per store: save each image in a store of its own")
    first = multiscales[0]
    if not isinstance(first, dict):
        raise InputError(f"{path}: its OME-Zarr 'multiscales' entry is not a set of named "
                         "fields; write the store again")
    datasets = first.get("datasets") or []
    axes_meta = first.get("axes")
    axes = ([a["name"] if isinstance(a, dict) else str(a) for a in axes_meta]
            if axes_meta else None)
    if not datasets or not all(isinstance(d, dict) and "path" in d for d in datasets):
        raise InputError(f"{path}: its OME-Zarr metadata lists no levels (datasets with a "
                         "'path'); write the store again")
    shapes = []
    for d in datasets:
        try:
            shapes.append(tuple(int(n) for n in group[str(d["path"])].shape))
        except (KeyError, TypeError, ValueError):
            raise InputError(
                f"{path}: its OME-Zarr metadata declares the level {d['path']!r}, which is not "
                "in the store (a copy that lost files?); copy the store again") from None
    scales = [_scale(d) for d in datasets]
    if all(sc is not None for sc in scales):
        ndim = {len(sc) for sc in scales if sc is not None}
        finest = [i for i, sc in enumerate(scales)
                  if all(np.all(np.asarray(sc) <= np.asarray(o)) for o in scales)]
        if len(ndim) != 1 or not finest:
            raise InputError(
                f"{path}: the scales of its OME-Zarr levels ({scales}) name no level finer "
                "than all the others along every axis; write the store again")
        index = finest[0]
    else:  # no scales: the level with the most pixels along every axis
        finest = [i for i, sh in enumerate(shapes) if all(
            all(a >= b for a, b in zip(sh, o, strict=False)) for o in shapes)]
        index = finest[0] if finest else 0
    return str(datasets[index]["path"]), axes


def _open_zarr(path: Path, keep_z: bool = False, channel: int | None = None,
               like: tuple | None = None) -> _ZarrFrames:
    try:
        import zarr
    except ImportError as exc:
        raise InputError(
            f"reading {path} needs the zarr package: pip install zarr"
        ) from exc

    try:
        node = zarr.open(str(path), mode="r")
    except Exception as exc:  # zarr raises many kinds of errors on bad stores
        raise InputError(f"cannot open {path} as Zarr: {exc}") from exc
    component = ""
    axes = None
    if isinstance(node, zarr.Group):
        attrs = dict(node.attrs)
        ms = attrs.get("multiscales") or attrs.get("ome", {}).get("multiscales")
        if ms:
            component, axes = _ome_level(path, node, ms)
        else:
            arrays = sorted(name for name, _ in node.arrays())
            if len(arrays) != 1:
                raise InputError(
                    f"{path} is a Zarr group with arrays {arrays or 'none'} and no OME-Zarr "
                    "multiscales metadata; point to one array, e.g. "
                    f"{path / (arrays[0] if arrays else 'ARRAY')}"
                )
            component = arrays[0]
        arr = zarr.open_array(str(path), path=component, mode="r")
    else:
        arr = node
    if axes is None:
        dims = arr.metadata.dimension_names if hasattr(arr.metadata, "dimension_names") else None
        if dims and all(dims):
            axes = list(dims)
    shape = tuple(int(n) for n in arr.shape)
    drop = _drop_axes(shape, axes, str(path), keep_z, channel, like)
    out_shape = tuple(n for n, d in zip(shape, drop, strict=True) if d is None)
    frames = _ZarrFrames(str(path), component, out_shape, arr.dtype, drop)
    timed = len(out_shape) == 4 or (len(out_shape) == 3 and not keep_z)
    frames.chunks_t = int(arr.chunks[drop.index(None)]) if len(out_shape) >= 3 else 1
    frames.missing = missing_chunks(arr, path / component if component else path,
                                    drop.index(None) if timed else None)
    frames.fill_value = arr.fill_value
    return frames


#: What tifffile logs when a file is not what it declares (a truncated copy, a broken chain of
#: pages, metadata that does not fit the pages): such a file is refused, never read shorter.
_TIFF_DAMAGE = re.compile(
    r"invalid (page|value|tag) offset|corrupt|truncat|failed to (reshape|read)|"
    r"metadata invalid|invalid .*metadata", re.IGNORECASE)


class _TiffLog(logging.Handler):
    """Collects what tifffile logs (warnings and errors) while a file is opened."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


def _series_list(tif: Any) -> str:
    """The series of a TIFF in words: ``0: 16 x 16 x 3 (YXS), 1: 10 x 64 x 64 (QYX)``."""
    return ", ".join(f"{i}: {' x '.join(str(n) for n in s.shape)} ({s.axes})"
                     for i, s in enumerate(tif.series))


def _declared_images(tif: Any) -> int | None:
    """How many 2-D images the file's ImageJ metadata says it holds (``images``), None when
    it says nothing."""
    ij = tif.imagej_metadata if tif.is_imagej else None
    if ij and isinstance(ij.get("images"), int):
        return int(ij["images"])
    return None


def _tiff_codec(series: Any) -> str | None:
    """The decoder a TIFF series needs and this install lacks (tifffile's words), or None:
    found before any frame is read."""
    import tifffile

    try:
        page = series.keyframe
        if page is not None and int(page.compression) != 1:  # 1: not compressed
            tifffile.TIFF.DECOMPRESSORS[page.compression]
    except KeyError as exc:
        return _first_words(exc)
    except Exception:  # noqa: BLE001 - anything else is said when its pixels are read
        return None
    return None


def _tiff_damage(path: Path, tif: Any, series: Any, log: list[str]) -> str | None:
    """Why a TIFF is not what it declares (None: it is): tifffile's own complaints while
    reading its pages and series, data that lies beyond the end of the file, or fewer
    images than its ImageJ metadata declares."""
    bad = [m for m in log if _TIFF_DAMAGE.search(m)]
    if bad:
        first = bad[0].strip().splitlines()[0]
        return f"tifffile says: {first[:160]}"
    if int(np.prod(series.shape, dtype=np.int64)) == 0:
        return None  # no pixels at all: refused as such (check_labels)
    size = path.stat().st_size
    if series.dataoffset is not None:
        end = int(series.dataoffset) + int(series.nbytes)
        if end > size:
            return (f"its pixels need {end} bytes but the file has {size} (a copy cut short)")
    else:
        for page in series.pages:
            if page is None:
                return "one of its pages is missing"
            offsets = getattr(page, "dataoffsets", ()) or ()
            counts = getattr(page, "databytecounts", ()) or ()
            for off, n in zip(offsets, counts, strict=False):
                if int(off) + int(n) > size:
                    return (f"a page's pixels lie beyond the end of the file ({int(off) + int(n)}"
                            f" of {size} bytes: a copy cut short)")
    declared = _declared_images(tif)
    if declared is not None and len(tif.series) == 1:
        planes = int(np.prod([n for n, a in zip(series.shape, series.axes, strict=True)
                              if a not in "YXS"], dtype=np.int64))
        if planes != declared:
            return (f"its ImageJ metadata declares {declared} images but {planes} can be read")
    return None


def _open_tiff(path: Path, keep_z: bool = False, series: int | None = None,
               channel: int | None = None, like: tuple | None = None) -> _TiffFrames:
    """A TIFF's series as frames, after checking that the file holds what it declares
    (:func:`_tiff_damage`) and that the series to read is known."""
    with _TIFF_LOG_LOCK:  # the logger is shared: one opening at a time changes it
        return _open_tiff_logged(path, keep_z, series, channel, like)


#: Held while :func:`_open_tiff` listens to tifffile's logger.
_TIFF_LOG_LOCK = threading.Lock()


def _open_tiff_logged(path: Path, keep_z: bool, series: int | None, channel: int | None = None,
                      like: tuple | None = None) -> _TiffFrames:
    import tifffile

    handler = _TiffLog()
    logger = logging.getLogger("tifffile")
    level, propagate = logger.level, logger.propagate
    # tifffile's complaints come here only (the error below says them), whatever the level
    logger.setLevel(logging.WARNING)
    logger.propagate = False
    logger.addHandler(handler)
    try:
        with tifffile.TiffFile(str(path)) as tif:
            len(tif.pages)  # the whole chain of pages, so that a broken one is seen
            listing = _series_list(tif)
            n_series = len(tif.series)
            if series is None and n_series > 1:
                raise InputError(
                    f"{path} holds {n_series} image series ({listing}); pfsdm reads one "
                    "movie per file: say which with --series N (series=N in Python)")
            index = 0 if series is None else int(series)
            if not -n_series <= index < n_series:
                raise InputError(f"{path} has no series {index}: it holds {n_series} "
                                 f"({listing}); give --series from 0 to {n_series - 1}")
            index %= n_series
            chosen = tif.series[index]
            missing = _tiff_codec(chosen)
            if missing is not None:
                raise InputError(_codec_words(path, missing))
            shape = tuple(int(n) for n in chosen.shape)
            dtype = chosen.dtype
            axes = list(chosen.axes.lower())
            damage = _tiff_damage(path, tif, chosen, handler.messages)
    except InputError:
        raise
    except Exception as exc:
        raise InputError(f"cannot read {path} as TIFF: {exc}") from exc
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)
        logger.propagate = propagate
    if int(np.prod(shape, dtype=np.int64)) == 0:
        from ..analysis.label_images import refuse_zero_size

        refuse_zero_size(shape, str(path))
    if damage is not None:
        raise InputError(
            f"{path} is damaged or truncated: {damage}. It would be read as a shorter or "
            "wrong movie; copy or export it again")
    # tifffile names a plain stack of pages "q" / "i"; treat it as time. A (3 or 4, Y, X)
    # array saved without photometric="minisblack" is stored as planar RGB(A) ("syx"): these
    # planes are frames too, of labels and of a reporter (integer or float) alike. A colour
    # image is judged by its last axis (interleaved samples, "yxs"), never by its frames.
    generic = sum(a in ("q", "i") for a in axes)
    axes = ["t" if a in ("q", "i") else a for a in axes]
    if axes[0] == "s" and "t" not in axes:
        axes[0] = "t"
    # several unnamed axes (a plain 4-D stack is "QQYX"): the file names none of them, so the
    # user's --axes decides (no metadata to obey)
    drop = _drop_axes(shape, None if generic > 1 else axes, str(path), keep_z, channel, like)
    out_shape = tuple(n for n, d in zip(shape, drop, strict=True) if d is None)
    frames = _TiffFrames(str(path), index, out_shape, dtype, drop)
    frames.chunks_t = 1
    return frames


def open_movie(path: str | os.PathLike, *, frames_per_chunk: int | None = None,
               axes: str | None = None, series: int | None = None,
               channel: int | None = None, like: tuple | None = None) -> da.Array:
    """Open a TIFF or Zarr movie lazily as a dask array of shape (T, Y, X) or (Y, X); when
    ``axes`` names a z axis (``"zyx"``, ``"tzyx"``), also (Z, Y, X) or (T, Z, Y, X).

    Parameters
    ----------
    path : str or PathLike
        A ``.tif``/``.tiff`` file, a Zarr array, a Zarr group holding exactly one array, or a
        multiscale OME-Zarr image (its full-resolution level is used).
    frames_per_chunk : int, optional
        Frames per dask chunk (whole frames in Y and X). Default: the Zarr chunking along T,
        or 1 for TIFF.
    axes : str, optional
        ``"zyx"`` or ``"tzyx"`` for 3-D objects.
    series : int, optional
        Which image series of a TIFF to read (``tifffile.TiffFile.series``; negative counts
        from the end). A TIFF of several series (positions of an OME-TIFF, a thumbnail beside
        the image) is refused without it.
    channel, like : int and tuple, optional
        For a reporter: ``like`` is the shape of its labels (as opened); an image with one
        axis of channels more (named ``c`` by its metadata, or found by shape as the napari
        plugin finds it) is read at ``channel``, refused without it.

    Raises
    ------
    InputError
        The file is not what it declares (truncated, pages missing, levels or axes its
        metadata names but that cannot be obeyed), holds several series and ``series`` is
        not given, or is not a movie pfsdm reads.

    Returns
    -------
    dask.array.Array
        Nothing is read until the array (or a slice of it) is computed.
    """
    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: no such file or folder")
    keep_z = axes is not None and "z" in str(axes).lower()
    if is_zarr(p):
        frames: _Frames = _open_zarr(p, keep_z, channel, like)
    elif is_tiff(p):
        frames = _open_tiff(p, keep_z, series, channel, like)
    else:
        raise InputError(
            f"{p}: not a TIFF file (.tif/.tiff) or a Zarr store (.zarr folder); "
            "convert the movie to one of these"
        )
    if frames.ndim == 4 or (frames.ndim == 3 and not (keep_z and len(str(axes)) == 3)):
        k = frames_per_chunk or frames.chunks_t
        chunks: tuple = (max(1, min(k, frames.shape[0])), *frames.shape[1:])
    else:
        chunks = frames.shape
    from dask.base import tokenize

    name = "pfsdm-read-" + tokenize(str(p.resolve()), frames.identity, frames.shape)
    meta = np.empty((0,) * frames.ndim, dtype=frames.dtype)
    arr = da.from_array(frames, chunks=chunks, name=name, asarray=True, fancy=False, meta=meta)
    # lets the batch read a task's frames in one call (napari_pfsdm.batch.tasks._Reader)
    _SOURCES[arr.name] = frames
    return arr


#: The file reader behind each movie :func:`open_movie` made, by the dask array's name (its
#: graph's key); weakly: a reader lives as long as a graph that reads through it.
_SOURCES: weakref.WeakValueDictionary = weakref.WeakValueDictionary()


def movie_source(movie: Any):
    """The file reader behind a movie from :func:`open_movie` (its frames are read straight
    from the file, a task's frames in one call), or None for any other array (a slice of that
    movie included)."""
    name = getattr(movie, "name", None)
    return _SOURCES.get(name) if isinstance(name, str) else None


def missing_frames(movie: Any) -> dict[int, int]:
    """``{frame: missing chunk files}`` of a movie from :func:`open_movie` (Zarr only; empty
    for TIFF, numpy arrays and complete stores)."""
    return dict(getattr(movie_source(movie), "missing", None) or {})


def refuse_missing_chunks(movie: Any, where: str) -> None:
    """Raise, in plain words, when a Zarr movie lacks chunk files (:func:`missing_chunks`)."""
    missing = missing_frames(movie)
    if not missing:
        return
    frames = sorted(missing)
    shown = ", ".join(str(t) for t in frames[:10]) + (" …" if len(frames) > 10 else "")
    n = sum(missing.values())
    raise InputError(
        f"{where} misses {n} chunk file{'s' if n > 1 else ''} "
        f"(frame{'s' if len(frames) > 1 else ''} {shown}): Zarr would read "
        f"{'them' if len(frames) > 1 else 'it'} as the fill value, "
        "i.e. as empty, and the objects there would be lost without a word. Copy the store "
        "again completely; if those chunks were left out on purpose (Zarr does not write "
        "chunks that hold only background), pass --allow-missing-chunks "
        "(allow_missing_chunks=True) to read them as they are"
    )


def missing_warning(movie: Any, name: str) -> list[str]:
    """One warning line per frame of a movie read with missing chunk files."""
    fill = getattr(movie_source(movie), "fill_value", 0)
    return [f"warning: {name}: frame {t}: {n} chunk file{'s' if n > 1 else ''} missing, read "
            f"as the fill value ({fill})" for t, n in sorted(missing_frames(movie).items())]




def check_labels(labels: Any, intensity: Any = None, where: str = "labels",
                 axes: str | None = None, intensity_where: str | None = None) -> None:
    """Raise a plain-language ValueError if labels/intensity cannot be measured together."""
    dtype = np.dtype(labels.dtype)
    if not (np.issubdtype(dtype, np.integer) or dtype == np.bool_):
        raise InputError(
            f"{where} is not a label image (its pixels are {dtype}, not integers): give the "
            "segmentation (one integer id per object, 0 = background), not the raw image"
        )
    if axes is not None:
        if labels.ndim != len(axes):
            raise InputError(f"{where} has shape {tuple(labels.shape)}, {labels.ndim} "
                             f"dimensions, but the axes given are {axes!r} ({len(axes)})")
    elif labels.ndim not in (2, 3):
        raise InputError(
            f"{where} has shape {tuple(labels.shape)}; expected (Y, X) or (T, Y, X), or say "
            "which axes it has (--axes zyx or tzyx for 3-D objects)"
        )
    from ..analysis.label_images import refuse_not_labels, refuse_zero_size, resolve_axes

    refuse_zero_size(tuple(labels.shape), where)
    if intensity is not None and tuple(intensity.shape) != tuple(labels.shape):
        raise InputError(
            f"the labels {where} and the reporter {intensity_where or ''} have different "
            f"shapes, {tuple(labels.shape)} and {tuple(intensity.shape)}; they must be the "
            "same movie, frame for frame. Give the reporter recorded with these labels"
            + (" (one channel of it: --reporter-channel N)" if intensity.ndim == labels.ndim + 1
               else ""))
    refuse_not_labels(labels, resolve_axes(tuple(labels.shape), axes), where)
