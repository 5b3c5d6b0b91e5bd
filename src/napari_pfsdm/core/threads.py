"""BLAS threads where they help: one thread for small matrix products, the machine's for large.

OpenBLAS splits every product over all its threads, whatever its size. A small one (an object's
matrices while measuring, the boundary term's per-shift products, a PCA of a few hundred rows)
gains little from a second thread on a quiet machine and loses many times over when another
process or napari's drawing holds a core: each product waits for the busy core's turn. On the
2-core test machine the default distances of 99 to 2,000 objects took 1.8-3.1 times as long on
the machine's two BLAS threads as on one, quiet or beside a busy process, before their products
were sized (``benchmarks/blas_threads.py``, docs/benchmarks.md).

:func:`one_blas_thread` limits BLAS to one thread within a block (threadpoolctl),
reference-counted so that concurrent threads restore the original setting only when the last
one leaves. :func:`blas_threads_for` does so for a product of fewer than
:data:`SMALL_PRODUCT` floating-point operations and leaves larger ones on the machine's
threads; :func:`blas_threads_by` decorates a function that makes products with the size of its
largest.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager, nullcontext
from typing import Any, TypeVar

__all__ = ["SMALL_PRODUCT", "blas_threads_by", "blas_threads_for", "one_blas_thread"]

_F = TypeVar("_F", bound=Callable[..., Any])

#: Floating-point operations (a complex multiply-add counts 8, a real one 2) below which a
#: matrix product runs on one BLAS thread. Measured on the 2-core test machine with products of
#: the distances' shapes (``benchmarks/blas_threads.py --products``, three runs), the machine's
#: two threads took, of one thread's time: from 0.09 to 0.5 GFLOP 1.2-6.2 times on the quiet
#: machine and up to 20 times beside a busy process; at 0.8 GFLOP 0.56-1.15 times; from 2
#: GFLOP 0.55-0.97 times in 22 of 24 measurements (the two others 1.24 and 1.47, a 2.1 GFLOP
#: complex product on the quiet machine). The line sits above the crossover: a product of
#: 0.8-2 GFLOP (the Gram matrix of 1,500-2,400 objects) gives up at most about a third of its
#: time on a quiet machine, never the many-fold losses.
SMALL_PRODUCT = 2e9

_BLAS_LOCK = threading.Lock()
_BLAS_STATE: dict[str, Any] = {"users": 0, "limiter": None, "controller": None}


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Limit BLAS to one thread within the block (module docstring). Reference-counted, so
    that concurrent threads restore the original setting only when the last one leaves."""
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


def blas_threads_for(flops: float) -> AbstractContextManager[None]:
    """:func:`one_blas_thread` for products of fewer than :data:`SMALL_PRODUCT` operations
    each, the machine's BLAS threads for larger ones.

    Examples
    --------
    >>> import numpy as np
    >>> a = np.ones((100, 32))
    >>> with blas_threads_for(2 * 100 * 32 * 100):  # 0.6 MFLOP: on one thread
    ...     g = a @ a.T
    """
    return one_blas_thread() if flops < SMALL_PRODUCT else nullcontext()


def blas_threads_by(flops: Callable[..., float]) -> Callable[[_F], _F]:
    """Decorate a function that makes matrix products: it runs within
    ``blas_threads_for(flops(*args, **kwargs))``, ``flops`` giving the operations of its
    largest product from its arguments."""
    def decorate(fn: _F) -> _F:
        @functools.wraps(fn)
        def run(*args: Any, **kwargs: Any) -> Any:
            with blas_threads_for(flops(*args, **kwargs)):
                return fn(*args, **kwargs)

        return run  # type: ignore[return-value]

    return decorate
