"""Lazy public names for a package (PEP 562): its modules are imported on first use of a name.

The package's ``__init__`` says once where each public name lives::

    __getattr__, __dir__, __all__ = lazy_names(__name__, {
        "descriptor": ["pfsdm", "render_disk"],
        "io": ["read_table_from as read_table"],
    })

The same form as scikit-image's ``lazy_loader.attach`` (submodule -> names), with
``"attr as name"`` for a name the module defines under another one. Used by
``napari_pfsdm/__init__.py`` and ``napari_pfsdm/core/__init__.py``.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping, Sequence
from typing import Any

__all__ = ["lazy_names"]


def lazy_names(package: str, names: Mapping[str, Sequence[str]]
               ) -> tuple[Callable[[str], Any], Callable[[], list[str]], list[str]]:
    """``__getattr__``, ``__dir__`` and ``__all__`` for ``package``.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    names : mapping
        Module (relative to ``package``, dotted) -> the names it gives, each ``"attr"`` or
        ``"attr as name"``.

    Examples
    --------
    >>> get, listing, public = lazy_names("napari_pfsdm.core", {"params": ["PFSDMParams"]})
    >>> public, get("PFSDMParams").__name__
    (['PFSDMParams'], 'PFSDMParams')
    """
    where: dict[str, tuple[str, str]] = {}
    for module, attrs in names.items():
        for spec in attrs:
            attr, _, name = (part.strip() for part in spec.partition(" as "))
            where[name or attr] = (module, attr)
    public = sorted(where)

    def __getattr__(name: str) -> Any:  # noqa: N807 - the module hook's name
        try:
            module, attr = where[name]
        except KeyError:  # a submodule (``from package import sub``) is found by the import
            # system after this error
            raise AttributeError(f"module {package!r} has no attribute {name!r}") from None
        value = getattr(importlib.import_module(f"{package}.{module}"), attr)
        sys.modules[package].__dict__[name] = value  # later look-ups skip this function
        return value

    def __dir__() -> list[str]:  # noqa: N807
        return sorted(set(sys.modules[package].__dict__) | set(where))

    return __getattr__, __dir__, public
