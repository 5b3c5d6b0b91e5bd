"""One movie measured in tasks of frames, on this machine's pool or on a dask cluster.

:func:`measure_dask` measures a movie in tasks planned as the napari plugin's process pool
plans them (:func:`napari_pfsdm.analysis.parallel.plan_tasks`: tasks of similar numbers of
objects, a large frame cut between tasks), with the pool's code for the objects, and joins the
tasks' row blocks in frame then label order, so the table is the pool's and
:func:`napari_pfsdm.measure`'s whichever scheduler ran it. Each task reads its own frames
(from the file, inside the worker, :class:`_Reader`), a few at a time (:data:`TASK_BYTES`), so
memory stays bounded even for a movie larger than RAM.

Faults of the machine or the cluster (a worker process killed, the scheduler lost) become a
plain :class:`~napari_pfsdm.errors.RunFault` (:func:`environment_fault`); anything else that
is not the input's fault stays what it is: a bug.
"""

from __future__ import annotations

import os
import threading
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pandas as pd

from ..analysis.measuring import ObjectMeasurer, check_frame_ids
from ..analysis.row_blocks import RowBlock, block_of, join_blocks
from ..analysis.schedulers import client_for, process_pool, resolve_scheduler
from ..core.params import PFSDMParams, as_params
from ..errors import InputError, RunFault
from .io import (
    check_labels,
    missing_frames,
    missing_warning,
    movie_source,
    refuse_missing_chunks,
)

__all__ = ["DASK_TASKS_PER_WORKER", "TASK_BYTES", "environment_fault", "measure_dask"]


class _Reader:
    """Frames ``start:stop`` of a movie, read where the task runs (in the worker).

    A movie from :func:`~napari_pfsdm.batch.io.open_movie` travels as its file's path (its
    :func:`~napari_pfsdm.batch.io.movie_source`) and is read straight from the file; a dask
    array travels as the graph of its slice and is computed in the worker with the
    synchronous scheduler; another array (zarr, h5py, ...) as its slice. Frames never travel
    through the scheduler or the client.
    """

    def __init__(self, array: Any, start: int, stop: int):
        self.source = movie_source(array)
        self.start = int(start)
        self.array = array[start:stop] if self.source is None else None

    def load(self, a: int, b: int) -> np.ndarray:
        """Frames ``a:b`` of the movie (numbered over the whole movie)."""
        if self.source is not None:
            return np.asarray(self.source[a:b])
        arr = self.array[a - self.start:b - self.start]
        if hasattr(arr, "dask") and hasattr(arr, "compute"):
            return np.asarray(arr.compute(scheduler="sync"))
        return np.asarray(arr)


#: Largest amount of image data (labels + intensity) one task reads at once: a task reads its
#: frames in runs of consecutive frames up to this size, and measures them one by one.
TASK_BYTES = 256 * 2**20

#: Tasks per worker that :func:`measure_dask` plans (the pool plans
#: :data:`~napari_pfsdm.analysis.parallel.TASKS_PER_WORKER`, of at most
#: :data:`~napari_pfsdm.analysis.parallel.MAX_TASK_OBJECTS` objects each). A dask task costs
#: more than a pool's: its messages to the scheduler, its result gathered by the client, the
#: worker's bookkeeping and profiler, its frames read and searched for objects once more when
#: a frame is split between tasks. On ``benchmarks/dask_vs_pool.py``'s movie (2 workers,
#: 4,800 nuclei) the pool's plan costs dask 1.22x the pool's wall time, 8 tasks per worker
#: 1.06x, 4 1.05x; eight still balance uneven frames between the workers. The size limit of
#: the pool's tasks (results unpickled beside napari's GUI thread) does not apply here.
DASK_TASKS_PER_WORKER = 8


def _runs(frames: Sequence[int], frame_bytes: int) -> list[tuple[int, int]]:
    """``frames`` (increasing) as runs ``(a, b)`` of consecutive frames of at most
    :data:`TASK_BYTES` together."""
    most = max(1, TASK_BYTES // max(int(frame_bytes), 1))
    runs: list[tuple[int, int]] = []
    for t in frames:
        if runs and runs[-1][1] == t and t - runs[-1][0] < most:
            runs[-1] = (runs[-1][0], t + 1)
        else:
            runs.append((t, t + 1))
    return runs


def _frame_ids(frame: np.ndarray, t: int) -> np.ndarray:
    """The labels present in frame ``t`` (sorted); negative labels are refused, as
    :func:`napari_pfsdm.measure` refuses them."""
    from ..analysis.label_images import present_ids

    return present_ids(check_frame_ids(frame, t))


def _count_task(labels: _Reader, start: int, stop: int, frame_bytes: int) -> list[np.ndarray]:
    """Worker task: the labels present in frames ``start:stop``, frame by frame."""
    out = []
    for a, b in _runs(range(start, stop), frame_bytes):
        block = labels.load(a, b)
        out += [_frame_ids(block[i], a + i) for i in range(b - a)]
    return out


#: The frames a worker process read last, with their objects' boxes: a frame split between
#: tasks (the plan cuts large frames) is read and searched for its objects once per worker,
#: not once per task. ``{(labels, intensity, frame): (frame, image, boxes)}``, at most
#: :data:`_RECENT_FRAMES` entries.
_RECENT: dict = {}
_RECENT_FRAMES = 2
_RECENT_LOCK = threading.Lock()


def _recent_key(labels: _Reader, intensity: _Reader | None, t: int) -> tuple | None:
    """The key of frame ``t`` in :data:`_RECENT`, for movies read from their files only."""
    if labels.source is None or (intensity is not None and intensity.source is None):
        return None
    return (labels.source._cache_key(),
            None if intensity is None else intensity.source._cache_key(), int(t))


def _measure_task(measurer: ObjectMeasurer, labels: _Reader, intensity: _Reader | None,
                  parts: list[tuple], frame_bytes: int) -> RowBlock:
    """Worker task: read the frames of ``parts`` (``(frame, labels wanted)``; None: all of
    the frame's) and measure their objects with ``measurer``, as the process pool's tasks do
    (:func:`napari_pfsdm.analysis.parallel.measure_entries`: whole frames, or the crops of
    the objects wanted); the rows as one block."""
    from ..analysis import parallel
    from ..analysis.label_images import object_boxes
    from ..core.threads import one_blas_thread

    rows: list = []
    wanted = dict(parts)
    with one_blas_thread():  # once per task (about 1 ms), not once per frame
        for a, b in _runs([t for t, _ in parts], frame_bytes):
            key = _recent_key(labels, intensity, a) if b - a == 1 else None
            with _RECENT_LOCK:
                hit = _RECENT.get(key) if key is not None else None
            if hit is None:
                lab = labels.load(a, b)
                img = intensity.load(a, b) if intensity is not None else None
            for t in range(a, b):
                if hit is not None:
                    frame, image, boxes = hit
                else:
                    frame, image = lab[t - a], None if img is None else img[t - a]
                    boxes = None
                if wanted[t] is None:  # the whole frame
                    entry = ("frame", t, frame, image, _frame_ids(frame, t))
                    rows += parallel.measure_entries(measurer, [entry])
                    continue
                if boxes is None:  # a frame of a plan by objects: maybe split, keep it
                    boxes = dict(object_boxes(check_frame_ids(frame, t)))
                    key = _recent_key(labels, intensity, t)
                    if key is not None:
                        with _RECENT_LOCK:
                            while len(_RECENT) >= _RECENT_FRAMES:
                                _RECENT.pop(next(iter(_RECENT)))
                            _RECENT[key] = (frame, image, boxes)
                crops = [measurer.crop(frame, image, t, int(label), boxes[int(label)])
                         for label in wanted[t]]
                rows += parallel.measure_entries(measurer, [("crops", crops)])
    return block_of(rows, measurer)


def measure_dask(
    labels: Any,
    intensity: Any = None,
    *,
    client: Any = None,
    scheduler: Any = None,
    num_workers: int | None = None,
    frames_per_task: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    pool: Any = None,
    params: PFSDMParams | None = None,
    axes: str | None = None,
    spacing: Any = None,
    allow_missing_chunks: bool = False,
    series: int | None = None,
    pixel_size: Any = None,
    space_unit: str | None = None,
    **options: Any,
) -> pd.DataFrame:
    """PF-SDM feature table of a movie, measured in parallel with dask.

    The same table as :func:`napari_pfsdm.measure` and as the process pool of
    :func:`napari_pfsdm.analysis.parallel.iter_blocks` (same rows, same order, same numbers:
    tested equal), on this machine or on a dask.distributed cluster. The tasks are planned by
    the pool's planner (:func:`~napari_pfsdm.analysis.parallel.plan_tasks` with
    :func:`~napari_pfsdm.analysis.parallel.task_count`: tasks of similar numbers of objects,
    a large frame split between tasks), fewer per worker (:data:`DASK_TASKS_PER_WORKER`);
    each task reads its own frames where it runs (a movie from
    :func:`~napari_pfsdm.batch.io.open_movie`: from the file) and sends back its rows as
    one block of arrays (:class:`~napari_pfsdm.analysis.row_blocks.RowBlock`). A first, light
    pass of tasks lists the labels of each frame (for the plan), also where the frames are.

    Parameters
    ----------
    labels : array-like
        Integer label image (Y, X) or movie (T, Y, X): numpy, Zarr, or a lazy dask array (e.g.
        from :func:`napari_pfsdm.batch.io.open_movie`); frames are read by the workers (a
        numpy array's frames, or its objects' crops, are sent with the tasks, as the pool
        sends them).
    intensity : array-like, optional
        Reporter image of the same shape.
    client : distributed.Client, optional
        Run on this cluster.
    scheduler : str or distributed.Client, optional
        ``"threads"`` (default), ``"processes"``, ``"sync"``, or a scheduler address such as
        ``"tcp://10.0.0.5:8786"`` (a client is opened and closed for this call).
    num_workers : int, optional
        Workers of the local threads/processes scheduler (default: the number of cores).
    frames_per_task : int, optional
        Tasks of this many whole frames each, without the first pass (default: tasks
        planned by objects, as the pool plans them).
    progress : callable, optional
        ``progress(frames_done, n_frames)``, called in the calling process after each task;
        a frame is done when all its objects are.
    pool : concurrent.futures.Executor, optional
        Re-use this process pool for the ``"processes"`` scheduler (saves start-up time when
        measuring many movies), e.g. from :func:`process_pool`; without one, the run starts
        and closes its own (:func:`process_pool`: a script needs no
        ``if __name__ == "__main__":`` guard).
    params : PFSDMParams, optional
        The method's options as one record (it travels to the workers as it is).
    axes, spacing, pixel_size, space_unit
        As :func:`napari_pfsdm.measure` (``"zyx"`` or ``"tzyx"`` for 3-D objects).
    allow_missing_chunks : bool
        A Zarr movie (from :func:`~napari_pfsdm.batch.io.open_movie`) whose chunk files are
        not all on disk is refused (``InputError``), as its missing frames would read as
        empty; True reads it as it is, with a ``UserWarning`` naming each such frame.
    **options
        Or the options as keywords (``n_fourier``, ``mapping``, ``sdf``, ...).

    Returns
    -------
    pandas.DataFrame
        One row per (frame, label), ``frame`` numbered from 0 over the whole movie;
        ``attrs["pfsdm"]`` holds the options.
    """
    from ..analysis.features import with_leave_out
    from ..analysis.label_images import resolve_axes, voxel_spacing

    p = as_params(params, options)
    check_labels(labels, intensity, axes=axes)
    _check_chunks(labels, intensity, allow_missing_chunks)
    axes = resolve_axes(tuple(labels.shape), axes)
    kind, obj = resolve_scheduler(scheduler, client)
    volume = "z" in axes
    measurer = ObjectMeasurer.of(
        p, ndim=3 if volume else 2, with_intensity=intensity is not None, axes=axes,
        spacing=voxel_spacing(axes, spacing) if pixel_size is None or not volume else spacing,
        pixel_size=pixel_size, space_unit=space_unit)
    if not axes.startswith("t"):  # one image or volume: frame 0 of a one-frame movie
        labels = labels[None]
        intensity = intensity[None] if intensity is not None else None

    where = _where(kind, obj)
    own = kind == "local" and obj == "processes" and pool is None
    blocks = None
    try:
        if own:  # the processes of this run, started without the caller's script
            pool = process_pool(num_workers)
        blocks = _measure_planned(labels, intensity, kind, obj, measurer, frames_per_task,
                                  num_workers, progress, pool)
    except Exception as exc:  # noqa: BLE001 - sorted: the environment's faults, or re-raised
        fault = environment_fault(exc, where)
        if fault is None:
            raise
        raise fault from exc
    finally:
        if own and pool is not None:  # idle after a finished run; killed after a failure
            pool.shutdown(wait=True, kill_workers=blocks is None)
        if kind == "local" and obj != "processes":  # run here: keep no frame after the run
            with _RECENT_LOCK:
                _RECENT.clear()
    if not blocks:  # no object at all: measure's empty table
        return with_leave_out(block_of([], measurer).table, p)
    return with_leave_out(join_blocks(blocks).table, p)


def _check_chunks(labels: Any, intensity: Any, allow: bool) -> None:
    """Refuse (or, when ``allow``, warn about) Zarr movies with missing chunk files."""
    for movie, what in ((labels, "the labels"), (intensity, "the intensity")):
        if movie is None or not missing_frames(movie):
            continue
        if not allow:
            refuse_missing_chunks(movie, what)
        lines = [line.removeprefix("warning: ") for line in missing_warning(movie, what)]
        warnings.warn("; ".join(lines), UserWarning, stacklevel=3)


def _where(kind: str, obj: Any) -> str:
    """Where a run's work goes, for messages: this machine or the scheduler's address."""
    if kind == "local":
        return "this machine"
    if kind == "address":
        return str(obj)
    address = getattr(getattr(obj, "scheduler", None), "address", None)
    return str(address) if address else "the dask cluster"


def _workers(kind: str, obj: Any, num_workers: int | None) -> int:
    """How many tasks run at once: the local scheduler's workers, or the cluster's threads."""
    if kind == "local":
        return 1 if obj == "sync" else int(num_workers or os.cpu_count() or 1)
    try:
        return max(1, sum(obj.nthreads().values()))
    except Exception:  # noqa: BLE001 - pragma: no cover - a client that cannot answer
        return 8


def _measure_planned(
    labels: Any, intensity: Any, kind: str, obj: Any, measurer: ObjectMeasurer,
    frames_per_task: int | None, num_workers: int | None,
    progress: Callable[[int, int], None] | None, pool: Any,
) -> list[RowBlock]:
    """The row blocks of a movie (``labels`` with a time axis first), measured by
    ``measurer`` where ``kind``/``obj`` say, in tasks planned as the process pool plans
    them."""
    from ..analysis import parallel

    n_frames = int(labels.shape[0])
    frame_bytes = int(np.prod(labels.shape[1:])) * np.dtype(labels.dtype).itemsize
    if intensity is not None:
        frame_bytes += int(np.prod(intensity.shape[1:])) * np.dtype(intensity.dtype).itemsize
    in_memory = isinstance(labels, np.ndarray) and (
        intensity is None or isinstance(intensity, np.ndarray))
    with client_for(kind, obj) as handle:  # opens a client for a scheduler address
        kind = "local" if kind == "local" else "distributed"
        run = _Runner(kind, handle, num_workers, pool)
        workers = _workers(kind, handle, num_workers)

        # the labels of each frame: listed where the frames are read, by the worker processes
        # or the cluster's workers (threads, sync: here; an array in memory: here, as the pool
        # lists them)
        counts: list[np.ndarray] | None = None
        if in_memory:
            counts = [_frame_ids(labels[t], t) for t in range(n_frames)]
        elif not frames_per_task and kind == "local" and handle != "processes":
            counts = _count_task(_Reader(labels, 0, n_frames), 0, n_frames, frame_bytes)
        elif not frames_per_task:
            spans = _spans(n_frames, max(1, -(-n_frames // (4 * workers))))
            calls = [(_count_task, (_Reader(labels, s, e), s, e, frame_bytes))
                     for s, e in spans]
            counts = [ids for part in run(calls, "count") for ids in part]

        if frames_per_task:  # whole frames, as many as asked per task
            tasks = [[(t, None if counts is None else counts[t]) for t in range(s, e)]
                     for s, e in _spans(n_frames, frames_per_task)]
        else:
            total = sum(len(c) for c in counts)
            tasks = parallel.plan_tasks(counts, parallel.task_count(
                total, workers, per_worker=DASK_TASKS_PER_WORKER, limited=False))
        if not tasks:
            if progress:
                progress(n_frames, n_frames)
            return []

        if in_memory:  # what the pool sends: whole frames, or the crops of a split frame
            boxes: dict = {}
            calls = [(parallel.block_of_entries, ((measurer, parallel.task_entries(
                measurer, labels, intensity, True, task, counts, boxes)),))
                for task in tasks]
        else:
            calls = []
            for task in tasks:
                s, e = task[0][0], task[-1][0] + 1
                calls.append((_measure_task, (
                    measurer, _Reader(labels, s, e),
                    _Reader(intensity, s, e) if intensity is not None else None,
                    task, frame_bytes)))
        return run(calls, "task", _frame_progress(tasks, n_frames, progress))


def _spans(n_frames: int, frames_per_task: int) -> list[tuple[int, int]]:
    step = max(1, int(frames_per_task))
    return [(s, min(s + step, n_frames)) for s in range(0, n_frames, step)]


def _frame_progress(tasks: list[list[tuple]], n_frames: int,
                    progress: Callable[[int, int], None] | None) -> Callable[[int], None]:
    """What to call as task ``i`` finishes: ``progress(frames done, n_frames)``, a frame done
    when every task that has some of its objects is (frames without objects: from the
    start)."""
    left = np.zeros(n_frames, np.int64)
    for task in tasks:
        for t, _ in task:
            left[t] += 1
    done = [int(np.sum(left == 0))]

    def finished(i: int) -> None:
        for t, _ in tasks[i]:
            left[t] -= 1
            done[0] += int(left[t] == 0)
        if progress:
            progress(done[0], n_frames)

    return finished


class _Call:
    """One task: a function and its arguments, opaque to dask. ``dask.delayed`` and
    ``distributed`` walk every list, tuple and dict of a task's arguments in search of dask
    collections and keys; a task's arguments are lists of frames, crops and label arrays, and
    that walk cost about a tenth of a run's time with the local scheduler."""

    __slots__ = ("fn", "args")

    def __init__(self, fn: Callable, args: tuple):
        self.fn, self.args = fn, args

    def __getstate__(self) -> tuple:
        return self.fn, self.args

    def __setstate__(self, state: tuple) -> None:
        self.fn, self.args = state


def _run_call(call: _Call) -> Any:
    return call.fn(*call.args)


class _Runner:
    """Runs a list of ``(function, args)`` calls on the local dask scheduler
    (:func:`_run_local`) or a cluster (:func:`_run_distributed`) and gives their results in
    order, calling ``finished(i)`` in this process as call ``i`` ends."""

    def __init__(self, kind: str, handle: Any, num_workers: int | None, pool: Any):
        self.kind, self.handle, self.num_workers, self.pool = kind, handle, num_workers, pool

    def __call__(self, calls: list[tuple], name: str,
                 finished: Callable[[int], None] | None = None) -> list:
        if self.kind == "local":
            return _run_local(calls, name, finished, self.handle, self.num_workers, self.pool)
        return _run_distributed(calls, name, finished, self.handle)


def _run_local(calls: list[tuple], name: str, finished: Callable[[int], None] | None,
               scheduler: str, num_workers: int | None, pool: Any) -> list:
    import dask
    from dask.callbacks import Callback

    prefix = f"pfsdm-{name}-"
    tasks = [dask.delayed(_run_call, pure=False)(_Call(fn, args), dask_key_name=f"{prefix}{i}")
             for i, (fn, args) in enumerate(calls)]

    class _Progress(Callback):
        def _posttask(self, key, result, dsk, state, worker_id):
            if isinstance(key, str) and key.startswith(prefix) and finished:
                finished(int(key.rsplit("-", 1)[1]))

    kwargs: dict[str, Any] = {"scheduler": scheduler}
    if scheduler != "sync":
        kwargs["num_workers"] = num_workers or os.cpu_count() or 1
    if scheduler == "processes" and pool is not None:
        kwargs["pool"] = pool
    with _Progress():
        return list(dask.compute(*tasks, **kwargs))


def _run_distributed(calls: list[tuple], name: str, finished: Callable[[int], None] | None,
                     client: Any) -> list:
    from distributed import as_completed

    run = os.urandom(4).hex()
    # one message to the scheduler for all the tasks (client.submit would send one each); the
    # tasks keep their order as priorities
    futures = client.map(_run_call, [_Call(fn, args) for fn, args in calls], pure=False,
                         key=[f"pfsdm-{name}-{i}-{run}" for i in range(len(calls))])
    index = {f.key: i for i, f in enumerate(futures)}
    results: list[Any] = [None] * len(futures)
    try:
        for fut in as_completed(futures):
            i = index[fut.key]
            results[i] = fut.result()
            fut.release()
            if finished:
                finished(i)
    finally:
        for f in futures:
            f.release()
    return results


#: What to do after an environment's fault: a batch resumes where it stopped.
_AGAIN = "then run the same command again (movies already finished are kept and skipped)"


def environment_fault(exc: BaseException, where: str) -> RunFault | None:
    """The plain-words :class:`~napari_pfsdm.errors.RunFault` for an exception that the
    machine or the cluster caused, or None when ``exc`` is not one (an input error, a bug).

    Parameters
    ----------
    exc : BaseException
        What the scheduler raised.
    where : str
        ``"this machine"`` or the scheduler's address, for the message.

    Examples
    --------
    >>> from concurrent.futures.process import BrokenProcessPool
    >>> str(environment_fault(BrokenProcessPool("terminated"), "this machine"))[:40]
    'a worker process on this machine stopped'
    >>> environment_fault(ZeroDivisionError(), "this machine") is None
    True
    """
    from concurrent.futures import BrokenExecutor, CancelledError

    if isinstance(exc, InputError):
        return None
    name = type(exc).__name__
    if isinstance(exc, BrokenExecutor):
        return RunFault(
            f"a worker process on {where} stopped while measuring (killed from outside, or by "
            "the system when memory ran out); if memory is short, use fewer --workers or a "
            f"smaller --frames-per-task, {_AGAIN}")
    if name == "KilledWorker":
        return RunFault(
            f"the dask cluster at {where} lost its workers while measuring (a task killed "
            "workers several times, often at their memory limit); look at the workers' logs, "
            f"give them more memory or use a smaller --frames-per-task, {_AGAIN}")
    if where != "this machine" and (
            isinstance(exc, CancelledError | TimeoutError) or name in (
                "CommClosedError", "FuturesCancelledError", "ClosedClientError")):
        return RunFault(
            f"lost the connection to the dask scheduler at {where} while measuring (the "
            f"scheduler stopped or the network failed); check that it is running, {_AGAIN}")
    return None
