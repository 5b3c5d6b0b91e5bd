"""Helpers for the napari plugin tests."""

from __future__ import annotations

import numpy as np

RUN_TIMEOUT_MS = 180_000
#: The plugin's widgets by their menu names (napari.yaml).
ANALYSIS = "PF-SDM analysis"
TRAJECTORIES = "PF-SDM trajectories (PCA)"
COMPARISON = "PF-SDM shape comparison"
PREDICTION = "PF-SDM prediction"
COMPONENTS = "PF-SDM components"


def dock(viewer, name: str = ANALYSIS):
    """Dock one of the plugin's widgets as Plugins ▸ napari-pfsdm does: napari makes it and
    hands it a public-only proxy of the viewer (not the viewer itself)."""
    _dock, widget = viewer.window.add_plugin_dock_widget("napari-pfsdm", name)
    return widget


def open_plots(qtbot, widget) -> list:
    """Press "Open plots" and wait for both plots to be docked and showing the results (the
    second docks in a later turn of the event loop, and each shows the layer in the turn
    after its docking)."""
    widget.open_plots()
    qtbot.waitUntil(lambda: len(widget.plots) == 2
                    and all(p.output is not None for p in widget.plots), timeout=30_000)
    return widget.plots


def wait_computed(qtbot, plot, timeout: int = 60_000) -> None:
    """Flush a plot's pending redraw and wait for its distances (computed in a worker)."""
    plot.flush()
    qtbot.waitUntil(lambda: not getattr(plot, "computing", False), timeout=timeout)
    plot.flush()


def run_and_wait(qtbot, widget, **kwargs):
    """Run the analysis and wait until the results are shown."""
    with qtbot.waitSignal(widget.finished, timeout=RUN_TIMEOUT_MS):
        worker = widget.run(**kwargs)
        assert worker is not None, widget.status.text()
    qtbot.waitUntil(lambda: widget.worker is None, timeout=5000)
    return widget.last_output


def wait_pictures(qtbot, widget, key=None, timeout: int = 30_000):
    """Wait until the pictures of ``key`` = (frame, label) (default: whatever is selected
    first) are shown; return them."""
    qtbot.waitUntil(lambda: widget.shown_key is not None
                    and (key is None or widget.shown_key == tuple(key)), timeout=timeout)
    return widget.pictures.get(widget.shown_key)


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
        mask = (u / a) ** 2 + (v / b) ** 2 <= 1
        labels[r * cell:(r + 1) * cell, c * cell:(c + 1) * cell][mask] = i + 1
    return labels
