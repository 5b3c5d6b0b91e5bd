"""The method's options as one frozen, validated record (docs/design.md §2).

:class:`PFSDMParams` names every option of :func:`napari_pfsdm.pfsdm` with its default and its
allowed values (:data:`CHOICES`, built from the core modules' own constants, so that the command
line and the widget offer exactly what the core accepts). ``measure``, ``iter_objects`` and the
batch check their options through it before any work starts, and the record a table carries in
its sidecar is :meth:`PFSDMParams.record`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

from .contour import DEFAULT_MIN_AREA
from .morphometric import (
    NORMALIZATIONS,
    RADII_PLACEMENTS,
    RING_WEIGHTINGS,
    mode_weights,
    ring_radii,
    ring_weights,
)
from .pushforward import MAPPINGS
from .sdf import SDF_KINDS

__all__ = ["CHOICES", "PFSDMParams", "as_params"]

#: Allowed values of the options that are a choice.
CHOICES: dict[str, tuple[str, ...]] = {
    "sdf": SDF_KINDS,
    "mapping": MAPPINGS,
    "normalization": NORMALIZATIONS,
    "radii": RADII_PLACEMENTS,
    "ring_weighting": RING_WEIGHTINGS,
    "components": ("largest", "raise"),
}

#: Keys a table's record holds that are derived from the options, not options themselves.
DERIVED = ("weights", "mode_weights")


@dataclass(frozen=True)
class PFSDMParams:
    """Every option of :func:`napari_pfsdm.pfsdm`, validated; defaults chosen on the benchmarks
    (README, "How the defaults were chosen").

    Examples
    --------
    >>> p = PFSDMParams(n_fourier=6)
    >>> p.n_fourier, p.mapping
    (6, 'harmonic')
    >>> PFSDMParams(mapping="harmonc")
    Traceback (most recent call last):
    ...
    ValueError: mapping must be one of harmonic, bijective, radial; got 'harmonc'.
    >>> PFSDMParams.from_options(n_radii=8).options()["n_radii"]
    8
    """

    n_fourier: int = 10
    n_radii: int = 16
    n_angles: int = 64
    sdf: str = "exact"
    viscosity: float = 0.05
    mapping: str = "harmonic"
    normalization: str = "none"
    radii: str | tuple[float, ...] = "uniform"
    ring_weighting: str = "depth"
    mode_exponent: float = 0.25
    components: str = "largest"
    min_area: int = DEFAULT_MIN_AREA

    def __post_init__(self) -> None:
        for name, allowed in CHOICES.items():
            value = getattr(self, name)
            if name == "radii" and not isinstance(value, str):
                radii = tuple(float(r) for r in np.ravel(value))
                if not radii or not all(0.0 < r < 1.0 for r in radii):
                    raise ValueError("radii given as numbers must all lie in (0, 1).")
                object.__setattr__(self, "radii", radii)
                continue
            if value not in allowed:
                raise ValueError(
                    f"{name} must be one of {', '.join(allowed)}; got {value!r}."
                )
        for name, low in (("n_fourier", 1), ("n_radii", 1), ("n_angles", 8), ("min_area", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not float(value).is_integer() or value < low:
                raise ValueError(f"{name} must be a whole number >= {low}; got {value!r}.")
            object.__setattr__(self, name, int(value))
        if self.n_angles % 2:
            raise ValueError(f"n_angles must be an even number of at least 8, got {self.n_angles}.")
        if self.n_fourier >= self.n_angles // 2 + 1:  # as core.morphometric.magnitude_embedding
            raise ValueError(f"n_fourier={self.n_fourier} needs more than {2 * self.n_fourier} "
                             "angles; raise n_angles.")
        for name in ("viscosity", "mode_exponent"):
            value = float(getattr(self, name))
            if not np.isfinite(value) or value < 0 or (name == "viscosity" and value == 0):
                raise ValueError(f"{name} must be a positive number; got {value!r}.")
            object.__setattr__(self, name, value)

    @classmethod
    def from_options(cls, options: dict[str, Any] | None = None, /, **more: Any) -> PFSDMParams:
        """From keyword options (as ``measure(**options)`` takes them) or a table's record.

        Unknown names are refused with the list of known ones; derived entries of a record
        (``weights``, ``mode_weights``) are ignored, and a record's explicit ``radii`` list is
        kept as numbers.
        """
        merged = {**(options or {}), **more}
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(merged) - known - set(DERIVED))
        if unknown:
            raise ValueError(
                f"unknown option{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}; "
                f"the options are {', '.join(sorted(known))}"
            )
        return cls(**{k: v for k, v in merged.items() if k in known})

    def options(self) -> dict[str, Any]:
        """The keyword arguments of :func:`napari_pfsdm.pfsdm`."""
        out = asdict(self)
        if isinstance(out["radii"], tuple):
            out["radii"] = np.asarray(out["radii"])
        return out

    def record(self) -> dict[str, Any]:
        """What a feature table carries (``attrs["pfsdm"]``, its sidecar's ``options``): the
        options, the rings' ``radii`` as numbers and their ``n_radii``, and the ring and mode
        ``weights`` that distances need."""
        out = asdict(self)
        r = ring_radii(self.n_radii, np.asarray(self.radii) if isinstance(self.radii, tuple)
                       else self.radii)
        out["radii"] = r.tolist()
        out["n_radii"] = len(r)
        out["weights"] = ring_weights(r, self.ring_weighting).tolist()
        out["mode_weights"] = mode_weights(self.n_fourier, self.mode_exponent).tolist()
        return out


def as_params(params: PFSDMParams | None = None, options: dict[str, Any] | None = None
              ) -> PFSDMParams:
    """The one record of a call's options, given as ``params=`` or as keyword ``options``
    (validated); both at once is refused rather than merged silently."""
    if params is not None and options:
        raise ValueError("give the options either as params=PFSDMParams(...) or as keywords, "
                         "not both")
    if params is not None and not isinstance(params, PFSDMParams):
        raise TypeError(f"params must be a PFSDMParams, got {type(params).__name__}")
    return params if params is not None else PFSDMParams.from_options(options)
