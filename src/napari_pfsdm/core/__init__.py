"""The PF-SDM method on arrays: contour, SDF, push-forward, morphometric, skeleton, distances.

Pure numpy/scipy/scikit-image; never imports Qt or napari.
"""

from .descriptor import DEFAULTS, PFSDMResult, pfsdm, render_disk
from .distances import INVARIANCES, Embeddings, distance, distance_matrix, weighted_features
from .medial_axis import Skeleton, skeleton

__all__ = [
    "DEFAULTS",
    "Embeddings",
    "INVARIANCES",
    "PFSDMResult",
    "Skeleton",
    "distance",
    "distance_matrix",
    "pfsdm",
    "render_disk",
    "skeleton",
    "weighted_features",
]
