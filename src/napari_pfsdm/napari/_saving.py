"""The jobs that write an analysis's files and the one that reads a saved analysis back: Save
analysis…, Export CSV…, Report… and Open analysis…, as :class:`~._jobs.Job` s of the layer.

They take the viewer, the layer and its :class:`~._model.Analysis` (what the model holds), never
a dock: a dock only starts them and shows their words. A saved analysis reopens on the data it
was made from however the user opened them again: the Labels layer of its name, any Labels or
whole-number Image layer of the same data (File ▸ Open, drag and drop: checked by fingerprint),
or the labels' file it recorded.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from napari.layers import Image, Labels
from napari.qt.threading import thread_worker

from ..saved import ANALYSIS_FILE
from ._jobs import JOBS, Job, layer_data, take_result
from ._model import Analysis, is_picture, layer_shape
from ._results import plural


# ------------------------------------------------------------------------- writing files
@thread_worker(start_thread=False)
def _writer(write, *args):
    yield "writing"  # Cancel before this point writes nothing
    return write(*args)


def start_save(viewer, labels, analysis: Analysis, folder) -> Job:
    """Save ``analysis`` (of ``labels``) into ``folder`` (:meth:`Analysis.save`)."""
    worker = _writer(analysis.save, folder, _ignore_errors=True)
    return JOBS.start(Job(labels.unique_id, "save", worker),
                      f"Saving the analysis into {folder}…",
                      lambda out: f"Saved the analysis into {out}: Open analysis… brings it "
                                  "back.",
                      "Nothing was saved", "Saving cancelled: nothing was written.")


def start_export(viewer, labels, analysis: Analysis, folder) -> Job:
    """Write the tables of ``analysis`` into ``folder`` (:func:`~._export.export`)."""
    from napari.utils.notifications import show_info

    from ._export import export

    def done(result):
        paths, note = result
        show_info(f"PF-SDM: {plural(len(paths), 'table')} written.")
        return (f"Wrote {plural(len(paths), 'file')} into {folder}: "
                + ", ".join(p.name for p in paths) + (f". {note}" if note else "."))

    worker = _writer(export, analysis, folder, labels.name, _ignore_errors=True)
    return JOBS.start(Job(labels.unique_id, "export", worker), f"Exporting into {folder}…",
                      done, "Nothing was exported", "Export cancelled: nothing was written.")


def _write_report(analysis: Analysis, path, title):
    from ..report import write_report

    return write_report(path, analysis.table, groups=analysis.groups or None,
                        predictions=analysis.prediction, labels=analysis.labels, title=title)


def start_report(viewer, labels, analysis: Analysis, path) -> Job:
    """Write the HTML report of ``analysis`` to ``path``."""
    worker = _writer(_write_report, analysis, path, f"PF-SDM: {labels.name}",
                     _ignore_errors=True)
    return JOBS.start(Job(labels.unique_id, "report", worker), f"Writing the report {path}…",
                      lambda out: f"Wrote {out}: one HTML file that opens in any browser, "
                                  "offline.",
                      "No report was written", "Report cancelled: nothing was written.")


# --------------------------------------------------------------------------- reading back
def candidates(viewer, saved: dict) -> list:
    """The layers that may hold the labels a saved analysis names (``saved``: its manifest's
    ``sources["labels"]``): Labels layers, then Image layers of whole numbers (a label image
    opened by File ▸ Open or drag and drop), of the saved shape, the one of the saved name
    first. Which one holds the same data is for the fingerprint to say."""
    shape = list(saved.get("shape") or [])
    found = [lay for lay in viewer.layers
             if isinstance(lay, (Labels, Image)) and not is_picture(lay)
             and not getattr(lay, "rgb", False) and list(layer_shape(lay)) == shape
             and np.issubdtype(np.dtype(layer_data(lay).dtype), np.integer)]
    return sorted(found, key=lambda lay: (lay.name != saved.get("name"),
                                          not isinstance(lay, Labels)))


@thread_worker(start_thread=False)
def _open_worker(folder, sources: dict, layers: list, images: list):
    """Read a saved analysis on the first of ``layers`` ((layer, array) pairs) whose data have
    the saved fingerprint (none: the labels' file), the reporter among ``images`` likewise;
    returns (the layer chosen or None, the :class:`~._model.Analysis`' fields)."""
    from ..saved import fingerprint, open_analysis
    from ._results import saved_fields

    yield "opening"
    want = sources.get("labels", {})
    chosen, array = None, None
    for layer, data in layers:
        if fingerprint(data)["sha256"] == want.get("sha256"):
            chosen, array = layer, data
            break
    if chosen is None and layers and (layers[0][0].name == want.get("name")
                                      or not _file_exists(want.get("path"))):
        array = layers[0][1]  # refused in open_analysis's words (what changed)
    reporter = sources.get("reporter", {})
    intensity = next((data for _lay, data in images
                      if fingerprint(data)["sha256"] == reporter.get("sha256")), None)
    saved = open_analysis(folder, labels=array, intensity=intensity, read_labels=array is None)
    return chosen, saved_fields(saved, saved.labels, intensity)


def _file_exists(path) -> bool:
    return bool(path) and Path(path).exists()


def start_open(viewer, folder) -> Job | str:
    """Open the analysis saved in ``folder`` on the data it was made from, found in the viewer
    (by fingerprint) or read from the file it recorded; returns the job, or why not (words)."""
    try:
        manifest = json.loads((Path(folder) / ANALYSIS_FILE).read_text(encoding="utf-8"))
        sources = manifest.get("sources", {})
    except (OSError, ValueError) as err:
        return (f"{folder} is not a saved analysis ({err}): choose the folder that Save "
                "analysis wrote.")
    layers = candidates(viewer, sources.get("labels", {}))
    reporter = sources.get("reporter", {})
    images = [lay for lay in viewer.layers if isinstance(lay, Image) and not is_picture(lay)
              and list(layer_shape(lay)) == list(reporter.get("shape") or [None])]
    images.sort(key=lambda lay: lay.name != reporter.get("name"))
    worker = _open_worker(folder, sources, [(lay, layer_data(lay)) for lay in layers],
                          [(lay, layer_data(lay)) for lay in images], _ignore_errors=True)
    key = layers[0].unique_id if layers else str(folder)

    def opened(result):
        layer, fields = result
        if layer is None:  # read from its file
            name = sources.get("labels", {}).get("name") or Path(folder).name
            layer = viewer.add_labels(fields["labels"], name=name)
        elif not isinstance(layer, Labels):
            layer = labels_of_image(viewer, layer)
        fields["message"] = (f"Opened the analysis saved in {folder}: "
                             f"{plural(len(fields['table']), 'object')}, nothing measured.")
        return take_result(viewer, layer, fields)

    return JOBS.start(Job(key, "open", worker), f"Opening the analysis saved in {folder}…",
                      opened, "The analysis was not opened", "Opening cancelled.")


def labels_of_image(viewer, image):
    """A Labels layer of ``image``'s data (no copy) beside it, the image hidden: a label image
    that napari opened as an Image layer. Returns the Labels layer."""
    made = viewer.add_labels(image.data, name=f"{image.name} labels", scale=image.scale,
                             translate=image.translate)
    made.metadata["source_path"] = source_path(image)
    image.visible = False
    return made


def source_path(layer) -> str | None:
    """The file ``layer`` was read from (napari's ``layer.source.path``, or the file of the image
    a Labels layer was made from), None when unknown."""
    path = getattr(getattr(layer, "source", None), "path", None)
    return str(path) if path else layer.metadata.get("source_path")
