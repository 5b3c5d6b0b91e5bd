"""The PF-SDM method on arrays: contour, SDF, push-forward, morphometric, skeleton, distances.

Pure numpy/scipy/scikit-image; never imports Qt or napari.
"""

from .descriptor import DEFAULTS, PFSDMResult, pfsdm, render_disk
from .descriptor3d import PFSDM3DResult, pfsdm3d, shell_maps, surface_mesh
from .distances import INVARIANCES, Embeddings, distance, distance_matrix, weighted_features
from .medial_axis import Skeleton, skeleton

__all__ = [
    "DEFAULTS",
    "Embeddings",
    "INVARIANCES",
    "PFSDMResult",
    "PFSDM3DResult",
    "Skeleton",
    "distance",
    "distance_matrix",
    "pfsdm",
    "pfsdm3d",
    "render_disk",
    "shell_maps",
    "skeleton",
    "surface_mesh",
    "weighted_features",
]
