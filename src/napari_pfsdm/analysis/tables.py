"""Feature tables as arrays: the bridge between a table (its columns and options, see
:mod:`napari_pfsdm.core.table_schema`) and the core's distances, which take arrays only.

:func:`distance_matrix` and :func:`weighted_features` accept a feature table or a list of
:class:`~napari_pfsdm.core.descriptor.PFSDMResult`; they are the package's public
``napari_pfsdm.distance_matrix`` and ``napari_pfsdm.weighted_features``.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from ..core import distances as _core
from ..core.distances import Embeddings
from ..core.distances3d import stack_3d
from ..core.morphometric import mode_weights
from ..core.params import leave_out_of
from ..core.table_options import table_options
from ..core.table_schema import (
    NO_TRACK,
    TRACK_COLUMN,
    check_feature_table,
    feature_columns,
    has_outline,
    has_signature,
    outline_columns,
    signature_columns,
    table_feature_columns,
    table_ndim,
)
from ..errors import InputError

__all__ = [
    "distance_matrix",
    "embeddings",
    "embeddings_from_table",
    "failed_rows",
    "left_out_reasons",
    "match_rows",
    "is_table",
    "key_rows",
    "outlines_from_table",
    "signatures_from_table",
    "weighted_features",
]


def key_rows(frames, labels, at_frames, at_labels) -> np.ndarray:
    """Where each (frame, label) pair lies among the pairs (``at_frames``, ``at_labels``).

    The pairs ``at`` are unique (one row per object, as in a feature table); returns the
    position of each pair of ``frames``, ``labels`` among them, −1 where it is absent.

    >>> key_rows([0, 0, 1], [5, 7, 5], [1, 0, 0], [5, 5, 9])
    array([ 1, -1,  0])
    """
    f, af = np.asarray(frames, np.int64), np.asarray(at_frames, np.int64)
    lab, alab = _ids(labels), _ids(at_labels)
    if not len(af) or not len(f):
        return np.full(len(f), -1)
    if lab.dtype != alab.dtype:  # ids of any size: both as unsigned when either is
        lab, alab = lab.astype(np.uint64), alab.astype(np.uint64)
    # each id by its rank among those present, so that a pair is one number without overflow
    # whatever the ids (up to 2**64 - 1) and the frames
    ranks = np.unique(np.concatenate([lab, alab]), return_inverse=True)[1].ravel()
    span = int(ranks.max()) + 1
    r, ar = ranks[: len(lab)].astype(np.int64), ranks[len(lab):].astype(np.int64)
    key, at_key = f * span + r, af * span + ar  # a pair as one number
    order = np.argsort(at_key, kind="stable")
    pos = np.minimum(np.searchsorted(at_key[order], key), len(at_key) - 1)
    return np.where(at_key[order][pos] == key, order[pos], -1)


#: What names a row of a table of many movies: its movie, frame and label.
ROW_KEYS = ("movie", "frame", "label")


def match_rows(left, right) -> np.ndarray:
    """Where each row of ``left`` lies among the rows of ``right``, matched by every key of
    :data:`ROW_KEYS` both tables have (movie, frame and label: two movies' label 1 are two
    objects), −1 where it is absent; the first of repeated rows of ``right``.

    Examples
    --------
    >>> import pandas as pd
    >>> a = pd.DataFrame({"movie": ["m1", "m2"], "frame": [0, 0], "label": [1, 1]})
    >>> b = pd.DataFrame({"movie": ["m2", "m1", "m3"], "frame": [0, 0, 0], "label": [1, 1, 1]})
    >>> match_rows(a, b).tolist()
    [1, 0]
    """
    import pandas as pd

    keys = [k for k in ROW_KEYS if k in left.columns and k in right.columns]
    if not keys:
        raise InputError("the two tables share no movie, frame or label column to match rows")
    there = pd.DataFrame({k: np.asarray(right[k]) for k in keys})
    there["_row"] = np.arange(len(there))
    here = pd.DataFrame({k: np.asarray(left[k]) for k in keys})
    for k in keys:  # text and numbers alike (a label read as 1.0 is label 1)
        kind = "str" if k == "movie" else "int64"
        there[k], here[k] = there[k].astype(kind), here[k].astype(kind)
    found = here.merge(there.drop_duplicates(keys), on=keys, how="left")["_row"]
    return found.fillna(-1).to_numpy(np.int64)
def _ids(values) -> np.ndarray:
    """Object ids as exact whole numbers: int64, or uint64 when they need it (2**63 and up)."""
    arr = np.asarray(values)
    if arr.dtype.kind in "iu":
        return arr
    as_int = [int(v) for v in arr.ravel().tolist()]
    big = any(v >= 2**63 for v in as_int)
    return np.array(as_int, dtype=np.uint64 if big else np.int64)


def is_table(items: Any) -> bool:
    """True for a DataFrame-like feature table (anything with ``columns``)."""
    return hasattr(items, "columns")


def check_table_cells(table, channels: Iterable[str] = ("shape",), *,
                      where: str = "the table") -> None:
    """Refuse, in plain words, cells of a feature table that no measurement writes: text in
    a feature column, a ``frame`` that is not a whole number >= 0, a ``label`` that is not a
    whole number >= 1, a ``track_id`` below -1, and two rows of the same (movie, frame,
    label), whose objects would be counted twice. A table edited by hand or by a spreadsheet
    is the usual cause; rows without features (NaN, an ``error``) are left to
    :func:`failed_rows`.

    Raises
    ------
    InputError
        Naming the row (0 = the first row under the header), the column and the value.
    """
    import pandas as pd

    if not hasattr(table, "columns") or not len(table):
        return
    opts = table_options(table) or {}

    def refuse(i: int, col: str, value: Any, must: str) -> None:
        value = value.item() if isinstance(value, np.generic) else value
        raise InputError(
            f"{where}: row {i} (0 = the first row under the header), column {col!r} holds "
            f"{value!r}, but {must}; the table was edited or damaged. Use the table as "
            "'pfsdm measure' wrote it, or measure again")

    columns = [c for ch in channels for c in table_feature_columns(opts, ch)
               if c in table.columns] if opts else []
    for col in columns:
        values = table[col]
        if values.dtype.kind not in "fiu":
            num = pd.to_numeric(values, errors="coerce")
            bad = np.flatnonzero(num.isna().to_numpy() & values.notna().to_numpy()
                                 & (values.astype(str).str.strip() != "").to_numpy())
            if len(bad):
                refuse(int(bad[0]), col, values.iloc[bad[0]], "a feature is a number")
    for col, low, must in (("frame", 0, "a frame is a whole number of at least 0"),
                           ("label", 1, "a label is a whole number of at least 1 (0 is "
                                        "background)"),
                           (TRACK_COLUMN, NO_TRACK, f"a track_id is a whole number of at "
                                                    f"least {NO_TRACK} (no track)")):
        if col not in table.columns:
            continue
        values = table[col]
        num = pd.to_numeric(values, errors="coerce").to_numpy(dtype=float)
        ok = np.isfinite(num) & (num == np.round(num)) & (num >= low)
        if not ok.all():
            i = int(np.flatnonzero(~ok)[0])
            refuse(i, col, values.iloc[i], must)
    keys = [k for k in ("movie", "frame", "label") if k in table.columns]
    if {"frame", "label"} <= set(keys):
        twice = np.flatnonzero(table.duplicated(keys).to_numpy())
        if len(twice):
            i = int(twice[0])
            row = table.iloc[i]
            what = ", ".join(f"{k} {row[k]}" for k in keys)
            raise InputError(
                f"{where}: {len(twice)} row{'s' if len(twice) > 1 else ''} repeat an object "
                f"of an earlier row (the first: row {i}, {what}); its features would count "
                "twice. Use the table as 'pfsdm measure' wrote it (tables of several runs: "
                "join them with different movie names), or measure again")


def embeddings_from_table(table, channel: str = "shape") -> tuple[np.ndarray, np.ndarray]:
    """Embeddings (n, n_radii, n_fourier + 1) and ring weights from a :func:`measure` table
    (3-D: (n, n_radii + 1, sh_degree + 1), the surface as the last row, its weight last).

    Rows with an ``error`` give NaN embeddings. The table must carry its options
    (``table.attrs["pfsdm"]``, as :func:`napari_pfsdm.measure` and
    :func:`napari_pfsdm.read_table` give it) and every feature column: a table without them is
    refused, never reinterpreted (see :mod:`napari_pfsdm.core.table_schema`).
    """
    opts, n_radii, n_modes = check_feature_table(table, [channel])
    if table_ndim(opts) == 3:  # shells plus the surface row of weight surface_weight
        shells = table[feature_columns(n_radii, n_modes, channel, letter="l")].to_numpy(float)
        shells = shells.reshape(len(table), n_radii, n_modes + 1)
        surface = table[table_feature_columns(opts, "shape")[-(n_modes + 1):]].to_numpy(float) \
            if channel == "shape" else None
        return stack_3d(shells, surface), np.append(np.asarray(opts["weights"], float),
                                                    float(opts["surface_weight"]))
    ordered = feature_columns(n_radii, n_modes, channel)
    values = table[ordered].to_numpy(float).reshape(len(table), n_radii, n_modes + 1)
    return values, np.asarray(opts["weights"], float)


def left_out_reasons(table, options: Mapping[str, Any]) -> np.ndarray:
    """Why each row is left out of shape spaces by the options ``border_objects`` and
    ``warned_objects`` ("" for a row kept), from its ``touches_border`` and ``warnings``.

    Examples
    --------
    >>> import pandas as pd
    >>> t = pd.DataFrame({"touches_border": [True, False, False],
    ...                   "warnings": ["", "", "29 % of the map folds"]})
    >>> left_out_reasons(t, {"border_objects": "leave_out"}).tolist()
    ['touches the image border (border_objects=leave_out)', '', '']
    >>> left_out_reasons(t, {"warned_objects": "leave_out"})[2]
    'warnings: 29 % of the map folds (warned_objects=leave_out)'
    """
    n = len(table)
    out = np.full(n, "", dtype=object)
    leave_out = leave_out_of(options)
    if leave_out["warned_objects"] == "leave_out" and "warnings" in table.columns:
        warn = table["warnings"].fillna("").astype(str).to_numpy()
        out = np.where(warn != "", np.array([f"warnings: {w} (warned_objects=leave_out)"
                                             for w in warn], dtype=object), out)
    if leave_out["border_objects"] == "leave_out" and "touches_border" in table:
        border = table["touches_border"].fillna(False).to_numpy().astype(bool)
        out[border] = "touches the image border (border_objects=leave_out)"
    return out


def failed_rows(table, channels: Iterable[str] = ("shape",)) -> list[tuple[Any, ...]]:
    """Rows of a feature table that have no features for ``channels``, or that its options
    leave out of shape spaces (:func:`left_out_reasons`).

    Returns
    -------
    list of (position, frame, label, reason)
        ``position`` is the row's position in ``table``; ``reason`` the ``error`` text, what
        the ``warnings`` column says about the intensity, or why the options leave it out.
    """
    channels = list(channels)
    opts, _, _ = check_feature_table(table, channels)
    check_table_cells(table, channels)
    n = len(table)
    err = (table["error"].fillna("").astype(str).to_numpy() if "error" in table.columns
           else np.full(n, ""))
    warn = (table["warnings"].fillna("").astype(str).to_numpy() if "warnings" in table.columns
            else np.full(n, ""))
    left = left_out_reasons(table, opts)
    err = np.where(err != "", err, left)
    bad = err != ""
    for channel in channels:
        vals = table[table_feature_columns(opts, channel)].to_numpy(float)
        bad |= ~np.isfinite(vals).all(axis=1)
    frames = table["frame"].to_numpy() if "frame" in table.columns else np.full(n, -1)
    labels = table["label"].to_numpy() if "label" in table.columns else np.full(n, -1)
    out = []
    for i in np.flatnonzero(bad):
        reason = err[i] or next((w for w in warn[i].split("; ") if "intensity" in w), "") \
            or "no features (NaN)"
        out.append((int(i), int(frames[i]), int(labels[i]), reason))
    return out


def embeddings(table, channels: Iterable[str] = ("shape",)) -> Embeddings:
    """The :class:`~napari_pfsdm.core.distances.Embeddings` of a feature table.

    Raises
    ------
    ValueError
        The table lacks its options or feature columns, or has rows without features for
        ``channels`` (named in the message: leave them out with
        :func:`napari_pfsdm.drop_failed`, so that rows and results stay in step).
    """
    channels = list(channels)
    bad = failed_rows(table, channels)
    if bad:
        shown = "; ".join(f"frame {f} label {lab}: {why}" for _, f, lab, why in bad[:5])
        raise InputError(
            f"{len(bad)} of {len(table)} rows have no {' or '.join(channels)} features or are "
            f"left out by the options ({shown}{'; …' if len(bad) > 5 else ''}). Leave them out "
            "first, e.g. napari_pfsdm.drop_failed(table), so that rows and matrix stay in step"
        )
    shape, weights = embeddings_from_table(table, "shape")
    intensity = embeddings_from_table(table, "intensity")[0] if "intensity" in channels else None
    return Embeddings(shape=shape, weights=weights,
                      mode_weights=_mode_weights(table, shape.shape[2]), intensity=intensity,
                      outline=outlines_from_table(table),
                      signature=signatures_from_table(table))


def outlines_from_table(table) -> np.ndarray | None:
    """The outline coefficients (n, 2K) of the boundary term from a table's
    ``outline_n±KK_re/im`` columns; None for a table without them (measured before the
    boundary term)."""
    k = has_outline(table.columns)
    if not k:
        return None
    values = table[outline_columns(k)].to_numpy(float).reshape(len(table), 2 * k, 2)
    return values[..., 0] + 1j * values[..., 1]


def signatures_from_table(table) -> np.ndarray | None:
    """The elastic term's outline signatures (n, channels, points) from a table's
    ``elastic_cC_pPP`` columns; None for a table without them (measured before the term)."""
    n_ch, n_pt = has_signature(table.columns)
    if not n_ch:
        return None
    return table[signature_columns(n_ch, n_pt)].to_numpy(float).reshape(len(table), n_ch, n_pt)


def _mode_weights(table, n_modes: int) -> np.ndarray:
    """The table's mode weights; tables from before them: (1 + n)^exponent (0 when absent)."""
    opts = table_options(table)
    mw = opts.get("mode_weights")
    if mw is None:
        mw = mode_weights(n_modes - 1, float(opts.get("mode_exponent", 0.0)))
    return np.asarray(mw, float)[:n_modes]


def weighted_features(items, channel: str = "shape") -> np.ndarray:
    """Flat feature vectors (n, n_radii × (n_fourier + 1)) scaled by the ring and mode weights,
    so that their Euclidean distances are the PF-SDM (magnitude) distances; use them for PCA
    or any Euclidean method. ``items``: results or a :func:`measure` table (rows without
    features give NaN vectors)."""
    if not is_table(items):
        return _core.weighted_features(items, channel)
    emb, weights = embeddings_from_table(items, channel)
    return _core.weighted_features(
        Embeddings(shape=emb, weights=weights, mode_weights=_mode_weights(items, emb.shape[2])))


def distance_matrix(
    items, intensity_weight: float = 0.0, *, invariance: str | None = None,
    boundary_weight: float | None = None, elastic_weight: float | None = None,
    chunk: int = 128,
) -> np.ndarray:
    """All pairwise PF-SDM distances of results or of a feature table's rows.

    A table holds magnitudes and outline coefficients, so its default distance (SDF
    magnitudes + boundary term) is the same as on the results it was measured from (to
    rounding); it must carry its options, and is refused when rows have no features
    (``ValueError`` naming them): see :func:`napari_pfsdm.drop_failed`. A table measured
    before the boundary term (no ``outline_*`` columns) gives the SDF term alone, with a
    warning. Everything else as :func:`napari_pfsdm.core.distances.distance_matrix`.

    Examples
    --------
    >>> import numpy as np
    >>> from napari_pfsdm import measure
    >>> labels = np.zeros((64, 128), int)
    >>> labels[10:50, 10:50] = 1
    >>> labels[20:40, 70:120] = 2
    >>> d = distance_matrix(measure(labels))
    >>> d.shape, bool(d[0, 1] > 0)
    ((2, 2), True)
    """
    if is_table(items):
        channels = ["shape"] + (["intensity"] if intensity_weight else [])
        volumes = table_ndim(table_options(items)) == 3  # no outline in 3-D
        items = embeddings(items, channels)
        if volumes:
            from ..core.distances import no_boundary_in_3d, no_elastic_in_3d

            boundary_weight = no_boundary_in_3d(boundary_weight)
            elastic_weight = no_elastic_in_3d(elastic_weight)
        elif items.outline is None and boundary_weight is None:
            warnings.warn(
                "This table has no outline_* columns (it was measured before the boundary "
                "term): its distances are the SDF term alone, not the default distance. "
                "Measure again to get the default.", stacklevel=2)
            boundary_weight = 0.0
    return _core.distance_matrix(items, intensity_weight, invariance=invariance,
                                 boundary_weight=boundary_weight,
                                 elastic_weight=elastic_weight, chunk=chunk)
