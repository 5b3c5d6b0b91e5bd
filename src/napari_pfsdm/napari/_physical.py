"""A layer's pixel size and its frames' times, as the panels offer them.

napari keeps a layer's pixel size as its ``scale`` (one number per axis) and its unit as its
``units`` (``pixel`` when nothing is known); the plugin's reader sets both, and the frames'
times (``metadata["times"]``, ``metadata["time_unit"]``), from what the file declares
(:func:`napari_pfsdm.io.metadata.read_metadata`). These functions turn them into what
:func:`napari_pfsdm.measure` takes (``pixel_size``, ``space_unit``, ``times``, ``time_unit``).
No Qt here.
"""

from __future__ import annotations

import re
from typing import Any

from ..core.units import LENGTHS, TIMES, space_unit, time_unit
from ..errors import InputError

__all__ = ["PIXELS", "SPACE_UNITS", "TIME_UNITS", "layer_pixel_size", "parse_numbers",
           "physical_options", "times_text"]

#: The space unit of a layer whose sizes are in pixels.
PIXELS = "pixels"
#: The space units offered: pixels, then :data:`~napari_pfsdm.core.units.LENGTHS`' names.
SPACE_UNITS = (PIXELS, *LENGTHS)
#: The time units offered: frames (no time), then :data:`~napari_pfsdm.core.units.TIMES`'.
TIME_UNITS = ("", *TIMES)
#: The fields' tooltips.
TIPS = {
    "pixel_size": "The size of a pixel (or of a voxel: Z, Y, X), from the layer's scale: the "
                  "areas, lengths and widths are then in its unit (µm², µm). 'pixels' keeps "
                  "them in pixels. A scale without a unit is taken to be in µm: change it "
                  "here if it is not.",
    "times": "Each frame's time, in frame order (e.g. 2, 5, 8, 10, 12, 12 for uneven days, "
             "a day imaged twice): the plots then put time on their axis, and the table "
             "gets a 'time' column. Blank: frames. Filled from the file when it says.",
}


def layer_pixel_size(layer, n_axes: int = 2) -> tuple[str, str]:
    """(the pixel size as text, its unit) of ``layer``'s last ``n_axes`` axes: its ``scale``
    and ``units``. A scale other than 1 with napari's default unit (``pixel``) is taken to be
    in µm, the microscopes' unit (the panel shows it, to be changed); a scale of 1 without a
    unit is pixels.

    >>> class L: scale, units = (1.0, 3.165, 3.165), ("pixel",) * 3
    >>> layer_pixel_size(L())
    ('3.165', 'µm')
    """
    scale = [float(v) for v in tuple(layer.scale)[-n_axes:]]
    units = [str(u) for u in tuple(getattr(layer, "units", ()) or ())[-n_axes:]]
    unit = None
    for u in units:
        try:
            unit = space_unit(u)[0]
            break
        except InputError:
            continue
    if unit is None:
        if all(v == 1.0 for v in scale):
            return "1", PIXELS
        unit = "µm"
    text = f"{scale[-1]:g}" if len(set(scale)) == 1 else ", ".join(f"{v:g}" for v in scale)
    return text, unit


def times_text(layer) -> tuple[str, str]:
    """(the frames' times as text, their unit) from ``layer.metadata`` (the reader's), or
    ("", "") when it has none."""
    meta = getattr(layer, "metadata", None) or {}
    times = meta.get("times")
    if not times:
        return "", ""
    return ", ".join(f"{float(t):g}" for t in times), str(meta.get("time_unit") or "")


def physical_options(pixel_text: str, unit: str, times: str, unit_of_time: str,
                     n_axes: int = 2) -> dict[str, Any]:
    """:func:`napari_pfsdm.measure`'s ``pixel_size``, ``space_unit``, ``times`` and
    ``time_unit`` from the panel's words: sizes in pixels when the unit is
    :data:`PIXELS`; no ``time`` column when ``times`` is blank. Refused in words
    (:class:`~napari_pfsdm.errors.InputError`) when a number cannot be read.

    >>> physical_options("3.165", "µm", "2, 5, 8 12", "day")
    {'pixel_size': (3.165,), 'space_unit': 'µm', 'times': (2.0, 5.0, 8.0, 12.0), 'time_unit': 'day'}
    >>> physical_options("1", "pixels", "", "")
    {}
    """
    out: dict[str, Any] = {}
    if unit and unit != PIXELS:
        out["pixel_size"] = parse_numbers(pixel_text, "the pixel size", "3.165 (or 2, 0.5, 0.5 for "
                                     "Z, Y, X)")
        out["space_unit"] = space_unit(unit)[0]
    if times.strip():
        out["times"] = parse_numbers(times, "the times", "2, 5, 8, 10 (one per frame)")
        out["time_unit"] = time_unit(unit_of_time)[0] if unit_of_time else None
    elif unit_of_time:
        raise InputError(f"a time unit ({unit_of_time}) was chosen without times: write each "
                         "frame's time in Times (e.g. 2, 5, 8, 10), or choose no unit")
    return out


def parse_numbers(text: str, what: str, example: str) -> tuple[float, ...]:
    """The numbers written in a form's field, separated by commas, semicolons or spaces;
    refused in words, naming the word that is not a number.

    >>> parse_numbers("2,5 ,8;10 12", "the times", "2, 5, 8")
    (2.0, 5.0, 8.0, 10.0, 12.0)
    """
    words = [w for w in re.split(r"[,;\s]+", str(text).strip()) if w]
    values = []
    for word in words:
        try:
            values.append(float(word))
        except ValueError:
            raise InputError(f"{what} must be numbers separated by commas (e.g. {example}); "
                             f"{word!r} is not a number") from None
    if not values:
        raise InputError(f"{what} {text!r} holds no number: write e.g. {example}")
    return tuple(values)
