"""napari-pfsdm: the Push-Forward Signed Distance Morphometric (PF-SDM).

Invariant shape (and intensity) descriptors of segmented objects, for scripts, the command line
and napari. The scripting API below imports no Qt and no napari.

>>> import numpy as np
>>> from napari_pfsdm import pfsdm, measure, distance_matrix
"""

from .analysis.features import ObjectResult, drop_failed, iter_objects, measure
from .core import (
    DEFAULTS,
    PFSDMResult,
    Skeleton,
    distance,
    distance_matrix,
    embeddings_from_table,
    pfsdm,
    render_disk,
    skeleton,
    weighted_features,
)
from .io_csv import read_table_csv as read_table
from .io_csv import write_table_csv as write_table

__version__ = "0.1.0"

__all__ = [
    "DEFAULTS",
    "ObjectResult",
    "PFSDMResult",
    "Skeleton",
    "__version__",
    "distance",
    "distance_matrix",
    "drop_failed",
    "embeddings_from_table",
    "iter_objects",
    "measure",
    "pfsdm",
    "read_table",
    "render_disk",
    "skeleton",
    "weighted_features",
    "write_table",
]
