"""Physical units of a table's sizes and times: their names as files and people write them,
and the factors between them.

A movie's metadata writes a micrometre as ``µm``, ``um``, ``micron`` or ``microns`` and a
minute as ``min`` or ``minutes``; :func:`space_unit` and :func:`time_unit` give each its one
name (``µm``, ``min``) and its size in the base unit (1 µm; 1 s), so that tables of movies
written by different software or microscopes share one unit. Pure Python.

Examples
--------
>>> space_unit("micron"), space_unit("nm")
(('µm', 1.0), ('nm', 0.001))
>>> convert_length(2.0, "mm", "µm"), convert_time(36.0, "h", "day")
(2000.0, 1.5)
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from ..errors import InputError

__all__ = ["LENGTHS", "TIMES", "check_pixel_size", "check_times", "convert_length",
           "convert_time", "space_unit", "time_unit"]

#: Length units: their one name, their size in µm, and how they are also written.
LENGTHS: dict[str, tuple[float, tuple[str, ...]]] = {
    "nm": (1e-3, ("nanometer", "nanometers", "nanometre", "nanometres")),
    "µm": (1.0, ("um", "μm", "micron", "microns", "micrometer", "micrometers", "micrometre",
                 "micrometres", "\u03bcm")),
    "mm": (1e3, ("millimeter", "millimeters", "millimetre", "millimetres")),
    "cm": (1e4, ("centimeter", "centimeters", "centimetre", "centimetres")),
    "m": (1e6, ("meter", "meters", "metre", "metres")),
}
#: Time units: their one name, their size in seconds, and how they are also written.
TIMES: dict[str, tuple[float, tuple[str, ...]]] = {
    "ms": (1e-3, ("millisecond", "milliseconds", "msec")),
    "s": (1.0, ("sec", "secs", "second", "seconds")),
    "min": (60.0, ("mins", "minute", "minutes")),
    "h": (3600.0, ("hr", "hrs", "hour", "hours")),
    "day": (86400.0, ("d", "days")),
}


def _lookup(table: dict[str, tuple[float, tuple[str, ...]]], text: str, what: str,
            example: str) -> tuple[str, float]:
    word = str(text).strip()
    for name, (size, others) in table.items():
        if word == name or word.lower() in (name.lower(), *(o.lower() for o in others)):
            return name, size
    known = ", ".join(table)
    raise InputError(f"{what} {text!r} is not one napari-pfsdm knows; use one of {known} "
                     f"(e.g. {example})")


def space_unit(text: str) -> tuple[str, float]:
    """(its one name, its size in µm) of a length unit written as ``text``; an unknown one is
    refused in words (:class:`~napari_pfsdm.errors.InputError`)."""
    return _lookup(LENGTHS, text, "the length unit", "--space-unit um")


def time_unit(text: str) -> tuple[str, float]:
    """(its one name, its size in seconds) of a time unit written as ``text``."""
    return _lookup(TIMES, text, "the time unit", "--time-unit day")


def convert_length(value: float, unit: str, to: str) -> float:
    """``value`` in length unit ``unit``, in unit ``to``."""
    return float(value) * space_unit(unit)[1] / space_unit(to)[1]


def convert_time(value: float, unit: str, to: str) -> float:
    """``value`` in time unit ``unit``, in unit ``to``."""
    return float(value) * time_unit(unit)[1] / time_unit(to)[1]


def check_pixel_size(value, ndim: int = 2) -> tuple[float, ...]:
    """A pixel size as one positive finite number per spatial axis (``ndim`` of them; one
    number stands for all), from 10⁻⁶ to 10⁶, refused in words otherwise. A 2-D pixel must be
    square: the shape features assume it (an anisotropic one is refused).

    Examples
    --------
    >>> check_pixel_size(0.65), check_pixel_size([2, 0.5, 0.5], 3)
    ((0.65, 0.65), (2.0, 0.5, 0.5))
    """
    try:
        values = [float(v) for v in (value if isinstance(value, Sequence) and not
                                     isinstance(value, str) else [value])]
    except (TypeError, ValueError):
        values = []
    if len(values) == 1:
        values = values * ndim
    if len(values) != ndim or not all(math.isfinite(v) and 1e-6 <= v <= 1e6 for v in values):
        raise InputError(
            f"the pixel size must be {'one number or ' if ndim == 2 else ''}{ndim} positive "
            f"numbers from 1e-06 to 1e+06 (one per axis{', Z Y X' if ndim == 3 else ''}); got "
            f"{value!r}")
    if ndim == 2 and values[0] != values[1]:
        raise InputError(
            f"the pixel size {tuple(values)} is not square: napari-pfsdm's shape features "
            "assume square pixels; resample the images to square pixels first")
    return tuple(values)


def check_times(times, n_frames: int | None = None) -> tuple[float, ...]:
    """The frames' times as finite numbers that never decrease (two frames may share a time:
    a day imaged twice), one per frame when ``n_frames`` is given; refused in words otherwise.

    Examples
    --------
    >>> check_times([2, 5, 8, 10, 12, 12, 16], 7)
    (2.0, 5.0, 8.0, 10.0, 12.0, 12.0, 16.0)
    """
    try:
        values = tuple(float(t) for t in times)
    except (TypeError, ValueError):
        raise InputError(f"the times must be numbers, one per frame; got {times!r}") from None
    if n_frames is not None and len(values) != n_frames:
        raise InputError(
            f"{len(values)} time{'s' if len(values) != 1 else ''} given for a movie of "
            f"{n_frames} frame{'s' if n_frames != 1 else ''}: give one time per frame")
    if not all(math.isfinite(t) for t in values):
        raise InputError(f"the times must be finite numbers; got {list(times)!r}")
    back = [i for i in range(1, len(values)) if values[i] < values[i - 1]]
    if back:
        i = back[0]
        raise InputError(
            f"the times go back: frame {i} is at {values[i]:g} after frame {i - 1} at "
            f"{values[i - 1]:g}; give the frames' times in frame order")
    return values
