"""Objects measured on several processes (napari_pfsdm.analysis.parallel): the same table as
``measure``, every object once and in order, and a stop that stops the processes."""

from __future__ import annotations

import multiprocessing

import numpy as np
import pandas as pd
import pytest

import napari_pfsdm as pf
from napari_pfsdm.analysis import parallel
from napari_pfsdm.analysis.measuring import ObjectMeasurer
from napari_pfsdm.analysis.row_blocks import join_blocks
from napari_pfsdm.core.params import PFSDMParams
from napari_pfsdm.data.gastruloids import make_timelapse_montage
from unguarded_script import run_once


def _drain(gen):
    steps = []
    try:
        while True:
            steps.append(next(gen))
    except StopIteration as stop:
        return stop.value, steps


def test_plan_tasks_lists_every_object_once_in_order():
    counts = [np.array([1, 2, 3]), np.array([], int), np.array([2, 5, 7, 9, 11, 12, 13]),
              np.array([4])]
    tasks = parallel.plan_tasks(counts, 4)
    flat = [(t, int(lab)) for task in tasks for t, labels in task for lab in labels]
    expected = [(t, int(lab)) for t, c in enumerate(counts) for lab in c]
    assert flat == expected
    # 11 objects in 4 tasks of ceil(11 / 4) = 3: the big frame 2 is cut after labels 7 and 12,
    # its last label shares a task with frame 3 (the empty frame 1 gives no task)
    assert [[(t, lab.tolist()) for t, lab in task] for task in tasks] == [
        [(0, [1, 2, 3])], [(2, [2, 5, 7])], [(2, [9, 11, 12])], [(2, [13]), (3, [4])]]


def test_plan_tasks_of_one_frame_and_of_more_tasks_than_objects():
    one = parallel.plan_tasks([np.arange(1, 11)], 3)  # 10 objects, ceil(10/3) = 4 per task
    assert [lab.tolist() for task in one for _, lab in task] == [[1, 2, 3, 4], [5, 6, 7, 8],
                                                                [9, 10]]
    many = parallel.plan_tasks([np.array([1]), np.array([3])], 10)
    assert [[(t, lab.tolist()) for t, lab in task] for task in many] == [[(0, [1])], [(1, [3])]]


@pytest.fixture
def small_movie():
    labels, intensity = make_timelapse_montage(5, 4, 160, seed=3)[:2]
    return labels, intensity


@pytest.mark.parametrize("with_intensity", [True, False])
def test_rows_from_two_processes_make_measures_table(small_movie, monkeypatch, with_intensity):
    labels, intensity = small_movie
    intensity = intensity if with_intensity else None
    monkeypatch.setattr(parallel, "MIN_OBJECTS", 1)  # a small movie, still in processes
    params = PFSDMParams()
    blocks, steps = _drain(parallel.iter_blocks(labels, intensity, params=params, axes="tyx",
                                            workers=2))
    assert parallel._POOL["pool"] is not None  # it did use the pool
    table = join_blocks(blocks).table
    expected = pf.measure(labels, intensity)
    pd.testing.assert_frame_equal(table, expected)
    n = len(expected)
    assert steps[-1][:2] == (n, n)
    assert all(a[0] <= b[0] for a, b in zip(steps, steps[1:], strict=False))


def test_one_large_frame_is_split_between_processes(monkeypatch):
    labels, _ = make_timelapse_montage(12, 1, 256, seed=5)[:2]
    frame = labels[0]
    monkeypatch.setattr(parallel, "MIN_OBJECTS", 1)
    tasks = parallel.plan_tasks([np.unique(frame)[1:]], 2 * parallel.TASKS_PER_WORKER)
    assert len(tasks) > 1 and all(len(task) == 1 for task in tasks)  # blocks of one frame
    blocks, _ = _drain(parallel.iter_blocks(frame, params=PFSDMParams(), axes="yx", workers=2))
    pd.testing.assert_frame_equal(join_blocks(blocks).table, pf.measure(frame))


def test_a_split_frame_is_sent_as_the_crops_of_its_objects_and_gives_measures_table(
        monkeypatch):
    """A frame split between tasks goes to the workers as each object's crop (its box one
    pixel wider), not as the whole frame and reporter for every task; the table (centroids,
    objects touching the border, reporter features) and the boxes are still measure's.
    Mutants: the whole frame sent again; a crop's centroid or box left in crop coordinates;
    touching the border judged against the crop."""
    from scipy import ndimage as ndi

    labels, intensity = make_timelapse_montage(12, 1, 256, seed=5)[:2]
    frame, image = labels[0].copy(), intensity[0].astype(np.float32)
    frame[:6, :9] = 40  # touching the top-left corner
    frame[100:110, -4:] = 41  # touching the right edge
    monkeypatch.setattr(parallel, "MIN_OBJECTS", 1)
    counts = parallel._labels_per_frame(frame, 1, False)
    tasks = parallel.plan_tasks(counts, 4)
    measurer = ObjectMeasurer.of(PFSDMParams(), with_intensity=True, axes="yx")
    sent = parallel.task_entries(measurer, frame, image, False, tasks[0], counts, {})
    assert len(tasks) > 1 and [entry[0] for entry in sent] == ["crops"]
    boxes = ndi.find_objects(frame)
    for crop in sent[0][1]:
        assert crop.box == boxes[crop.label - 1] and crop.labels.shape == crop.image.shape
        big = tuple(slice(o, o + n) for o, n in zip(crop.origin, crop.labels.shape,
                                                     strict=True))
        np.testing.assert_array_equal(crop.labels, frame[big])
        assert crop.labels.base is None  # its own pixels, not a view of the frame
        assert crop.labels.size < frame.size / 20
    blocks, _ = _drain(parallel.iter_blocks(frame, image, params=PFSDMParams(), axes="yx",
                                            workers=2))
    joined = join_blocks(blocks)
    expected = pf.measure(frame, image)
    pd.testing.assert_frame_equal(joined.table, expected)
    assert set(expected.loc[expected["touches_border"], "label"]) == {40, 41}
    want = [[s.start for s in boxes[lab - 1]] + [s.stop for s in boxes[lab - 1]]
            for lab in expected["label"]]
    np.testing.assert_array_equal(joined.boxes, want)


def test_few_objects_stay_in_this_process(small_movie, monkeypatch):
    labels, intensity = small_movie
    parallel.shutdown_pool()
    monkeypatch.setattr(parallel, "MIN_OBJECTS", 10_000)
    blocks, steps = _drain(parallel.iter_blocks(labels, intensity, params=PFSDMParams(),
                                            axes="tyx", workers=2))
    assert parallel._POOL["pool"] is None
    assert len(blocks) == 1 and len(steps) == len(blocks[0].table)  # a step per object


def test_a_warm_pool_measures_even_a_small_movie_in_processes(monkeypatch):
    """warm_pool starts the processes in the background; once they run, a movie far below
    MIN_OBJECTS goes to them (and gives measure's table), in a few tasks of at least
    MIN_TASK_OBJECTS objects, not one task per object."""
    labels, intensity = make_timelapse_montage(8, 6, 160, seed=4)[:2]  # 48 objects
    parallel.shutdown_pool()
    assert not parallel.pool_ready(2)
    thread = parallel.warm_pool(2)
    assert thread is not None
    thread.join(timeout=120)
    assert parallel.pool_ready(2) and parallel.warm_pool(2) is None  # started once
    pool = parallel._POOL["pool"]
    sent = []
    real_plan = parallel.plan_tasks
    monkeypatch.setattr(parallel, "plan_tasks",
                        lambda counts, n: sent.append(n) or real_plan(counts, n))
    blocks, steps = _drain(parallel.iter_blocks(labels, intensity, params=PFSDMParams(),
                                            axes="tyx", workers=2))
    assert parallel._POOL["pool"] is pool  # the same processes, not a new pool
    assert sent == [max(2, 48 // parallel.MIN_TASK_OBJECTS)] == [3]
    table = join_blocks(blocks).table
    pd.testing.assert_frame_equal(table, pf.measure(labels, intensity))
    assert len(steps) < len(table)  # a step per task, not per object


def test_many_objects_go_in_tasks_of_at_most_max_task_objects(monkeypatch):
    """Each task's result is unpickled in one go, holding the interpreter lock the viewer's
    GUI thread needs: a large movie goes in tasks of at most MAX_TASK_OBJECTS, more than
    TASKS_PER_WORKER per worker if need be; the table is measure's."""
    labels, intensity = make_timelapse_montage(8, 6, 160, seed=4)[:2]  # 48 objects
    parallel.warm_pool(2).join(timeout=120) if not parallel.pool_ready(2) else None
    monkeypatch.setattr(parallel, "MAX_TASK_OBJECTS", 5)
    monkeypatch.setattr(parallel, "TASKS_PER_WORKER", 1)  # alone: 2 tasks of 24
    planned = []
    real_plan = parallel.plan_tasks
    monkeypatch.setattr(parallel, "plan_tasks",
                        lambda counts, n: planned.append(real_plan(counts, n)) or planned[-1])
    blocks, _ = _drain(parallel.iter_blocks(labels, intensity, params=PFSDMParams(), axes="tyx",
                                        workers=2))
    sizes = [sum(len(wanted) for _t, wanted in task) for task in planned[0]]
    assert len(sizes) == 10 and max(sizes) == 5 and sum(sizes) == 48  # ceil(48 / 5) tasks
    table = join_blocks(blocks).table
    pd.testing.assert_frame_equal(table, pf.measure(labels, intensity))


def test_a_warm_pool_of_another_size_or_too_few_objects_stays_here(monkeypatch):
    labels, intensity = make_timelapse_montage(4, 6, 160, seed=4)[:2]  # 24 < 2 x 16
    parallel.shutdown_pool()
    parallel.warm_pool(2).join(timeout=120)
    monkeypatch.setattr(parallel, "plan_tasks", None)  # the pool's route would call it
    blocks, steps = _drain(parallel.iter_blocks(labels, intensity, params=PFSDMParams(),
                                            axes="tyx", workers=2))
    assert len(blocks) == 1 and len(steps) == len(blocks[0].table) == 24  # measured here
    assert not parallel.pool_ready(3)


def test_stopping_early_stops_the_processes(small_movie, monkeypatch):
    labels, intensity = small_movie
    monkeypatch.setattr(parallel, "MIN_OBJECTS", 1)
    parallel.shutdown_pool()
    before = set(multiprocessing.active_children())
    gen = parallel.iter_blocks(labels, intensity, params=PFSDMParams(), axes="tyx", workers=2)
    next(gen)
    processes = set(multiprocessing.active_children()) - before  # the pool's workers
    assert len(processes) == 2
    gen.close()  # what a napari worker's quit does at a yield
    assert parallel._POOL["pool"] is None
    for proc in processes:
        proc.join(timeout=10)
        assert not proc.is_alive()


def test_a_script_without_a_main_guard_runs_once(tmp_path):
    """multiprocessing's spawn/forkserver children re-import the main module: a biologist's
    script with no ``if __name__ == "__main__":`` must not start again in every worker."""
    out = run_once(tmp_path, [
        "from napari_pfsdm.analysis import parallel",
        "from napari_pfsdm.core.params import PFSDMParams",
        "from napari_pfsdm.data.gastruloids import make_timelapse_montage",
        "parallel.MIN_OBJECTS = 1",
        "lab, img, _ = make_timelapse_montage(3, 2, 128, seed=1)",
        "g = parallel.iter_blocks(lab, img, params=PFSDMParams(), axes='tyx', workers=2)",
        "try:",
        "    while True:",
        "        next(g)",
        "except StopIteration as stop:",
        "    print('rows', sum(len(b.table) for b in stop.value))"])
    assert "rows 6" in out
