"""The names of the method's choices, and the smallest object measured: constants only.

They live here, not beside the code that implements each choice, so that
:mod:`~napari_pfsdm.core.params` (and the napari panel, which builds its controls from them)
imports no scipy or scikit-image: those modules are loaded when an object is measured.
"""

from __future__ import annotations

__all__ = ["ANTERIOR_RULES", "BALL_MAPS", "DEFAULT_MIN_AREA", "IDENTITIES", "KEEP_OR_LEAVE_OUT",
           "MAPPINGS", "SDF_KINDS"]

#: Push-forward maps of the unit disk (:func:`~napari_pfsdm.core.pushforward.make_map`).
MAPPINGS = ("harmonic", "bijective", "radial")
#: Maps of the unit ball in 3-D (:func:`~napari_pfsdm.core.ball.make_ball_map`).
BALL_MAPS = ("radial", "harmonic")
#: Signed distance functions (:func:`~napari_pfsdm.core.sdf.make_sdf`).
SDF_KINDS = ("exact", "viscous")
#: Objects with fewer pixels than this are refused: their outline is mostly rasterisation.
DEFAULT_MIN_AREA = 20
#: What happens to objects of a kind (on the border, with warnings) in shape spaces: kept, or
#: left out of PCA, comparison and prediction (their rows stay in the table).
KEEP_OR_LEAVE_OUT = ("keep", "leave_out")
#: Which end of an object's midline is "anterior", where its profiles start
#: (:func:`~napari_pfsdm.core.midline.midline`): the reporter's high or low end, or the end
#: nearer the image's top (left when the midline runs more left-right) or the other one.
ANTERIOR_RULES = ("reporter", "reporter_low", "first", "last")
#: How an object keeps its identity through time (the option ``link``): ``"auto"`` links the
#: objects only when their label ids do not follow them, ``"labels"`` trusts the ids, and the
#: linking methods (:mod:`napari_pfsdm.analysis.tracking`) always link that way.
IDENTITIES = ("auto", "labels", "centroid", "overlap", "laptrack")
