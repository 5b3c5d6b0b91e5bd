"""The feature table's format, in one place: column names and what a table must carry.

A feature table (from :func:`napari_pfsdm.measure`, or read back from CSV) has one row per
(frame, label), base columns (:data:`BASE_COLUMNS`; a linked table also a ``track_id`` after
``label``, :data:`OPTIONAL_BASE_COLUMNS`), then ``shape_rXX_nYY`` and optionally
``intensity_rXX_nYY`` columns (ring ``XX``, Fourier index ``YY``), and its options in
``attrs["pfsdm"]``: at least ``n_fourier`` and the rings' quadrature ``weights``. The
outline's normalised Fourier coefficients (what the boundary term of the default distance
compares, :mod:`napari_pfsdm.core.boundary`) follow as ``outline_n±KK_re`` /
``outline_n±KK_im`` (:func:`outline_columns`: 64 columns, 512 bytes per row in memory, about
1.2 kB per row in a CSV written with exact numbers), then the outline signature of the
elastic term (:mod:`napari_pfsdm.core.elastic`) as ``elastic_cC_pPP`` (channel C, point PP;
:func:`signature_columns`: 7 × 64 = 448 columns).

A table of 3-D objects (its options say ``ndim: 3``) has :data:`BASE_COLUMNS_3D`, then
``shape_rXX_lYY`` (shell ``XX``, spherical-harmonic degree ``YY``: √P_l(r)), ``surface_lYY``
(the outer surface's radial function) and optionally ``intensity_rXX_lYY``; its options add
``sh_degree``, ``surface_weight``, ``axes`` and ``spacing``; no outline columns. Distances and
PCA need all of these; :func:`check_feature_table` refuses a table that lacks any of them
rather than guess (a table re-saved without its options once gave other distances silently).

Pure Python: no pandas import (the table is anything with ``columns`` and ``attrs``).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from typing import Any

from ..errors import InputError

__all__ = [
    "pc_column",
    "pc_columns",
    "BASE_COLUMNS",
    "BASE_COLUMNS_3D",
    "base_columns",
    "surface_columns",
    "table_feature_columns",
    "table_ndim",
    "CHANNELS",
    "NO_TRACK",
    "OPTIONAL_BASE_COLUMNS",
    "TRACK_COLUMN",
    "check_feature_table",
    "feature_columns",
    "has_channel",
    "has_outline",
    "has_signature",
    "outline_columns",
    "signature_columns",
]

#: Columns before the features, in this order.
BASE_COLUMNS = ["frame", "label", "area", "centroid_y", "centroid_x", "touches_border",
                "n_components", "n_holes", "folded_fraction", "error", "warnings"]
#: The identity of an object across frames when labels were linked (or taken from a napari
#: Tracks layer): whole numbers, :data:`NO_TRACK` for rows no track reaches. Placed right after
#: ``label``. When present, trajectories follow it instead of ``label``
#: (:mod:`napari_pfsdm.analysis.tracking`).
TRACK_COLUMN = "track_id"
#: ``track_id`` of a row that belongs to no track: -1 keeps the column whole numbers in CSV
#: (an empty cell would make pandas read 3.0, 4.0, ...).
NO_TRACK = -1
#: Base columns a table may carry besides :data:`BASE_COLUMNS` (added after measuring).
OPTIONAL_BASE_COLUMNS = [TRACK_COLUMN]
#: Columns before the features in a table of 3-D objects: ``volume`` in voxels, the centroid
#: in voxels (z, y, x), ``crossing_fraction`` the share of rays from the centroid that cross
#: the surface more than once.
BASE_COLUMNS_3D = ["frame", "label", "volume", "centroid_z", "centroid_y", "centroid_x",
                   "touches_border", "n_components", "n_holes", "folded_fraction",
                   "crossing_fraction", "error", "warnings"]
#: Feature channels and their column prefixes.
CHANNELS = ("shape", "intensity")


def feature_columns(n_radii: int, n_fourier: int, channel: str = "shape", *,
                    letter: str = "n") -> list[str]:
    """Column names ``{channel}_rXX_nYY`` (ring-major), as in :func:`measure`'s table; with
    ``letter="l"`` the 3-D shells' ``{channel}_rXX_lYY`` (degree l).

    Examples
    --------
    >>> feature_columns(2, 1)
    ['shape_r00_n00', 'shape_r00_n01', 'shape_r01_n00', 'shape_r01_n01']
    >>> feature_columns(1, 1, letter="l")
    ['shape_r00_l00', 'shape_r00_l01']
    """
    return [f"{channel}_r{r:02d}_{letter}{n:02d}" for r in range(n_radii)
            for n in range(n_fourier + 1)]


def surface_columns(sh_degree: int) -> list[str]:
    """The 3-D surface term's columns ``surface_l00`` … ``surface_l{sh_degree}``."""
    return [f"surface_l{n:02d}" for n in range(sh_degree + 1)]


def table_ndim(options: Mapping[str, Any]) -> int:
    """2 or 3: the objects' dimension a table's options record (2 when they do not say)."""
    value = options.get("ndim", 2) or 2
    if isinstance(value, bool) or value not in (2, 3):
        raise InputError(f"the table's options say ndim {value!r}: it must be 2 or 3. Use the "
                         "table with the .json file 'pfsdm' wrote beside it, or measure again.")
    return int(value)


def base_columns(ndim: int = 2) -> list[str]:
    """:data:`BASE_COLUMNS` or :data:`BASE_COLUMNS_3D`."""
    return list(BASE_COLUMNS_3D if ndim == 3 else BASE_COLUMNS)


def table_feature_columns(options: Mapping[str, Any], channel: str = "shape") -> list[str]:
    """Every feature column of ``channel`` that a table with these options has: for 2-D
    ``{channel}_rXX_nYY``; for 3-D ``{channel}_rXX_lYY`` and, for the shape, ``surface_lYY``.
    """
    n_radii = len(options["weights"])
    if table_ndim(options) == 3:
        degree = int(options["sh_degree"])
        cols = feature_columns(n_radii, degree, channel, letter="l")
        return cols + surface_columns(degree) if channel == "shape" else cols
    return feature_columns(n_radii, int(options["n_fourier"]), channel)


def outline_columns(n_modes: int) -> list[str]:
    """Column names of the outline coefficients a_n, n = −K … −1, 1 … K (the order of
    :func:`napari_pfsdm.core.boundary.outline_modes`), real then imaginary part of each.

    Examples
    --------
    >>> outline_columns(1)
    ['outline_n-01_re', 'outline_n-01_im', 'outline_n+01_re', 'outline_n+01_im']
    """
    modes = [-k for k in range(n_modes, 0, -1)] + list(range(1, n_modes + 1))
    return [f"outline_n{n:+03d}_{part}" for n in modes for part in ("re", "im")]


def has_outline(columns: Iterable[str]) -> int:
    """K when the columns hold the outline coefficients ``outline_n±KK_re/im`` (all of
    them, :func:`outline_columns`), else 0."""
    names = {str(c) for c in columns}
    k = sum(1 for c in names if c.startswith("outline_n+") and c.endswith("_re"))
    return k if k and all(c in names for c in outline_columns(k)) else 0


def pc_column(channel: str, k: int) -> str:
    """The one name of a PCA score column: ``{channel}_PC{k}`` (k from 1), as every PCA table
    the package writes names it (``pfsdm trajectories``, the batch reports).

    Examples
    --------
    >>> pc_column("shape", 1)
    'shape_PC1'
    """
    return f"{channel}_PC{int(k)}"


def pc_columns(columns: Iterable[str], channel: str) -> list[str]:
    """The PCA score columns of ``channel`` among ``columns``, in the order PC1, PC2, ….

    Examples
    --------
    >>> pc_columns(["frame", "shape_PC2", "shape_PC1", "intensity_PC1"], "shape")
    ['shape_PC1', 'shape_PC2']
    """
    prefix = pc_column(channel, 0)[:-1]
    found = [c for c in columns if str(c).startswith(prefix) and str(c)[len(prefix):].isdigit()]
    return sorted(found, key=lambda c: int(str(c)[len(prefix):]))


def has_channel(columns: Iterable[str], channel: str) -> bool:
    """True when any ``{channel}_rXX_nYY`` column is present."""
    prefix = f"{channel}_r"
    return any(str(c).startswith(prefix) for c in columns)


def _span(names: list[str]) -> str:
    return names[0] if len(names) == 1 else f"{names[0]} … {names[-1]} ({len(names)} columns)"


def check_feature_table(
    table: Any, channels: Iterable[str] = ("shape",), *, where: str = "the table"
) -> tuple[Mapping[str, Any], int, int]:
    """Check that a table carries its options and every feature column of ``channels``.

    Parameters
    ----------
    table : DataFrame-like
        With ``columns`` and ``attrs``.
    channels : iterable of str
        ``"shape"`` and/or ``"intensity"``.
    where : str
        How to name the table in messages (e.g. its file name).

    Returns
    -------
    options, n_radii, n_modes
        ``n_modes`` is ``n_fourier`` (2-D) or ``sh_degree`` (3-D).

    Raises
    ------
    ValueError
        The options are missing (no ``attrs["pfsdm"]`` with ``weights`` and ``n_fourier``) or
        wrong (:func:`~napari_pfsdm.core.params.check_record`: out of range, NaN or negative
        weights, a wrong number of them), or feature columns are missing or more than the
        options account for; the message names them and says what to do.
    """
    from .params import check_record

    opts = getattr(table, "attrs", {}).get("pfsdm") or {}
    check_record(opts, f"the options of {where}")
    needed = ("weights", "sh_degree", "surface_weight") if table_ndim(opts) == 3 else \
        ("weights", "n_fourier")
    missing_opts = [k for k in needed if opts.get(k) is None]
    if missing_opts:
        raise InputError(
            f"{where} does not say how it was measured (no {' or '.join(missing_opts)} in its "
            "options), so its distances cannot be computed correctly. Keep the .csv.json file "
            "that 'pfsdm measure' writes next to the .csv (read tables with "
            "napari_pfsdm.read_table), or measure again"
        )
    n_radii = len(opts["weights"])
    n_modes = int(opts["sh_degree"] if table_ndim(opts) == 3 else opts["n_fourier"])
    names = table.columns
    columns = set(map(str, names.tolist() if hasattr(names, "tolist") else names))
    for channel in channels:
        expected = table_feature_columns(opts, channel)
        missing = [c for c in expected if c not in columns]
        if len(missing) == len(expected):
            if channel == "intensity":
                raise InputError(
                    f"{where} has no intensity features; measure with an intensity image "
                    "(--intensity IMAGE) or leave the intensity out"
                )
            raise InputError(
                f"{where} has no shape_rXX_{'l' if table_ndim(opts) == 3 else 'n'}YY feature "
                "columns: it is not a PF-SDM feature "
                "table; make one with: pfsdm measure LABELS -o features.csv"
            )
        if missing:
            raise InputError(
                f"{where} misses {len(missing)} of its {len(expected)} {channel} feature "
                f"columns ({_span(missing)}); it was cut or edited. Use the table as "
                "'pfsdm measure' wrote it, or measure again"
            )
        feature = re.compile(rf"{channel}_r\d+_[nl]\d+")
        extra = sorted(c for c in columns.difference(expected)
                       if c.startswith(f"{channel}_r") and feature.fullmatch(c))
        if extra:
            raise InputError(
                f"{where} has {len(extra)} {channel} feature columns more than its options "
                f"account for ({_span(extra)}): its options (the .json file beside it) belong "
                "to another table. Use the table with its own .json file, or measure again"
            )
    return opts, n_radii, n_modes


def signature_columns(n_channels: int, n_points: int) -> list[str]:
    """Column names of the elastic term's outline signature, channel-major:
    ``elastic_cC_pPP`` (:func:`napari_pfsdm.core.elastic_signature.outline_signature`).

    Examples
    --------
    >>> signature_columns(2, 2)
    ['elastic_c0_p00', 'elastic_c0_p01', 'elastic_c1_p00', 'elastic_c1_p01']
    """
    return [f"elastic_c{c}_p{p:02d}" for c in range(n_channels) for p in range(n_points)]


def has_signature(columns: Iterable[str]) -> tuple[int, int]:
    """(channels, points) when the columns hold a whole outline signature
    (:func:`signature_columns`), else (0, 0)."""
    names = {str(c) for c in columns}
    n_ch = sum(1 for c in names if c.startswith("elastic_c") and c.endswith("_p00"))
    n_pt = sum(1 for c in names if c.startswith("elastic_c0_p"))
    if n_ch and n_pt and all(c in names for c in signature_columns(n_ch, n_pt)):
        return n_ch, n_pt
    return 0, 0
