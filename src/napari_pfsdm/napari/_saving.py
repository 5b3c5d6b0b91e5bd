"""The analysis dock's Save analysis… and Open analysis…: a run kept in a folder and brought
back on the layer it was made from (:mod:`napari_pfsdm.saved`), in napari workers."""

from __future__ import annotations

import json
from pathlib import Path

from napari.layers import Labels
from napari.qt.threading import thread_worker

from ..saved import ANALYSIS_FILE
from ._model import is_picture, layer_shape
from ._store import layer_data as _data
from ._store import store_run


@thread_worker(start_thread=False)
def _save_worker(analysis, folder, labels):
    from ..saved import save_analysis

    yield "saving"
    source = getattr(getattr(labels, "source", None), "path", None)
    return save_analysis(folder, analysis.table, labels=analysis.labels,
                         intensity=analysis.intensity, pca=analysis.pca,
                         groups=analysis.groups, boxes=analysis.boxes,
                         names={"labels": labels.name,
                                "reporter": analysis.sources.get("reporter")},
                         paths={"labels": str(source) if source else None})


@thread_worker(start_thread=False)
def _open_worker(folder, labels, intensity):
    """Read a saved analysis and check it against ``labels`` (or the labels' file when
    ``labels`` is None); the fields of the :class:`~._model.Analysis` made from it."""
    from ..saved import open_analysis
    from ._results import saved_fields

    yield "opening"
    saved = open_analysis(folder, labels=labels, intensity=intensity,
                          read_labels=labels is None)
    return saved, saved_fields(saved, saved.labels, intensity)


def save(dock, folder):
    """Save ``dock``'s analysis into ``folder`` in a worker; returns it (None: refused)."""
    if dock.bound is None or dock.export_worker is not None:
        return None
    labels, analysis = dock.bound
    return _start(dock, _save_worker(analysis, folder, labels, _ignore_errors=True),
                  f"Saving the analysis into {folder}…",
                  "Saved the analysis into {}: Open analysis… brings it back.",
                  "Nothing was saved")


def _start(dock, worker, doing: str, done: str, failed: str):
    """Start a worker that writes files for ``dock`` (its export slot), saying what it does,
    what it did (``done.format(result)``) or why it failed."""
    dock.export_worker = worker
    dock.say(doing)
    worker.returned.connect(lambda out: dock.say(done.format(out)))
    worker.errored.connect(lambda err: dock.say(f"{failed}: {err}", True))
    worker.finished.connect(dock._export_finished)
    worker.start()
    return worker


def saved_layer(viewer, saved: dict):
    """The viewer's Labels layer a saved analysis names (by name, else the one of its shape)."""
    layers = [lay for lay in viewer.layers if isinstance(lay, Labels) and not is_picture(lay)]
    for lay in layers:
        if lay.name == saved.get("name"):
            return lay
    same = [lay for lay in layers if list(layer_shape(lay)) == list(saved.get("shape") or [])]
    return same[0] if len(same) == 1 else None


def open_saved(dock, folder):
    """Open the analysis saved in ``folder`` on the layer it was made from (found by its name,
    or read from its file) in a worker; returns it (None: refused)."""
    if dock.worker is not None:
        return None
    try:
        manifest = json.loads((Path(folder) / ANALYSIS_FILE).read_text(encoding="utf-8"))
        sources = manifest.get("sources", {})
    except (OSError, ValueError) as err:
        dock.say(f"{folder} is not a saved analysis ({err}): choose the folder that Save "
                 "analysis wrote.", error=True)
        return None
    layer = saved_layer(dock.viewer, sources.get("labels", {}))
    reporter = sources.get("reporter", {}).get("name")
    image = dock.viewer.layers[reporter] if reporter in dock.viewer.layers else None
    dock.worker = worker = _open_worker(folder, None if layer is None else _data(layer),
                                        None if image is None else _data(image),
                                        _ignore_errors=True)

    def opened(result):
        saved, fields = result
        target = layer
        if target is None:  # read from its file
            name = sources.get("labels", {}).get("name") or Path(folder).name
            target = dock.viewer.add_labels(fields["labels"], name=name)
        fields["message"] = f"Opened the analysis saved in {folder}."
        store_run(dock.viewer, target, None, fields)
        dock.labels.value = target.name

    worker.returned.connect(opened)
    worker.errored.connect(lambda err: dock.say(f"The analysis was not opened: {err}", True))
    worker.finished.connect(dock._run_finished)
    dock.run_button.enabled = False
    dock.say(f"Opening the analysis saved in {folder}…")
    worker.start()
    return worker


@thread_worker(start_thread=False)
def _report_worker(analysis, path, title):
    from ..report import write_report

    yield "writing"
    return write_report(path, analysis.table, groups=analysis.groups or None,
                        predictions=analysis.prediction, labels=analysis.labels, title=title)


def report(dock, path):
    """Write the HTML report of ``dock``'s analysis to ``path`` in a worker (None: refused)."""
    if dock.bound is None or dock.export_worker is not None:
        return None
    labels, analysis = dock.bound
    return _start(dock, _report_worker(analysis, path, f"PF-SDM: {labels.name}",
                                       _ignore_errors=True),
                  f"Writing the report {path}…",
                  "Wrote {}: one HTML file that opens in any browser, offline.",
                  "No report was written")
