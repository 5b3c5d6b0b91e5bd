"""The screenshots in docs/: the plugin as a user sees it after a run, plots open, an object
selected, at the window sizes of a laptop (1280 × 800) and of a desktop (1600 × 1000).

A fresh ``napari.Viewer`` (with napari's settings in a temporary file, so that no window or
dock geometry saved by an earlier session changes the layout), the gastruloid sample, the
widgets docked through the Plugins menu's route (``add_plugin_dock_widget``), Run, Open plots,
frame 9 and label 5. Run from the repository root on a (virtual) X screen at least as large::

    xvfb-run -a -s "-screen 0 1600x1000x24" .venv/bin/python benchmarks/screenshots.py

Writes ``docs/screenshot.png`` (1600 × 1000), ``docs/screenshot_1280x800.png`` and, with the
components and prediction docks open after a prediction on the sample's groups,
``docs/screenshot_components.png`` and ``docs/screenshot_prediction.png`` (1280 × 800).
Look at them before committing.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1] / "docs"
SIZES = {(1600, 1000): "screenshot.png", (1280, 800): "screenshot_1280x800.png"}
#: The reading and prediction docks (issue 22), at a laptop's size.
PANELS = "screenshot_components.png"  # and screenshot_prediction.png


def shoot(width: int, height: int, out: Path, panels: bool = False) -> None:
    """One screenshot in this process (napari's settings must be set before import)."""
    import napari
    from qtpy.QtCore import QEventLoop, QTimer

    from napari_pfsdm.napari._sample_data import gastruloid_timelapse

    def spin(ms: int) -> None:
        loop = QEventLoop()
        QTimer.singleShot(ms, loop.quit)
        loop.exec()

    viewer = napari.Viewer(show=True)
    viewer.window._qt_window.resize(width, height)
    for data, kwargs, kind in gastruloid_timelapse():
        getattr(viewer, f"add_{kind}")(data, **kwargs)
    _dock, widget = viewer.window.add_plugin_dock_widget("napari-pfsdm", "PF-SDM analysis")
    widget.run()
    while widget.worker is not None or widget.last_output is None:
        spin(50)
    labels = viewer.layers["gastruloids"]
    if panels:  # the components' reading and the prediction, side by side
        window = viewer.window
        comp_dock, comp = window.add_plugin_dock_widget("napari-pfsdm", "PF-SDM components")
        _d, pred = window.add_plugin_dock_widget("napari-pfsdm", "PF-SDM prediction",
                                                 tabify=True)
        pred.classes = {}
        frame0 = widget.last_output.table.sort_values("frame").drop_duplicates("track_id")
        groups = labels.metadata["groups"]
        pred.classes = {int(t): groups[int(lab)] for t, lab in
                        zip(frame0["track_id"], frame0["label"], strict=True)}
        pred.source.setCurrentText("groups CSV")
        pred._show_classes()
        pred.last.setValue(5)
        pred.run()
        while pred.worker is not None or comp.worker is not None:
            spin(100)
        comp_dock.raise_()
    else:
        widget.open_plots()
    viewer.layers["gastruloids reporter"].visible = False
    viewer.dims.set_point(0, 9)
    labels.selected_label = 5
    spin(3000)
    for plot in getattr(widget, "plots", []):
        plot.flush()
    spin(2000)
    from imageio.v3 import imwrite  # napari's own dependency

    img = viewer.screenshot(canvas_only=False, flash=False)
    imwrite(out, img[..., :3])
    print(f"wrote {out} ({img.shape[1]} × {img.shape[0]})")
    if panels:  # and the prediction's tab
        _d.raise_()
        spin(1500)
        img = viewer.screenshot(canvas_only=False, flash=False)
        second = out.with_name(out.stem.replace("components", "prediction") + out.suffix)
        imwrite(second, img[..., :3])
        print(f"wrote {second} ({img.shape[1]} × {img.shape[0]})")
    viewer.close()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", nargs=2, type=int, help="one size only (width height)")
    parser.add_argument("--out", type=Path, help="file to write (with --size)")
    parser.add_argument("--panels", action="store_true",
                        help="the components and prediction docks instead of the plots")
    args = parser.parse_args(argv)
    if args.size:
        shoot(*args.size, args.out or DOCS / SIZES.get(tuple(args.size), "screenshot_x.png"),
              panels=args.panels)
        return 0
    jobs = [((w, h), name, []) for (w, h), name in SIZES.items()]
    jobs.append(((1280, 800), PANELS, ["--panels"]))
    for (width, height), name, extra in jobs:  # one process each: a fresh napari
        with tempfile.TemporaryDirectory() as tmp:
            env = dict(os.environ, NAPARI_CONFIG=str(Path(tmp) / "settings.yaml"))
            subprocess.run([sys.executable, __file__, "--size", str(width), str(height),
                            "--out", str(DOCS / name), *extra], env=env, check=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
