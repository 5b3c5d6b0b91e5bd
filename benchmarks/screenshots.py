"""The screenshots in docs/: the plugin as a user sees it after a run, every dock open, an object
selected, at the window sizes of a laptop (1280 × 800) and of a desktop (1600 × 1000).

A fresh ``napari.Viewer`` (with napari's settings in a temporary file, so that no window or
dock geometry saved by an earlier session changes the layout), the gastruloid sample, the
analysis and prediction docks opened the way the Plugins menu does
(``add_plugin_dock_widget``), Run, the plots through the analysis dock's Open plots, a
prediction from frames 0–5 on the sample's groups, then frame 9 and label 5. Run from the
repository root on a (virtual) X screen at least as large::

    xvfb-run -a -s "-screen 0 1600x1000x24" .venv/bin/python benchmarks/screenshots.py

napari-clusters-plotter (when installed) is docked below the plugin's tab group, plotting the
Labels layer (every frame's rows), in every picture at 1280 × 800 (the 1600 × 1000 one has the
plugin alone, its plots docked). Beside it a docked plot is too small to
read and says "Float for a larger view" (``docs/screenshot_plots_docked.png``); the pictures of
a plots tab at 1280 × 800 have the plots floated over the window (Float), grabbed from the
screen. Writes ``docs/screenshot.png`` (1600 × 1000, the plots' Trajectories tab in front)
and, at 1280 × 800, ``docs/screenshot_1280x800.png`` (the analysis dock in front: the layer,
Run, Cancel, the status), ``docs/screenshot_plots_docked.png``,
``docs/screenshot_trajectories.png``, ``docs/screenshot_components.png`` (the plots' PCs tab),
``docs/screenshot_prediction.png`` (the prediction dock), ``docs/screenshot_over_time.png``
(Over time: circularity) and ``docs/screenshot_similar.png`` (Similar). Look at them before
committing.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1] / "docs"
TABS = ("trajectories", "comparison", "components", "over time", "similar")
#: What is in front of the plugin's tab group: a dock, or a tab of the plots.
FRONT = ("analysis", "prediction", *TABS)
#: (width, height, what is in front, the plots floated) → file in docs/
JOBS = {(1600, 1000, "trajectories", False): "screenshot.png",
        (1280, 800, "analysis", False): "screenshot_1280x800.png",
        (1280, 800, "trajectories", False): "screenshot_plots_docked.png",
        (1280, 800, "trajectories", True): "screenshot_trajectories.png",
        (1280, 800, "components", True): "screenshot_components.png",
        (1280, 800, "prediction", False): "screenshot_prediction.png",
        (1280, 800, "over time", True): "screenshot_over_time.png",
        (1280, 800, "similar", True): "screenshot_similar.png"}
FRAME, LABEL = 9, 5


def shoot(width: int, height: int, out: Path, tab: str = "trajectories",
          floated: bool = False) -> None:
    """One screenshot in this process (napari's settings must be set before import); with
    ``floated``, the plots dock floated over the window (Float), as the screen shows it."""
    import napari
    from imageio.v3 import imwrite  # napari's own dependency
    from qtpy.QtCore import QEventLoop, QTimer

    from napari_pfsdm.napari._sample_data import gastruloid_timelapse

    def spin(ms: int) -> None:
        loop = QEventLoop()
        QTimer.singleShot(ms, loop.quit)
        loop.exec()

    def wait(done, what: str, timeout: float = 300.0) -> None:
        t0 = time.perf_counter()
        while not done():
            if time.perf_counter() - t0 > timeout:
                raise TimeoutError(f"{what}: not done after {timeout:.0f} s")
            spin(50)

    viewer = napari.Viewer(show=True)
    viewer.window.resize(width, height)
    for data, kwargs, kind in gastruloid_timelapse():
        getattr(viewer, f"add_{kind}")(data, **kwargs)
    labels = viewer.layers["gastruloids"]
    window = viewer.window
    _d, widget = window.add_plugin_dock_widget("napari-pfsdm", "PF-SDM analysis")
    _d, predictor = window.add_plugin_dock_widget("napari-pfsdm", "PF-SDM prediction")
    if widget.run() is None:
        raise RuntimeError(f"Run refused: {widget.status.value}")
    wait(lambda: widget.worker is None, "Run")
    if widget.bound is None:
        raise RuntimeError(f"the Run gave no results: {widget.status.value}")
    widget.open_plots()
    _d, plots = window.add_plugin_dock_widget("napari-pfsdm", "PF-SDM plots")  # the one docked
    predictor.layer_choice.value = labels.name
    predictor.last.value = 5
    predictor.run()
    wait(lambda: predictor.worker is None, "prediction")
    objects = widget.add_objects_layer()
    objects.visible = False
    widget.say(widget.bound[1].message)  # the status line says what the Run found
    # the plotter biologists already use, docked below the plugin, plotting the labels (at
    # 1280 × 800; the desktop-sized picture shows the plugin's plots docked, alone)
    if width <= 1280:
        try:
            window.add_plugin_dock_widget("napari-clusters-plotter", "Plot & select features")
        except Exception as err:  # noqa: BLE001 - not installed: the plugin alone
            print(f"no napari-clusters-plotter: {err}")
    viewer.layers.selection.active = labels
    spin(500)
    viewer.layers["gastruloids reporter"].visible = False
    viewer.dims.set_current_step(0, FRAME)
    labels.selected_label = LABEL
    from napari_pfsdm.napari._widgets import dock_of

    front = {"analysis": widget, "prediction": predictor}.get(tab, plots)
    dock_of(front).raise_()
    if tab in TABS:
        plots.tabs.setCurrentIndex(TABS.index(tab))
        if tab == "over time":
            plots.made[3].column.value = "circularity"

    def shown() -> bool:
        key = widget.pictures.shown
        similar = plots.made[4]
        return (key is not None and key[1:] == (FRAME, LABEL) and widget.pictures.worker is None
                and plots.comparison.worker is None and plots.components.worker is None
                and (similar is None or similar.worker is None))

    if floated:  # beside the plotter a docked plot says "Float for a larger view"
        plots.toggle_floating()
    wait(shown, "pictures and plots")
    viewer.reset_view()  # napari's Home: the view made when the first pictures came was narrower
    spin(2000)
    if floated:  # the screen, where the floating plots lie over napari's window
        from qtpy.QtWidgets import QApplication

        qt_window = window._qt_window  # noqa: SLF001 - where the window is on the screen
        corner = qt_window.frameGeometry().topLeft()
        shot = QApplication.primaryScreen().grabWindow(0, corner.x(), corner.y(),
                                                       qt_window.frameGeometry().width(),
                                                       qt_window.frameGeometry().height())
        shot.save(str(out))
        print(f"wrote {out} ({shot.width()} × {shot.height()}, the plots floated)")
        viewer.close()
        return
    img = viewer.screenshot(canvas_only=False, flash=False)
    imwrite(out, img[..., :3])
    print(f"wrote {out} ({img.shape[1]} × {img.shape[0]})")
    viewer.close()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", nargs=2, type=int, help="one size only (width height)")
    parser.add_argument("--tab", choices=FRONT, default="trajectories",
                        help="the dock, or the plots' tab, in front (with --size)")
    parser.add_argument("--out", type=Path, help="file to write (with --size)")
    parser.add_argument("--float", action="store_true",
                        help="the plots floated over the window (with --size)")
    args = parser.parse_args(argv)
    if args.size:
        name = JOBS.get((*args.size, args.tab, args.float), "screenshot_x.png")
        shoot(*args.size, args.out or DOCS / name, tab=args.tab, floated=args.float)
        return 0
    for (width, height, tab, floated), name in JOBS.items():  # one process each: a fresh napari
        with tempfile.TemporaryDirectory() as tmp:
            env = dict(os.environ, NAPARI_CONFIG=str(Path(tmp) / "settings.yaml"))
            subprocess.run([sys.executable, __file__, "--size", str(width), str(height),
                            "--tab", tab, "--out", str(DOCS / name),
                            *(["--float"] if floated else [])], env=env, check=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
