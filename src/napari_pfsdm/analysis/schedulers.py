"""Which dask scheduler runs a computation: this machine (threads, processes, sync) or a
cluster (an address, or a ``distributed.Client``). Shared by :func:`napari_pfsdm.batch.
measure_dask` and :func:`napari_pfsdm.nearest_neighbours` (analysis may not import batch).
"""

from __future__ import annotations

import contextlib
import re
from collections.abc import Iterator
from typing import Any

from ..errors import InputError

__all__ = ["LOCAL_SCHEDULERS", "resolve_scheduler"]

LOCAL_SCHEDULERS = ("threads", "processes", "sync", "synchronous", "single-threaded")


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
def _client_for(kind: str, obj: Any) -> Iterator[Any]:
    if kind == "address":
        try:
            from distributed import Client
        except ImportError as exc:
            raise InputError(
                "running on a dask cluster needs the distributed package: "
                "pip install 'napari-pfsdm[batch]'"
            ) from exc

        try:
            client = Client(obj, timeout="20s")
        except OSError as exc:
            raise InputError(f"cannot reach the dask scheduler at {obj}: {exc}") from exc
        try:
            yield client
        finally:
            client.close()
    else:
        yield obj


