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

from ..errors import InputError
from .choices import BALL_MAPS, DEFAULT_MIN_AREA, MAPPINGS, SDF_KINDS
from .morphometric import (
    NORMALIZATIONS,
    RADII_PLACEMENTS,
    RING_WEIGHTINGS,
    mode_weights,
    ring_radii,
    ring_weights,
)

__all__ = ["CHOICES", "PFSDMParams", "as_params"]

#: Allowed values of the options that are a choice.
CHOICES: dict[str, tuple[str, ...]] = {
    "sdf": SDF_KINDS,
    "mapping": MAPPINGS,
    "normalization": NORMALIZATIONS,
    "radii": RADII_PLACEMENTS,
    "ring_weighting": RING_WEIGHTINGS,
    "components": ("largest", "raise"),
    "ball_map": BALL_MAPS,
}

#: Keys a table's record holds that are derived from the options or describe the input (its
#: dimension, axes and voxel size), not options themselves.
DERIVED = ("weights", "mode_weights", "ndim", "axes", "spacing")

#: Options that apply to 2-D masks only, and to 3-D masks only (docs/design.md §6.6).
ONLY_2D = ("n_fourier", "n_angles", "sdf", "viscosity", "mapping", "normalization")
ONLY_3D = ("sh_degree", "surface_weight", "ball_map")


@dataclass(frozen=True)
class PFSDMParams:
    """Every option of :func:`napari_pfsdm.pfsdm`, validated; defaults chosen on the benchmarks
    (README, "How the defaults were chosen").

    Examples
    --------
    >>> p = PFSDMParams(n_fourier=6)
    >>> p.n_fourier, p.mapping
    (6, 'harmonic')
    >>> try:
    ...     PFSDMParams(mapping="harmonc")
    ... except InputError as exc:
    ...     print(exc)
    mapping must be one of harmonic, bijective, radial; got 'harmonc'.
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
    sh_degree: int = 8
    surface_weight: float = 4.0
    ball_map: str = "radial"

    def __post_init__(self) -> None:
        for name, allowed in CHOICES.items():
            value = getattr(self, name)
            if name == "radii" and not isinstance(value, str):
                radii = tuple(float(r) for r in np.ravel(value))
                if not radii or not all(0.0 < r < 1.0 for r in radii):
                    raise InputError("radii given as numbers must all lie in (0, 1).")
                object.__setattr__(self, "radii", radii)
                continue
            if value not in allowed:
                raise InputError(
                    f"{name} must be one of {', '.join(allowed)}; got {value!r}."
                )
        for name, low in (("n_fourier", 1), ("n_radii", 1), ("n_angles", 8), ("min_area", 1),
                          ("sh_degree", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not float(value).is_integer() or value < low:
                raise InputError(f"{name} must be a whole number >= {low}; got {value!r}.")
            object.__setattr__(self, name, int(value))
        if self.n_angles % 2:
            raise InputError(f"n_angles must be an even number of at least 8, got {self.n_angles}.")
        if self.n_fourier >= self.n_angles // 2 + 1:  # as core.morphometric.magnitude_embedding
            raise InputError(f"n_fourier={self.n_fourier} needs more than {2 * self.n_fourier} "
                             "angles; raise n_angles.")
        if self.sh_degree > 40:
            raise InputError(f"sh_degree must be at most 40 (a 3-D object rarely carries detail "
                             f"beyond degree 20); got {self.sh_degree}.")
        for name in ("viscosity", "mode_exponent", "surface_weight"):
            value = float(getattr(self, name))
            if not np.isfinite(value) or value < 0 or (name == "viscosity" and value == 0):
                raise InputError(f"{name} must be a positive number; got {value!r}.")
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
            raise InputError(
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

    def check_dimension(self, ndim: int) -> None:
        """Refuse options set away from their defaults that do not apply to ``ndim``-D objects
        (e.g. ``mapping`` for a volume, ``sh_degree`` for a 2-D mask), rather than ignore them.
        """
        default = PFSDMParams()
        other = ONLY_2D if ndim == 3 else ONLY_3D
        changed = [n for n in other if getattr(self, n) != getattr(default, n)]
        if changed:
            hint = ("these options are for 2-D masks (3-D ones have sh_degree, surface_weight "
                    "and ball_map)" if ndim == 3 else "these options are for 3-D volumes only")
            raise InputError(
                f"{', '.join(changed)} {'was' if len(changed) == 1 else 'were'} set, but the "
                f"objects are {ndim}-D: {hint}. Leave {'it' if len(changed) == 1 else 'them'} "
                "at the default."
            )

    def record(self, ndim: int = 2) -> dict[str, Any]:
        """What a feature table carries (``attrs["pfsdm"]``, its sidecar's ``options``): the
        options, the rings' ``radii`` as numbers and their ``n_radii``, and the ring and mode
        ``weights`` that distances need. For 3-D objects (``ndim=3``) also ``ndim``, and the
        mode weights run over the spherical-harmonic degrees 0 … ``sh_degree``."""
        out = asdict(self)
        r = ring_radii(self.n_radii, np.asarray(self.radii) if isinstance(self.radii, tuple)
                       else self.radii)
        out["radii"] = r.tolist()
        out["n_radii"] = len(r)
        out["weights"] = ring_weights(r, self.ring_weighting).tolist()
        n_modes = self.sh_degree if ndim == 3 else self.n_fourier
        out["mode_weights"] = mode_weights(n_modes, self.mode_exponent).tolist()
        if ndim == 3:
            out["ndim"] = 3
        return out


def as_params(params: PFSDMParams | None = None, options: dict[str, Any] | None = None
              ) -> PFSDMParams:
    """The one record of a call's options, given as ``params=`` or as keyword ``options``
    (validated); both at once is refused rather than merged silently."""
    if params is not None and options:
        raise InputError("give the options either as params=PFSDMParams(...) or as keywords, "
                         "not both")
    if params is not None and not isinstance(params, PFSDMParams):
        raise TypeError(f"params must be a PFSDMParams, got {type(params).__name__}")
    return params if params is not None else PFSDMParams.from_options(options)


@dataclass(frozen=True)
class Option:
    """One option of the method (provisional form; the option record replaces it)."""

    name: str
    kind: type
    default: Any
    help: str = ""
    choices: tuple | None = None
    low: float | None = None
    high: float | None = None
    dims: str = "both"
    basic: bool = False


def _provisional() -> tuple[Option, ...]:
    out = []
    for f in fields(PFSDMParams):
        d = f.default
        kind = type(d) if not isinstance(d, tuple) else str
        dims = "2d" if f.name in ONLY_2D else "3d" if f.name in ONLY_3D else "both"
        out.append(Option(f.name, kind, d, f.name.replace("_", " "), CHOICES.get(f.name),
                          0 if kind in (int, float) else None, None, dims,
                          f.name in ("n_fourier", "n_radii", "mapping", "sdf", "min_area")))
    return tuple(out)


OPTIONS = _provisional()
