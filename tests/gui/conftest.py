"""Fixtures for the napari plugin tests (run on a virtual X screen: pytest-xvfb or xvfb-run)."""

from __future__ import annotations

import pytest

pytest.importorskip("napari")
pytest.importorskip("pytestqt")


@pytest.fixture
def sample_layers():
    from napari_pfsdm.napari._sample_data import gastruloid_timelapse

    return gastruloid_timelapse()


def _sample_viewer(make_viewer, layers, **kwargs):
    from napari_helpers import dock

    viewer = make_viewer(**kwargs)
    for data, layer_kwargs, kind in layers:
        getattr(viewer, f"add_{kind}")(data, **layer_kwargs)
    return viewer, dock(viewer)


@pytest.fixture
def viewer_widget(make_napari_viewer_proxy, sample_layers):
    """A public-only viewer with the gastruloid sample and the analysis dock docked from the
    plugin menu."""
    return _sample_viewer(make_napari_viewer_proxy, sample_layers)


@pytest.fixture
def shown_viewer_widget(make_napari_viewer_proxy, sample_layers):
    """The same, its window on screen at 1280 × 800 (plots are drawn only on screen)."""
    viewer, widget = _sample_viewer(make_napari_viewer_proxy, sample_layers, show=True)
    viewer.window.resize(1280, 800)
    return viewer, widget


@pytest.fixture(autouse=True)
def _workers_done():
    """Let the docks' workers finish before the next test. A worker started while Qt's event
    loop runs is handed to the thread pool by a 1 ms timer, so pending events are processed
    and the pool awaited until it stays idle: a worker left running would swap the process's
    warning filters (superqt's workers catch warnings) in the middle of a later test."""
    yield
    import time

    from qtpy.QtCore import QThreadPool
    from qtpy.QtWidgets import QApplication
    from superqt.utils._qthreading import WorkerBase

    pool = QThreadPool.globalInstance()
    for _ in range(100):
        WorkerBase.await_workers(msecs=30_000)
        time.sleep(0.01)
        QApplication.processEvents()
        if pool.activeThreadCount() == 0:
            break
