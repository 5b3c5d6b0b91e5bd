"""The method's options, each declared once, and the frozen, validated record built from them.

:data:`OPTIONS` holds one :class:`Option` per option of :func:`napari_pfsdm.pfsdm`: its name,
type, default, allowed range or choices, a one-line help text in plain words, the objects it
applies to (2-D masks, 3-D volumes or both) and whether a form shows it by default (``basic``).
Everything else is generated from it: :class:`PFSDMParams` (the record ``measure``, the batch
and the plugin pass around), :data:`CHOICES`, the keywords of ``pfsdm()`` and of the
scikit-learn transformer (:func:`with_option_keywords`) and the command line's method options;
the napari plugin builds its form from it. A bad value gets the same plain message from every door
(:meth:`Option.check`), and a table's record read back from a file is checked the same way,
with its ring and mode weights (:func:`check_record`), before any work.

The pattern is scikit-learn's ``_parameter_constraints``: constraints as data, one checker.
This module imports numpy only (the napari panel builds its form from it without loading
scipy or scikit-image).

Its length (about 700 lines, most of them the :data:`OPTIONS` entries and their words) is the
point: every option, its range, its help and its rules between options in one place, so that
no door declares one again.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, fields, make_dataclass, replace
from functools import lru_cache
from numbers import Integral, Real
from typing import Any

import numpy as np

from ..errors import InputError
from .choices import (
    ANTERIOR_RULES,
    BALL_MAPS,
    DEFAULT_MIN_AREA,
    IDENTITIES,
    KEEP_OR_LEAVE_OUT,
    MAPPINGS,
    SDF_KINDS,
)
from .morphometric import (
    NORMALIZATIONS,
    RADII_PLACEMENTS,
    RING_WEIGHTINGS,
    mode_weights,
    ring_radii,
    ring_weights,
)

__all__ = [
    "CHOICES",
    "DERIVED",
    "MIDLINE_OPTIONS",
    "ONLY_2D",
    "ONLY_3D",
    "OPTIONS",
    "LEAVE_OUT_OPTIONS",
    "LINK_OPTION",
    "SELECTION_OPTIONS",
    "Option",
    "PFSDMParams",
    "as_params",
    "check_record",
    "leave_out_of",
    "option",
    "params_of",
    "with_option_keywords",
]

#: The objects an option may apply to.
DIMS = ("2d", "3d", "both")


def _number(x: float) -> str:
    """A bound as a person writes it: 1, 0.5, 4096 (never 1.0 or 4.096e+03)."""
    return f"{x:g}" if isinstance(x, float) else str(x)


def _shown(value: Any, limit: int = 60) -> str:
    """``repr(value)``, cut short for a long list."""
    text = repr(value.tolist() if isinstance(value, np.ndarray) else value)
    return text if len(text) <= limit else text[: limit - 5] + " …" + text[-1]


@dataclass(frozen=True)
class Option:
    """One option of the method: what it is, what it may be, and where it applies.

    Attributes
    ----------
    name : str
        The keyword of :func:`napari_pfsdm.pfsdm` (``--n-fourier`` on the command line).
    kind : type
        ``int``, ``float`` or ``str`` (a choice).
    default : int, float or str
        The value used when the option is not given.
    help : str
        One line in plain words, for forms and ``--help``.
    choices : tuple of str, optional
        The allowed values of a ``str`` option.
    low, high : int or float, optional
        The allowed range of a number (None: no bound on that side). For an option that also
        takes numbers (``numbers``), the range of each number.
    low_inclusive, high_inclusive : bool
        Whether ``low`` and ``high`` themselves are allowed.
    dims : {"2d", "3d", "both"}
        The objects the option applies to: 2-D masks, 3-D volumes, or both.
    basic : bool
        True for the few options a biologist may want to change in a form; the others stay
        behind an "advanced" fold.
    numbers : bool
        A choice option that also takes a list of numbers in (``low``, ``high``) instead
        (``radii``: the rings' radii given explicitly).
    only_with : (str, str) or None
        The option applies only when another option has a value (``viscosity`` with
        ``sdf="viscous"``): a form shows it only then.
    """

    name: str
    kind: type
    default: Any
    help: str
    choices: tuple[str, ...] | None = None
    low: float | None = None
    high: float | None = None
    low_inclusive: bool = True
    high_inclusive: bool = True
    dims: str = "both"
    basic: bool = False
    numbers: bool = False
    only_with: tuple[str, str] | None = None

    def applies(self, values: Mapping[str, Any]) -> bool:
        """Whether the option applies, given the other options' ``values`` (:attr:`only_with`).

        >>> option("viscosity").applies({"sdf": "exact"}), option("viscosity").applies({})
        (False, False)
        """
        if self.only_with is None:
            return True
        name, value = self.only_with
        return values.get(name, option(name).default) == value

    def __post_init__(self) -> None:
        if self.kind not in (int, float, str) or self.dims not in DIMS:
            raise TypeError(f"option {self.name}: kind must be int, float or str and dims one "
                            f"of {DIMS}")
        if (self.kind is str) != (self.choices is not None):
            raise TypeError(f"option {self.name}: a str option needs choices, a number none")
        self.check(self.default)  # a default outside its own range is a bug, found at import

    @property
    def flag(self) -> str:
        """The command line's name of the option: ``--n-fourier`` for ``n_fourier``."""
        return "--" + self.name.replace("_", "-")

    def _range(self) -> str:
        low, high = self.low, self.high
        if low is not None and high is not None and self.low_inclusive and self.high_inclusive:
            return f"from {_number(low)} to {_number(high)}"
        words = []
        if low is not None:
            words.append(f"{'at least' if self.low_inclusive else 'above'} {_number(low)}")
        if high is not None:
            words.append(f"{'at most' if self.high_inclusive else 'below'} {_number(high)}")
        return " and ".join(words)

    def allowed(self) -> str:
        """What the option may be, in words (the end of its error message).

        Examples
        --------
        >>> option("n_fourier").allowed()
        'a whole number from 1 to 256'
        >>> option("viscosity").allowed()
        'a number above 0 and at most 1'
        """
        if self.kind is str:
            text = f"one of {', '.join(self.choices or ())}"
            if self.numbers:
                text += f", or numbers {self._range().replace('above', 'strictly above')}"
            return text
        what = "a whole number" if self.kind is int else "a number"
        bounds = self._range()
        if bounds.startswith("at "):
            bounds = "of " + bounds
        return f"{what} {bounds}" if bounds else what

    def message(self, value: Any) -> str:
        """The one message for a bad ``value``, whichever door it came through."""
        return f"{self.name} must be {self.allowed()}; got {_shown(value)}."

    def _in_range(self, x: float) -> bool:
        if not math.isfinite(x):
            return False
        if self.low is not None and (x < self.low or (x == self.low and not self.low_inclusive)):
            return False
        return not (self.high is not None
                    and (x > self.high or (x == self.high and not self.high_inclusive)))

    def check(self, value: Any) -> Any:
        """``value`` as the option's type (``6.0`` → ``6`` for a whole number, a list of radii →
        a tuple of floats), or :class:`~napari_pfsdm.errors.InputError` with :meth:`message`.

        Text is refused for a number (the command line parses it first, :meth:`parse`), as are
        booleans, NaN, infinities and values out of range.

        Examples
        --------
        >>> option("n_fourier").check(6.0)
        6
        >>> option("n_fourier").check("ten")
        Traceback (most recent call last):
        ...
        napari_pfsdm.errors.InputError: n_fourier must be a whole number from 1 to 256; got 'ten'.
        """
        if self.kind is str:
            if isinstance(value, str):
                if value in (self.choices or ()):
                    return str(value)
                raise InputError(self.message(value))
            if self.numbers:
                return self._check_numbers(value)
            raise InputError(self.message(value))
        if isinstance(value, bool | np.bool_) or not isinstance(value, Real):
            raise InputError(self.message(value))
        x = float(value)
        if not self._in_range(x):
            raise InputError(self.message(value))
        if self.kind is int:
            if isinstance(value, Integral):
                return int(value)
            if not x.is_integer():
                raise InputError(self.message(value))
            return int(x)
        return x

    def _check_numbers(self, value: Any) -> tuple[float, ...]:
        try:
            arr = np.asarray(value, dtype=float).ravel()
        except (TypeError, ValueError):
            raise InputError(self.message(value)) from None
        if (arr.size == 0 or arr.size > _MAX_RINGS
                or not all(self._in_range(float(x)) for x in arr)):
            raise InputError(self.message(value))
        return tuple(float(x) for x in arr)

    def parse(self, text: str) -> Any:
        """The value of the option written as ``text`` (the command line), checked.

        Examples
        --------
        >>> option("n_fourier").parse("12"), option("mode_exponent").parse("0.5")
        (12, 0.5)
        """
        if self.kind is str:
            return self.check(text)
        value: Any = text
        for read in ((float,) if self.kind is float else (int, float)):  # int: "1e3" too
            try:
                value = read(text)
                break
            except ValueError:
                continue
        return self.check(value)  # text that is no number: refused with the option's words


#: Upper bounds that keep one object's memory small: rings × angles samples of the disk, and
#: (N_F + 1) or (L + 1) columns per ring. A value beyond them is a typing mistake, refused
#: before anything is allocated.
_MAX_RINGS = 512

#: The largest weight (of a ring, a Fourier index or degree, a channel or a term of the
#: distance) that the distances take. Features are bounded (signed distances within a few
#: object radii, Fourier magnitudes of at most a few hundred), so weights up to this keep every
#: distance below about 1e60, far from a float's overflow (1.8e308); a weight of 1e308 made
#: every distance ``inf - inf = NaN`` and is refused instead.
MAX_WEIGHT = 1e12

#: Every option of the method, in the order of :class:`PFSDMParams`' fields. Defaults were
#: chosen on the benchmarks (README, "How the defaults were chosen").
OPTIONS: tuple[Option, ...] = (
    Option("n_fourier", int, 10,
           "how much outline detail is kept: Fourier modes per ring",
           low=1, high=256, dims="2d", basic=True),
    Option("n_radii", int, 16,
           "rings sampled from the object's centre to its outline",
           low=1, high=_MAX_RINGS, basic=True),
    Option("n_angles", int, 64,
           "samples around each ring (an even number)",
           low=8, high=4096, dims="2d"),
    Option("sdf", str, "exact",
           "distance to the outline: 'exact' (fast) or 'viscous' (the paper's smoothed "
           "version, ~25x slower)",
           choices=SDF_KINDS, dims="2d", basic=True),
    Option("viscosity", float, 0.05,
           "smoothing of the viscous distance, in object sizes",
           low=0.0, high=1.0, low_inclusive=False, dims="2d", only_with=("sdf", "viscous")),
    Option("mapping", str, "harmonic",
           "how the unit disk is laid onto the object: 'harmonic' (fast), 'bijective' (never "
           "folds; for snake-like or branched objects), 'radial' (the paper's; round, "
           "star-shaped objects only)",
           choices=MAPPINGS, dims="2d", basic=True),
    Option("normalization", str, "none",
           "'ring' rescales each ring's modes to unit length as in the paper (unstable for "
           "near-round objects)",
           choices=NORMALIZATIONS, dims="2d"),
    Option("radii", str, "uniform",
           "ring placement: 'uniform' or 'boundary' (packed toward the outline, where shapes "
           "differ most)",
           choices=RADII_PLACEMENTS, low=0.0, high=1.0, low_inclusive=False,
           high_inclusive=False, numbers=True),
    Option("ring_weighting", str, "depth",
           "extra weight of the outer rings in distances",
           choices=RING_WEIGHTINGS),
    Option("mode_exponent", float, 0.25,
           "how much distances stress fine outline detail: they compare (1 + n)^exponent "
           "|c_n|; 0 is the paper's choice",
           low=0.0, high=4.0),
    Option("elastic_smoothing", float, 4.0,
           "smoothing of the outline signature that the elastic term of distances compares, "
           "in 1/256 of the outline's length",
           low=0.0, high=32.0, dims="2d"),
    Option("elastic_signature", str, "none",
           "'table': each row carries the outline signature (448 elastic_* columns) that the "
           "opt-in elastic term of distances (elastic_weight) compares; 'none' keeps tables "
           "small",
           choices=("none", "table"), dims="2d"),
    Option("components", str, "largest",
           "an object in several pieces: keep the 'largest' or report an error for it "
           "('raise')",
           choices=("largest", "raise")),
    Option("min_area", int, DEFAULT_MIN_AREA,
           "objects smaller than this (pixels, or voxels in 3-D) get an error instead of "
           "features",
           low=1, high=10**9, basic=True),  # above: no object of any image would be kept
    Option("border_objects", str, "keep",
           "objects touching the image border (maybe cut off): 'keep' them in PCA, comparison "
           "and prediction, or 'leave_out' (their rows stay in the table)",
           choices=KEEP_OR_LEAVE_OUT, basic=True),
    Option("warned_objects", str, "keep",
           "objects with warnings (a map that folds, several pieces, holes filled): 'keep' "
           "them in PCA, comparison and prediction, or 'leave_out'",
           choices=KEEP_OR_LEAVE_OUT, basic=True),
    Option("sh_degree", int, 8,
           "highest spherical-harmonic degree per shell",
           low=1, high=40, dims="3d"),
    Option("surface_weight", float, 4.0,
           "weight of the outer surface's term in distances",
           low=0.0, high=MAX_WEIGHT, dims="3d"),
    Option("ball_map", str, "radial",
           "how the unit ball is laid onto the object",
           choices=BALL_MAPS, dims="3d"),
    Option("profile_bins", int, 0,
           "the object's own axis (midline length, widths, reporter profile, polarity "
           "direction): pieces of the midline for its width and reporter profiles, e.g. 10 "
           "for gastruloids; 0 (default): no midline measures (each object costs about 2 ms "
           "more with them)",
           low=0, high=100, dims="2d", basic=True),
    Option("anterior", str, "reporter",
           "which end of the midline its profiles start from: 'reporter' (the reporter's high "
           "end), 'reporter_low', 'first' (the top end, or the left one for a left-right "
           "axis) or 'last'",
           choices=ANTERIOR_RULES, dims="2d"),
)

#: The weights of the distance's terms: ``pfsdm compare``'s ``--intensity-weight`` and
#: ``--boundary-weight``, the same keywords of the distance functions, and the entries of a
#: sidecar that records them. Not options of the measurement (no field of PFSDMParams).
WEIGHT_OPTIONS: tuple[Option, ...] = (
    Option("intensity_weight", float, 0.0,
           "weight of the reporter pattern in the distance (0: shape only)",
           low=0.0, high=MAX_WEIGHT),
    # λ = 1: why, at core.distances.BOUNDARY_WEIGHT (which reads it here)
    Option("boundary_weight", float, 1.0,
           "weight of the outline (boundary) term in the distance (0: the pushed-forward SDF "
           "alone)",
           low=0.0, high=MAX_WEIGHT),
    Option("elastic_weight", float, 0.0,
           "weight of the opt-in elastic outline term in the distance (0: off; 0.375 retrieves "
           "best on MPEG-7); needs the objects' outline signatures",
           low=0.0, high=MAX_WEIGHT),
)

#: How objects keep their identity through time: one vocabulary for ``pfsdm measure --link``,
#: the table-reading commands' ``--link``, the plugin's Identity choice,
#: :func:`~napari_pfsdm.analysis.tracking.link_movie` and the table's sidecar (``link``).
LINK_OPTION = Option(
    "link", str, "auto",
    "how objects keep their identity through time: 'auto' links them only when their label "
    "ids do not follow them (per-frame segmentation, e.g. cellpose), 'labels' trusts the "
    "label ids, 'centroid', 'overlap' (of the masks) or 'laptrack' always link that way",
    choices=IDENTITIES)

_BY_NAME: dict[str, Option] = {o.name: o for o in (*OPTIONS, *WEIGHT_OPTIONS, LINK_OPTION)}


def option(name: str) -> Option:
    """The :class:`Option` called ``name``.

    Examples
    --------
    >>> option("mapping").choices
    ('harmonic', 'bijective', 'radial')
    """
    return _BY_NAME[name]


#: Allowed values of the options that are a choice.
CHOICES: dict[str, tuple[str, ...]] = {o.name: o.choices for o in OPTIONS if o.choices}

#: Keys a table's record holds that are derived from the options or describe the input (its
#: dimension, axes and voxel size), not options themselves.
DERIVED = ("weights", "mode_weights", "ndim", "axes", "spacing")

#: Options that apply to 2-D masks only, and to 3-D masks only (docs/design.md §6.6).
ONLY_2D = tuple(o.name for o in OPTIONS if o.dims == "2d")
ONLY_3D = tuple(o.name for o in OPTIONS if o.dims == "3d")

#: Options that choose which objects are measured, not how: tables measured with different
#: values of them still share one shape space.
SELECTION_OPTIONS = ("components", "min_area", "border_objects", "warned_objects")

#: Options that leave measured objects out of shape spaces (PCA, distances, neighbours,
#: prediction, plots, the report), read from the table's record where a shape space is built
#: (:func:`leave_out_of`). They change nothing that is measured: an
#: :class:`~napari_pfsdm.analysis.measuring.ObjectMeasurer` holds them at their defaults
#: (:meth:`PFSDMParams.measured`), so changing them measures nothing again.
LEAVE_OUT_OPTIONS = ("border_objects", "warned_objects")


def leave_out_of(record: Mapping[str, Any]) -> dict[str, str]:
    """The leave-out options of a table's record (:data:`LEAVE_OUT_OPTIONS`), each checked,
    its default where the record has none.

    Examples
    --------
    >>> leave_out_of({"border_objects": "leave_out"})
    {'border_objects': 'leave_out', 'warned_objects': 'keep'}
    """
    return {name: option(name).check(record.get(name, option(name).default))
            for name in LEAVE_OUT_OPTIONS}

#: Options of the midline measures (:mod:`napari_pfsdm.core.midline`), not of the features:
#: tables measured with different values of them still share one shape space.
MIDLINE_OPTIONS = ("profile_bins", "anterior")


def _check_together(values: Mapping[str, Any]) -> None:
    """The rules between options (each already checked alone); an absent one is skipped."""
    n_angles, n_fourier = values.get("n_angles"), values.get("n_fourier")
    if n_angles is not None and n_angles % 2:
        raise InputError(f"n_angles must be an even number of at least 8, got {n_angles}.")
    if n_angles is not None and n_fourier is not None and n_fourier >= n_angles // 2 + 1:
        # as core.morphometric.magnitude_embedding
        raise InputError(f"n_fourier={n_fourier} needs more than {2 * n_fourier} angles; "
                         "raise n_angles.")


class _ParamsMethods:
    """The behaviour of :class:`PFSDMParams`; its fields come from :data:`OPTIONS`."""

    def __post_init__(self) -> None:
        for opt in OPTIONS:
            object.__setattr__(self, opt.name, opt.check(getattr(self, opt.name)))
        _check_together(self.__dict__)

    @classmethod
    def from_options(cls, options: Mapping[str, Any] | None = None, /,
                     **more: Any) -> PFSDMParams:
        """From keyword options (as ``measure(**options)`` takes them) or a table's record.

        Unknown names are refused with the list of known ones; the derived entries of a record
        (``weights``, ``mode_weights``, …) are checked (:func:`check_record`) and left out, and
        a record's explicit ``radii`` list is kept as numbers.
        """
        merged = {**(options or {}), **more}
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(merged) - known - set(DERIVED))
        if unknown:
            raise InputError(
                f"unknown option{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}; "
                f"the options are {', '.join(sorted(known))}"
            )
        if any(k in merged for k in DERIVED):
            check_record(merged, "the options")
        return cls(**{k: v for k, v in merged.items() if k in known})

    def measured(self) -> PFSDMParams:
        """The record of what is measured: this one with the options that only leave objects
        out of shape spaces (:data:`LEAVE_OUT_OPTIONS`) at their defaults.

        >>> PFSDMParams(border_objects="leave_out", n_fourier=6).measured() == \\
        ...     PFSDMParams(n_fourier=6)
        True
        """
        defaults = {name: option(name).default for name in LEAVE_OUT_OPTIONS}
        if all(getattr(self, k) == v for k, v in defaults.items()):
            return self  # type: ignore[return-value]
        return replace(self, **defaults)  # type: ignore[type-var]

    def leave_out(self) -> dict[str, str]:
        """The values of :data:`LEAVE_OUT_OPTIONS` (what a table's record adds to what was
        measured)."""
        return {name: getattr(self, name) for name in LEAVE_OUT_OPTIONS}

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
        other = ONLY_2D if ndim == 3 else ONLY_3D
        changed = [n for n in other if getattr(self, n) != option(n).default]
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
        radii = self.radii  # type: ignore[attr-defined]
        r = ring_radii(self.n_radii,  # type: ignore[attr-defined]
                       np.asarray(radii) if isinstance(radii, tuple) else radii)
        out["radii"] = r.tolist()
        out["n_radii"] = len(r)
        out["weights"] = ring_weights(r, self.ring_weighting).tolist()  # type: ignore
        n_modes = (self.sh_degree if ndim == 3  # type: ignore[attr-defined]
                   else self.n_fourier)  # type: ignore[attr-defined]
        out["mode_weights"] = mode_weights(n_modes,
                                           self.mode_exponent).tolist()  # type: ignore
        if ndim == 3:
            out["ndim"] = 3
        return out


def _annotation(opt: Option) -> Any:
    return str | tuple[float, ...] if opt.numbers else opt.kind


PFSDMParams = make_dataclass(
    "PFSDMParams",
    [(o.name, _annotation(o), field(default=o.default, metadata={"option": o}))
     for o in OPTIONS],
    bases=(_ParamsMethods,),
    frozen=True,
    namespace={"__module__": __name__, "__doc__": """\
Every option of :func:`napari_pfsdm.pfsdm`, validated: one field per :data:`OPTIONS` entry,
with its default (``dataclasses.fields(PFSDMParams)[i].metadata["option"]`` is the entry).

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
"""},
)


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


def _key(value: Any) -> Any:
    """A hashable stand-in for an option's value that tells ``True`` from ``1``."""
    if isinstance(value, np.ndarray):
        value = tuple(value.ravel().tolist())
    elif isinstance(value, list):
        value = tuple(value)
    hash(value)
    return type(value).__name__, value


@lru_cache(maxsize=64)
def _params_cached(key: tuple) -> PFSDMParams:
    return PFSDMParams.from_options({name: value for name, (_, value) in key})


def params_of(options: Mapping[str, Any]) -> PFSDMParams:
    """:meth:`PFSDMParams.from_options` of keyword options, remembered for the last few sets
    of values (``pfsdm`` is called once per object with the same options)."""
    try:
        key = tuple(sorted((k, _key(v)) for k, v in options.items()))
    except TypeError:  # an unhashable value: checked (and refused) without the memory
        return PFSDMParams.from_options(options)
    return _params_cached(key)


def with_option_keywords(func: Callable) -> inspect.Signature:
    """The signature of ``func`` with its ``**options`` replaced by one keyword-only parameter
    per :data:`OPTIONS` entry (its default and type): what ``help()``, IDEs and
    scikit-learn's ``get_params`` read. Set it as ``func.__signature__``."""
    params = [p for p in inspect.signature(func).parameters.values()
              if p.kind is not inspect.Parameter.VAR_KEYWORD]
    at = next((i for i, p in enumerate(params) if p.kind is inspect.Parameter.KEYWORD_ONLY),
              len(params))
    added = [inspect.Parameter(o.name, inspect.Parameter.KEYWORD_ONLY, default=o.default,
                               annotation=_annotation(o)) for o in OPTIONS]
    return inspect.Signature(params[:at] + added + params[at:])


# ------------------------------------------------------------------------------------------
# a table's record read back from a file


def _numbers(name: str, value: Any, count: int | None, what: str,
             whats: str) -> np.ndarray:
    """``value`` as ``count`` finite numbers from 0 to :data:`MAX_WEIGHT`, not all 0, one per
    ``what`` (plural ``whats``), or a plain refusal."""
    words = f"{count} numbers" if count is not None else "numbers"
    bad = (f"{name} must be {words} of at least 0 and at most {MAX_WEIGHT:g}, one per {what} "
           f"(not all 0); got {_shown(value)}.")
    if isinstance(value, str | bytes | Mapping) or value is None:
        raise InputError(bad)
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(bad) from None
    if arr.ndim != 1 or arr.size == 0 or arr.size > _MAX_RINGS + 1:
        raise InputError(bad)
    if count is not None and arr.size != count:
        raise InputError(
            f"{name} has {arr.size} numbers but the table has {count} {whats}: its distances "
            "would weigh other columns than those measured."
        )
    if (not np.all(np.isfinite(arr)) or np.any(arr < 0) or not np.any(arr > 0)
            or np.any(arr > MAX_WEIGHT)):
        raise InputError(bad)
    return arr


def check_record(record: Mapping[str, Any], where: str = "the table's options") -> None:
    """Refuse a table's record (``attrs["pfsdm"]``, a sidecar's ``options``) that would make
    wrong numbers or exhaust memory, before any work.

    Each option present is checked as :meth:`Option.check` (the same message as from any other
    door), with the rules between them; ``n_radii``, the ring ``weights`` (one finite number
    >= 0 per ring), the ``mode_weights`` (one per Fourier index 0 … ``n_fourier``, or per degree
    0 … ``sh_degree`` in 3-D), ``ndim`` (2 or 3) and ``spacing`` (3 positive numbers) likewise.
    Entries that are absent (records of older versions) and other keys (the run's
    bookkeeping, e.g. ``intensity_weight``) pass.

    Parameters
    ----------
    record : mapping
        The options as read.
    where : str
        How to name the record in messages (e.g. the sidecar's file name).

    Raises
    ------
    InputError
        Naming ``where``, the entry and what it must be.

    Examples
    --------
    >>> try:
    ...     check_record({"n_fourier": 2, "weights": [0.5, float("nan")]})
    ... except InputError as exc:
    ...     print(str(exc)[:62])
    the table's options: weights must be numbers of at least 0 and
    """
    if not isinstance(record, Mapping):
        raise InputError(f"{where} are not a set of named options; got {_shown(record)}")
    try:
        _check_record(record)
    except InputError as exc:
        raise InputError(
            f"{where}: {exc} Use the table with the .json file 'pfsdm' wrote beside it, or "
            "measure again."
        ) from None


def _check_record(record: Mapping[str, Any]) -> None:
    values = {o.name: o.check(record[o.name]) for o in OPTIONS if o.name in record}
    for o in WEIGHT_OPTIONS:  # a distance's record (compare's sidecar)
        if record.get(o.name) is not None:
            o.check(record[o.name])
    if "n_radii" in record:
        values["n_radii"] = option("n_radii").check(record["n_radii"])
    _check_together(values)
    ndim = record.get("ndim", 2)
    if ndim is None:
        ndim = 2
    if isinstance(ndim, bool) or ndim not in (2, 3):
        raise InputError(f"ndim must be 2 or 3; got {_shown(ndim)}.")
    n_rings = values.get("n_radii")
    if n_rings is None and isinstance(values.get("radii"), tuple):
        n_rings = len(values["radii"])
    if "weights" in record:
        _numbers("weights", record["weights"], n_rings, "ring", "rings")
    n_modes = values.get("sh_degree" if ndim == 3 else "n_fourier")
    if "mode_weights" in record and record["mode_weights"] is not None:
        _numbers("mode_weights", record["mode_weights"],
                 None if n_modes is None else n_modes + 1,
                 *(("degree", "degrees") if ndim == 3 else ("Fourier index", "Fourier indices")))
    spacing = record.get("spacing")
    if spacing is not None:
        try:
            sp = np.asarray(spacing, dtype=float).ravel()
        except (TypeError, ValueError):
            sp = np.array([np.nan])
        if sp.size != 3 or not np.all(np.isfinite(sp)) or np.any(sp <= 0):
            raise InputError(f"spacing must be 3 positive numbers (Z, Y, X); got "
                             f"{_shown(spacing)}.")
        from .volume_sdf import check_spacing  # its range: one rule for every door

        check_spacing(sp, 3)
