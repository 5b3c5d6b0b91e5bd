"""The PF-SDM method on arrays: contour, SDF, push-forward, morphometric, skeleton, distances.

Pure numpy/scipy/scikit-image; never imports Qt or napari. The names below are loaded
lazily (PEP 562, :mod:`napari_pfsdm.core._lazy`), as the package's top level is:
``from napari_pfsdm.core.params import PFSDMParams`` (what the napari panel needs when napari
docks it) then imports no scipy or scikit-image (~0.6 s of imports, ``python -X importtime``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ._lazy import lazy_names

#: Module -> the public names it defines (``core._lazy``).
__getattr__, __dir__, __all__ = lazy_names(__name__, {
    "descriptor": ["DEFAULTS", "PFSDMResult", "pfsdm", "render_disk"],
    "descriptor3d": ["PFSDM3DResult", "pfsdm3d", "shell_maps", "surface_mesh"],
    "distances": ["INVARIANCES", "Embeddings", "distance", "distance_matrix",
                  "weighted_features"],
    "medial_axis": ["Skeleton", "skeleton"],
})

if TYPE_CHECKING:  # pragma: no cover - the same names, for type checkers and IDEs
    from .descriptor import DEFAULTS, PFSDMResult, pfsdm, render_disk  # noqa: F401
    from .descriptor3d import PFSDM3DResult, pfsdm3d, shell_maps, surface_mesh  # noqa: F401
    from .distances import (  # noqa: F401
        INVARIANCES,
        Embeddings,
        distance,
        distance_matrix,
        weighted_features,
    )
    from .medial_axis import Skeleton, skeleton  # noqa: F401
