"""Reductions of a feature table shared by the command line and the napari plugin: PCA, MDS, the
distance-table layout, row and object ids, and the groups file.

One implementation each, so that the CLI's and the widget's maps of the same table are the same
numbers (docs/design.md §2.8). The PCA is :class:`~napari_pfsdm.analysis.shape_space.ShapePCA`
(scikit-learn's), imported when a PCA is asked for, so that this module loads without
scikit-learn; the classical MDS is an eigendecomposition in plain numpy.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from ..core.table_options import carry_options
from ..core.table_schema import NO_TRACK, TRACK_COLUMN
from ..errors import InputError

__all__ = [
    "KEY_COLUMNS",
    "attach_groups",
    "distance_table",
    "graph_coordinates",
    "neighbour_table",
    "mds_coordinates",
    "object_ids",
    "pca_scores",
    "read_groups",
    "row_ids",
]

#: Columns that identify an object across frames in a groups file (``track_id`` for a linked
#: table, whose labels may change between frames).
KEY_COLUMNS = ("movie", "label", TRACK_COLUMN)


def object_ids(table: pd.DataFrame) -> pd.Series:
    """One id per object of a table, which trajectories follow through time.

    With a ``track_id`` column (a linked table, see :mod:`napari_pfsdm.analysis.tracking`) an
    object is its track: ``"movie/track7"`` (``"track7"`` without movies); a row without a
    track (``track_id`` -1) is an object of its own, ``"movie/t<frame>/l<label>"``. Without
    ``track_id`` an object is its label: ``"movie/label"`` (or the label alone).

    Examples
    --------
    >>> t = pd.DataFrame({"frame": [0, 1, 1], "label": [4, 9, 4], "track_id": [1, 1, -1]})
    >>> object_ids(t).tolist()
    ['track1', 'track1', 't1/l4']
    >>> object_ids(t.drop(columns="track_id")).tolist()
    ['4', '9', '4']
    """
    if TRACK_COLUMN in table.columns:
        tracks = table[TRACK_COLUMN].to_numpy()
        ids = pd.Series(np.where(tracks != NO_TRACK, "track" + table[TRACK_COLUMN].astype(str),
                                 "t" + table["frame"].astype(str) + "/l"
                                 + table["label"].astype(str)), index=table.index)
    else:
        ids = table["label"].astype(str)
    if "movie" in table.columns:
        return table["movie"].astype(str) + "/" + ids
    return ids


def row_ids(table: pd.DataFrame) -> list[str]:
    """One id per row: ``movie/t<frame>/l<label>`` (without ``movie/`` when there is none)."""
    base = "t" + table["frame"].astype(str) + "/l" + table["label"].astype(str)
    if "movie" in table.columns:
        base = table["movie"].astype(str) + "/" + base
    return base.tolist()


def pca_scores(
    table: pd.DataFrame,
    channel: str = "shape",
    n_components: int = 3,
    *,
    standardize: bool = False,
) -> tuple[pd.DataFrame, np.ndarray]:
    """PCA of all (movie, frame, label) rows of a feature table: :class:`ShapePCA`'s
    ``fit_transform`` on it, and the fraction of the variance each component explains.

    Weighted as the PF-SDM distance by default, each feature standardised with
    ``standardize=True``; rows with an ``error`` or non-finite features are left out; each
    component signed so that its largest loading is positive
    (:class:`~napari_pfsdm.analysis.shape_space.ShapePCA`).

    Parameters
    ----------
    table : DataFrame
        A feature table with its options (:func:`napari_pfsdm.measure`, ``read_table``).
    channel : {"shape", "intensity"}
    n_components : int
        At most this many components (fewer when there are fewer rows or features).
    standardize : bool
        Standardise the raw features instead of weighting them.

    Returns
    -------
    scores : DataFrame
        The key columns (``movie``, ``frame``, ``label``, ``track_id``, ``group`` when present) and
        ``{channel}_PC1`` …, one row per measured row, in table order.
    explained : ndarray
        Fraction of the variance explained by each component.

    Raises
    ------
    ValueError
        Fewer than two measured rows.

    Examples
    --------
    >>> import numpy as np
    >>> from napari_pfsdm import measure
    >>> labels = np.zeros((3, 64, 64), int)
    >>> for t in range(3):
    ...     labels[t, 10:30, 10:30 + 5 * t] = 1
    >>> scores, explained = pca_scores(measure(labels), n_components=2)
    >>> list(scores.columns), bool(explained[0] > 0.9)
    (['frame', 'label', 'shape_PC1', 'shape_PC2'], True)
    """
    from .shape_space import ShapePCA

    space = ShapePCA(n_components, channel, standardize=standardize)
    return space.fit_transform(table), space.explained_variance_ratio_


def mds_coordinates(d: np.ndarray, n_components: int = 2) -> np.ndarray:
    """Classical (Torgerson) MDS of a distance matrix: (n, n_components) coordinates.

    Deterministic and exact for Euclidean distances. Rows and columns with NaN are left out of
    the fit and get NaN coordinates.

    Examples
    --------
    >>> pts = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 4.0]])
    >>> d = np.hypot(*(pts[:, None] - pts[None]).transpose(2, 0, 1))
    >>> xy = mds_coordinates(d)
    >>> bool(np.allclose(np.hypot(*(xy[:, None] - xy[None]).transpose(2, 0, 1)), d))
    True
    """
    d = np.asarray(d, dtype=float)
    n = d.shape[0]
    out = np.full((n, n_components), np.nan)
    ok = np.isfinite(d).all(axis=1) if n else np.zeros(0, bool)
    ok &= np.isfinite(d[:, ok]).all(axis=1) if ok.any() else ok
    m = int(ok.sum())
    if m == 0:
        return out
    sub = d[np.ix_(ok, ok)]
    j = np.eye(m) - 1.0 / m
    b = -0.5 * j @ (sub**2) @ j
    w, v = np.linalg.eigh(b)
    order = np.argsort(w)[::-1][:n_components]
    coords = v[:, order] * np.sqrt(np.clip(w[order], 0, None))
    if coords.shape[1] < n_components:
        coords = np.hstack([coords, np.zeros((m, n_components - coords.shape[1]))])
    out[ok] = coords
    return out


#: The embeddings of :func:`graph_coordinates`, the default first (benchmarks/neighbour_maps.py).
GRAPH_MAPS = ("tsne", "umap", "spectral")
#: Above this many objects maps are drawn from the neighbour graph (t-SNE of each object's
#: :data:`MAP_NEIGHBOURS` nearest) instead of classical MDS of the full n x n matrix: at 2,000
#: objects the matrix costs ~8 s and its MDS (an n x n eigendecomposition) a few more, and
#: both grow as n² and n³ (docs/benchmarks.md). ``pfsdm compare --mds`` and the plugin's
#: "all frames" comparison.
FULL_MATRIX_LIMIT = 2000
#: Neighbours per object of the graph a map is drawn from (benchmarks/neighbour_maps.py).
MAP_NEIGHBOURS = 15
#: Above this many objects a t-SNE map takes minutes (10,000: 33 s, 50,000: 474 s measured
#: here; UMAP 20 s and 47 s): ``pfsdm compare`` suggests --map umap, the plugin draws the
#: spectral map when umap-learn is missing.
TSNE_SLOW = 10_000


def graph_coordinates(indices: np.ndarray, distances: np.ndarray, method: str = "tsne", *,
                      seed: int = 0) -> np.ndarray:
    """A 2-D map drawn from a neighbour graph alone: (n, 2) coordinates, no n x n matrix.

    ``indices``, ``distances``: each object's K nearest, itself excluded
    (:func:`napari_pfsdm.nearest_neighbours`). ``"tsne"`` is scikit-learn's t-SNE on the
    sparse distance graph (the PF-SDM distance is a squared Euclidean one, as t-SNE's Gaussian
    expects), perplexity (K − 2) / 3, 500 iterations (on MPEG-7 as good as 1,000, in half
    the time); ``"spectral"`` scikit-learn's spectral embedding of the
    locally scaled Gaussian affinities exp(−d_ij / (σ_i σ_j)), σ_i² the distance to the K-th
    neighbour; ``"umap"`` umap-learn's UMAP on the sparse graph of √d (a metric), an optional
    dependency (``pip install "napari-pfsdm[umap]"``). Measured on MPEG-7
    (benchmarks/neighbour_maps.py, docs/benchmarks.md): t-SNE keeps the 70 classes apart best
    (93 % 5-NN accuracy in 2-D, UMAP 89 %, spectral 47 %, MDS of the full matrix 47 %); UMAP
    grows more slowly with n (10,000 points: t-SNE 33 s, UMAP 20 s with its compilation). A
    zero distance (two identical shapes) is stored as 1e-12 so that it stays a neighbour.
    """
    from scipy import sparse

    idx = np.asarray(indices, dtype=np.int64)
    dist = np.asarray(distances, dtype=float)
    n, k = idx.shape
    if method not in GRAPH_MAPS:
        raise InputError(f"method must be one of {', '.join(GRAPH_MAPS)}; got {method!r}")
    if n < 3 or k < 2:
        raise InputError("a neighbour map needs at least 3 objects and 2 neighbours each")

    def graph(values: np.ndarray):
        rows = np.repeat(np.arange(n), k)
        g = sparse.csr_matrix((np.maximum(values, 1e-12).ravel(), (rows, idx.ravel())),
                              shape=(n, n))
        return g.maximum(g.T).tocsr()

    if method == "umap":
        try:
            import umap
        except ImportError:
            raise InputError('the UMAP map needs umap-learn, which is not installed: '
                             'pip install "napari-pfsdm[umap]" (or use the t-SNE map)') from None
        import warnings

        with warnings.catch_warnings():  # "n_jobs overridden by random_state" and numba's
            warnings.simplefilter("ignore")
            return umap.UMAP(n_components=2, n_neighbors=k, metric="precomputed",
                             random_state=seed).fit_transform(graph(np.sqrt(dist)))
    if method == "spectral":
        from sklearn.manifold import SpectralEmbedding

        sigma = np.sqrt(np.maximum(dist[:, -1], 1e-300))
        w = np.exp(-dist / (sigma[:, None] * sigma[idx]))
        return SpectralEmbedding(n_components=2, affinity="precomputed",
                                 random_state=seed).fit_transform(graph(w))
    import inspect
    import warnings

    from sklearn.manifold import TSNE
    from sklearn.neighbors import sort_graph_by_row_values

    g = sort_graph_by_row_values(graph(dist), warn_when_not_sorted=False)
    # scikit-learn < 1.5 calls the number of iterations n_iter
    steps = "max_iter" if "max_iter" in inspect.signature(TSNE).parameters else "n_iter"
    with warnings.catch_warnings():  # "not sorted" of older versions; sorted above
        warnings.simplefilter("ignore", category=UserWarning)
        return TSNE(n_components=2, metric="precomputed", init="random", random_state=seed,
                    perplexity=max(1.0, min((k - 2) / 3, (n - 1) / 3)),
                    **{steps: 500}).fit_transform(g)


def neighbour_table(table: pd.DataFrame, indices: np.ndarray, distances: np.ndarray, *,
                    rows: np.ndarray | None = None) -> pd.DataFrame:
    """The edge list of a neighbour graph: one row per (object, neighbour), nearest first.

    Columns ``row``, ``neighbour`` (the two objects' rows: ``rows`` when given, e.g. their rows
    in the feature file, else their positions in ``table``), ``rank`` (1 = nearest),
    ``distance``, then the keys of both ends: ``movie``, ``frame``, ``label``, ``track_id``
    (those the table has) and ``neighbour_movie``, ``neighbour_frame``, ...

    Examples
    --------
    >>> t = pd.DataFrame({"frame": [0, 0, 1], "label": [1, 2, 1]})
    >>> e = neighbour_table(t, np.array([[1], [0], [0]]), np.array([[0.5], [0.5], [0.25]]))
    >>> e.to_dict("list")["neighbour_label"], list(e.columns)[:4]
    ([2, 1, 1], ['row', 'neighbour', 'rank', 'distance'])
    """
    idx = np.asarray(indices, dtype=np.int64)
    dist = np.asarray(distances, dtype=float)
    n, k = idx.shape
    rows = np.arange(n) if rows is None else np.asarray(rows, dtype=np.int64)
    me = np.repeat(np.arange(n), k)
    other = idx.ravel()
    out = pd.DataFrame({"row": rows[me], "neighbour": rows[other],
                        "rank": np.tile(np.arange(1, k + 1), n), "distance": dist.ravel()})
    keys = [c for c in ("movie", "frame", "label", TRACK_COLUMN) if c in table.columns]
    for c in keys:
        out[c] = table[c].to_numpy()[me]
    for c in keys:
        out["neighbour_" + c] = table[c].to_numpy()[other]
    return out


def distance_table(table: pd.DataFrame, d: np.ndarray) -> pd.DataFrame:
    """The one layout of a distance matrix: square, rows and columns named by :func:`row_ids`
    (index name ``object``); written with its index, read back with ``index_col=0``."""
    ids = row_ids(table)
    return pd.DataFrame(np.asarray(d), index=pd.Index(ids, name="object"), columns=ids)


def read_groups(path: str | os.PathLike) -> pd.DataFrame:
    """Read a groups CSV: a ``group`` column plus ``label``, ``track_id`` and/or ``movie``
    columns (``track_id`` names the objects of a linked table, whose labels change between
    frames).

    Examples of valid files::

        label,group            movie,group               movie,label,group
        1,single-axis          gastruloid01,single-axis  plate1,3,multi-axes
        2,multi-axes           gastruloid02,multi-axes

    Returns
    -------
    DataFrame
        The key columns (as text) and ``group``.

    Raises
    ------
    ValueError
        A missing file, missing columns, a ``label`` that is not a whole number, or two groups
        for the same object.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{p}: no such groups file" if not p.exists() else
                         f"{p} is not a file (a folder or a pipe?); give a groups CSV file")
    try:
        groups = pd.read_csv(p, dtype=str, comment="#", keep_default_na=False)
    except pd.errors.EmptyDataError:
        raise InputError(f"the groups file {p} is empty; write a header such as label,group "
                         "and one row per object") from None
    except (pd.errors.ParserError, UnicodeDecodeError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"the groups file {p} is not a readable CSV table ({first}); save it "
                         "as CSV (UTF-8) with a header such as label,group") from None
    groups.columns = [str(c).strip().lower() for c in groups.columns]
    keys = [k for k in KEY_COLUMNS if k in groups.columns]
    if "group" not in groups.columns or not keys:
        raise InputError(
            f"{p} must have a 'group' column and a 'label', 'track_id' and/or 'movie' column "
            f"(it has {list(groups.columns)}), e.g. label,group then 3,multi-axes"
        )
    groups = groups[keys + ["group"]]
    blank = groups.apply(lambda col: col.str.strip() == "").any(axis=1)
    if blank.any():
        rows = [str(i + 2) for i in np.flatnonzero(blank.to_numpy())]  # +2: header, from 1
        warnings.warn(
            f"the groups file {p.name}: row{'s' if len(rows) > 1 else ''} "
            f"{', '.join(rows[:10])}{' …' if len(rows) > 10 else ''} (counting the header as "
            "row 1) left out: a cell is empty", UserWarning, stacklevel=2)
        groups = groups[~blank.to_numpy()]
    for key in ("label", TRACK_COLUMN):
        if key not in keys:
            continue
        try:  # exact, whatever the size (ids up to 2**64 - 1): Python's int, not int64
            groups[key] = [str(int(v)) for v in groups[key].str.strip()]
        except ValueError:
            raise InputError(
                f"The {key!r} column of the group file {p.name} must hold whole numbers."
            ) from None
    if groups.duplicated(keys).any():
        raise InputError(f"{p} gives several groups to the same {'/'.join(keys)}")
    return groups.reset_index(drop=True)


def attach_groups(table: pd.DataFrame, groups: pd.DataFrame) -> pd.DataFrame:
    """Add a ``group`` column to a feature table (objects without a group get ``""``)."""
    keys = [k for k in KEY_COLUMNS if k in groups.columns]
    missing = [k for k in keys if k not in table.columns]
    if missing:
        raise InputError(
            f"the groups file has a {missing[0]!r} column but the feature table has none"
        )
    left = table.drop(columns=["group"], errors="ignore").copy()
    for k in keys:
        left["_key_" + k] = left[k].astype(str)
    right = groups.rename(columns={k: "_key_" + k for k in keys})
    out = left.merge(right, on=["_key_" + k for k in keys], how="left")
    out = out.drop(columns=["_key_" + k for k in keys])
    out["group"] = out["group"].fillna("")
    unmatched = unmatched_groups(table, groups)
    if unmatched:
        warnings.warn(
            f"{len(unmatched)} row{'s' if len(unmatched) > 1 else ''} of the groups file "
            f"match{'es' if len(unmatched) == 1 else ''} no object of the table and "
            f"{'are' if len(unmatched) > 1 else 'is'} not used: {'; '.join(unmatched[:5])}"
            f"{' …' if len(unmatched) > 5 else ''} (check the movie names and labels)",
            UserWarning, stacklevel=2)
    return carry_options(table, out)


def unmatched_groups(table: pd.DataFrame, groups: pd.DataFrame) -> list[str]:
    """The rows of a groups table (:func:`read_groups`) that name no object of ``table``, in
    words (``"movie e9, label 3 -> single-axis"``).

    Examples
    --------
    >>> t = pd.DataFrame({"label": [1, 2]})
    >>> unmatched_groups(t, pd.DataFrame({"label": ["1", "7"], "group": ["a", "b"]}))
    ['label 7 -> b']
    """
    keys = [k for k in KEY_COLUMNS if k in groups.columns and k in table.columns]
    if not keys or not len(groups):
        return []
    have = set(zip(*(table[k].astype(str) for k in keys), strict=True))
    out = []
    for row in groups[keys + ["group"]].itertuples(index=False):
        if tuple(row[:-1]) not in have:
            out.append(", ".join(f"{k} {v}" for k, v in zip(keys, row[:-1], strict=True))
                       + f" -> {row[-1]}")
    return out
