"""The study dock's picture in docs/: every dock of the plugin open at 1280 × 800, four synthetic
movies (two clones × two organoids, labels repeated in each, uneven days, 0.65 µm pixels) run
as one study, an object clicked, the Over time tab showing area per clone with its statistics.

Run::

    xvfb-run -a -s "-screen 0 1280x1024x24" .venv/bin/python benchmarks/screenshot_study.py

Writes ``docs/screenshot_study.png``; look at it before committing.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

DOCS = Path(__file__).resolve().parents[1] / "docs"
#: The days of the frames (uneven; day 12 imaged twice).
DAYS = [2, 5, 8, 12, 12, 16]
PIXEL = 0.65  # µm
DOCKS = ("PF-SDM analysis", "PF-SDM plots", "PF-SDM prediction", "PF-SDM study")


def movie(scale: float, seed: int, n_objects: int = 6, size: int = 160) -> np.ndarray:
    """Ellipses growing over the frames of :data:`DAYS` (labels 1 … n in every movie)."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:size, :size]
    out = np.zeros((len(DAYS), size, size), np.uint16)
    centres = [(30 + 50 * (i // 3), 30 + 50 * (i % 3)) for i in range(n_objects)]
    axes = rng.uniform(0.5, 1.0, (n_objects, 2))
    for t, day in enumerate(DAYS):
        r = scale * (6 + 0.6 * day)
        for i, (cy, cx) in enumerate(centres):
            a, b = r * axes[i]
            out[t][((yy - cy) / a) ** 2 + ((xx - cx) / b) ** 2 <= 1] = i + 1
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", type=Path, default=DOCS / "screenshot_study.png")
    args = parser.parse_args(argv)

    import napari
    from imageio.v3 import imwrite
    from qtpy.QtCore import QEventLoop, QTimer

    from napari_pfsdm.napari._widgets import dock_of

    def spin(ms: int) -> None:
        loop = QEventLoop()
        QTimer.singleShot(ms, loop.quit)
        loop.exec()

    viewer = napari.Viewer(show=True)
    viewer.window.resize(1280, 800)
    for k, (clone, scale) in enumerate([("c1", 1.0), ("c1", 1.0), ("c2", 1.3), ("c2", 1.3)]):
        viewer.add_labels(movie(scale, seed=k % 2), name=f"{clone}_org{k + 1:02d}",
                          scale=(1, PIXEL, PIXEL))
    docks = {name: viewer.window.add_plugin_dock_widget("napari-pfsdm", name)[1]
             for name in DOCKS}
    study = docks["PF-SDM study"]
    study.movies.value = list(study.movies.choices)
    study.times.value = ",".join(str(d) for d in DAYS)
    study.time_unit.value = "day"
    if study.run() is None:
        raise RuntimeError(study.status.value)
    t0 = time.perf_counter()
    while study.worker is not None:
        if time.perf_counter() - t0 > 300:
            raise TimeoutError("the study's Run")
        spin(50)
    dock_of(study).raise_()
    study.tabs.setCurrentIndex(1)
    over = study.plots[1]
    over.measure.value = "area"
    spin(300)
    study.show_object("c2_org03", 3, 2)
    spin(1500)
    img = viewer.screenshot(canvas_only=False, flash=False)
    imwrite(args.o, img[..., :3])
    print(f"wrote {args.o} ({img.shape[1]} × {img.shape[0]}); status: {study.status.value}")
    print(" ".join(over.sentences))
    viewer.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
