"""Comparing more objects than an all-pairs matrix holds, in the viewer's workers (no Qt).

Above :data:`GRAPH_ROWS` objects the comparison view and the export use each object's
nearest neighbours (:func:`napari_pfsdm.nearest_neighbours`' exact search, block by block so
that a worker can report progress and stop between blocks) and a map drawn from that graph
(:func:`napari_pfsdm.analysis.reduction.graph_coordinates`), never the n × n matrix: 50,000
objects would need 18.6 GiB for it (docs/benchmarks.md, "Nearest neighbours").

The map runs in a worker *process* of its own (started like
:mod:`napari_pfsdm.analysis.parallel`'s pool): t-SNE cannot be stopped half-way inside a
thread, a process can (Cancel terminates it, and only it).
"""

from __future__ import annotations

import importlib.util
import multiprocessing as mp
from collections.abc import Generator
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pandas as pd

from ..analysis.reduction import FULL_MATRIX_LIMIT, MAP_NEIGHBOURS, TSNE_SLOW

#: Above this many objects the viewer compares by nearest neighbours, not all pairs (as
#: ``pfsdm compare``: the matrix image and classical MDS grow as n² and n³).
GRAPH_ROWS = FULL_MATRIX_LIMIT
#: Neighbours per object kept for the map, the re-ranking and the export.
GRAPH_K = MAP_NEIGHBOURS
#: Query rows per step (one step per thread; progress and Cancel between steps).
STEP_ROWS = 256


#: Above this many objects t-SNE takes minutes (50,000: ~8 min): without umap-learn the
#: viewer draws the spectral map instead (seconds; it mixes kinds of shapes more).
TSNE_ROWS = TSNE_SLOW


def map_method(n: int = 0) -> str:
    """The graph map the viewer draws for ``n`` objects: UMAP when umap-learn is installed
    (under a minute for 50,000 objects), else t-SNE up to :data:`TSNE_ROWS` objects
    (scikit-learn only; it keeps kinds of shapes apart best), else spectral
    (docs/benchmarks.md, "Maps and re-ranking on the neighbour graph")."""
    # asked of the installation, not imported: importing umap-learn (numba, LLVM) takes
    # ~2 s and held the interpreter lock long enough to freeze the viewer; the map is
    # computed in a process of its own, which imports it
    if importlib.util.find_spec("umap") is None:
        return "tsne" if n <= TSNE_ROWS else "spectral"
    return "umap"


def neighbour_steps(sub: pd.DataFrame, k: int = GRAPH_K, intensity_weight: float = 0.0,
                    threads: int = 2) -> Generator[tuple[int, int], None, tuple]:
    """The k nearest neighbours of every row of the feature table ``sub``, in steps.

    Yields ``(rows done, rows)`` after every ``threads`` blocks of :data:`STEP_ROWS` queries
    (each block on its own thread, BLAS on one thread each); returns ``(indices,
    distances)`` as :func:`napari_pfsdm.nearest_neighbours` does (tested equal).
    """
    from ..analysis.neighbours import _search_block, neighbour_index
    from ..core.neighbours import blocks, check_k

    index = neighbour_index(sub, intensity_weight)
    n = len(index)
    k = check_k(min(int(k), n - 1), n)
    parts = blocks(n, STEP_ROWS)
    found: list[tuple[np.ndarray, np.ndarray]] = []
    with ThreadPoolExecutor(max(1, threads)) as pool:
        for i in range(0, len(parts), max(1, threads)):
            chunk = parts[i:i + max(1, threads)]
            found += list(pool.map(lambda rows: _search_block(index, rows, k, "bound"), chunk))
            yield int(chunk[-1][-1]) + 1, n
    return np.vstack([f[0] for f in found]), np.vstack([f[1] for f in found])


def graph_of(output, rows: np.ndarray, intensity_weight: float = 0.0
             ) -> Generator[tuple[int, int], None, tuple]:
    """:func:`neighbour_steps` of the rows at positions ``rows`` of ``output.table``,
    computed once per run's table and kept in ``output.derived``: the comparison view, its
    re-ranking and the export share one search (50,000 objects: about a minute and a half
    each). The rows are taken from the table only when the search runs (in the worker)."""
    rows = np.asarray(rows, dtype=np.int64)
    key = ("neighbours", float(intensity_weight), int(rows[0]), int(rows[-1]), len(rows),
           GRAPH_K)
    derived = getattr(output, "derived", None)
    if derived is not None and key in derived:
        return derived[key]
    found = yield from neighbour_steps(output.table.iloc[rows], GRAPH_K, intensity_weight)
    if derived is not None:
        derived[key] = found
    return found


def rerank_graph(indices: np.ndarray, distances: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The neighbour graph re-ranked by diffusion (:func:`napari_pfsdm.analysis.rerank.
    rerank_neighbours`, k = 10 as the matrix view's re-ranking)."""
    from ..analysis.rerank import rerank_neighbours

    out = rerank_neighbours(indices, distances, "diffusion", k=min(10, indices.shape[1]))
    return out[0], out[1]


def map_steps(indices: np.ndarray, distances: np.ndarray,
              method: str | None = None) -> Generator[str, None, np.ndarray]:
    """The 2-D map of a neighbour graph (:func:`~napari_pfsdm.analysis.reduction.
    graph_coordinates`), computed in a worker process; yields ``"mapping"`` about every
    0.2 s while it runs, so that the caller can stop (closing the generator terminates the
    process); returns the (n, 2) coordinates."""
    from ..analysis import parallel
    from ..analysis.reduction import graph_coordinates

    # a process of its own, not the shared pool: stopping the map must not stop a Run
    pool = parallel._start(1)
    try:
        job = pool.apply_async(graph_coordinates, (indices, distances, method or map_method()))
        while True:
            try:
                xy = job.get(timeout=0.2)
                break
            except mp.TimeoutError:
                yield "mapping"
    finally:
        pool.terminate()
    return np.asarray(xy)
