"""napari-pfsdm: the Push-Forward Signed Distance Morphometric (PF-SDM).

Invariant shape (and intensity) descriptors of segmented objects, for scripts, the command line
and napari. The scripting API below imports no Qt and no napari, and is loaded lazily (PEP 562,
:mod:`napari_pfsdm.core._lazy`):
``import napari_pfsdm.core`` pulls in numpy, scipy and scikit-image only, and a name such as
``napari_pfsdm.measure`` imports its module (and pandas) on first use. The layers are described
in ``docs/design.md``.

>>> import numpy as np
>>> from napari_pfsdm import pfsdm, measure, distance_matrix
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ._version import __version__
from .core._lazy import lazy_names

#: Module -> the public names it defines: the one place that says where each name lives.
__getattr__, __dir__, __all__ = lazy_names(__name__, {
    "core.descriptor": ["DEFAULTS", "PFSDMResult", "pfsdm", "render_disk"],
    "core.descriptor3d": ["PFSDM3DResult", "shell_maps", "surface_mesh"],
    "core.medial_axis": ["Skeleton", "skeleton"],
    "core.distances": ["RECOMMENDED_ELASTIC_WEIGHT", "distance"],
    "analysis.tables": ["distance_matrix", "embeddings_from_table", "weighted_features"],
    "analysis.features": ["ObjectResult", "drop_failed", "iter_objects", "measure"],
    "analysis.transformer": ["PFSDMTransformer"],
    "analysis.neighbours": ["nearest_neighbours"],
    "analysis.tracking": ["check_tracking", "link", "track_ids_from_tracks"],
    "analysis.rerank": ["rerank"],
    "io": ["read_table", "write_table"],
})
__all__ = ["__version__", *__all__]

if TYPE_CHECKING:  # pragma: no cover - the same names, for type checkers and IDEs
    from .analysis.features import ObjectResult, drop_failed, iter_objects, measure  # noqa: F401
    from .analysis.neighbours import nearest_neighbours  # noqa: F401
    from .analysis.rerank import rerank  # noqa: F401
    from .analysis.tables import distance_matrix, embeddings_from_table, weighted_features  # noqa: F401
    from .analysis.tracking import check_tracking, link, track_ids_from_tracks  # noqa: F401
    from .analysis.transformer import PFSDMTransformer  # noqa: F401
    from .core.descriptor import DEFAULTS, PFSDMResult, pfsdm, render_disk  # noqa: F401
    from .core.descriptor3d import PFSDM3DResult, shell_maps, surface_mesh  # noqa: F401
    from .core.distances import RECOMMENDED_ELASTIC_WEIGHT, distance  # noqa: F401
    from .core.medial_axis import Skeleton, skeleton  # noqa: F401
    from .io import read_table, write_table  # noqa: F401
