"""One BLAS thread while objects are measured, however many threads measure them.

One object's matrices are small: BLAS threads only add overhead and, with several workers,
oversubscribe the cores (parallelism comes from frames and objects: the pool, the dask
batch). :func:`one_blas_thread` limits BLAS to one thread (threadpoolctl), reference-counted
so that concurrent threads restore the original setting only when the last one leaves.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["one_blas_thread"]

_BLAS_LOCK = threading.Lock()


_BLAS_STATE: dict[str, Any] = {"users": 0, "limiter": None, "controller": None}


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Limit BLAS to one thread while objects are computed: one object's matrices are small,
    threads only add overhead and, with several workers, oversubscribe the cores (parallelism
    comes from frames: the dask batch). Reference-counted, so that concurrent threads restore
    the original setting only when the last one leaves."""
    with _BLAS_LOCK:
        if _BLAS_STATE["users"] == 0:
            if _BLAS_STATE["controller"] is None:
                # finding the BLAS libraries reads the process's memory map (a few ms): once,
                # after SciPy's own OpenBLAS (its linear algebra, scikit-learn's PCA) is loaded
                import scipy.linalg  # noqa: F401
                from threadpoolctl import ThreadpoolController

                _BLAS_STATE["controller"] = ThreadpoolController()
            _BLAS_STATE["limiter"] = _BLAS_STATE["controller"].limit(limits=1,
                                                                     user_api="blas")
        _BLAS_STATE["users"] += 1
    try:
        yield
    finally:
        with _BLAS_LOCK:
            _BLAS_STATE["users"] -= 1
            if _BLAS_STATE["users"] == 0:
                _BLAS_STATE["limiter"].restore_original_limits()
