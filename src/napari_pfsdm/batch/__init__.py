"""Batch measurement of movies on disk (TIFF, Zarr, OME-Zarr) with dask.

- :func:`open_movie`, :func:`find_movies`, :func:`pair_movies`: lazy reading and pairing;
- :func:`measure_dask`: one movie, frames in parallel (threads, processes or a
  dask.distributed cluster), same table as :func:`napari_pfsdm.measure`;
- :func:`run_batch`: many movies into one CSV, resumable per movie;
- :func:`process_pool`: worker processes for the ``"processes"`` scheduler, kept between
  movies.
"""

from ..analysis.schedulers import process_pool
from .io import Movie, find_movies, open_movie, pair_movies
from .run import run_batch
from .tasks import measure_dask

__all__ = ["Movie", "find_movies", "measure_dask", "open_movie", "pair_movies", "process_pool",
           "run_batch"]
