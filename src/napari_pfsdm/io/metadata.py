"""What a movie's file says of its frames' times and its pixels' size.

Read from what the file declares, never guessed:

- **ImageJ TIFF**: ``finterval`` (the frame interval) with ``tunit`` (seconds when absent),
  ``unit`` with the X/Y resolution tags (pixels per unit), ``spacing`` for Z-stacks;
- **OME-TIFF**: the ``Pixels`` element's ``PhysicalSizeX/Y/Z`` with their units (µm when
  absent) and the frames' times: each plane's ``DeltaT`` when the planes carry them (uneven
  times), else ``TimeIncrement`` (both with their units, seconds when absent);
- **plain TIFF**: the X/Y resolution tags when their unit is the centimetre or the inch (the
  inch's 72 and 96 dots, which image software writes by default, say nothing of a microscope
  and are ignored);
- **OME-Zarr**: the full-resolution level's ``scale`` on the ``t``, ``z``, ``y`` and ``x``
  axes with the axes' ``unit``.

Anything else has no times or pixel size (:class:`MovieMetadata` with ``None``): the user gives
them (``--times``, ``--pixel-size``) or the table stays in frames and pixels.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..core.units import space_unit, time_unit

__all__ = ["MovieMetadata", "read_metadata"]

#: Resolutions (dots per inch) that image software writes when it knows nothing of the
#: pixels: not a pixel size.
_DEFAULT_DPI = (72.0, 96.0)


@dataclass(frozen=True)
class MovieMetadata:
    """A movie's times and pixel size, as its file declares them (None: not declared).

    Attributes
    ----------
    times : tuple of float or None
        The time of each frame: the planes' ``DeltaT`` as written, or 0, Δt, 2Δt, … for a
        frame interval.
    time_unit : str or None
        :data:`~napari_pfsdm.core.units.TIMES`' name of their unit.
    pixel_size : tuple of float or None
        (Y, X), or (Z, Y, X) for a Z-stack.
    space_unit : str or None
        :data:`~napari_pfsdm.core.units.LENGTHS`' name of its unit.
    source : str
        Where they were read (for messages), "" when nowhere.
    """

    times: tuple[float, ...] | None = None
    time_unit: str | None = None
    pixel_size: tuple[float, ...] | None = None
    space_unit: str | None = None
    source: str = ""


def read_metadata(path: str | Path, n_frames: int, *, series: int | None = None,
                  volume: bool = False) -> MovieMetadata:
    """The times of ``n_frames`` frames and the pixel size that the file at ``path``
    declares (module docstring); ``volume``: the movie's frames are Z-stacks (the pixel size
    is then Z, Y, X). Unknown units and unreadable metadata count as undeclared."""
    path = Path(path)
    try:
        if path.suffix.lower() in (".tif", ".tiff"):
            return _tiff(path, n_frames, 0 if series is None else series, volume)
        if (path / ".zattrs").exists() or (path / "zarr.json").exists():
            return _ome_zarr(path, n_frames, volume)
    except (OSError, ValueError, KeyError, TypeError, IndexError, ET.ParseError):
        pass
    return MovieMetadata()


def _regular(interval: float, n_frames: int) -> tuple[float, ...]:
    return tuple(float(interval) * t for t in range(n_frames))


def _known_time_unit(text: Any) -> str | None:
    try:
        return time_unit(str(text))[0]
    except ValueError:
        return None


def _known_space_unit(text: Any) -> str | None:
    try:
        return space_unit(str(text))[0]
    except ValueError:
        return None


def _tiff(path: Path, n_frames: int, series: int, volume: bool) -> MovieMetadata:
    import tifffile

    with tifffile.TiffFile(path) as tif:
        if tif.is_ome and tif.ome_metadata:
            found = _ome_xml(tif.ome_metadata, n_frames, series, volume)
            if found.times is not None or found.pixel_size is not None:
                return found
        page = tif.series[series].pages[0] if tif.series else tif.pages[0]
        tags = page.tags
        ij = tif.imagej_metadata or {}
        times = t_unit = None
        if ij.get("finterval"):
            t_unit = _known_time_unit(ij.get("tunit", "s"))
            times = _regular(float(ij["finterval"]), n_frames) if t_unit else None
        size = s_unit = None
        res_x, res_y = tags.get("XResolution"), tags.get("YResolution")
        if res_x is not None and res_y is not None:
            per_x = res_x.value[0] / res_x.value[1]  # pixels per unit
            per_y = res_y.value[0] / res_y.value[1]
            unit = int(tags["ResolutionUnit"].value) if "ResolutionUnit" in tags else 2
            if ij.get("unit") and unit == 1:  # ImageJ: pixels per its own unit
                s_unit = _known_space_unit(ij["unit"])
                scale = 1.0
            elif unit == 3:  # pixels per centimetre
                s_unit, scale = "µm", 1e4
            elif unit == 2 and per_x not in _DEFAULT_DPI:  # pixels per inch
                s_unit, scale = "µm", 25400.0
            if s_unit and per_x > 0 and per_y > 0:
                # units per pixel, as the fraction is written (13/20, not 1 / (20/13))
                size = (scale * res_y.value[1] / res_y.value[0],
                        scale * res_x.value[1] / res_x.value[0])
                if volume:
                    size = (float(ij.get("spacing", 1.0)) * scale, *size)
        source = "ImageJ metadata" if ij else ("TIFF resolution" if size else "")
        return MovieMetadata(times, t_unit if times else None, size, s_unit if size else None,
                             source if (times or size) else "")


def _ome_xml(xml: str, n_frames: int, series: int, volume: bool) -> MovieMetadata:
    root = ET.fromstring(xml)
    ns = {"ome": root.tag.split("}")[0].strip("{")} if root.tag.startswith("{") else {}
    prefix = "ome:" if ns else ""
    images = root.findall(f"{prefix}Image", ns)
    if not images:
        return MovieMetadata()
    pixels = images[min(series, len(images) - 1)].find(f"{prefix}Pixels", ns)
    if pixels is None:
        return MovieMetadata()
    size = s_unit = None
    if pixels.get("PhysicalSizeX") and pixels.get("PhysicalSizeY"):
        s_unit = _known_space_unit(pixels.get("PhysicalSizeXUnit", "µm"))
        y_unit = _known_space_unit(pixels.get("PhysicalSizeYUnit", "µm"))
        if s_unit and y_unit == s_unit:
            size = (float(pixels.get("PhysicalSizeY")), float(pixels.get("PhysicalSizeX")))
            if volume:
                z_unit = _known_space_unit(pixels.get("PhysicalSizeZUnit", "µm"))
                if z_unit != s_unit or not pixels.get("PhysicalSizeZ"):
                    size = None
                else:
                    size = (float(pixels.get("PhysicalSizeZ")), *size)
    times = t_unit = None
    deltas: dict[int, float] = {}
    units = set()
    for plane in pixels.findall(f"{prefix}Plane", ns):
        if plane.get("DeltaT") is None:
            continue
        t = int(plane.get("TheT", 0))
        if t not in deltas and int(plane.get("TheZ", 0)) == 0 and int(plane.get("TheC", 0)) == 0:
            deltas[t] = float(plane.get("DeltaT"))
            units.add(plane.get("DeltaTUnit", "s"))
    if len(deltas) == n_frames and len(units) == 1:
        t_unit = _known_time_unit(units.pop())
        times = tuple(deltas[t] for t in range(n_frames)) if t_unit else None
    elif pixels.get("TimeIncrement"):
        t_unit = _known_time_unit(pixels.get("TimeIncrementUnit", "s"))
        times = _regular(float(pixels.get("TimeIncrement")), n_frames) if t_unit else None
    return MovieMetadata(times, t_unit if times else None, size, s_unit if size else None,
                         "OME-XML")


def _ome_zarr(path: Path, n_frames: int, volume: bool) -> MovieMetadata:
    attrs_file = path / ".zattrs"
    attrs = json.loads(attrs_file.read_text()) if attrs_file.exists() else \
        json.loads((path / "zarr.json").read_text()).get("attributes", {})
    attrs = attrs.get("ome", attrs)
    scales = attrs.get("multiscales") or []
    if not scales:
        return MovieMetadata()
    ms = scales[0]
    axes = [a if isinstance(a, dict) else {"name": a} for a in ms.get("axes", [])]
    levels = []
    for ds in ms.get("datasets", []):
        scale = next((t["scale"] for t in ds.get("coordinateTransformations", [])
                      if t.get("type") == "scale"), None)
        if scale is not None and len(scale) == len(axes):
            levels.append(scale)
    if not levels:
        return MovieMetadata()
    finest = min(levels, key=lambda s: [float(v) for v in s[::-1]])
    by_name = {a.get("name"): (float(v), a.get("unit")) for a, v in zip(axes, finest,
                                                                       strict=True)}
    times = t_unit = None
    if "t" in by_name and by_name["t"][1]:
        t_unit = _known_time_unit(by_name["t"][1])
        times = _regular(by_name["t"][0], n_frames) if t_unit else None
    size = s_unit = None
    names = ("z", "y", "x") if volume else ("y", "x")
    if all(n in by_name and by_name[n][1] for n in names):
        units = {_known_space_unit(by_name[n][1]) for n in names}
        if len(units) == 1 and None not in units:
            s_unit = units.pop()
            size = tuple(by_name[n][0] for n in names)
    return MovieMetadata(times, t_unit if times else None, size, s_unit if size else None,
                         "OME-Zarr metadata" if (times or size) else "")
