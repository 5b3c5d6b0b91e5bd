"""The PF-SDM method on arrays: contour, SDF, push-forward, morphometric, skeleton, distances.

Pure numpy/scipy/scikit-image; never imports Qt or napari.
"""

from .descriptor import DEFAULTS, PFSDMResult, pfsdm, render_disk
from .distances import (
    INVARIANCES,
    distance,
    distance_matrix,
    embeddings_from_table,
    weighted_features,
)
from .medial_axis import Skeleton, skeleton

__all__ = [
    "DEFAULTS",
    "INVARIANCES",
    "PFSDMResult",
    "Skeleton",
    "distance",
    "distance_matrix",
    "embeddings_from_table",
    "pfsdm",
    "render_disk",
    "skeleton",
    "weighted_features",
]
