"""The feature table's format, in one place: column names and what a table must carry.

A feature table (from :func:`napari_pfsdm.measure`, or read back from CSV) has one row per
(frame, label), base columns (:data:`BASE_COLUMNS`), then ``shape_rXX_nYY`` and optionally
``intensity_rXX_nYY`` columns (ring ``XX``, Fourier index ``YY``), and its options in
``attrs["pfsdm"]``: at least ``n_fourier`` and the rings' quadrature ``weights``. The
outline's normalised Fourier coefficients (what the boundary term of the default distance
compares, :mod:`napari_pfsdm.core.boundary`) follow as ``outline_n±KK_re`` /
``outline_n±KK_im`` (:func:`outline_columns`: 64 columns, 512 bytes per row in memory, about
1.2 kB per row in a CSV written with exact numbers). Distances and
PCA need all of these; :func:`check_feature_table` refuses a table that lacks any of them
rather than guess (a table re-saved without its options once gave other distances silently).

Pure Python: no pandas import (the table is anything with ``columns`` and ``attrs``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

__all__ = [
    "BASE_COLUMNS",
    "CHANNELS",
    "check_feature_table",
    "feature_columns",
    "has_channel",
    "has_outline",
    "outline_columns",
]

#: Columns before the features, in this order.
BASE_COLUMNS = ["frame", "label", "area", "centroid_y", "centroid_x", "touches_border",
                "n_components", "n_holes", "folded_fraction", "error", "warnings"]
#: Feature channels and their column prefixes.
CHANNELS = ("shape", "intensity")


def feature_columns(n_radii: int, n_fourier: int, channel: str = "shape") -> list[str]:
    """Column names ``{channel}_rXX_nYY`` (ring-major), as in :func:`measure`'s table.

    Examples
    --------
    >>> feature_columns(2, 1)
    ['shape_r00_n00', 'shape_r00_n01', 'shape_r01_n00', 'shape_r01_n01']
    """
    return [f"{channel}_r{r:02d}_n{n:02d}" for r in range(n_radii) for n in range(n_fourier + 1)]


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
    options, n_radii, n_fourier

    Raises
    ------
    ValueError
        The options are missing (no ``attrs["pfsdm"]`` with ``weights`` and ``n_fourier``), or
        feature columns are missing; the message names them and says what to do.
    """
    opts = getattr(table, "attrs", {}).get("pfsdm") or {}
    missing_opts = [k for k in ("weights", "n_fourier") if opts.get(k) is None]
    if missing_opts:
        raise ValueError(
            f"{where} does not say how it was measured (no {' or '.join(missing_opts)} in its "
            "options), so its distances cannot be computed correctly. Keep the .csv.json file "
            "that 'pfsdm measure' writes next to the .csv (read tables with "
            "napari_pfsdm.read_table), or measure again"
        )
    n_radii, n_fourier = len(opts["weights"]), int(opts["n_fourier"])
    columns = set(map(str, table.columns))
    for channel in channels:
        expected = feature_columns(n_radii, n_fourier, channel)
        missing = [c for c in expected if c not in columns]
        if len(missing) == len(expected):
            if channel == "intensity":
                raise ValueError(
                    f"{where} has no intensity features; measure with an intensity image "
                    "(--intensity IMAGE) or leave the intensity out"
                )
            raise ValueError(
                f"{where} has no shape_rXX_nYY feature columns: it is not a PF-SDM feature "
                "table; make one with: pfsdm measure LABELS -o features.csv"
            )
        if missing:
            raise ValueError(
                f"{where} misses {len(missing)} of its {len(expected)} {channel} feature "
                f"columns ({_span(missing)}); it was cut or edited. Use the table as "
                "'pfsdm measure' wrote it, or measure again"
            )
    return opts, n_radii, n_fourier
