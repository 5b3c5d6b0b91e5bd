"""napari-pfsdm: the Push-Forward Signed Distance Morphometric (PF-SDM).

Invariant shape (and intensity) descriptors of segmented objects, for scripts, the command line
and napari. The scripting API below imports no Qt and no napari, and is loaded lazily (PEP 562):
``import napari_pfsdm.core`` pulls in numpy, scipy and scikit-image only, and a name such as
``napari_pfsdm.measure`` imports its module (and pandas) on first use. The layers are described
in ``docs/design.md``.

>>> import numpy as np
>>> from napari_pfsdm import pfsdm, measure, distance_matrix
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from ._version import __version__

#: Public name -> (module, attribute): the one place that says where each name lives.
_EXPORTS: dict[str, tuple[str, str]] = {
    "DEFAULTS": (".core.descriptor", "DEFAULTS"),
    "PFSDMResult": (".core.descriptor", "PFSDMResult"),
    "pfsdm": (".core.descriptor", "pfsdm"),
    "render_disk": (".core.descriptor", "render_disk"),
    "PFSDM3DResult": (".core.descriptor3d", "PFSDM3DResult"),
    "shell_maps": (".core.descriptor3d", "shell_maps"),
    "surface_mesh": (".core.descriptor3d", "surface_mesh"),
    "Skeleton": (".core.medial_axis", "Skeleton"),
    "skeleton": (".core.medial_axis", "skeleton"),
    "distance": (".core.distances", "distance"),
    "distance_matrix": (".analysis.tables", "distance_matrix"),
    "embeddings_from_table": (".analysis.tables", "embeddings_from_table"),
    "weighted_features": (".analysis.tables", "weighted_features"),
    "ObjectResult": (".analysis.features", "ObjectResult"),
    "PFSDMTransformer": (".analysis.transformer", "PFSDMTransformer"),
    "drop_failed": (".analysis.features", "drop_failed"),
    "iter_objects": (".analysis.features", "iter_objects"),
    "measure": (".analysis.features", "measure"),
    "nearest_neighbours": (".analysis.neighbours", "nearest_neighbours"),
    "check_tracking": (".analysis.tracking", "check_tracking"),
    "link": (".analysis.tracking", "link"),
    "track_ids_from_tracks": (".analysis.tracking", "track_ids_from_tracks"),
    "read_table": (".io_csv", "read_table_csv"),
    "rerank": (".analysis.rerank", "rerank"),
    "write_table": (".io_csv", "write_table_csv"),
}

__all__ = [
    "__version__",
    "DEFAULTS",
    "ObjectResult",
    "PFSDMTransformer",
    "PFSDMResult",
    "PFSDM3DResult",
    "Skeleton",
    "check_tracking",
    "distance",
    "distance_matrix",
    "drop_failed",
    "embeddings_from_table",
    "iter_objects",
    "link",
    "measure",
    "nearest_neighbours",
    "pfsdm",
    "read_table",
    "render_disk",
    "shell_maps",
    "rerank",
    "skeleton",
    "track_ids_from_tracks",
    "surface_mesh",
    "weighted_features",
    "write_table",
]


def __getattr__(name: str) -> Any:
    try:
        module, attr = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module 'napari_pfsdm' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module, __name__), attr)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))


if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs only
    from .analysis.features import ObjectResult, drop_failed, iter_objects, measure
    from .analysis.neighbours import nearest_neighbours
    from .analysis.rerank import rerank
    from .analysis.tables import distance_matrix, embeddings_from_table, weighted_features
    from .analysis.tracking import check_tracking, link, track_ids_from_tracks
    from .analysis.transformer import PFSDMTransformer
    from .core.descriptor import DEFAULTS, PFSDMResult, pfsdm, render_disk
    from .core.descriptor3d import PFSDM3DResult, shell_maps, surface_mesh
    from .core.distances import distance
    from .core.medial_axis import Skeleton, skeleton
    from .io_csv import read_table_csv as read_table
    from .io_csv import write_table_csv as write_table
