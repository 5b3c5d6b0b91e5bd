"""Batch measurement of movies on disk (TIFF, Zarr, OME-Zarr) with dask.

- :mod:`.movies`: :func:`find_movies`, :func:`pair_movies` (which movies, with which reporter);
- :mod:`.io`: :func:`open_movie` (lazy reading, what the file declares checked);
- :mod:`.fingerprint`: whether a movie on disk changed (for readers and resumed runs);
- :mod:`.tasks`: :func:`measure_dask`, one movie, frames in parallel (threads, processes or a
  dask.distributed cluster), same table as :func:`napari_pfsdm.measure`;
- :mod:`.run`: :func:`run_batch`, many movies into one table, resumable per movie;
- :func:`process_pool`: worker processes for the ``"processes"`` scheduler, kept between
  movies.
"""

from ..analysis.schedulers import process_pool
from .io import open_movie
from .movies import Movie, find_movies, pair_movies
from .run import run_batch
from .tasks import measure_dask

__all__ = ["Movie", "find_movies", "measure_dask", "open_movie", "pair_movies", "process_pool",
           "run_batch"]
