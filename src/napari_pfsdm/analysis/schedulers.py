"""Which dask scheduler runs a computation: this machine (threads, processes, sync) or a
cluster (an address, or a ``distributed.Client``), and the worker processes of the
``"processes"`` scheduler (:func:`process_pool`). Shared by :func:`napari_pfsdm.batch.
measure_dask` and :func:`napari_pfsdm.nearest_neighbours` (analysis may not import batch).
"""

from __future__ import annotations

import contextlib
import numbers
import os
import re
import socket
import threading
from collections.abc import Iterator
from typing import Any

from ..errors import InputError

__all__ = ["CONNECT_TIMEOUT", "LOCAL_SCHEDULERS", "available_cores", "check_workers", "client_for",
           "process_pool", "resolve_scheduler"]

LOCAL_SCHEDULERS = ("threads", "processes", "sync", "synchronous", "single-threaded")

#: Seconds to reach a scheduler and hear it greet as a dask scheduler.
CONNECT_TIMEOUT = 20.0


def resolve_scheduler(scheduler: Any = None, client: Any = None) -> tuple[str, Any]:
    """Normalise the scheduler choice into ``(kind, object)``.

    Returns ``("distributed", Client)``, ``("address", str)`` (a client is opened on demand)
    or ``("local", name)`` with name in threads / processes / sync.
    """
    if client is not None:
        return "distributed", client
    if scheduler is None:
        return "local", "threads"
    if isinstance(scheduler, str):
        s = scheduler.strip()
        if s in LOCAL_SCHEDULERS:
            return "local", {"synchronous": "sync", "single-threaded": "sync"}.get(s, s)
        if "://" in s or re.fullmatch(r"[\w.\-]+:\d+", s):
            return "address", s
        raise InputError(
            f"unknown scheduler {scheduler!r}: use threads, processes, sync, or the address "
            "of a dask scheduler such as tcp://10.0.0.5:8786"
        )
    # a distributed.Client passed as scheduler
    if hasattr(scheduler, "submit") and hasattr(scheduler, "gather"):
        return "distributed", scheduler
    raise InputError(f"unknown scheduler {scheduler!r}")


@contextlib.contextmanager
def client_for(kind: str, obj: Any) -> Iterator[Any]:
    if kind == "address":
        try:
            from distributed import Client
        except ImportError as exc:
            raise InputError(
                "running on a dask cluster needs the distributed package: "
                "pip install 'napari-pfsdm[batch]'"
            ) from exc

        probe_scheduler(obj, CONNECT_TIMEOUT)
        try:
            client = Client(obj, timeout=f"{CONNECT_TIMEOUT:g}s")
        except OSError as exc:
            raise InputError(f"cannot reach the dask scheduler at {obj}: {exc}") from exc
        try:
            yield client
        finally:
            client.close()
    else:
        yield obj




def _unreachable(address: str, why: str) -> InputError:
    return InputError(
        f"cannot reach the dask scheduler at {address} ({why}); check the address (the one the "
        "scheduler prints when it starts, e.g. tcp://10.0.0.5:8786) and that it is running"
    )


def probe_scheduler(address: str, timeout: float) -> None:
    """Check that a ``tcp://`` address answers as a dask scheduler, within ``timeout`` seconds.

    A dask scheduler greets every new connection at once (its side of the comm handshake);
    a port that accepts the connection and stays silent (a web dashboard's port 8787 instead
    of the scheduler's 8786, another service) would keep ``distributed.Client`` waiting for
    ever, past its own timeout. Other protocols (``tls://``, ``inproc://``, ...) are left to
    ``distributed``.

    Raises
    ------
    InputError
        Nothing listens there, or something that is not a dask scheduler does.
    """
    scheme, _, rest = address.rpartition("://")
    if (scheme or "tcp") != "tcp":
        return
    host, _, port = rest.rpartition(":")
    try:
        conn = socket.create_connection((host.strip("[]"), int(port)), timeout=timeout)
    except (OSError, ValueError) as exc:
        raise _unreachable(address, getattr(exc, "strerror", None) or str(exc)) from None
    with conn:
        conn.settimeout(timeout)
        try:
            greeting = conn.recv(1)
        except TimeoutError:
            greeting = None
        except OSError:
            greeting = b""
    if not greeting:
        raise InputError(
            f"{address} accepts connections but does not answer as a dask scheduler "
            f"{'within ' + format(timeout, 'g') + ' s' if greeting is None else '(it hung up)'}"
            ": it is another service (a dask dashboard listens on 8787, the scheduler on "
            "8786). Give the address the scheduler prints when it starts, e.g. "
            "tcp://10.0.0.5:8786"
        )


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity where the system says it, as a
    batch system or ``taskset`` sets it; else the machine's count)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # macOS, Windows
        return max(1, os.cpu_count() or 1)


def check_workers(workers: Any, what: str = "workers") -> int | None:
    """``workers`` (None: one per core) as a whole number from 1 to :func:`available_cores`,
    else :class:`InputError` saying how many cores there are: more processes than cores only
    compete for them, and each holds its frames in memory."""
    if workers is None:
        return None
    cores = available_cores()
    if isinstance(workers, bool) or not isinstance(workers, numbers.Integral) or workers < 1:
        raise InputError(f"{what} must be a whole number of at least 1; got {workers!r}")
    if workers > cores:
        raise InputError(
            f"{what} {workers}: this machine offers {cores} core{'s' if cores > 1 else ''} to "
            f"this process; more workers than cores only compete for them, each holding its "
            f"frames in memory. Give at most {cores}, or leave it out for one per core (a "
            "dask cluster's workers are started on its machines, with 'dask worker')")
    return int(workers)


def process_pool(workers: int | None = None) -> Any:
    """A process pool for the ``"processes"`` scheduler: ``workers`` processes (fresh
    interpreters; default: one per core), all started before it is returned, that exit with
    this process and do not run the caller's script (loky's executor never imports
    ``__main__`` in its workers: a script without an ``if __name__ == "__main__":`` guard
    measures once, not again in every worker).

    Returns
    -------
    loky.ProcessPoolExecutor
        A :class:`concurrent.futures.Executor`; close it with ``shutdown()`` (or use it in a
        ``with`` block).
    """
    from loky import ProcessPoolExecutor

    workers = check_workers(workers) or available_cores()
    pool = ProcessPoolExecutor(max_workers=workers, initializer=_exit_with_parent,
                               initargs=(os.getpid(),))
    try:
        for future in [pool.submit(os.getpid) for _ in range(workers)]:
            future.result()
    except BaseException:
        pool.shutdown(wait=False, kill_workers=True)
        raise
    return pool


def _exit_with_parent(parent_pid: int) -> None:
    """Pool worker initializer: exit when the parent dies (e.g. ``kill -9`` of ``pfsdm``).

    Without it, the workers of a killed run would wait forever for work that never comes.
    """
    import time

    def watch() -> None:
        while True:
            if os.getppid() != parent_pid:
                os._exit(1)
            time.sleep(1.0)

    threading.Thread(target=watch, daemon=True, name="pfsdm-parent-watch").start()
