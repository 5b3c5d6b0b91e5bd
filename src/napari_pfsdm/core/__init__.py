"""The PF-SDM method on arrays: contour, SDF, push-forward, morphometric, skeleton, distances.

Pure numpy/scipy/scikit-image; never imports Qt or napari. The names below are loaded
lazily (PEP 562), as the package's top level is: ``from napari_pfsdm.core.params import
PFSDMParams`` (what the napari panel needs when napari docks it) then imports no scipy or
scikit-image, which took ~0.6 s of the viewer's freeze when the panel was docked from the
menu in a fresh session (``python -X importtime``; docs/design.md §5, "So is the measuring
code").
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

#: Public name -> module (under this package) that defines it.
_EXPORTS: dict[str, str] = {
    "DEFAULTS": ".descriptor",
    "PFSDMResult": ".descriptor",
    "pfsdm": ".descriptor",
    "render_disk": ".descriptor",
    "PFSDM3DResult": ".descriptor3d",
    "pfsdm3d": ".descriptor3d",
    "shell_maps": ".descriptor3d",
    "surface_mesh": ".descriptor3d",
    "INVARIANCES": ".distances",
    "Embeddings": ".distances",
    "distance": ".distances",
    "distance_matrix": ".distances",
    "weighted_features": ".distances",
    "Skeleton": ".medial_axis",
    "skeleton": ".medial_axis",
}

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


def __getattr__(name: str) -> Any:
    try:
        module = _EXPORTS[name]
    except KeyError:  # a submodule (``from napari_pfsdm.core import distances``) is found
        # by the import system after this error
        raise AttributeError(f"module 'napari_pfsdm.core' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))


if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs only
    from .descriptor import DEFAULTS, PFSDMResult, pfsdm, render_disk
    from .descriptor3d import PFSDM3DResult, pfsdm3d, shell_maps, surface_mesh
    from .distances import INVARIANCES, Embeddings, distance, distance_matrix, weighted_features
    from .medial_axis import Skeleton, skeleton
