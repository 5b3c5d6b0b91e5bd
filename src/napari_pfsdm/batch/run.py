"""Measure movies in parallel with dask, on this machine or on any dask.distributed cluster.

:func:`measure_dask` measures a movie in tasks planned as the napari plugin's process pool
plans them (:func:`napari_pfsdm.analysis.parallel.plan_tasks`: tasks of similar numbers of
objects, a large frame cut between tasks), with the pool's code for the objects, and joins the
tasks' row blocks in frame then label order, so the table is the pool's and
:func:`napari_pfsdm.measure`'s whichever scheduler ran it. Each task reads its own frames
(from the file, inside the worker), a few at a time, so memory stays bounded even for a movie
larger than RAM.

:func:`run_batch` measures a list of movies into one table with a ``movie`` column. It writes
one part file per finished movie (Parquet when pyarrow is installed, else CSV, each with a
checked sidecar) into a parts folder next to the output; a re-run skips movies whose part
exists (for the same data, :func:`~napari_pfsdm.batch.io.data_fingerprint`, and options) and
measures a damaged part again, so a killed run loses at most the movie in progress. The final
CSV is written atomically, by one run at a time (:func:`~napari_pfsdm.io_csv.output_lock`).

Faults of the machine or the cluster (a worker process killed, the scheduler lost) become a
plain :class:`~napari_pfsdm.errors.RunFault` (:func:`environment_fault`); anything else that
is not the input's fault stays what it is: a bug.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import threading
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..analysis.row_blocks import RowBlock, block_of, join_blocks
from ..analysis.schedulers import client_for, process_pool, resolve_scheduler
from ..core.params import PFSDMParams, as_params
from ..core.table_options import carry_options, plain, set_options, table_options
from ..core.table_schema import NO_TRACK, TRACK_COLUMN
from ..errors import InputError, RunFault
from ..io_csv import (
    _pyarrow,
    _to_jsonable,
    is_parquet,
    output_lock,
    read_table_csv,
    remove_leftovers,
    sidecar_path,
    write_table_csv,
)
from .io import (
    Movie,
    check_labels,
    data_fingerprint,
    missing_frames,
    missing_warning,
    movie_source,
    open_movie,
    refuse_missing_chunks,
)

__all__ = ["environment_fault", "measure_dask", "process_pool", "run_batch",
           "resolve_scheduler"]



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
    from ..analysis.features import present_ids

    if frame.dtype == bool:
        frame = frame.astype(np.uint8)
    if frame.size and frame.min() < 0:
        raise InputError(
            f"Frame {t} has negative labels; labels must be 0 (background) or positive.")
    return present_ids(frame)


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


def _measure_task(labels: _Reader, intensity: _Reader | None, parts: list[tuple],
                  options: dict, block_kw: dict, frame_bytes: int) -> RowBlock:
    """Worker task: read the frames of ``parts`` (``(frame, labels wanted)``; None: all of
    the frame's) and measure their objects with the process pool's own code
    (:func:`napari_pfsdm.analysis.parallel._measure_task`: whole frames, or the crops of the
    objects wanted, as the pool sends them); the rows as one block."""
    from ..analysis import parallel
    from ..analysis.features import crop_of, object_boxes, one_blas_thread

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
                    ids = _frame_ids(frame, t)
                    entry = ("frame", t, frame, image, ids)
                    rows += parallel._measure_task([entry], options)
                    continue
                if boxes is None:  # a frame of a plan by objects: maybe split, keep it
                    boxes = dict(object_boxes(frame.astype(np.uint8) if frame.dtype == bool
                                              else frame))
                    key = _recent_key(labels, intensity, t)
                    if key is not None:
                        with _RECENT_LOCK:
                            while len(_RECENT) >= _RECENT_FRAMES:
                                _RECENT.pop(next(iter(_RECENT)))
                            _RECENT[key] = (frame, image, boxes)
                crops = []
                for label in wanted[t]:
                    box = boxes[int(label)]
                    big = crop_of(box, frame.shape)
                    crops.append((int(label), box, big, np.array(frame[big]),
                                  None if image is None else np.array(image[big])))
                rows += parallel._measure_task([("crops", t, frame.shape, crops)], options)
    return block_of(rows, **block_kw)


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
    axes, spacing
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
    from ..analysis.features import resolve_axes

    p = as_params(params, options)
    check_labels(labels, intensity, axes=axes)
    _check_chunks(labels, intensity, allow_missing_chunks)
    axes = resolve_axes(tuple(labels.shape), axes)
    kind, obj = resolve_scheduler(scheduler, client)
    volume = "z" in axes
    p.check_dimension(3 if volume else 2)
    where_kw = {"axes": axes, "spacing": spacing} if volume else {"axes": axes}
    block_kw = {"with_intensity": intensity is not None, "params": p, **where_kw}
    if not axes.startswith("t"):  # one image or volume: frame 0 of a one-frame movie
        labels = labels[None]
        intensity = intensity[None] if intensity is not None else None

    where = _where(kind, obj)
    own = kind == "local" and obj == "processes" and pool is None
    try:
        if own:  # the processes of this run, started without the caller's script
            pool = process_pool(num_workers)
        blocks = _measure_planned(labels, intensity, kind, obj, p, axes, spacing,
                                  frames_per_task, num_workers, progress, pool, block_kw)
    except Exception as exc:  # noqa: BLE001 - sorted: the environment's faults, or re-raised
        fault = environment_fault(exc, where)
        if fault is None:
            raise
        raise fault from exc
    finally:
        if own and pool is not None:
            pool.shutdown(cancel_futures=True)
        if kind == "local" and obj != "processes":  # run here: keep no frame after the run
            with _RECENT_LOCK:
                _RECENT.clear()
    if not blocks:  # no object at all: measure's empty table
        return block_of([], **block_kw).table
    return join_blocks(blocks).table


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
    labels: Any, intensity: Any, kind: str, obj: Any, p: PFSDMParams, axes: str,
    spacing: Any, frames_per_task: int | None, num_workers: int | None,
    progress: Callable[[int, int], None] | None, pool: Any, block_kw: dict,
) -> list[RowBlock]:
    """The row blocks of a movie (``labels`` with a time axis first), measured where
    ``kind``/``obj`` say, in tasks planned as the process pool plans them."""
    from ..analysis import parallel
    from ..analysis.features import voxel_spacing

    n_frames = int(labels.shape[0])
    options = p.options()
    voxel = voxel_spacing(axes, spacing)
    if voxel is not None:
        options["spacing"] = voxel
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
            calls = [(parallel._block_task, ((parallel._task_args(
                labels, intensity, True, task, counts, boxes), options, block_kw),))
                for task in tasks]
        else:
            calls = []
            for task in tasks:
                s, e = task[0][0], task[-1][0] + 1
                calls.append((_measure_task, (
                    _Reader(labels, s, e),
                    _Reader(intensity, s, e) if intensity is not None else None,
                    task, options, block_kw, frame_bytes)))
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


# ---------------------------------------------------------------------------------------------
# Resumable batches over many movies
# ---------------------------------------------------------------------------------------------

def _have_parquet() -> bool:
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        return False
    return True


def _part_name(movie: Movie, params: PFSDMParams, axes: str | None = None,
               spacing: Any = None, series: int | None = None) -> str:
    """Stable file name of a movie's part: its name plus a hash of its inputs' data
    (:func:`~napari_pfsdm.batch.io.data_fingerprint`) and the options."""
    def stamp(p: Path | None) -> Any:
        if p is None:
            return None
        p = Path(p).resolve()
        return [str(p), data_fingerprint(p)]  # a replaced or re-written movie: measured again

    key = json.dumps(
        [stamp(movie.labels), stamp(movie.intensity), _to_jsonable(params.record())]
        + ([axes, None if spacing is None else [float(v) for v in np.ravel(spacing)]]
           if axes is not None and "z" in axes else [])
        + ([["series", int(series)]] if series is not None else []),
        sort_keys=True
    )
    digest = hashlib.sha1(key.encode()).hexdigest()[:10]
    safe = re.sub(r"[^\w.\-]+", "_", movie.name)[:80]
    return f"{safe}-{digest}"


def _write_part(table: pd.DataFrame, path: Path, options: dict) -> None:
    """Write a movie's part with its sidecar (the options, the part's size and SHA-256), each
    atomically through a temporary file of a unique name created exclusively in the parts
    folder (:func:`~napari_pfsdm.io_csv.write_table_csv`: no planted file or symbolic link is
    written through). The sidecar comes first: the part appearing marks the movie as done."""
    write_table_csv(table, path, options, table_type="part")


def _read_part(path: Path) -> pd.DataFrame:
    """A movie's part as written by :func:`_write_part`, checked against its sidecar (the one
    reader of the package, :func:`napari_pfsdm.io_csv.read_table_csv`: exact floats, text
    columns as written); any mismatch with the sidecar is damage."""
    return read_table_csv(path, strict=True)


def _resumed(part: Path, name: str, say: Callable[[str], None]) -> pd.DataFrame | None:
    """The table of a movie measured by an earlier run, or None when it must be measured: no
    part yet, or a damaged one (truncated, not matching its sidecar), which is removed."""
    if not part.exists():
        return None
    try:
        table = _read_part(part)
    except Exception as exc:  # noqa: BLE001 - any reader's error: the part is not usable
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        say(f"{name}: its saved part {part.name} is damaged ({first[:160]}); measuring "
            f"{name} again")
        for f in (part, sidecar_path(part), part.with_suffix(".json")):
            with contextlib.suppress(OSError):
                f.unlink()
        return None
    say(f"skipped {name} (already measured: {part.name})")
    if not table_options(table):  # a part of an earlier version: options beside it
        old = part.with_suffix(".json")
        if old.exists():
            set_options(table, json.loads(old.read_text()))
    return table


def _link(table: pd.DataFrame, lab: Any, how: str, name: str,
          say: Callable[[str], None]) -> tuple[pd.DataFrame, str]:
    """Check and link one movie's table (see :func:`run_batch`'s ``link``)."""
    from ..analysis.tracking import link_movie

    source = movie_source(lab)  # read frames straight from the file
    source = lab if source is None else source
    if len(lab.shape) == 2:  # one frame
        source = np.asarray(source[:])[None]
    out, check, used = link_movie(table, source, how)
    out = carry_options(table, out)
    if used:
        n = out.loc[out[TRACK_COLUMN] >= 0, TRACK_COLUMN].nunique()
        why = check.message.split(". Link")[0] if not check.tracked else check.message
        say(f"{name}: {why}; linked by {used}: {n} tracks in the track_id column")
    elif how != "none" and check.verdict == "tracked":
        say(f"{name}: {check.message}: track_id = label")
    return out, used


def default_parts_dir(output: str | os.PathLike) -> Path:
    """Where :func:`run_batch` keeps per-movie parts for ``output``: ``<output>.parts/``."""
    output = Path(output)
    return output.with_name(output.name + ".parts")


def _batch_pool(num_workers: int | None) -> Any:
    """The worker processes of a batch on the ``"processes"`` scheduler
    (:func:`~napari_pfsdm.analysis.schedulers.process_pool`), a failed start in plain words."""
    try:
        return process_pool(num_workers)
    except Exception as exc:  # noqa: BLE001 - the machine's fault, or re-raised
        fault = environment_fault(exc, "this machine")
        if fault is None:
            raise
        raise fault from exc


def run_batch(
    movies: Sequence[Movie],
    output: str | os.PathLike,
    *,
    client: Any = None,
    scheduler: Any = None,
    num_workers: int | None = None,
    frames_per_task: int | None = None,
    parts_dir: str | os.PathLike | None = None,
    progress: Callable[[str, int, int], None] | None = None,
    log: Callable[[str], None] | None = None,
    allow_empty: bool = True,
    params: PFSDMParams | None = None,
    link: str = "none",
    axes: str | None = None,
    spacing: Any = None,
    allow_missing_chunks: bool = False,
    series: int | None = None,
    **options: Any,
) -> pd.DataFrame:
    """Measure many movies into one CSV with a ``movie`` column, resumably.

    Parameters
    ----------
    movies : sequence of Movie
        From :func:`napari_pfsdm.batch.io.pair_movies`.
    output : str or PathLike
        Final CSV (written atomically, with the options in its ``.csv.json`` sidecar).
    client, scheduler, num_workers, frames_per_task
        As in :func:`measure_dask`.
    parts_dir : str or PathLike, optional
        Folder of per-movie parts (default ``<output>.parts``). A movie whose part is there
        (the same files, unchanged: size, modification time and inode; the same options) is
        not measured again.
    progress : callable, optional
        ``progress(movie_name, frames_done, n_frames)``.
    log : callable, optional
        Receives one-line messages (e.g. ``"skipped movie01 (already measured)"``).
    allow_empty : bool
        When False, labels without any object raise ``ValueError`` and no table is written
        (all-background labels are usually the wrong file).
    params : PFSDMParams, optional
        The method's options as one record.
    link : {"none", "auto", "overlap", "centroid", "laptrack"}
        Link each movie's objects into tracks (a ``track_id`` column) with
        :func:`napari_pfsdm.analysis.tracking.link_movie`: ``"auto"`` links (by overlap of the
        labels) only the movies whose label ids do not follow objects, and gives the others
        ``track_id = label``; the column is left out when no movie needed linking. ``log``
        says what was found and done for each movie. The parts stay unlinked, so a re-run
        with another ``link`` measures nothing again.
    axes, spacing
        As :func:`napari_pfsdm.measure`, for every movie (``"zyx"``/``"tzyx"``: 3-D objects).
    allow_missing_chunks : bool
        A Zarr movie whose chunk files are not all on disk stops the run before any work
        (its missing frames would read as empty); True measures it as it is, ``log`` warns
        once per such frame and the sidecar lists them (``missing_chunks``).
    series : int, optional
        The image series read from every TIFF (:func:`~napari_pfsdm.batch.io.open_movie`);
        a TIFF of several series is refused without it.
    **options
        Or the options as keywords, as :func:`napari_pfsdm.measure` takes them.

    Returns
    -------
    pandas.DataFrame
        The concatenated table (also written to ``output``). Its sidecar lists, per movie,
        the frames without any object (``empty_frames``) and those read with missing chunk
        files (``missing_chunks``); ``log`` names them too.
    """
    output = Path(output)
    out_dir = output.parent if str(output.parent) else Path(".")
    if not out_dir.is_dir():
        raise InputError(f"cannot write {output}: the folder {out_dir} does not exist")
    if not os.access(out_dir, os.W_OK):
        raise InputError(f"cannot write {output}: the folder {out_dir} is not writable")
    p = as_params(params, options)  # a bad option fails here, before any movie is read
    _refuse_collisions(movies)
    if is_parquet(output) and output.suffix.lower() == ".parquet":
        _pyarrow(output, "writing")  # a missing package fails here, not after measuring
    with output_lock(output):  # one run at a time per output; a second one refuses
        return _run_batch_locked(
            movies, output, p, client=client, scheduler=scheduler, num_workers=num_workers,
            frames_per_task=frames_per_task, parts_dir=parts_dir, progress=progress,
            say=log or (lambda msg: None), allow_empty=allow_empty, link=link, axes=axes,
            spacing=spacing, allow_missing_chunks=allow_missing_chunks, series=series)


def _refuse_collisions(movies: Sequence[Movie]) -> None:
    """One name, one movie: refuse two movies of one name, or one label file twice (their
    rows would be merged under one name, or doubled)."""
    names: dict[str, Movie] = {}
    files: dict[Path, Movie] = {}
    for m in movies:
        if m.name in names:
            raise InputError(
                f"two movies are named {m.name!r} ({names[m.name].labels} and {m.labels}): "
                "their rows could not be told apart in the table; give them different names")
        key = Path(m.labels).resolve()
        if key in files:
            raise InputError(
                f"the label movie {m.labels} is given twice (as {files[key].name!r} and "
                f"{m.name!r}): its objects would be counted twice; give each movie once")
        names[m.name] = m
        files[key] = m


#: Temporary files a killed run may leave in a parts folder: those of
#: :func:`~napari_pfsdm.io_csv.atomic_write` and the fixed names of earlier versions, for a
#: part's name only (``movie-0123456789.parquet``, :func:`_part_name`): a user's own file in a
#: folder given as ``--parts`` is never removed.
_PART_TEMP = re.compile(
    r"\..+-[0-9a-f]{10}\.(?:parquet|csv)(?:\.json)?(?:\.[a-z0-9_]{8})?\.tmp")


def _remove_part_leftovers(parts: Path) -> None:
    """Remove the temporary part files of a killed run (holding the output's lock)."""
    for entry in os.scandir(parts):
        if _PART_TEMP.fullmatch(entry.name) and not entry.is_dir(follow_symlinks=False):
            with contextlib.suppress(OSError):
                os.unlink(entry.path)


def _run_batch_locked(
    movies: Sequence[Movie], output: Path, p: PFSDMParams, *, client: Any, scheduler: Any,
    num_workers: int | None, frames_per_task: int | None,
    parts_dir: str | os.PathLike | None, progress: Callable[[str, int, int], None] | None,
    say: Callable[[str], None], allow_empty: bool, link: str, axes: str | None,
    spacing: Any, allow_missing_chunks: bool, series: int | None = None,
) -> pd.DataFrame:
    """:func:`run_batch`'s work, holding the output's lock."""
    remove_leftovers(output)
    parts = Path(parts_dir) if parts_dir is not None else default_parts_dir(output)
    parts.mkdir(parents=True, exist_ok=True)
    _remove_part_leftovers(parts)
    suffix = ".parquet" if _have_parquet() else ".csv"

    # Open and check every movie first: a bad file fails the run before any long work.
    opened = []
    for m in movies:
        lab = open_movie(m.labels, frames_per_chunk=frames_per_task, axes=axes, series=series)
        img = open_movie(m.intensity, frames_per_chunk=frames_per_task, axes=axes,
                         series=series) if m.intensity else None
        check_labels(lab, img, where=str(m.labels), axes=axes)
        if img is not None and tuple(img.shape) != tuple(lab.shape):  # pragma: no cover
            raise InputError(f"{m.labels} and {m.intensity} have different shapes")
        for movie, path in ((lab, m.labels), (img, m.intensity)):
            if movie is not None and not allow_missing_chunks:
                refuse_missing_chunks(movie, str(path))
        opened.append((m, lab, img))
    missing = _missing_chunks(opened, say)

    kind, obj = resolve_scheduler(scheduler, client)
    tables = []
    attrs: dict = {}
    linked = False
    empty: dict[str, list[int]] = {}
    with contextlib.ExitStack() as kept, client_for(kind, obj) as cl:
        pool = None
        for m, lab, img in opened:
            part = parts / (_part_name(m, p, axes, spacing, series) + suffix)
            table = _resumed(part, m.name, say)
            if table is not None:
                attrs = attrs or _to_jsonable(table_options(table) or {})
            else:
                if kind == "local" and obj == "processes" and pool is None:
                    # started for the first movie to measure, kept for the others
                    pool = kept.enter_context(_batch_pool(num_workers))

                def _prog(done: int, total: int, _name: str = m.name) -> None:
                    if progress:
                        progress(_name, done, total)

                with warnings.catch_warnings():  # the missing chunks were said above
                    warnings.filterwarnings("ignore", ".*chunk files? missing", UserWarning)
                    table = measure_dask(
                        lab, img,
                        client=cl if kind != "local" else None,
                        scheduler=obj if kind == "local" else None,
                        num_workers=num_workers, frames_per_task=frames_per_task,
                        progress=_prog, pool=pool, params=p, axes=axes, spacing=spacing,
                        allow_missing_chunks=True,  # checked above, with the user's word
                    )
                attrs = _to_jsonable(table_options(table) or attrs)
                table = table.copy()
                table.insert(0, "movie", m.name)
                _write_part(table, part, attrs)
                say(f"measured {m.name}: {len(table)} objects")
            empty[m.name] = _empty_frames(table, lab, axes)
            if empty[m.name]:
                shown = ", ".join(str(t) for t in empty[m.name])
                say(f"{m.name}: no objects in frame{'s' if len(empty[m.name]) > 1 else ''} "
                    f"{shown} (of {_n_frames(lab, axes)})")
            if link != "none" and len(table):
                table, used = _link(table, lab, link, m.name, say)
                linked = linked or bool(used)
            tables.append(table)

    tables = [plain(t) for t in tables]
    if link == "auto" and not linked:  # every movie was tracked: its labels are the ids
        tables = [t.drop(columns=[TRACK_COLUMN], errors="ignore") for t in tables]
    result = pd.concat(tables, ignore_index=True) if tables else pd.DataFrame()
    if TRACK_COLUMN in result.columns:  # a movie without objects has none
        result[TRACK_COLUMN] = result[TRACK_COLUMN].fillna(NO_TRACK).astype(np.int64)
    if not attrs:
        attrs = p.record(3 if axes and "z" in axes else 2)
    if len(result) == 0 and not allow_empty:
        names = ", ".join(str(m.labels) for m in movies[:3]) + (" …" if len(movies) > 3 else "")
        raise InputError(
            f"no objects: {names} hold{'s' if len(movies) == 1 else ''} only background (0) "
            "in every frame, so nothing was written. Check that these are the segmentation "
            "(labels), or pass --allow-empty to write an empty table"
        )
    set_options(result, attrs)
    extra = {"empty_frames": {k: v for k, v in empty.items() if v},
             "missing_chunks": missing}
    write_table_csv(result, output, attrs, table_type="features", extra=extra)
    return result


def _n_frames(movie: Any, axes: str | None) -> int:
    """Frames of a movie: its first axis when that is time, else 1."""
    from ..analysis.features import resolve_axes

    timed = resolve_axes(tuple(movie.shape), axes).startswith("t")
    return int(movie.shape[0]) if timed else 1


def _empty_frames(table: pd.DataFrame, movie: Any, axes: str | None) -> list[int]:
    """The frames of ``movie`` that have no row (no object at all) in its ``table``."""
    have = set(table["frame"].astype(int).tolist()) if "frame" in table.columns else set()
    return [t for t in range(_n_frames(movie, axes)) if t not in have]


def _missing_chunks(opened: list[tuple], say: Callable[[str], None]) -> dict[str, dict]:
    """Warn once per frame read with missing chunk files; ``{movie: {frame: count}}``."""
    out: dict[str, dict] = {}
    for m, lab, img in opened:
        counts: dict[str, int] = {}
        for movie in (lab, img):
            if movie is None:
                continue
            for line in missing_warning(movie, m.name):
                say(line)
            for t, n in missing_frames(movie).items():
                counts[str(t)] = counts.get(str(t), 0) + n
        if counts:
            out[m.name] = dict(sorted(counts.items(), key=lambda kv: int(kv[0])))
    return out
