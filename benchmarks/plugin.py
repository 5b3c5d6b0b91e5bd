"""The napari plugin against the library on the same movie: run time, memory, browsing latency.

Run from the repository root, on a (virtual) X screen::

    xvfb-run -a -s "-screen 0 1600x1000x24" .venv/bin/python benchmarks/plugin.py
    xvfb-run -a -s "-screen 0 1600x1000x24" .venv/bin/python benchmarks/plugin.py --quick

Data: ``make_timelapse_montage`` — ``--objects`` gastruloid-like objects per frame on a grid,
``--frames`` frames of ``--size`` × ``--size`` pixels with a reporter (default 25 × 40 = 1,000
objects in 512 × 512). In one process, in this order:

1. ``pf.measure(labels, intensity)`` (the library): wall time, and the peak of Python-tracked
   memory (``tracemalloc``: numpy arrays included) above the start.
2. ``run_analysis`` (the widget's computation, no Qt) in the same way: its peak must stay
   within 150 MB of ``measure``'s (issue 12).
3. The widget in a napari viewer: Run until the results are shown (wall time, ratio to 1.).
   Then the time from selecting a label to its pictures being shown (first look: made in a
   worker; again: from the cache; first look after 5 s idle: made ahead meanwhile), from a
   time-slider step to the pictures of the new frame
   (the neighbouring frames are made ahead), and the plots' redraw after a step (distance
   matrix + MDS of that frame) and highlight.

Under Xvfb the canvas is drawn by software OpenGL (llvmpipe) on the same two cores: drawing
costs far more than on a desktop with a GPU, so the latencies here are upper bounds. Writes
``plugin.csv`` and ``plugin.png`` to ``--out``.
"""

from __future__ import annotations

import argparse
import gc
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pandas as pd


def _timed_and_peak_mb(fn):
    """(result, seconds, peak MB of tracemalloc above the start): timed in a first call
    without tracing (tracing slows numpy down), the memory in a second one."""
    gc.collect()
    t0 = time.perf_counter()
    out = fn()
    dt = time.perf_counter() - t0
    gc.collect()
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    fn()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return out, dt, (peak - base) / 2**20


def _drain(gen):
    try:
        while True:
            next(gen)
    except StopIteration as stop:
        return stop.value


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", type=int, default=25, help="objects per frame")
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--looks", type=int, default=8, help="labels selected for the latency")
    parser.add_argument("--quick", action="store_true", help="9 objects × 6 frames, 256 px")
    parser.add_argument("--out", default="benchmarks/out")
    args = parser.parse_args(argv)
    if args.quick:
        args.objects, args.frames, args.size, args.looks = 9, 6, 256, 3

    import napari_pfsdm as pf
    from napari_pfsdm.data.gastruloids import make_timelapse_montage
    from napari_pfsdm.napari._compute import run_analysis

    labels, intensity, _ = make_timelapse_montage(n_objects=args.objects,
                                                  n_frames=args.frames, size=args.size, seed=1)
    n = int(sum(len(np.unique(f)) - 1 for f in labels))
    print(f"{n} objects: {args.frames} frames × {args.objects} objects, "
          f"{args.size} × {args.size} px, with a reporter")
    table, t_lib, mem_lib = _timed_and_peak_mb(lambda: pf.measure(labels, intensity))
    out, t_run, mem_run = _timed_and_peak_mb(lambda: _drain(run_analysis(labels, intensity)))
    num = [c for c in table.columns if c not in ("error", "warnings")]
    same = np.array_equal(table[num].to_numpy(float), out.table[num].to_numpy(float),
                          equal_nan=True)

    import napari
    from qtpy.QtCore import QEventLoop, QTimer

    from napari_pfsdm.napari import _layers
    from napari_pfsdm.napari._widget import AnalysisWidget

    viewer = napari.Viewer(show=True)
    viewer.window._qt_window.resize(1500, 950)
    viewer.add_image(intensity, name="reporter")
    labels_layer = viewer.add_labels(labels, name="cells")
    widget = AnalysisWidget(viewer)
    viewer.window.add_dock_widget(widget, name="PF-SDM analysis")

    def spin(ms: int) -> None:
        loop = QEventLoop()
        QTimer.singleShot(ms, loop.quit)
        loop.exec()

    def until(cond, t0: float, timeout: float = 60.0) -> float:
        """Seconds from ``t0`` (before the action) until ``cond()`` holds, checked every 2 ms
        by a timer inside Qt's own event loop (a Python loop around ``processEvents`` would
        hold the interpreter lock and slow the worker threads down several times)."""
        loop = QEventLoop()
        timer = QTimer(interval=2)
        done = []

        def check():
            if cond():
                done.append(time.perf_counter())
                loop.quit()
            elif time.perf_counter() - t0 > timeout:
                loop.quit()

        timer.timeout.connect(check)
        timer.start()
        if not cond():
            loop.exec()
        else:
            done.append(time.perf_counter())
        timer.stop()
        if not done:
            raise TimeoutError("the viewer did not answer in time")
        return done[0] - t0

    spin(500)
    t0 = time.perf_counter()
    widget.run()
    until(lambda: widget.worker is None and widget.last_output is not None, t0, 600)
    t_widget = time.perf_counter() - t0
    until(lambda: widget.shown_key is not None, time.perf_counter())
    spin(1500)
    rows = []
    frame = _layers.current_frame(viewer, labels_layer)
    present = [int(v) for v in widget.last_output.labels_in(frame)]
    looks = present[1:args.looks + 1]
    for kind in ("first look", "again (cache)"):
        for label in looks:
            spin(300)
            t0 = time.perf_counter()
            labels_layer.selected_label = label
            rows.append({"action": f"select a label, {kind}", "ms": 1e3 * until(
                lambda lab=label: widget.shown_key == (frame, lab), t0)})
    # after a pause the other objects of the frame are made ahead: a first look is then a
    # cache hit too
    spin(5000)
    for label in present[args.looks + 1:args.looks + 5]:
        spin(300)
        t0 = time.perf_counter()
        labels_layer.selected_label = label
        rows.append({"action": "select a label, first look after 5 s idle", "ms": 1e3 * until(
            lambda lab=label: widget.shown_key == (frame, lab), t0)})
    for step in (1, 1, 1, -1, -1):
        spin(600)  # the frames around are made ahead meanwhile
        frame = int(np.clip(frame + step, 0, args.frames - 1))
        t0 = time.perf_counter()
        viewer.dims.set_point(0, frame)
        rows.append({"action": "time-slider step", "ms": 1e3 * until(
            lambda f=frame: widget.shown_key is not None and widget.shown_key[0] == f, t0)})
    widget.open_plots()
    spin(1500)
    traj, comp = widget.plots
    for _ in range(3):
        frame = (frame + 1) % args.frames
        viewer.dims.set_point(0, frame)
        t0 = time.perf_counter()
        comp.flush()
        rows.append({"action": "comparison redraw (new frame)",
                     "ms": 1e3 * (time.perf_counter() - t0)})
        t0 = time.perf_counter()
        traj.flush()
        rows.append({"action": "trajectory highlight", "ms": 1e3 * (time.perf_counter() - t0)})
    lat = pd.DataFrame(rows).groupby("action", sort=False)["ms"].agg(["median", "max", "count"])
    viewer.close()

    print(f"\ntables identical (widget vs measure): {same}")
    summary = pd.DataFrame([
        {"what": "pf.measure (library)", "seconds": t_lib, "peak MB": mem_lib, "ratio": 1.0},
        {"what": "run_analysis (widget's computation, no Qt)", "seconds": t_run,
         "peak MB": mem_run, "ratio": t_run / t_lib},
        {"what": "widget: Run until shown", "seconds": t_widget, "peak MB": np.nan,
         "ratio": t_widget / t_lib},
    ])
    print(summary.to_string(index=False, float_format=lambda v: f"{v:.2f}"))
    print("\nlatency (ms)")
    print(lat.to_string(float_format=lambda v: f"{v:.0f}"))
    outdir = Path(args.out)
    outdir.mkdir(parents=True, exist_ok=True)
    pd.concat([summary.assign(kind="run"), lat.reset_index().assign(kind="latency")]).to_csv(
        outdir / "plugin.csv", index=False)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.6), constrained_layout=True)
    a.barh(summary["what"], summary["seconds"], color=["#4c72b0", "#55a868", "#c44e52"])
    a.set_xlabel("seconds")
    a.set_title(f"{n} objects")
    a.invert_yaxis()
    b.barh(lat.index, lat["median"], xerr=[0 * lat["median"], lat["max"] - lat["median"]],
           color="#8172b2")
    b.axvline(100, color="k", ls="--", lw=0.8)
    b.set_xlabel("ms: bar median, line to the max")
    b.set_title("dashed: 100 ms", fontsize=9)
    b.invert_yaxis()
    fig.savefig(outdir / "plugin.png", dpi=110)
    print(f"\nwrote {outdir / 'plugin.csv'} and {outdir / 'plugin.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
