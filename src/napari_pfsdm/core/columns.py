"""What a column of napari-pfsdm's tables is: its name, its meaning in plain words and its unit.

A :class:`Column` declares one named column, a :class:`Family` the columns whose names carry
numbers (``shape_r03_n02``, ``width_b04``). This module declares the columns that are not
per-object measures: the keys of a row (``movie``, ``frame``, ``time``, ``label``,
``track_id``), what the descriptor says of the object (:data:`BASE`), the feature families and
the columns the analysis adds (PC scores, probabilities). The per-object measures declare their
own columns beside the code that computes them
(:data:`napari_pfsdm.analysis.measuring.MEASURES`); the glossary
(:mod:`napari_pfsdm.analysis.glossary`) and docs/columns.md are made from both.

Units are kinds (:data:`UNITS`): a table's sizes are in pixels until a pixel size is known,
then in its unit (``"um"``: areas in µm²); shape features have none.

Pure Python: no numpy, no pandas.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass

__all__ = [
    "BASE",
    "BASE_2D",
    "BASE_3D",
    "Column",
    "DERIVED",
    "FAMILIES",
    "Family",
    "KEYS",
    "UNITS",
    "unit_text",
]

#: The kinds of unit a column may have: "" (none: counts, ratios, shape features),
#: "length", "area", "volume" (pixels, or the pixel size's unit), "position" (pixels of the
#: image, whatever the pixel size), "time" (the table's time unit, frames when none is known),
#: "intensity" (the reporter image's own units), "degrees".
UNITS = ("", "length", "area", "volume", "position", "time", "intensity", "degrees")


@dataclass(frozen=True)
class Column:
    """One named column.

    Attributes
    ----------
    name : str
    meaning : str
        What it holds, in plain words (the glossary's entry), without its unit.
    unit : str
        One of :data:`UNITS`.
    """

    name: str
    meaning: str
    unit: str = ""

    def __post_init__(self) -> None:
        if self.unit not in UNITS:
            raise ValueError(f"column {self.name}: unit {self.unit!r} is not one of {UNITS}")


@dataclass(frozen=True)
class Family:
    """Columns whose names carry numbers: ``pattern`` (a regular expression matched against the
    whole name) and the meaning of one of them from the match (``words``).

    Attributes
    ----------
    pattern : str
    example : str
        How the family is written in docs/columns.md (``width_bXX``).
    words : callable(re.Match) -> str
        The meaning of one column of the family.
    summary : str
        The family's meaning in docs/columns.md.
    unit : str
        One of :data:`UNITS`.
    """

    pattern: str
    example: str
    words: Callable[[re.Match], str]
    summary: str
    unit: str = ""

    def __post_init__(self) -> None:
        if self.unit not in UNITS:
            raise ValueError(f"family {self.example}: unit {self.unit!r} is not one of {UNITS}")

    def match(self, name: str) -> re.Match | None:
        """The match of ``name`` against the whole pattern, or None."""
        return re.fullmatch(self.pattern, name)


#: The keys of a row: which object of which movie at which time.
KEYS = (
    Column("movie", "the movie (file) the object comes from"),
    Column("frame", "the frame (time point), from 0"),
    Column("time", "the frame's time (from the movie's metadata or as given; the frame number "
                   "when no time is known)", "time"),
    Column("label", "the object's label (its whole number in the segmentation) in that frame"),
    Column("track_id", "the object's identity through time (−1: no track): trajectories "
                       "follow it"),
)

_AREA = Column("area", "area of the object's labelled pixels", "area")
_VOLUME = Column("volume", "volume of the object's labelled voxels", "volume")
_CENTROIDS = (
    Column("centroid_z", "centre of the object, z (slices)", "position"),
    Column("centroid_y", "centre of the object, y (rows)", "position"),
    Column("centroid_x", "centre of the object, x (columns)", "position"),
)
_CHECKS = (
    Column("touches_border", "1 when the object touches the image border (it may be cut off)"),
    Column("n_components", "pieces of the object (only the largest is described)"),
    Column("n_holes", "holes of the object (filled before it is described)"),
    Column("folded_fraction", "share of the disk's samples where the map folds (leaves the "
                              "object): high values mean the features are less reliable"),
)
_CROSSING = Column("crossing_fraction", "share of rays from the centre that cross the surface "
                                        "more than once (3-D)")
_ERRORS = (
    Column("error", "why the object has no features (empty: it has them)"),
    Column("warnings", "what to look at twice (border, folds, holes, pieces)"),
)

#: What the descriptor says of a 2-D object, in the table's order after ``frame, label``.
BASE_2D = (_AREA, *_CENTROIDS[1:], *_CHECKS, *_ERRORS)
#: The same for 3-D objects.
BASE_3D = (_VOLUME, *_CENTROIDS, *_CHECKS, _CROSSING, *_ERRORS)
#: Every base column, once.
BASE = tuple({c.name: c for c in (*BASE_2D, *BASE_3D)}.values())

#: Columns the analysis and the exports add.
DERIVED = (
    Column("failed", "1 when the object has no features (see the error column)"),
    Column("index", "napari's key of the row: the label"),
    Column("aspect_ratio", "minor / major axis length (1: round)"),
)

_HARMONIC = {0: "mean: thickness", 1: "shift", 2: "elongation", 3: "triangularity",
             4: "squareness"}


def _ring_words(m: re.Match) -> str:
    index = int(m[3])
    what = "SDF" if m[1] == "shape" else "reporter"
    named = f" ({index}: {_HARMONIC[index]})" if index in _HARMONIC else ""
    return (f"{m[1]}: Fourier magnitude |c_{index}| of the pushed-forward {what} on ring "
            f"{int(m[2])} (0 = centre) of the unit disk{named}")


#: The feature families and the analysis' numbered columns.
FAMILIES = (
    Family(r"(shape|intensity)_r(\d+)_n(\d+)", "shape_rXX_nYY, intensity_rXX_nYY", _ring_words,
           "shape: Fourier magnitude \\|c_YY\\| of the pushed-forward SDF on ring XX (0 = "
           "centre) of the unit disk; YY = 0 mean (thickness), 1 shift, 2 elongation, 3 "
           "triangularity, 4 squareness …"),
    Family(r"(shape|intensity)_r(\d+)_l(\d+)", "shape_rXX_lYY, intensity_rXX_lYY (3-D)",
           lambda m: f"{m[1]}: spherical-harmonic power √P_{int(m[3])} of the pushed-forward "
                     f"{'SDF' if m[1] == 'shape' else 'reporter'} on shell {int(m[2])} (0 = "
                     "centre) of the unit ball",
           "shape: spherical-harmonic power √P_YY of the pushed-forward SDF on shell XX (0 = "
           "centre) of the unit ball"),
    Family(r"surface_l(\d+)", "surface_lYY (3-D)",
           lambda m: f"surface: spherical-harmonic power √P_{int(m[1])} of the outer "
                     "surface's distance from the centre",
           "surface: spherical-harmonic power √P_YY of the outer surface's distance from the "
           "centre"),
    Family(r"outline_n([+-]\d+)_(re|im)", "outline_n±KK_re, outline_n±KK_im",
           lambda m: f"the outline's normalised Fourier coefficient of index {int(m[1]):+d}, "
                     f"{'real' if m[2] == 're' else 'imaginary'} part (what the outline term "
                     "of the distance compares)",
           "the outline's normalised Fourier coefficient of index ±KK, real / imaginary part "
           "(what the outline term of the distance compares)"),
    Family(r"elastic_c(\d+)_p(\d+)", "elastic_cC_pPP",
           lambda m: f"the outline's elastic signature, channel {int(m[1])} (0–4: turning "
                     "angle over an arc of the perimeter; 5: the centroid distance / its "
                     "mean; 6: the log local thickness / its mean), at point "
                     f"{int(m[2])} of the outline (what the opt-in elastic term compares)",
           "the outline's elastic signature, channel C (0–4: turning angle over an arc of the "
           "perimeter; 5: the centroid distance / its mean; 6: the log local thickness / its "
           "mean) at point PP of the outline (what the opt-in elastic term compares)"),
    Family(r"(shape|intensity)_PC(\d+)", "shape_PCk, intensity_PCk",
           lambda m: f"score on principal component {m[2]} of the {m[1]} features (a PCA "
                     "over every row)",
           "score on principal component k of the shape features (a PCA over every row)"),
    Family(r"PC(\d+)", "PCk", lambda m: f"score on principal component {m[1]}",
           "score on principal component k"),
    Family(r"p_(.+)", "p_<group>",
           lambda m: f"predicted probability that the object belongs to group '{m[1]}'",
           "predicted probability that the object belongs to group <group>"),
)

#: How a size's unit is written in pixels, and in a physical unit ``{s}``.
_UNIT_WORDS = {"length": ("pixels", "{s}"), "area": ("pixels", "{s}²"),
               "volume": ("voxels", "{s}³")}


def unit_text(kind: str, space_unit: str | None = None, time_unit: str | None = None) -> str:
    """How the unit of a column of unit ``kind`` is written, for a table whose sizes are in
    ``space_unit`` (None: pixels) and times in ``time_unit`` (None: frames); "" for none.

    Examples
    --------
    >>> unit_text("area"), unit_text("area", "µm"), unit_text("length", "µm")
    ('pixels', 'µm²', 'µm')
    >>> unit_text("time"), unit_text("time", time_unit="day"), unit_text("")
    ('frames', 'day', '')
    """
    if kind in _UNIT_WORDS:
        pixels, physical = _UNIT_WORDS[kind]
        return physical.format(s=space_unit) if space_unit else pixels
    if kind == "position":
        return "pixels"
    if kind == "time":
        return time_unit or "frames"
    if kind == "intensity":
        return "the reporter's units"
    return "degrees" if kind == "degrees" else ""


def names(columns: Iterable[Column]) -> list[str]:
    """The names of ``columns``, in order."""
    return [c.name for c in columns]
