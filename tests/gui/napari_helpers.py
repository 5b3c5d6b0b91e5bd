"""Helpers for the napari plugin tests: dock as napari does, wait for what a user waits for."""

from __future__ import annotations

import numpy as np

RUN_TIMEOUT_MS = 180_000
ANALYSIS, PLOTS, PREDICTION = "PF-SDM analysis", "PF-SDM plots", "PF-SDM prediction"


def dock(viewer, name: str = ANALYSIS):
    """Dock one of the plugin's widgets as Plugins ▸ PF-SDM morphometrics does (napari makes
    it and hands it a public-only proxy of the viewer)."""
    _dock, widget = viewer.window.add_plugin_dock_widget("napari-pfsdm", name)
    return widget


def run_and_wait(qtbot, widget):
    """Press Run and wait until the results are shown; returns the layer's analysis."""
    worker = widget.run()
    assert worker is not None, widget.status.value
    qtbot.waitUntil(lambda: widget.worker is None, timeout=RUN_TIMEOUT_MS)
    assert widget.bound is not None, widget.status.value
    return widget.bound[1]


def settled(widget) -> bool:
    """True when the pictures on screen are those of the selection (nothing pending)."""
    pics = widget.pictures
    return pics.worker is None and pics.wanted is not None and pics.shown == pics.wanted[2]


def wait_pictures(qtbot, widget, timeout: int = 60_000) -> None:
    qtbot.waitUntil(lambda: settled(widget), timeout=timeout)


def many_objects(n_rows: int = 10, n_cols: int = 20, cell: int = 24) -> np.ndarray:
    """A 2-D label image with n_rows × n_cols small ellipses (labels 1 … n)."""
    yy, xx = np.mgrid[0:cell, 0:cell] - (cell - 1) / 2
    labels = np.zeros((n_rows * cell, n_cols * cell), dtype=np.uint16)
    rng = np.random.default_rng(0)
    for i in range(n_rows * n_cols):
        r, c = divmod(i, n_cols)
        a, b = rng.uniform(5, 10), rng.uniform(4, 7)
        th = rng.uniform(0, np.pi)
        u = xx * np.cos(th) + yy * np.sin(th)
        v = -xx * np.sin(th) + yy * np.cos(th)
        labels[r * cell:(r + 1) * cell, c * cell:(c + 1) * cell][(u / a) ** 2 + (v / b) ** 2
                                                                 <= 1] = i + 1
    return labels
