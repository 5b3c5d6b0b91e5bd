"""The package's compiled kernels (numba): compiled once, loaded from numba's cache after, and said.

The elastic term's kernels (:mod:`.elastic_kernel`: its distance and its neighbour search;
:mod:`.signature_kernel`: the outline signature) are module-level ``@numba.njit(cache=True)``
functions that take every array and number as an argument. numba keeps what it compiles
beside the module (``__pycache__``; in the user's cache folder where that cannot be written;
``NUMBA_CACHE_DIR`` moves it), under the module file's time stamp: the first use after an
install or an edit of the module compiles (about a minute on 2 cores), every later process
loads the machine code in about a second. (Kernels built as closures that capture other
compiled functions never hit that cache: numba hashes the captured functions, which differ
from process to process; numba issue #6264.)

A compile is said: :func:`compile_notice` passes a callable that receives
:data:`COMPILING`'s message when one of the package's kernels starts to compile (never when
it is loaded), once per kernel and process (a kernel compiled inside another's compile is not
said again); the CLI prints it on stderr, the plugin shows it
in its progress. Without one, the message goes to the ``napari_pfsdm`` logger (level INFO).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

__all__ = ["COMPILING", "compile_notice", "watch"]

#: What is said when a kernel compiles ({what}: which one).
COMPILING = ("compiling the elastic kernel, once ({what}: about a minute; later runs load it "
             "from numba's cache)")

_LOCK = threading.Lock()
_SINKS: list[Callable[[str], None]] = []
#: Kernels watched: the dispatcher's function's module and name -> what the message calls it.
_WATCHED: dict[tuple[str, str], str] = {}
_SAID: set[tuple[str, str]] = set()
_LISTENING = False
#: Watched compiles under way in this thread (a kernel that calls another compiles it inside
#: its own compile: one message, not two).
_DEPTH = threading.local()


@contextmanager
def compile_notice(say: Callable[[str], None]) -> Iterator[None]:
    """Inside the block, ``say(message)`` is called when one of the package's compiled
    kernels starts to compile (module docstring), in the thread that compiles it.

    Examples
    --------
    >>> from napari_pfsdm.core.compiled import compile_notice
    >>> with compile_notice(print):
    ...     pass  # e.g. distance_matrix(table, elastic_weight=0.375)
    """
    with _LOCK:
        _SINKS.append(say)
    try:
        yield
    finally:
        with _LOCK:
            _SINKS.remove(say)


def _said(key: tuple[str, str]) -> None:
    with _LOCK:
        if key in _SAID:
            return
        _SAID.add(key)
        sinks = list(_SINKS)
    message = COMPILING.format(what=_WATCHED[key])
    if not sinks:
        logging.getLogger("napari_pfsdm").info(message)
    for say in sinks:
        say(message)


def watch(kernel, what: str) -> None:
    """Say :data:`COMPILING` (``what``: the kernel's role) when the numba dispatcher
    ``kernel`` starts to compile (a miss of numba's cache)."""
    global _LISTENING
    from numba.core import event

    with _LOCK:
        _WATCHED[(kernel.py_func.__module__, kernel.py_func.__qualname__)] = what
        if _LISTENING:
            return
        _LISTENING = True

    def watched(ev) -> tuple[str, str] | None:
        func = getattr(ev.data.get("dispatcher"), "py_func", None)
        key = (getattr(func, "__module__", None), getattr(func, "__qualname__", None))
        return key if key in _WATCHED else None

    class _Listener(event.Listener):
        def on_start(self, ev):
            key = watched(ev)
            if key is not None:
                depth = getattr(_DEPTH, "n", 0)
                _DEPTH.n = depth + 1
                if depth == 0:
                    _said(key)

        def on_end(self, ev):
            if watched(ev) is not None:
                _DEPTH.n = getattr(_DEPTH, "n", 1) - 1

    event.register("numba:compile", _Listener())
