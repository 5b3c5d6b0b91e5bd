"""Many movies measured into one table, resumably: a part file per finished movie.

:func:`run_batch` measures a list of movies (each with :func:`~.tasks.measure_dask`) into one
table with a ``movie`` column. It writes one part file per finished movie (Parquet when pyarrow
is installed, else CSV, each with a checked sidecar) into a parts folder next to the output
(:func:`default_parts_dir`); a re-run skips movies whose part exists (for the same data,
:func:`~napari_pfsdm.batch.fingerprint.data_fingerprint`, and options) and measures a damaged part
again, so a killed run loses at most the movie in progress. Movies whose names would share a
part are refused before any is measured; what a killed run left in the parts folder is
removed. The final table is written atomically, by one run at a time
(:func:`~napari_pfsdm.io.output_lock`), each movie's objects linked into tracks when asked.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..analysis.physical import add_times
from ..analysis.schedulers import (
    LOCAL_SCHEDULERS,
    check_workers,
    client_for,
    process_pool,
    resolve_scheduler,
)
from ..core.params import LINK_OPTION, PFSDMParams, as_params
from ..core.table_options import carry_options, plain, set_options, table_options
from ..core.table_schema import NO_TRACK, TRACK_COLUMN
from ..errors import InputError, RunFault
from ..io import (
    is_parquet,
    output_lock,
    read_table,
    remove_leftovers,
    require_pyarrow,
    sidecar_path,
    to_jsonable,
    write_table,
    written_by_pfsdm,
)
from ..io.metadata import read_metadata
from ..io.sidecar import is_pfsdm_sidecar
from .calibration import Calibration, calibrate
from .fingerprint import data_fingerprint
from .io import (
    check_labels,
    missing_frames,
    missing_warning,
    movie_source,
    open_movie,
    refuse_missing_chunks,
)
from .movies import Movie
from .tasks import environment_fault, measure_dask

__all__ = ["default_parts_dir", "rows_words", "run_batch"]


def _have_parquet() -> bool:
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        return False
    return True


def _part_name(movie: Movie, params: PFSDMParams, axes: str | None = None,
               spacing: Any = None, series: int | None = None,
               calibration: Calibration | None = None, channel: int | None = None) -> str:
    """Stable file name of a movie's part: its name plus a hash of its inputs' data
    (:func:`~napari_pfsdm.batch.fingerprint.data_fingerprint`) and of what is measured
    (:meth:`~napari_pfsdm.core.params.PFSDMParams.measured`: the options that leave objects
    out of shape spaces do not name a part, so changing them measures nothing again)."""
    def stamp(p: Path | None) -> Any:
        if p is None:
            return None
        p = Path(p).resolve()
        return [str(p), data_fingerprint(p)]  # a replaced or re-written movie: measured again

    key = json.dumps(
        [stamp(movie.labels), stamp(movie.intensity), to_jsonable(params.measured().record())]
        + ([axes, None if spacing is None else [float(v) for v in np.ravel(spacing)]]
           if axes is not None and "z" in axes else [])
        + ([["series", int(series)]] if series is not None else [])
        # the pixel size and its unit change the sizes measured (not the times: added later)
        + ([["pixel_size", list(calibration.pixel_size), calibration.space_unit]]
           if calibration is not None and calibration.pixel_size is not None else [])
        + ([["reporter_channel", int(channel)]] if channel is not None else []),
        sort_keys=True
    )
    digest = hashlib.sha1(key.encode()).hexdigest()[:10]
    safe = re.sub(r"[^\w.\-]+", "_", movie.name)[:80]
    return f"{safe}-{digest}"


def _write_part(table: pd.DataFrame, path: Path, options: dict) -> None:
    """Write a movie's part with its sidecar (the options, the part's size and SHA-256), each
    atomically through a temporary file of a unique name created exclusively in the parts
    folder (:func:`~napari_pfsdm.io.write_table`: no planted file or symbolic link is
    written through). The sidecar comes first: the part appearing marks the movie as done."""
    write_table(table, path, options, table_type="part")


def _read_part(path: Path) -> pd.DataFrame:
    """A movie's part as written by :func:`_write_part`, checked against its sidecar (the one
    reader of the package, :func:`napari_pfsdm.io.read_table`: exact floats, text
    columns as written); any mismatch with the sidecar is damage."""
    return read_table(path, strict=True)


def _resumed(part: Path, name: str, say: Callable[[str], None]) -> pd.DataFrame | None:
    """The table of a movie measured by an earlier run, or None when it must be measured: no
    part yet, or a damaged one (truncated, not matching its sidecar), which is removed."""
    side = sidecar_path(part)
    if not part.exists():
        if (side.exists() or side.is_symlink()) and not is_pfsdm_sidecar(side):
            raise InputError(
                f"{side} has the name of the sidecar of {name}'s saved part but pfsdm did not "
                "write it; nothing was changed. Move that file out of the parts folder, or "
                "give another folder with --parts")
        return None
    if not (sidecar_path(part).exists() or part.with_suffix(".json").is_file()
            or written_by_pfsdm(part)):  # a part pfsdm wrote has a sidecar, damaged or not
        raise InputError(
            f"{part} has the name of {name}'s saved part but pfsdm did not write it (it has "
            "no pfsdm sidecar); nothing was changed. Move that file out of the parts folder, "
            "or give another folder with --parts")
    try:
        table = _read_part(part)
    except Exception as exc:  # noqa: BLE001 - any reader's error: the part is not usable
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        say(f"{name}: its saved part {part.name} is damaged ({first[:160]}); measuring "
            f"{name} again")
        for f in (part, sidecar_path(part), part.with_suffix(".json")):
            with contextlib.suppress(OSError):
                f.unlink()
        return None
    say(f"skipped {name} (already measured: {part.name})")
    if not table_options(table):  # a part of an earlier version: options beside it
        old = part.with_suffix(".json")
        if old.exists():
            set_options(table, json.loads(old.read_text()))
    return table


def _link(table: pd.DataFrame, lab: Any, how: str, name: str,
          say: Callable[[str], None]) -> tuple[pd.DataFrame, str]:
    """Check and link one movie's table (see :func:`run_batch`'s ``link``)."""
    from ..analysis.tracking import link_movie

    source = movie_source(lab)  # read frames straight from the file
    source = lab if source is None else source
    if len(lab.shape) == 2:  # one frame
        source = np.asarray(source[:])[None]
    out, check, used = link_movie(table, source, how)
    out = carry_options(table, out)
    if used:
        n = out.loc[out[TRACK_COLUMN] >= 0, TRACK_COLUMN].nunique()
        why = check.message.split(". Link")[0] if not check.tracked else check.message
        say(f"{name}: {why}; linked by {used}: {n} tracks in the track_id column")
    elif how != "labels" and check.verdict == "tracked":
        say(f"{name}: {check.message}: track_id = label")
    return out, used


def default_parts_dir(output: str | os.PathLike) -> Path:
    """Where :func:`run_batch` keeps per-movie parts for ``output``: ``<output>.parts/``."""
    output = Path(output)
    return output.with_name(output.name + ".parts")


def _batch_pool(num_workers: int | None) -> Any:
    """The worker processes of a batch on the ``"processes"`` scheduler
    (:func:`~napari_pfsdm.analysis.schedulers.process_pool`), a failed start in plain words."""
    try:
        return process_pool(num_workers)
    except Exception as exc:  # noqa: BLE001 - the machine's fault, or re-raised
        fault = environment_fault(exc, "this machine")
        if fault is None:
            raise
        raise fault from exc


def run_batch(
    movies: Sequence[Movie],
    output: str | os.PathLike,
    *,
    client: Any = None,
    scheduler: Any = None,
    num_workers: int | None = None,
    frames_per_task: int | None = None,
    parts_dir: str | os.PathLike | None = None,
    progress: Progress | None = None,
    log: Callable[[str], None] | None = None,
    allow_empty: bool = True,
    params: PFSDMParams | None = None,
    link: str = "labels",
    axes: str | None = None,
    spacing: Any = None,
    allow_missing_chunks: bool = False,
    series: int | None = None,
    times: Any = None,
    time_unit: str | None = None,
    pixel_size: Any = None,
    space_unit: str | None = None,
    reporter_channel: int | None = None,
    **options: Any,
) -> pd.DataFrame:
    """Measure many movies into one CSV with a ``movie`` column, resumably.

    Parameters
    ----------
    movies : sequence of Movie
        From :func:`napari_pfsdm.batch.movies.pair_movies`.
    output : str or PathLike
        Final CSV (written atomically, with the options in its ``.csv.json`` sidecar).
    client, scheduler, num_workers, frames_per_task
        As in :func:`measure_dask`.
    parts_dir : str or PathLike, optional
        Folder of per-movie parts (default ``<output>.parts``). A movie whose part is there
        (the same files, unchanged: size, modification time and inode; the same options) is
        not measured again.
    progress : callable, optional
        ``progress(stage, done, total, what)`` from the start of the run, over every movie:
        ``"checking"`` (movies opened and checked, ``what`` the movie), then ``"measuring"``
        (frames measured of every movie not measured before, ``what`` the movie, or what
        the run waits for).
    log : callable, optional
        Receives one-line messages (e.g. ``"skipped movie01 (already measured)"``).
    allow_empty : bool
        When False, labels without any object raise ``ValueError`` and no table is written
        (all-background labels are usually the wrong file).
    params : PFSDMParams, optional
        The method's options as one record.
    link : {"labels", "auto", "centroid", "overlap", "laptrack"}
        Link each movie's objects into tracks (a ``track_id`` column) with
        :func:`napari_pfsdm.analysis.tracking.link_movie`: ``"auto"`` links (by overlap of the
        labels) only the movies whose label ids do not follow objects, and gives the others
        ``track_id = label``; the column is left out when no movie needed linking. ``log``
        says what was found and done for each movie. The parts stay unlinked, so a re-run
        with another ``link`` measures nothing again.
    axes, spacing
        As :func:`napari_pfsdm.measure`, for every movie (``"zyx"``/``"tzyx"``: 3-D objects).
    allow_missing_chunks : bool
        A Zarr movie whose chunk files are not all on disk stops the run before any work
        (its missing frames would read as empty); True measures it as it is, ``log`` warns
        once per such frame and the sidecar lists them (``missing_chunks``).
    series : int, optional
        The image series read from every TIFF (:func:`~napari_pfsdm.batch.io.open_movie`);
        a TIFF of several series is refused without it.
    times : sequence of float, or {movie: {frame: time}}, optional
        The frames' times (the same for every movie, or per movie as
        :func:`~napari_pfsdm.batch.calibration.read_times_file` reads them); without them,
        each movie's file's own (ImageJ, OME), else none. The table gets a ``time`` column.
    time_unit : str, optional
        Their unit; files' times are converted to it.
    pixel_size : float or sequence of float, optional
        The pixel size of every movie; without it, each file's own (ImageJ, OME, TIFF
        resolution), else sizes stay in pixels.
    space_unit : str, optional
        Its unit (µm when not given); files' pixel sizes are converted to it.
    reporter_channel : int, optional
        The channel read from reporters of several channels (an axis more than their labels,
        named ``c`` or found by shape, as the napari plugin offers them); such a reporter is
        refused without it.
    **options
        Or the options as keywords, as :func:`napari_pfsdm.measure` takes them.

    Returns
    -------
    pandas.DataFrame
        The concatenated table (also written to ``output``). Its sidecar lists, per movie,
        the frames without any object (``empty_frames``) and those read with missing chunk
        files (``missing_chunks``); ``log`` names them too.
    """
    output = Path(output)
    out_dir = output.parent if str(output.parent) else Path(".")
    if not out_dir.is_dir():
        raise InputError(f"cannot write {output}: the folder {out_dir} does not exist")
    if not os.access(out_dir, os.W_OK):
        raise InputError(f"cannot write {output}: the folder {out_dir} is not writable")
    p = as_params(params, options)  # a bad option fails here, before any movie is read
    link = LINK_OPTION.check(link)
    if client is None and (scheduler is None or scheduler in LOCAL_SCHEDULERS):
        check_workers(num_workers, "num_workers")  # this machine's cores, at most
    _refuse_collisions(movies)
    if is_parquet(output) and output.suffix.lower() == ".parquet":
        require_pyarrow(output, "writing")  # a missing package fails here, not after measuring
    with output_lock(output):  # one run at a time per output; a second one refuses
        return _run_batch_locked(
            movies, output, p, client=client, scheduler=scheduler, num_workers=num_workers,
            frames_per_task=frames_per_task, parts_dir=parts_dir, progress=progress,
            say=log or (lambda msg: None), allow_empty=allow_empty, link=link, axes=axes,
            spacing=spacing, allow_missing_chunks=allow_missing_chunks, series=series,
            units={"times": times, "time_unit": time_unit, "pixel_size": pixel_size,
                   "space_unit": space_unit}, reporter_channel=reporter_channel)


def _refuse_collisions(movies: Sequence[Movie]) -> None:
    """One name, one movie: refuse two movies of one name, or one label file twice (their
    rows would be merged under one name, or doubled)."""
    names: dict[str, Movie] = {}
    files: dict[Path, Movie] = {}
    for m in movies:
        if m.name in names:
            raise InputError(
                f"two movies are named {m.name!r} ({names[m.name].labels} and {m.labels}): "
                "their rows could not be told apart in the table; give them different names")
        key = Path(m.labels).resolve()
        if key in files:
            raise InputError(
                f"the label movie {m.labels} is given twice (as {files[key].name!r} and "
                f"{m.name!r}): its objects would be counted twice; give each movie once")
        names[m.name] = m
        files[key] = m


#: Temporary files a killed run may leave in a parts folder: those of
#: :func:`~napari_pfsdm.io.atomic_write` and the fixed names of earlier versions, for a
#: part's name only (``movie-0123456789.parquet``, :func:`_part_name`): a user's own file in a
#: folder given as ``--parts`` is never removed.
_PART_TEMP = re.compile(
    r"\..+-[0-9a-f]{10}\.(?:parquet|csv)(?:\.json)?(?:\.[a-z0-9_]{8})?\.tmp")


def _remove_part_leftovers(parts: Path) -> None:
    """Remove the temporary part files of a killed run (holding the output's lock)."""
    for entry in os.scandir(parts):
        if _PART_TEMP.fullmatch(entry.name) and not entry.is_dir(follow_symlinks=False):
            with contextlib.suppress(OSError):
                os.unlink(entry.path)


def _run_batch_locked(
    movies: Sequence[Movie], output: Path, p: PFSDMParams, *, client: Any, scheduler: Any,
    num_workers: int | None, frames_per_task: int | None,
    parts_dir: str | os.PathLike | None, progress: Progress | None,
    say: Callable[[str], None], allow_empty: bool, link: str, axes: str | None,
    spacing: Any, allow_missing_chunks: bool, series: int | None = None,
    units: dict | None = None,
    reporter_channel: int | None = None,
) -> pd.DataFrame:
    """:func:`run_batch`'s work, holding the output's lock: open and check every movie, find
    their times and pixel sizes, measure those without a part, put the table together."""
    remove_leftovers(output)
    parts = Path(parts_dir) if parts_dir is not None else default_parts_dir(output)
    parts.mkdir(parents=True, exist_ok=True)
    _remove_part_leftovers(parts)
    suffix = ".parquet" if _have_parquet() else ".csv"
    progress = progress or (lambda *a: None)

    opened = _open_movies(movies, frames_per_task, axes, series, allow_missing_chunks,
                          progress, reporter_channel)
    missing = _missing_chunks(opened, say)
    cal = _calibrations(opened, axes, series, units or {}, say)
    plan = [(m, lab, img, parts / (_part_name(m, p, axes, spacing, series, cal[m.name],
                                             reporter_channel) + suffix))
            for m, lab, img in opened]
    total = sum(_n_frames(lab, axes) for _, lab, _, part in plan if not part.exists())
    done = 0
    progress("measuring", 0, total, "")
    kind, obj = resolve_scheduler(scheduler, client)
    tables, attrs, methods, empty = [], {}, {}, {}
    with contextlib.ExitStack() as kept, client_for(kind, obj) as cl:
        pool = None
        for m, lab, img, part in plan:
            table = _resumed(part, m.name, say)
            if table is None:
                if kind == "local" and obj == "processes" and pool is None:
                    # started for the first movie to measure, kept for the others
                    progress("measuring", done, total, "starting the worker processes")
                    pool = kept.enter_context(_batch_pool(num_workers))

                def _prog(frames: int, n: int, _name: str = m.name, _at: int = done) -> None:
                    progress("measuring", _at + frames, total, _name)

                with warnings.catch_warnings(), _naming(m.labels):  # chunks: said above
                    warnings.filterwarnings("ignore", ".*chunk files? missing", UserWarning)
                    table = measure_dask(
                        lab, img, client=cl if kind != "local" else None,
                        scheduler=obj if kind == "local" else None, num_workers=num_workers,
                        frames_per_task=frames_per_task, progress=_prog, pool=pool,
                        params=p.measured(), axes=axes, spacing=spacing,
                        pixel_size=cal[m.name].pixel_size, space_unit=cal[m.name].space_unit,
                        allow_missing_chunks=True,  # checked above, with the user's word
                    )
                done += _n_frames(lab, axes)
                table = table.copy()
                table.insert(0, "movie", m.name)
                _write_part(table, part, to_jsonable(table_options(table) or {}))
                say(f"measured {m.name}: {rows_words(table)}")
            attrs = attrs or to_jsonable(table_options(table) or {})
            empty[m.name] = _empty_frames(table, lab, axes)
            if empty[m.name]:
                shown = ", ".join(str(t) for t in empty[m.name])
                say(f"{m.name}: no objects in frame{'s' if len(empty[m.name]) > 1 else ''} "
                    f"{shown} (of {_n_frames(lab, axes)})")
            if cal[m.name].times is not None and len(table):
                table = add_times(table, cal[m.name].times, cal[m.name].time_unit)
            if link != "labels" and len(table):
                table, used = _link(table, lab, link, m.name, say)
                methods[m.name] = used or "labels"
            tables.append(table)
    progress("measuring", total, total, "")
    result = _joined(tables, link, any(v != "labels" for v in methods.values()))
    attrs = _table_record(attrs or p.record(3 if axes and "z" in axes else 2), p, cal)
    if len(result) == 0 and not allow_empty:
        names = ", ".join(str(m.labels) for m in movies[:3]) + (" …" if len(movies) > 3 else "")
        raise InputError(
            f"no objects: {names} hold{'s' if len(movies) == 1 else ''} only background (0) "
            "in every frame, so nothing was written. Check that these are the segmentation "
            "(labels), or pass --allow-empty to write an empty table"
        )
    set_options(result, attrs)
    extra = {"empty_frames": {k: v for k, v in empty.items() if v},
             "missing_chunks": missing, "link": link,
             "linked": {k: v for k, v in methods.items() if v != "labels"},
             "calibration": {k: c.source for k, c in cal.items() if c.source}}
    write_table(result, output, attrs, table_type="features", extra=extra)
    return result


#: ``progress(stage, done, total, what)``: ``"checking"`` (movies opened and checked) then
#: ``"measuring"`` (frames measured, over every movie to measure; ``what``: the movie, or
#: what the run waits for).
Progress = Callable[[str, int, int, str], None]


def rows_words(table: pd.DataFrame) -> str:
    """What a table's rows count, in words: ``"24 objects in 11 frames (263 rows)"`` (an
    object is its label in each movie, not yet followed through time)."""
    if not len(table):
        return "no objects"
    keys = [c for c in ("movie", "label") if c in table.columns]
    n_objects = len(table[keys].drop_duplicates()) if keys else len(table)
    n_frames = table["frame"].nunique() if "frame" in table.columns else 1
    if n_frames == 1 and n_objects == len(table):
        return f"{n_objects} object{'s' if n_objects != 1 else ''}"
    return (f"{n_objects} object{'s' if n_objects != 1 else ''} in {n_frames} "
            f"frame{'s' if n_frames != 1 else ''} ({len(table):,} rows: one per object and "
            "frame)")


def _open_movies(movies: Sequence[Movie], frames_per_task: int | None, axes: str | None,
                 series: int | None, allow_missing_chunks: bool, progress: Progress,
                 reporter_channel: int | None = None) -> list[tuple[Movie, Any, Any]]:
    """Open and check every movie first: a bad file fails the run before any long work."""
    opened = []
    for i, m in enumerate(movies):
        progress("checking", i, len(movies), m.name)
        lab = open_movie(m.labels, frames_per_chunk=frames_per_task, axes=axes, series=series)
        img = open_movie(m.intensity, frames_per_chunk=frames_per_task, axes=axes,
                         series=series, channel=reporter_channel,
                         like=tuple(lab.shape)) if m.intensity else None
        check_labels(lab, img, where=str(m.labels), axes=axes,
                     intensity_where=str(m.intensity) if m.intensity else None)
        if img is not None and tuple(img.shape) != tuple(lab.shape):  # pragma: no cover
            raise InputError(f"{m.labels} and {m.intensity} have different shapes")
        for movie, path in ((lab, m.labels), (img, m.intensity)):
            if movie is not None and not allow_missing_chunks:
                refuse_missing_chunks(movie, str(path))
        opened.append((m, lab, img))
    progress("checking", len(movies), len(movies), "")
    return opened


def _calibrations(opened: list[tuple], axes: str | None, series: int | None, units: dict,
                  say: Callable[[str], None]) -> dict[str, Calibration]:
    """Each movie's times and pixel size (:func:`~.calibration.calibrate`): as given in
    ``units`` (``times``, ``time_unit``, ``pixel_size``, ``space_unit``), else as its file
    declares."""
    from .movies import match_name

    volume = bool(axes) and "z" in axes
    found = [(m.name, _n_frames(lab, axes),
              read_metadata(m.labels, _n_frames(lab, axes), series=series, volume=volume))
             for m, lab, _ in opened]
    cal = calibrate(found, times=units.get("times"), time_unit_given=units.get("time_unit"),
                    pixel_size=units.get("pixel_size"),
                    space_unit_given=units.get("space_unit"), volume=volume,
                    match=match_name, say=say)
    for name, c in cal.items():
        if c.source:
            say(f"{name}: {c.source}")
    return cal


def _joined(tables: list[pd.DataFrame], link: str, linked: bool) -> pd.DataFrame:
    """The movies' tables as one."""
    tables = [plain(t) for t in tables]
    if link == "auto" and not linked:  # every movie was tracked: its labels are the ids
        tables = [t.drop(columns=[TRACK_COLUMN], errors="ignore") for t in tables]
    result = pd.concat(tables, ignore_index=True) if tables else pd.DataFrame()
    if TRACK_COLUMN in result.columns:  # a movie without objects has none
        result[TRACK_COLUMN] = result[TRACK_COLUMN].fillna(NO_TRACK).astype(np.int64)
    return result


def _table_record(attrs: dict, p: PFSDMParams, cal: dict[str, Calibration]) -> dict:
    """The joined table's record: what was measured, this run's leave-out options (the parts
    hold what was measured), the units of its times and sizes, each movie's pixel size."""
    attrs = {k: v for k, v in attrs.items() if k not in ("pixel_size", "space_unit",
                                                         "time_unit", "pixel_sizes")}
    attrs.update(p.leave_out())
    sizes = {n: list(c.pixel_size) for n, c in cal.items() if c.pixel_size is not None}
    if sizes:
        attrs["space_unit"] = next(c.space_unit for c in cal.values() if c.space_unit)
        attrs["pixel_sizes"] = sizes
        if len({tuple(v) for v in sizes.values()}) == 1:
            attrs["pixel_size"] = next(iter(sizes.values()))
    units = {c.time_unit for c in cal.values() if c.times is not None}
    if any(c.times is not None for c in cal.values()):
        attrs["time_unit"] = units.pop() if units else None
    return attrs


@contextlib.contextmanager
def _naming(path: Any):
    """The user's errors met while measuring a movie name its file (a frame's negative ids,
    say, that the checks before the run did not look at)."""
    try:
        yield
    except InputError as exc:
        if str(path) in str(exc) or isinstance(exc, RunFault):
            raise
        raise InputError(f"{path}: {exc}") from exc


def _n_frames(movie: Any, axes: str | None) -> int:
    """Frames of a movie: its first axis when that is time, else 1."""
    from ..analysis.label_images import resolve_axes

    timed = resolve_axes(tuple(movie.shape), axes).startswith("t")
    return int(movie.shape[0]) if timed else 1


def _empty_frames(table: pd.DataFrame, movie: Any, axes: str | None) -> list[int]:
    """The frames of ``movie`` that have no row (no object at all) in its ``table``."""
    have = set(table["frame"].astype(int).tolist()) if "frame" in table.columns else set()
    return [t for t in range(_n_frames(movie, axes)) if t not in have]


def _missing_chunks(opened: list[tuple], say: Callable[[str], None]) -> dict[str, dict]:
    """Warn once per frame read with missing chunk files; ``{movie: {frame: count}}``."""
    out: dict[str, dict] = {}
    for m, lab, img in opened:
        counts: dict[str, int] = {}
        for movie in (lab, img):
            if movie is None:
                continue
            for line in missing_warning(movie, m.name):
                say(line)
            for t, n in missing_frames(movie).items():
                counts[str(t)] = counts.get(str(t), 0) + n
        if counts:
            out[m.name] = dict(sorted(counts.items(), key=lambda kv: int(kv[0])))
    return out
