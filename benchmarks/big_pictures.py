"""A 1-megapixel object's pictures after a Run: the plugin against napari alone adding the same
layers (issue 68, point 4).

Run from the repository root on a (virtual) X screen, QT_QPA_PLATFORM unset::

    xvfb-run -a -s "-screen 0 1600x1000x24" .venv/bin/python benchmarks/big_pictures.py \\
        --mask A02.tif --repeats 3

``--mask``: a real gastruloid's mask from fmi-basel/gliberal-gastruloid-2023-methods (MIT),
``data/200129MZ072BBB07/FG_MASK/200129MZ072BBB07_A02_T0001F001L01A04Z01C01.tif`` (2160 × 2560,
one object of 1,091,760 px; clone the repository or download that file). Without it the
benchmark draws a bent capsule of the same size (``bent_capsule_mask``, r = 1,000 px).

Each repeat is two fresh processes (napari builds a layer of a new kind once per process, the
cost that dominates here), in turn:

* **napari**: a 1280 × 800 viewer with the mask as a Labels layer; the object's pictures
  computed beforehand (``object_pictures``, what the plugin's worker computes); timed: napari
  adding the same picture layers with the same data (the plugin's ``_pictures.show`` in that
  viewer, napari's public API only) and drawing them (``viewer.screenshot``);
* **plugin**: the same viewer with the analysis dock; Run; timed: from the moment the Run's
  result reaches the plugin's model (it then selects the object) until the object's pictures
  are on screen and drawn (``viewer.screenshot``).

Prints each repeat's seconds, the medians, plugin − napari (target ≤ 0.3 s) and plugin ÷ napari.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SIZE = (1280, 800)
TARGET_S = 0.3


def load(mask: Path | None) -> np.ndarray:
    if mask is not None:
        import tifffile

        return (tifffile.imread(mask) > 0).astype(np.uint16)
    from napari_pfsdm.data.shapes import bent_capsule_mask

    return bent_capsule_mask(1000).astype(np.uint16)


def spin_until(app, done, timeout: float = 300.0) -> None:
    t0 = time.perf_counter()
    while not done():
        if time.perf_counter() - t0 > timeout:
            raise TimeoutError("not done")
        app.processEvents()
        time.sleep(0.002)


def one(kind: str, mask: Path | None) -> float:
    """Seconds of one measurement in this (fresh) process."""
    import napari
    from qtpy.QtWidgets import QApplication

    labels = load(mask)
    viewer = napari.Viewer(show=True)
    viewer.window.resize(*SIZE)
    layer = viewer.add_labels(labels, name="gastruloid")
    app = QApplication.instance()
    for _ in range(50):  # the window and the labels drawn
        app.processEvents()
        time.sleep(0.01)
    if kind == "napari":
        import napari_pfsdm as pf
        from napari_pfsdm.analysis.pictures import object_pictures
        from napari_pfsdm.core.params import PFSDMParams
        from napari_pfsdm.napari import _pictures
        from napari_pfsdm.napari._model import Analysis

        table = pf.measure(labels)
        analysis = Analysis("napari", 1, table, dict(table.attrs.get("pfsdm") or {}),
                            axes="yx")
        pictures = object_pictures(labels, None, 0, 1, params=PFSDMParams(), axes="yx",
                                   size=_pictures.SIZE, midline=True)
        t0 = time.perf_counter()
        _pictures.show(viewer, layer, analysis, pictures)
        viewer.reset_view()
        viewer.screenshot(canvas_only=True, flash=False)  # drawn
        seconds = time.perf_counter() - t0
    else:
        from napari_pfsdm.napari._model import REGISTRY

        _dock, widget = viewer.window.add_plugin_dock_widget("napari-pfsdm",
                                                             "PF-SDM analysis")
        marks: dict = {}
        REGISTRY.updated.connect(lambda _id: marks.setdefault("t0", time.perf_counter()))
        if widget.run() is None:
            raise RuntimeError(widget.status.value)

        def shown() -> bool:
            pics = widget.pictures
            return ("t0" in marks and pics.worker is None and pics.wanted is not None
                    and pics.shown == pics.wanted[2])

        spin_until(app, shown)
        viewer.screenshot(canvas_only=True, flash=False)  # drawn
        seconds = time.perf_counter() - marks["t0"]
    viewer.close()
    return seconds


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mask", type=Path, help="the gastruloid mask (a TIFF)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--one", choices=["napari", "plugin"], help=argparse.SUPPRESS)
    parser.add_argument("--json", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.one:
        args.json.write_text(json.dumps(one(args.one, args.mask)))
        return 0
    times: dict[str, list[float]] = {"napari": [], "plugin": []}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.repeats):
            for kind in ("napari", "plugin") if i % 2 == 0 else ("plugin", "napari"):
                out = Path(tmp) / f"{kind}{i}.json"
                cmd = [sys.executable, __file__, "--one", kind, "--json", str(out)]
                if args.mask:
                    cmd += ["--mask", str(args.mask)]
                env = {**os.environ, "NAPARI_CONFIG": str(Path(tmp) / "settings.yaml")}
                subprocess.run(cmd, check=True, env=env)
                times[kind].append(json.loads(out.read_text()))
    labels = load(args.mask)
    print(f"`benchmarks/big_pictures.py {' '.join(argv if argv is not None else sys.argv[1:])}`")
    print(f"\nmask: {args.mask or 'bent capsule r = 1,000 px'}, {labels.shape[0]} × "
          f"{labels.shape[1]}, object {int((labels > 0).sum()):,} px\n")
    print("| | repeats (s) | median (s) |\n|---|---|---|")
    for kind, words in (("napari", "napari adding the same picture layers"),
                        ("plugin", "plugin: Run's result → the object's pictures drawn")):
        print(f"| {words} | {', '.join(f'{t:.2f}' for t in times[kind])} | "
              f"{statistics.median(times[kind]):.2f} |")
    a, b = statistics.median(times["napari"]), statistics.median(times["plugin"])
    print(f"\nplugin − napari: {b - a:+.2f} s (target ≤ +{TARGET_S} s); plugin ÷ napari: "
          f"{b / a:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
