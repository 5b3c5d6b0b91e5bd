"""What every column of napari-pfsdm's tables means, in plain words (pure Python).

:func:`describe_column` explains a column from its name: the named columns of
:data:`MEANINGS`, and the families whose names carry numbers (``shape_r03_n02``,
``outline_n+16_im``, ``surface_l04``, ``width_b03``, ``reporter_b03``, ``shape_PC1``,
``p_<group>``). The napari plugin's export
writes the glossary of its features table beside it (``<prefix>_columns.csv``); docs/columns.md
shows the same text.

Examples
--------
>>> describe_column("outline_n+16_im").split(" (")[0]
"the outline's normalised Fourier coefficient of index +16, imaginary part"
>>> describe_column("shape_r03_n02").split(" of the unit")[0]
'shape: Fourier magnitude |c_2| of the pushed-forward SDF on ring 3 (0 = centre)'
"""

from __future__ import annotations

import re

__all__ = ["MEANINGS", "describe_column", "glossary"]

#: The columns known by name.
MEANINGS = {
    "movie": "the movie (file) the object comes from",
    "frame": "the frame (time point), from 0",
    "label": "the object's label (its whole number in the segmentation) in that frame",
    "track_id": "the object's identity through time (−1: no track): trajectories follow it",
    "area": "area in pixels",
    "volume": "volume in voxels",
    "centroid_z": "centre of the object, z (slices)",
    "centroid_y": "centre of the object, y (rows, pixels)",
    "centroid_x": "centre of the object, x (columns, pixels)",
    "touches_border": "1 when the object touches the image border (it may be cut off)",
    "n_components": "pieces of the object (only the largest is described)",
    "n_holes": "holes of the object (filled before it is described)",
    "folded_fraction": "share of the disk's samples where the map folds (leaves the object): "
                       "high values mean the features are less reliable",
    "crossing_fraction": "share of rays from the centre that cross the surface more than "
                         "once (3-D)",
    "error": "why the object has no features (empty: it has them)",
    "warnings": "what to look at twice (border, folds, holes, pieces)",
    "failed": "1 when the object has no features (see the error column)",
    "index": "napari's key of the row: the label",
    "perimeter": "perimeter in pixels (scikit-image's regionprops)",
    "eccentricity": "eccentricity of the ellipse of the same second moments (0: a disk)",
    "solidity": "area / area of the convex hull (1: no indentation)",
    "axis_major_length": "major axis of the ellipse of the same second moments",
    "axis_minor_length": "minor axis of the ellipse of the same second moments",
    "circularity": "4π·area / perimeter² (1 for a disk, smaller when elongated or ragged)",
    "aspect_ratio": "minor / major axis length (1: round)",
    "intensity_mean": "mean reporter intensity on the object",
    "intensity_integrated": "summed reporter intensity on the object",
    "intensity_polarity": "how far the reporter's centre of mass lies from the object's "
                          "centre, in object radii (0: even; towards 1: at one pole)",
    "midline_length": "length of the object along its own axis: the skeleton's main path "
                      "extended to the outline at both ends, in pixels (NaN in 3-D)",
    "width_mean": "mean width of the object across its midline, over its length, in pixels "
                  "(area / length for a straight axis)",
    "width_max": "largest width of the object across its midline, in pixels",
    "polarity_angle_image": "direction of the reporter's centre of mass from the object's "
                            "centre, degrees in the image (0: towards +x, the columns; "
                            "counter-clockwise as shown, 90: up)",
    "polarity_angle_midline": "angle (0 to 180 degrees) between the reporter's centre-of-mass "
                              "offset and the midline's anterior-to-posterior direction (0: "
                              "towards the posterior end, 180: the anterior one)",
}
_HARMONIC = {0: "mean: thickness", 1: "shift", 2: "elongation", 3: "triangularity",
             4: "squareness"}
_PATTERNS = [
    (re.compile(r"^(shape|intensity)_r(\d+)_n(\d+)$"),
     lambda m: f"{m[1]}: Fourier magnitude |c_{int(m[3])}| of the pushed-forward "
               f"{'SDF' if m[1] == 'shape' else 'reporter'} on ring {int(m[2])} (0 = centre) "
               f"of the unit disk" + (f" ({int(m[3])}: {_HARMONIC[int(m[3])]})"
                                      if int(m[3]) in _HARMONIC else "")),
    (re.compile(r"^(shape|intensity)_r(\d+)_l(\d+)$"),
     lambda m: f"{m[1]}: spherical-harmonic power √P_{int(m[3])} of the pushed-forward "
               f"{'SDF' if m[1] == 'shape' else 'reporter'} on shell {int(m[2])} (0 = centre) "
               "of the unit ball"),
    (re.compile(r"^surface_l(\d+)$"),
     lambda m: f"surface: spherical-harmonic power √P_{int(m[1])} of the outer surface's "
               "distance from the centre"),
    (re.compile(r"^outline_n([+-]\d+)_(re|im)$"),
     lambda m: f"the outline's normalised Fourier coefficient of index {int(m[1]):+d}, "
               f"{'real' if m[2] == 're' else 'imaginary'} part (what the outline term of the "
               "distance compares)"),
    (re.compile(r"^elastic_c(\d+)_p(\d+)$"),
     lambda m: f"the outline's elastic signature, channel {int(m[1])} (0–4: turning angle "
               "over an arc of the perimeter; 5: the centroid distance / its mean; 6: the log "
               f"local thickness / its mean), at point {int(m[2])} of the outline (what the "
               "opt-in elastic term compares)"),
    (re.compile(r"^width_b(\d+)$"),
     lambda m: f"mean width across the midline (pixels) on piece {int(m[1])} of its "
               "profile_bins equal pieces, counted from the anterior end (0)"),
    (re.compile(r"^reporter_b(\d+)$"),
     lambda m: f"mean reporter (the image's units) of the object's pixels nearest piece "
               f"{int(m[1])} of the midline's profile_bins equal pieces, counted from the "
               "anterior end (0)"),
    (re.compile(r"^(shape|intensity)_PC(\d+)$"),
     lambda m: f"score on principal component {m[2]} of the {m[1]} features (a PCA over "
               "every row)"),
    (re.compile(r"^PC(\d+)$"),
     lambda m: f"score on principal component {m[1]}"),
    (re.compile(r"^p_(.+)$"),
     lambda m: f"predicted probability that the object belongs to group '{m[1]}'"),
]


def describe_column(name: str) -> str:
    """What the column ``name`` of a napari-pfsdm table holds, in plain words ("" for a column
    napari-pfsdm does not make)."""
    if name in MEANINGS:
        return MEANINGS[name]
    for pattern, words in _PATTERNS:
        match = pattern.match(name)
        if match:
            return words(match)
    return ""


def glossary(columns) -> list[tuple[str, str]]:
    """``(column, meaning)`` for each of ``columns``, in their order."""
    return [(str(c), describe_column(str(c))) for c in columns]
