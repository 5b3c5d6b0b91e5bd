"""Each movie's times and pixel size for a batch: as the user gave them, else as its file
declares them (:mod:`.metadata`), in one time unit and one length unit for the whole table.

Given values win over the files' (a note says where they differ); a batch where some movies
have times or a pixel size and others none is refused, naming them, because one column would
then mix frames with days, or pixels with micrometres.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from ..core.units import (
    check_pixel_size,
    check_times,
    convert_length,
    convert_time,
    space_unit,
    time_unit,
)
from ..errors import InputError
from ..io.metadata import MovieMetadata
from ..io.times_file import read_times_file

__all__ = ["Calibration", "calibrate", "read_times_file"]


@dataclass(frozen=True)
class Calibration:
    """One movie's times and pixel size, in the batch's units (None: not known).

    Attributes
    ----------
    times : tuple of float or None
    time_unit : str or None
    pixel_size : tuple of float or None
        (Y, X), or (Z, Y, X) for Z-stacks.
    space_unit : str or None
    source : str
        Where they came from, in words (for the log and the sidecar).
    """

    times: tuple[float, ...] | None
    time_unit: str | None
    pixel_size: tuple[float, ...] | None
    space_unit: str | None
    source: str


def _given_times(name: str, n_frames: int, times: Any,
                 match: Callable[[str, Sequence[str]], str | None]) -> tuple[float, ...]:
    """The times given for movie ``name``: the same list for every movie, or its entry of a
    times file (``{movie: {frame: time}}``)."""
    if not isinstance(times, Mapping):
        return check_times(times, n_frames)
    key = match(name, list(times))
    if key is None:
        shown = ", ".join(sorted(times)[:5])
        raise InputError(f"the times file names no movie {name!r} (it names {shown}"
                         f"{' …' if len(times) > 5 else ''}): give every movie's frames")
    by_frame = times[key]
    absent = [t for t in range(n_frames) if t not in by_frame]
    if absent:
        raise InputError(f"the times file has no time for frame {absent[0]} of {name} "
                         f"({n_frames} frames): give one per frame")
    return check_times([by_frame[t] for t in range(n_frames)], n_frames)


def calibrate(
    movies: Sequence[tuple[str, int, MovieMetadata]], *, times: Any = None,
    time_unit_given: str | None = None, pixel_size: Any = None,
    space_unit_given: str | None = None, volume: bool = False,
    match: Callable[[str, Sequence[str]], str | None] | None = None,
    say: Callable[[str], None] = lambda m: None,
) -> dict[str, Calibration]:
    """Each movie's :class:`Calibration`.

    Parameters
    ----------
    movies : sequence of (name, frames, MovieMetadata)
    times : sequence of float, or {movie: {frame: time}}, optional
        Given times: one list for every movie, or per movie (:func:`read_times_file`).
    time_unit_given, space_unit_given : str, optional
        The units of the given values, and the table's; the files' values are converted to
        them. Without them, the first movie's unit is the table's.
    pixel_size : float or sequence, optional
        Given for every movie (µm when no unit is given).
    volume : bool
        Z-stacks: the pixel size is Z, Y, X.
    match : callable(name, names) -> name or None
        Finds a movie's entry in a times file (default: the same name).
    say : callable
        Receives notes (given values that differ from a file's).
    """
    match = match or (lambda n, names: n if n in names else None)
    t_unit = time_unit(time_unit_given)[0] if time_unit_given else None
    s_unit = space_unit(space_unit_given)[0] if space_unit_given else None
    if pixel_size is not None:
        pixel_size = check_pixel_size(pixel_size, 3 if volume else 2)
        s_unit = s_unit or "µm"
    if s_unit is not None and pixel_size is None and not any(m.pixel_size for _, _, m in movies):
        raise InputError(f"--space-unit {space_unit_given} was given without a pixel size, "
                         "and no movie's file declares one: give --pixel-size too")
    if t_unit is not None and times is None and not any(m.times for _, _, m in movies):
        raise InputError(f"--time-unit {time_unit_given} was given without times, and no "
                         "movie's file declares them: give --times too")
    _refuse_partial("times", [(n, m.times) for n, _, m in movies], times is not None,
                    "--times 2,5,8 (every movie) or --times times.csv (movie, frame, time)")
    _refuse_partial("pixel size", [(n, m.pixel_size) for n, _, m in movies],
                    pixel_size is not None, "--pixel-size 0.65 --space-unit um")
    out: dict[str, Calibration] = {}
    for name, n_frames, meta in movies:
        words = []
        if times is not None:
            frame_times = _given_times(name, n_frames, times, match)
            words.append("times given")
            if meta.times and t_unit and meta.time_unit and any(
                    abs(convert_time(a, meta.time_unit, t_unit) - b) > 1e-9 * max(1, abs(b))
                    for a, b in zip(meta.times, frame_times, strict=False)):
                say(f"{name}: the times given differ from those its file declares "
                    f"({meta.source}); the given ones are used")
        elif meta.times:
            t_unit = t_unit or meta.time_unit
            frame_times = tuple(convert_time(v, meta.time_unit, t_unit) for v in meta.times)
            words.append(f"times from {meta.source}")
        else:
            frame_times = None
        if pixel_size is not None:
            size = pixel_size
            words.append("pixel size given")
        elif meta.pixel_size:
            s_unit = s_unit or meta.space_unit
            size = tuple(convert_length(v, meta.space_unit, s_unit) for v in meta.pixel_size)
            words.append(f"pixel size from {meta.source}")
        else:
            size = None
        out[name] = Calibration(frame_times, t_unit if frame_times else None, size,
                                s_unit if size else None, "; ".join(words))
    return out


def _refuse_partial(what: str, values: list[tuple[str, Any]], given: bool, example: str
                    ) -> None:
    """Refuse a batch where some movies' files declare ``what`` and others do not, unless it
    is given for all."""
    if given:
        return
    have = [n for n, v in values if v]
    lack = [n for n, v in values if not v]
    if have and lack:
        raise InputError(
            f"{len(have)} movie(s) declare their {what} ({', '.join(have[:3])}"
            f"{' …' if len(have) > 3 else ''}) but {len(lack)} do not ({', '.join(lack[:3])}"
            f"{' …' if len(lack) > 3 else ''}): one table cannot mix them. Give it for every "
            f"movie, e.g. {example}")
