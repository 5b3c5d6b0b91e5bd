"""Nearest neighbours under the default distance, for collections too big for a matrix.

:func:`nearest_neighbours` is the package's public ``napari_pfsdm.nearest_neighbours``: the
k nearest objects of every object (results, embeddings or a feature table), without ever
holding the n × n distance matrix (docs/design.md §2.6, §2.9; the search itself is
:mod:`napari_pfsdm.core.neighbours`).
"""

from __future__ import annotations

import os
import warnings
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from ..core import distances as _dist
from ..core import distances3d
from ..core.embeddings import Embeddings
from ..core.neighbours import METHODS, NeighbourIndex, blocks, check_k, search_rows
from ..core.table_options import table_options
from ..core.table_schema import table_ndim
from .tables import embeddings as _table_embeddings
from .tables import is_table

__all__ = ["NeighbourSearch", "Neighbours", "nearest_neighbours", "neighbour_index"]


def neighbour_index(items, intensity_weight: float = 0.0,
                    boundary_weight: float | None = None) -> NeighbourIndex:
    """The arrays a neighbour search needs, from results, :class:`Embeddings` or a table, with
    the same options and checks as :func:`napari_pfsdm.distance_matrix` (so that its
    distances are that matrix's entries)."""
    if is_table(items):
        channels = ["shape"] + (["intensity"] if intensity_weight else [])
        volumes = table_ndim(table_options(items)) == 3
        items = _table_embeddings(items, channels)
        if volumes:
            boundary_weight = _dist.no_boundary_in_3d(boundary_weight)
        elif items.outline is None and boundary_weight is None:
            warnings.warn(
                "This table has no outline_* columns (it was measured before the boundary "
                "term): its neighbours are by the SDF term alone, not the default distance. "
                "Measure again to get the default.", stacklevel=3)
            boundary_weight = 0.0
    elif not isinstance(items, Embeddings):
        items = list(items)
        if items and distances3d.is_3d(items):
            items = distances3d.embeddings_3d(items, with_intensity=bool(intensity_weight))
            boundary_weight = _dist.no_boundary_in_3d(boundary_weight)
    lam = _dist.check_boundary_weight(boundary_weight)
    w_i = _dist.check_weight("intensity_weight", intensity_weight)
    if not isinstance(items, Embeddings) and not items:
        return NeighbourIndex.build(np.zeros((0, 1)), None, 0.0)
    feats = _dist.magnitude_features(*_dist.channel_arrays(items, "shape"))
    if w_i:
        inten = _dist.magnitude_features(*_dist.channel_arrays(items, "intensity"))
        feats = np.hstack([feats, np.sqrt(w_i) * inten])  # d² = d_shape² + w_I d_int²
    outline = _dist.outlines_of(items) if lam else None
    return NeighbourIndex.build(feats, outline, lam)


def nearest_neighbours(
    items: Any,
    k: int = 10,
    *,
    intensity_weight: float = 0.0,
    boundary_weight: float | None = None,
    elastic_weight: float | None = None,
    elastic_candidates: int | None = None,
    method: str = "bound",
    block: int = 512,
    n_jobs: int | None = None,
    scheduler: Any = None,
    client: Any = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The k nearest neighbours of every object under the default PF-SDM distance.

    The distance is :func:`napari_pfsdm.distance_matrix`'s default, D = d_SDF + λ d_B
    (docs/design.md §2.6: the Euclidean distance of the weighted magnitude features, plus the
    intensity term; §2.9: λ times the outline's Procrustes distance), computed for blocks of
    rows against all objects, so that memory stays about ``block × n`` numbers.

    Parameters
    ----------
    items : sequence of PFSDMResult, Embeddings, or a feature table
        As :func:`napari_pfsdm.distance_matrix` accepts them (a table must carry its options
        and have no failed rows: :func:`napari_pfsdm.drop_failed`). 3-D results: the shells
        and the surface term, no boundary term.
    k : int
        Neighbours per object, 1 ≤ k ≤ n − 1 (else :class:`~napari_pfsdm.errors.InputError`).
    intensity_weight : float
        w_I, as in :func:`napari_pfsdm.distance_matrix`.
    boundary_weight : float, optional
        λ (default 1, :data:`napari_pfsdm.core.distances.BOUNDARY_WEIGHT`; 0: SDF term only).
    elastic_weight : float, optional
        μ, the weight of the elastic outline term (default 0,
        :data:`napari_pfsdm.core.distances.ELASTIC_WEIGHT`;
        :data:`~napari_pfsdm.core.distances.RECOMMENDED_ELASTIC_WEIGHT` for retrieval). With
        μ > 0 the search is approximate and says so in its result: candidates from the
        term's own cheaper forms, then the exact distances of those
        (:mod:`napari_pfsdm.core.elastic_neighbours`; recall against the full matrix:
        docs/benchmarks.md, "The elastic term's neighbours").
    elastic_candidates : int, optional
        With the elastic term, the candidates per object whose exact distance is computed
        (and a pool of ten times that); default: measured on a sample of the objects
        (:func:`napari_pfsdm.core.elastic_neighbours.depth`).
    method : {"bound", "brute"}
        ``"bound"`` (default): exact search by a lower bound (below); ``"brute"``: every
        pair, block by block (the reference, ~2 µs per pair).
    block : int
        Query rows computed at once (memory: about 1 kB × block × n per worker).
    n_jobs : int, optional
        Threads over the query blocks when no ``scheduler`` / ``client`` is given (default:
        the number of cores; BLAS runs one thread each meanwhile).
    scheduler : str or distributed.Client, optional
        Run the query blocks as dask tasks, as :func:`napari_pfsdm.batch.measure_dask` does:
        ``"threads"``, ``"processes"``, ``"sync"``, or a scheduler address such as
        ``"tcp://10.0.0.5:8786"`` (a client is opened and closed for this call).
    client : distributed.Client, optional
        Run on this cluster: the objects' arrays (n × ~250 numbers) are scattered to every
        worker once, each task is one block of queries against all objects.

    Returns
    -------
    Neighbours
        The pair ``(indices, distances)`` (unpacked as a tuple), with ``certified`` rows,
        ``exact`` and ``depth`` (:class:`Neighbours`).
    indices : ndarray of int, shape (n, k)
        Row numbers of each object's neighbours, nearest first, never the object itself.
        Equal distances are ordered by row number.
    distances : ndarray of float, shape (n, k)
        Their distances: the entries of ``distance_matrix(items)`` (to rounding; ≤ 1.1e-6
        on MPEG-7, where the boundary term's start-shift search of an ambiguous pair depends
        on the order of summation: the matrix itself moves by up to 1.7e-3 when the objects
        come in another order).

    Notes
    -----
    Without the elastic term the search is exact (the same neighbours as sorting the rows of
    ``distance_matrix``, tested; on MPEG-7 up to ties within 1e-6, which the matrix itself
    does not reproduce when the objects are reordered: docs/benchmarks.md, "Nearest
    neighbours"). For each
    block of queries it computes, for all objects at once and in single precision, a lower
    bound LB ≤ D: the distance of the features projected on their first ≤ 32 principal
    components (a projection never lengthens a difference) plus λ sqrt(1 − min(1,
    Σ_n |a_n||b_n|)²), which is ≤ d_B because the correlation of two unit-norm outlines over
    every start shift and the mirror is at most Σ_n |a_n||b_n| (docs/design.md §2.12). D is
    then computed exactly, in increasing order of LB and in rounds of 2k, 4k, ... out of a
    pool of each query's 1,024 smallest bounds, for the objects whose LB is at most the k-th
    distance found so far, until the k-th distance is below the next LB (past the pool,
    every object is looked at): whatever is left out has LB, hence D, at least the k-th
    distance found (margins cover the single precision). On 3,000 moving blobs that is ~48
    exact distances per object instead of 2,999 (docs/benchmarks.md, "Nearest neighbours").

    Objects without features or outline (NaN rows of results or embeddings) are nobody's
    neighbour, and their own rows are index -1 and distance NaN; when fewer than k other
    objects have features, the missing places are index -1 and distance inf.

    Examples
    --------
    >>> import numpy as np
    >>> from napari_pfsdm import measure
    >>> labels = np.zeros((64, 200), int)
    >>> labels[10:50, 10:50] = 1           # a square
    >>> labels[12:48, 60:100] = 2          # a slightly smaller, wider one
    >>> labels[25:35, 120:190] = 3         # a bar
    >>> idx, dist = nearest_neighbours(measure(labels), k=1)
    >>> idx[:, 0].tolist()
    [1, 0, 1]
    """
    if method not in METHODS:
        from ..errors import InputError

        raise InputError(f"method must be one of {METHODS}, got {method!r}")
    search = NeighbourSearch(items, intensity_weight=intensity_weight,
                             boundary_weight=boundary_weight, elastic_weight=elastic_weight)
    k = check_k(k, len(search))
    mu = search.elastic_weight
    parts = blocks(len(search), max(1, int(block) if not mu else min(int(block), _ELASTIC_BLOCK)))
    if mu and method == "brute":
        out = [search.rows(rows, k, "brute") for rows in parts]
        return Neighbours(np.vstack([o[0] for o in out]), np.vstack([o[1] for o in out]))
    if mu:
        depth = search.depth(k, elastic_candidates)
        index, method, elastic = search.elastic, "elastic", (mu, *depth)
    else:
        depth, index, elastic = None, search.index, ()
    if scheduler is None and client is None:
        out = _run_threads(index, parts, k, method, n_jobs, elastic)
    else:
        out = _run_dask(index, parts, k, method, scheduler, client, elastic)
    return Neighbours(np.vstack([o[0] for o in out]), np.vstack([o[1] for o in out]),
                      np.concatenate([o[2] for o in out]) if mu else None, depth=depth)


class NeighbourSearch:
    """A neighbour search prepared once, for queries a few rows at a time (the plugin's
    Similar tab keeps one per run): the same options, checks and results as
    :func:`nearest_neighbours`.

    Examples
    --------
    >>> import numpy as np
    >>> from napari_pfsdm import measure
    >>> labels = np.zeros((64, 200), int)
    >>> labels[10:50, 10:50] = 1
    >>> labels[12:48, 60:100] = 2
    >>> labels[25:35, 120:190] = 3
    >>> search = NeighbourSearch(measure(labels))
    >>> search.rows([2], k=1).indices.tolist()
    [[1]]
    """

    def __init__(self, items: Any, *, intensity_weight: float = 0.0,
                 boundary_weight: float | None = None,
                 elastic_weight: float | None = None) -> None:
        self.elastic_weight = _dist.check_elastic_weight(elastic_weight)
        signatures = _signatures(items) if self.elastic_weight else None
        self.index = neighbour_index(items, intensity_weight, boundary_weight)
        self.elastic = None
        if self.elastic_weight:
            from ..core.elastic_neighbours import ElasticIndex

            self.elastic = ElasticIndex.build(self.index, signatures)
        self._depth: dict = {}

    def __len__(self) -> int:
        return len(self.index)

    def depth(self, k: int, candidates: int | None = None) -> tuple[int, int]:
        """With the elastic term: the pool and candidates per object for k neighbours
        (:func:`napari_pfsdm.core.elastic_neighbours.depth`, measured once per k)."""
        from ..core import elastic_neighbours as en

        if candidates:
            return en.sizes(k, len(self), candidates)
        if k not in self._depth:
            self._depth[k] = en.depth(self.elastic, self.elastic_weight, k)
        return self._depth[k]

    def rows(self, rows, k: int, method: str = "bound") -> Neighbours:
        """The k nearest of the objects ``rows`` among all (:func:`nearest_neighbours`'s
        rows for them)."""
        rows = np.asarray(rows, np.intp)
        k = check_k(k, len(self))
        if not self.elastic_weight:
            return Neighbours(*search_rows(self.index, rows, k, method))
        from ..core import elastic_neighbours as en

        if method == "brute":
            return Neighbours(*en.brute_rows(self.elastic, rows, k, self.elastic_weight))
        depth = self.depth(k)
        idx, dist, cert = en.search_rows(self.elastic, rows, k, self.elastic_weight, *depth)
        return Neighbours(idx, dist, cert, depth=depth)


class Neighbours(tuple):
    """What :func:`nearest_neighbours` returns: the pair ``(indices, distances)`` (unpacked as
    before), and what is known of it.

    Attributes
    ----------
    indices, distances : ndarray, shape (n, k)
        The two arrays.
    certified : ndarray of bool, shape (n,)
        Rows proven to be the k nearest of all objects (every row for the default distance;
        with the elastic term, rows whose k-th distance is below the lower bound of every
        object left out of their candidates).
    exact : bool
        Every row certified.
    depth : (int, int) or None
        With the elastic term: the pool and the candidates per object that the search looked
        at (:func:`napari_pfsdm.core.elastic_neighbours.depth`).
    """

    def __new__(cls, indices: np.ndarray, distances: np.ndarray,
                certified: np.ndarray | None = None,
                depth: tuple[int, int] | None = None) -> Neighbours:
        self = super().__new__(cls, (indices, distances))
        self.certified = (np.ones(len(indices), bool) if certified is None
                          else np.asarray(certified, bool))
        self.depth = depth
        return self

    def __getnewargs__(self):
        return (self[0], self[1], self.certified, self.depth)

    @property
    def indices(self) -> np.ndarray:
        return self[0]

    @property
    def distances(self) -> np.ndarray:
        return self[1]

    @property
    def exact(self) -> bool:
        return bool(self.certified.all())

    def describe(self) -> str:
        """One sentence for a user: exact, or which share of the rows is certified."""
        if self.exact:
            return "exact: every object's neighbours are those of the full distance matrix"
        return (f"approximate: {self.certified.mean():.0%} of the objects' neighbours are "
                "certified those of the full distance matrix; the others are the nearest "
                "among each object's candidates (recall against the full matrix measured in "
                "docs/benchmarks.md)")


#: Query rows per thread or task with the elastic term (at most): its blocks cost ~100× the
#: default's per row, and smaller ones share the cores more evenly.
_ELASTIC_BLOCK = 128


def _signatures(items) -> np.ndarray:
    """The outline signatures of results, :class:`Embeddings` or a table (2-D only)."""
    if is_table(items):
        from .tables import signatures_from_table

        if table_ndim(table_options(items)) == 3:
            _dist.no_elastic_in_3d(1.0)
        sig = signatures_from_table(items)
        if sig is None:
            from ..errors import InputError

            raise InputError(_dist.NO_SIGNATURES)
        return sig
    if not isinstance(items, Embeddings):
        items = list(items)
        if items and distances3d.is_3d(items):
            _dist.no_elastic_in_3d(1.0)
    return _dist.signatures_of(items)


def _search_block(index, rows: np.ndarray, k: int, method: str, elastic: tuple = ()):
    """One dask task / thread: a block of queries with BLAS on one thread; ``method``
    "elastic": with the elastic term (``index`` an ElasticIndex, ``elastic`` (μ, pool,
    candidates)), its d_E on this thread."""
    from ..core.threads import one_blas_thread

    with one_blas_thread():
        if method == "elastic":
            from ..core.elastic_neighbours import search_rows as elastic_rows

            return elastic_rows(index, rows, k, *elastic, here=True)
        return search_rows(index, rows, k, method)


def _run_threads(index, parts, k, method, n_jobs, elastic=()):
    n_jobs = max(1, min(int(n_jobs or os.cpu_count() or 1), len(parts)))
    if n_jobs == 1:
        return [_search_block(index, rows, k, method, elastic) for rows in parts]
    with ThreadPoolExecutor(n_jobs) as pool:
        return list(pool.map(lambda rows: _search_block(index, rows, k, method, elastic),
                             parts))


def _run_dask(index, parts, k, method, scheduler, client, elastic=()):
    from .schedulers import available_cores, client_for, process_pool, resolve_scheduler

    kind, obj = resolve_scheduler(scheduler, client)
    if kind == "local":
        import dask

        shared = dask.delayed(index, traverse=False)
        tasks = [dask.delayed(_search_block, pure=False)(shared, rows, k, method, elastic)
                 for rows in parts]
        if obj != "processes":
            return list(dask.compute(*tasks, scheduler=obj))
        # worker processes that do not run the caller's script again
        with process_pool(max(1, min(len(parts), available_cores()))) as pool:
            return list(dask.compute(*tasks, scheduler=obj, pool=pool))
    with client_for(kind, obj) as handle:  # opens a client for a scheduler address
        shared = handle.scatter(index, broadcast=True)
        tag = os.urandom(4).hex()
        futures = [handle.submit(_search_block, shared, rows, k, method, elastic, pure=False,
                                 key=f"pfsdm-neighbours-{i}-{tag}")
                   for i, rows in enumerate(parts)]
        try:
            return handle.gather(futures)
        finally:
            for f in futures:
                f.release()
            shared.release()
