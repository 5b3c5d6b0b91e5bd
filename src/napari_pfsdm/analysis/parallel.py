"""Objects measured on every core, rows in the order :func:`~napari_pfsdm.iter_objects` gives.

The napari widget's Run (and anyone who wants ``measure``'s objects faster on one machine)
hands the frames to a pool of worker processes; each task measures some objects of one or a
few frames exactly as :func:`~napari_pfsdm.iter_objects` does (the run's
:class:`~napari_pfsdm.analysis.measuring.ObjectMeasurer`, sent with the task) and sends back
only what the table needs of them, as a block of table rows
(:mod:`~napari_pfsdm.analysis.row_blocks`: a few arrays, not one Python object per object
for the garbage collector to walk in the viewer's process). The blocks come back in frame
order, then label order, so that
:func:`~napari_pfsdm.analysis.row_blocks.join_blocks` gives the table
:func:`~napari_pfsdm.measure` builds (tested equal).

Processes, not threads: one object's work is many small numpy / scikit-image calls that hold
Python's lock, so threads gain little (docs/design.md §5). The pool is loky's process
executor (the process pool of joblib and scikit-learn): its workers are fresh interpreters
(forking the viewer's own process, with Qt and its threads, is unsafe) that never import the
caller's ``__main__`` (a script without an ``if __name__ == "__main__":`` guard, one that
opens a viewer or measures a movie, runs once, not again in every worker), and a worker that
dies breaks the pool at once (a plain :class:`~napari_pfsdm.errors.RunFault`, never a run
that waits for ever). The pool is kept for the next run (:func:`shared_pool`), because
starting it costs seconds (each worker imports numpy, scipy and scikit-image itself;
``benchmarks/pool_start.py``); :func:`warm_pool` starts it ahead of a run.

Cancelling: closing :func:`iter_blocks` (the widget's worker stops at a yield) kills the
pool's processes at once; the next run starts a new pool.
"""

from __future__ import annotations

import atexit
import os
import threading
from collections import deque
from collections.abc import Generator, Iterator
from concurrent.futures import BrokenExecutor, wait
from typing import Any

import numpy as np

from ..core.params import PFSDMParams
from ..core.threads import one_blas_thread
from .features import iter_objects
from .label_images import check_arrays, frame_at, object_boxes, present_ids, voxel_spacing
from .measuring import ObjectMeasurer, ObjectResult, light
from .row_blocks import RowBlock, block_of

__all__ = [
    "MAX_TASK_OBJECTS",
    "MIN_OBJECTS",
    "available_cores",
    "block_of_entries",
    "iter_blocks",
    "measure_entries",
    "plan_tasks",
    "shared_pool",
    "pool_ready",
    "shutdown_pool",
    "task_count",
    "task_entries",
    "warm_pool",
]

#: Below this many objects a run stays in one process unless the pool is already running
#: (:func:`warm_pool`): starting the processes (about 0.6 s) costs more than they save (the
#: 72-object sample measures in 0.2 s).
MIN_OBJECTS = 300
#: At least this many objects per task: fewer, and sending a task and its rows costs more
#: than measuring it (the sample on a running pool: 64 tasks of one object 0.23 s, 4 tasks
#: of 18 objects 0.13 s, one process 0.21 s).
MIN_TASK_OBJECTS = 16
#: About this many tasks per worker process: enough to balance uneven frames (the last task
#: of one worker is the other's idle time) and to report progress, few enough that sending
#: frames costs little. 10,000 blobs: 8 tasks per worker 0.61x measure's time, 32 0.58x.
TASKS_PER_WORKER = 32
#: At most this many objects per task: a task's result is unpickled in one go by the pool's
#: result thread, holding the interpreter lock the viewer's GUI thread needs (745 objects,
#: 50,000 in 64 tasks: ~22 ms; 128 objects: ~4 ms), and progress comes after each task.
MAX_TASK_OBJECTS = 128


def available_cores() -> int:
    """Cores this process may use (its CPU affinity where the system tells it)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - macOS, Windows
        return os.cpu_count() or 1


# --------------------------------------------------------------------------- tasks
def plan_tasks(counts: list[np.ndarray], n_tasks: int) -> list[list[tuple[int, np.ndarray]]]:
    """Split the objects of a movie into about ``n_tasks`` tasks of similar size, in order.

    Parameters
    ----------
    counts : list of ndarray
        The labels present in each frame (sorted), frame by frame.
    n_tasks : int
        Wanted number of tasks (at least 1).

    Returns
    -------
    list of list of (frame, labels)
        Each task: consecutive frames (small frames are grouped) or a block of consecutive
        labels of one large frame. Concatenated, the tasks list every (frame, label) once,
        in frame then label order.

    Examples
    --------
    >>> plan_tasks([np.array([1, 2]), np.array([1, 2, 3, 4])], 3)
    [[(0, array([1, 2]))], [(1, array([1, 2]))], [(1, array([3, 4]))]]
    """
    total = int(sum(len(c) for c in counts))
    size = max(1, -(-total // max(1, int(n_tasks))))  # objects per task, rounded up
    tasks: list[list[tuple[int, np.ndarray]]] = []
    current: list[tuple[int, np.ndarray]] = []
    filled = 0
    for t, labels in enumerate(counts):
        start = 0
        while start < len(labels):
            take = min(size - filled, len(labels) - start)
            current.append((t, labels[start:start + take]))
            filled += take
            start += take
            if filled == size:
                tasks.append(current)
                current, filled = [], 0
    if current:
        tasks.append(current)
    return tasks


def task_count(total: int, workers: int, per_worker: int | None = None,
               limited: bool = True) -> int:
    """How many tasks :func:`plan_tasks` should make of ``total`` objects for ``workers``
    workers: about ``per_worker`` per worker (default :data:`TASKS_PER_WORKER`), none smaller
    than :data:`MIN_TASK_OBJECTS` objects (unless there are fewer objects than workers) nor,
    when ``limited``, larger than :data:`MAX_TASK_OBJECTS`. The one rule of the package: the
    pool here (with the defaults) and :func:`napari_pfsdm.batch.measure_dask` (dask's
    workers: :data:`napari_pfsdm.batch.tasks.DASK_TASKS_PER_WORKER`, not limited) plan their
    tasks with it.

    Examples
    --------
    >>> task_count(1200, 2), task_count(10, 4), task_count(50_000, 2)
    (64, 4, 391)
    >>> task_count(1200, 2, per_worker=8, limited=False)
    16
    """
    total, workers = int(total), max(1, int(workers))
    per_worker = TASKS_PER_WORKER if per_worker is None else max(1, int(per_worker))
    n = min(workers * per_worker, max(workers, total // MIN_TASK_OBJECTS))
    return max(n, -(-total // MAX_TASK_OBJECTS)) if limited else n


def _labels_per_frame(labels, n_frames: int, timelapse: bool) -> list[np.ndarray]:
    out = []
    for t in range(n_frames):
        out.append(present_ids(frame_at(labels, t, timelapse)))
    return out


def measure_entries(measurer: ObjectMeasurer, entries: list[tuple]) -> list[ObjectResult]:
    """Worker process: the light rows (:func:`~napari_pfsdm.analysis.measuring.light`) of a
    task's entries (:func:`task_entries`): ``("frame", frame index, frame, image, labels)``
    or ``("crops", crops)``."""
    rows: list[ObjectResult] = []
    with one_blas_thread():
        for entry in entries:
            if entry[0] == "crops":
                crops = entry[1]
            else:
                _, t, frame, image, wanted = entry
                crops = measurer.crops(frame, image, int(t), wanted)
            rows += [light(measurer.measure(crop)) for crop in crops]
    return rows


# --------------------------------------------------------------------------- the pool
_POOL: dict[str, Any] = {"pool": None, "workers": 0}
_POOL_LOCK = threading.Lock()
#: Imported by each worker as it starts, so that no worker imports them in its first task
#: (what the first object imports lazily: regionprops, contours, moments, BLAS control).
_PRELOAD = ("napari_pfsdm.analysis.parallel", "skimage.measure._regionprops",
            "skimage.measure._find_contours", "skimage.measure._moments", "threadpoolctl")


def _preload() -> None:
    """Worker initializer: import :data:`_PRELOAD`."""
    import importlib

    for name in _PRELOAD:
        importlib.import_module(name)


def _start(workers: int) -> Any:
    """A pool of ``workers`` processes (loky's executor: fresh interpreters that do not run the
    caller's script)."""
    from loky import ProcessPoolExecutor

    return ProcessPoolExecutor(max_workers=workers, initializer=_preload)


def _stop(pool: Any) -> None:
    """Kill a pool's processes now, without waiting for their tasks; return once they are
    gone (the executor's own thread kills them: not waiting for it could leave a worker
    that was still starting alive)."""
    pool.shutdown(wait=True, kill_workers=True)


def shared_pool(workers: int | None = None):
    """The process pool of this Python session (started on first use, then kept).

    Parameters
    ----------
    workers : int, optional
        Processes (default :func:`available_cores`); a pool of another size is replaced.
    """
    workers = int(workers or available_cores())
    with _POOL_LOCK:
        pool = _POOL["pool"]
        if pool is None or _POOL["workers"] != workers:
            if pool is not None:
                _stop(pool)
            pool = _start(workers)
            _POOL.update(pool=pool, workers=workers)
        return pool


def pool_ready(workers: int | None = None) -> bool:
    """Whether the shared pool is running with ``workers`` processes (default
    :func:`available_cores`), without waiting for one being started."""
    workers = int(workers or available_cores())
    return _POOL["pool"] is not None and _POOL["workers"] == workers


def warm_pool(workers: int | None = None) -> threading.Thread | None:
    """Start the shared pool in the background, so that the next run, however small, is
    measured on every core without waiting for the processes.

    The napari widget calls it when it is docked. Returns the starting thread (None when
    the pool is running already or there is one core only). The processes wait idle until a
    run; :func:`shutdown_pool` stops them.
    """
    workers = int(workers or available_cores())
    if workers <= 1 or pool_ready(workers):
        return None
    thread = threading.Thread(target=_start_warm, args=(workers,), name="pfsdm-warm-pool",
                              daemon=True)
    thread.start()
    return thread


def _start_warm(workers: int) -> None:
    pool = shared_pool(workers)
    # one small object per process: its first FFTs and contours cost 0.1 s more than later
    # ones (plans, caches); a pool stopped meanwhile just ends the wait
    wait([pool.submit(_warm_task, i) for i in range(workers)], timeout=60)


def _warm_task(_index: int) -> None:
    yy, xx = np.mgrid[:32, :32]
    frame = ((yy - 15.5) ** 2 + (xx - 15.5) ** 2 < 100).astype(np.uint8)
    args = [("frame", 0, frame, frame.astype(np.float32), np.array([1]))]
    measure_entries(ObjectMeasurer.of(PFSDMParams(), with_intensity=True), args)


def shutdown_pool() -> None:
    """Stop the shared pool's processes now (a cancelled run; the end of the session)."""
    with _POOL_LOCK:
        pool = _POOL["pool"]
        _POOL.update(pool=None, workers=0)
    if pool is not None:
        _stop(pool)


atexit.register(shutdown_pool)


# --------------------------------------------------------------------------- the rows
def iter_blocks(
    labels, intensity=None, *, params: PFSDMParams, axes: str, spacing=None,
    workers: int | None = None, total: int | None = None, pixel_size=None,
    space_unit: str | None = None,
) -> Generator[tuple[int, int, int, int], None, list[RowBlock]]:
    """The rows of every object as blocks (:mod:`~napari_pfsdm.analysis.row_blocks`), on
    ``workers`` processes; a generator.

    Parameters
    ----------
    labels, intensity, axes, spacing
        As for :func:`~napari_pfsdm.iter_objects` (``axes`` resolved: ``"yx"``, ``"tyx"``,
        ``"zyx"`` or ``"tzyx"``).
    params : PFSDMParams
        The method's options.
    workers : int, optional
        Processes: default :func:`available_cores`. 1 measures here, in this thread, object
        by object; so do fewer than :data:`MIN_OBJECTS` objects, unless the pool is running
        already (:func:`pool_ready`) and there are at least :data:`MIN_TASK_OBJECTS` per
        process.
    total : int, optional
        The number of objects, if already counted (progress says ``done / total``).
    pixel_size, space_unit : optional
        The physical size of a pixel (or voxel) and its unit: the table's sizes in that unit
        (:meth:`~napari_pfsdm.analysis.measuring.ObjectMeasurer.of`).

    Yields
    ------
    (done, total, frame, label)
        After each object (one process) or each finished task (several); while waiting for a
        task, the last value again about every 0.2 s, so that a caller that stops at a yield
        (a napari worker's ``quit``) is never kept waiting.

    Returns
    -------
    list of RowBlock
        One per task (one in all when measured here), in frame order, then label order, as
        :func:`~napari_pfsdm.iter_objects` yields the objects:
        :func:`~napari_pfsdm.analysis.row_blocks.join_blocks` gives :func:`~napari_pfsdm.
        measure`'s table.
    """
    workers = int(workers or available_cores())
    volume = "z" in axes
    if total is None:
        from .label_images import count_objects

        total = count_objects(labels, axes)
    where = {"axes": axes, "spacing": spacing} if volume else {"axes": axes}
    measurer = ObjectMeasurer.of(params, ndim=3 if volume else 2,
                                 with_intensity=intensity is not None, axes=axes,
                                 spacing=voxel_spacing(axes, spacing), pixel_size=pixel_size,
                                 space_unit=space_unit)
    pooled = total >= MIN_OBJECTS or (pool_ready(workers)
                                      and total >= workers * MIN_TASK_OBJECTS)
    if workers <= 1 or not pooled:
        rows = []
        for done, obj in enumerate(iter_objects(labels, intensity, params=params, **where),
                                   start=1):
            rows.append(light(obj))
            yield done, total, int(obj.frame), int(obj.label)
        return [block_of(rows, measurer)] if rows else []
    return (yield from _iter_blocks_pool(labels, intensity, measurer, workers, total))


def task_entries(measurer: ObjectMeasurer, labels, intensity, timelapse: bool, task,
                 counts: list[np.ndarray], boxes: dict) -> list[tuple]:
    """What a worker process is sent for one task (:func:`measure_entries`): each whole frame
    it measures, with the labels wanted, or, for a block of the labels of a frame split
    between tasks, each object's :class:`~napari_pfsdm.analysis.measuring.Crop` (its pixels
    only). Sent whole to each of its tasks, a 2,200² frame of 3,000 objects with its
    reporter (29 MB, 64 tasks) made the Run slower than one process (11.2 s against
    measure's 10.0 s). ``counts``: the labels of each frame; ``boxes``: the bounding boxes
    of the last split frame, kept between its tasks."""
    out: list[tuple] = []
    for t, wanted in task:
        frame = frame_at(labels, t, timelapse)
        image = None if intensity is None else frame_at(intensity, t, timelapse)
        if len(wanted) == len(counts[t]):
            out.append(("frame", t, frame, image, wanted))
            continue
        if t not in boxes:
            boxes.clear()
            boxes[t] = dict(object_boxes(frame))
        out.append(("crops", [measurer.crop(frame, image, t, int(label),
                                            boxes[t][int(label)]).detached()
                              for label in wanted]))
    return out


def _iter_blocks_pool(labels, intensity, measurer: ObjectMeasurer, workers: int, total: int):
    axes = measurer.axes
    n_frames, timelapse, axes = check_arrays(labels, intensity, axes)
    counts = _labels_per_frame(labels, n_frames, timelapse)
    tasks = plan_tasks(counts, task_count(total, workers))
    pool = shared_pool(workers)
    boxes: dict = {}
    args: Iterator[tuple] = ((measurer, task_entries(measurer, labels, intensity, timelapse,
                                                     task, counts, boxes))
                             for task in tasks)
    pending: deque = deque()

    def send() -> None:  # the next task's frames, read only when a worker is about to free up
        entry = next(args, None)
        if entry is not None:
            pending.append(pool.submit(block_of_entries, entry))

    for _ in range(2 * workers):
        send()
    blocks: list[RowBlock] = []
    done = 0
    finished = False
    try:
        last = (0, total, 0, 0)
        for _ in tasks:
            future = pending.popleft()
            while True:
                try:
                    block = future.result(timeout=0.2)
                    break
                except TimeoutError:
                    yield last
                except BrokenExecutor:  # a worker died: its task is lost
                    raise _killed_worker() from None
            send()
            blocks.append(block)
            done += len(block.table)
            if len(block.table):
                end = block.table.iloc[-1]
                last = (done, total, int(end["frame"]), int(end["label"]))
            yield last
        finished = True
    finally:
        if not finished:  # stopped early (Cancel) or failed: stop the processes now
            shutdown_pool()
    return blocks


def _killed_worker() -> Exception:
    """The plain-words error for a worker process that died during a run."""
    from ..errors import RunFault

    return RunFault(
        "a worker process stopped while measuring (killed from outside, or by the system when "
        "memory ran out); run again, with fewer worker processes if memory is short")


def block_of_entries(args: tuple[ObjectMeasurer, list[tuple]]) -> RowBlock:
    """Worker process: the block of one task's objects (``args``: the run's measurer and the
    task's entries, :func:`task_entries`)."""
    measurer, entries = args
    return block_of(measure_entries(measurer, entries), measurer)
