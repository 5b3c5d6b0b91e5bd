"""The plugin's long jobs: a Run, opening or saving an analysis, the export, the report.

Each is a napari ``thread_worker`` (napari's progress bar and notifications) kept in :data:`JOBS`
under the Labels layer it is about, not by the dock that started it: any analysis dock showing
that layer shows the job (what it does, Cancel), a dock opened during it included, and what the
job makes reaches the model (:data:`~._model.REGISTRY`) whether or not a dock is open. Removing
the layer during a Run stops it and shows again the image the Run hid.

Examples
--------
The jobs of a layer, found by its unique id::

    job = start_run(viewer, labels, arrays)       # Run
    JOBS.of(labels.unique_id)                     # [job] while it runs
    job.events.said.connect(print)                # what it does, what it did
    job.cancel()
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from napari.qt.threading import thread_worker
from napari.utils import progress
from napari.utils.notifications import show_error, show_info, show_warning
from psygnal import Signal, SignalGroup

from ._model import REGISTRY, Analysis, current_frame
from ._results import plural

#: Seconds between two counts of a Run's objects in the words a dock shows.
SAY_EVERY = 1.0


def layer_data(layer):
    """A layer's data at full resolution (the first level of a multiscale one)."""
    return layer.data[0] if getattr(layer, "multiscale", False) else layer.data


class JobEvents(SignalGroup):
    """What a job tells the docks that show it."""

    #: A sentence on what it does or did, and whether it is an error.
    said = Signal(str, bool)
    #: It ended (done, failed or cancelled).
    finished = Signal()


@dataclass(eq=False)
class Job:
    """One long job of the plugin.

    Attributes
    ----------
    key : str
        What it is about: the Labels layer's unique id (or the folder being opened when the
        labels are read from their file).
    kind : str
        ``"run"``, ``"open"`` (both give the layer a new analysis), or ``"save"``,
        ``"export"``, ``"report"`` (they write files).
    worker
        napari's worker.
    text, error
        The last sentence said, and whether it was an error.
    cancelled
        What it says when it is stopped.
    """

    key: str
    kind: str
    worker: Any = field(repr=False)
    text: str = ""
    error: bool = False
    #: What it says when it is stopped.
    cancelled: str = "Cancelled."
    events: JobEvents = field(default_factory=JobEvents, repr=False)

    @property
    def writes(self) -> bool:
        """Whether it writes files (else it makes an analysis)."""
        return self.kind in ("save", "export", "report")

    def say(self, text: str, error: bool = False) -> None:
        self.text, self.error = text, error
        self.events.said.emit(text, error)

    def cancel(self) -> None:
        """Stop it: a Run keeps nothing, an export writes nothing."""
        self.worker.quit()


class Jobs:
    """The running jobs, by what they are about."""

    #: A job started (the docks showing its layer show it).
    started = Signal(object)

    def __init__(self) -> None:
        self._jobs: list[Job] = []

    def of(self, key: str | None) -> list[Job]:
        """The running jobs about ``key`` (a layer's unique id)."""
        return [job for job in self._jobs if job.key == key]

    def start(self, job: Job, doing: str, done: Callable[[Any], str | None],
              failed: str, cancelled: str) -> Job:
        """Start ``job``, saying ``doing``; at its end it says ``done(result)`` (None: nothing
        more), ``failed: <error>`` (with napari's error notification) or ``cancelled``."""
        worker = job.worker

        def returned(result):
            words = done(result)
            if words:
                job.say(words)

        def errored(err):
            job.say(f"{failed}: {err}", True)
            show_error(job.text)

        def finished():
            self._jobs.remove(job)
            job.events.finished.emit()

        worker.returned.connect(returned)
        worker.errored.connect(errored)
        job.cancelled = cancelled
        worker.aborted.connect(lambda: job.say(job.cancelled))
        worker.finished.connect(finished)
        self._jobs.append(job)
        job.say(doing)
        self.started.emit(job)
        worker.start()
        return job


#: The process's jobs (napari's layer ids are unique across viewers).
JOBS = Jobs()


# ------------------------------------------------------------------------------------- Run
@thread_worker(start_thread=False)
def _run_worker(labels, intensity, params, first_axis, spacing, identity, weight,
                physical=None):
    """Measure, find the identities, and make what the GUI thread shows first (the viewer
    stays free meanwhile): the fields of the :class:`Analysis`, with its layer features and
    its words."""
    from ._features import layer_features
    from ._results import explain, identify, reporter_problem, run_analysis, run_message

    fields = yield from run_analysis(labels, intensity, params, first_axis, spacing,
                                     **(physical or {}))
    fields["options"]["intensity_weight"] = weight
    mode, tracks, name = identity
    try:
        fields["table"], fields["tracking_message"] = identify(
            fields["table"], labels, fields["axes"].startswith("t"), mode, tracks, name)
    except ValueError as err:  # e.g. the Tracks layer does not fit: trust the ids
        fields["table"], _ = identify(fields["table"], labels, True, "labels")
        fields["tracking_message"] = f"{err} The label ids were used."
    fields["features"] = layer_features(fields["table"], fields["pca"], fields["measures"])
    fields["sentences"] = {"shape": explain(fields["pca"], fields["measures"])}
    fields["message"] = run_message(fields, labels, reporter_problem(intensity))
    return fields


@dataclass
class RunInput:
    """What a Run measures: the arrays and the form's choices."""

    intensity: Any
    params: Any
    first_axis: str = "time"
    spacing: tuple | None = None
    identity: tuple = ("auto", None, "")
    weight: float = 0.0
    #: The layers' names (``{"reporter": …}``) and the files they came from (``{"labels": …}``).
    names: dict = field(default_factory=dict)
    paths: dict = field(default_factory=dict)
    #: ``pixel_size``, ``space_unit``, ``times``, ``time_unit`` (:func:`run_analysis`'s).
    physical: dict = field(default_factory=dict)


def start_run(viewer, labels, run: RunInput, hidden=None) -> Job:
    """Measure every object of the Labels layer ``labels`` in a worker, with napari's progress
    bar; the result becomes the layer's analysis (:func:`take_result`). ``hidden``: a layer the
    Run hid (the image ``labels`` was made from), shown again when ``labels`` is removed
    before the Run ends (the Run then stops)."""
    worker = _run_worker(layer_data(labels), run.intensity, run.params, run.first_axis,
                         run.spacing, run.identity, run.weight, run.physical,
                         _ignore_errors=True)
    job = Job(labels.unique_id, "run", worker)
    start = time.perf_counter()
    bar = progress(total=0, desc="PF-SDM")
    said = [0.0]

    def count(value):  # napari's bar counts the objects done; the docks, every second
        done, total = value
        bar.total = total
        bar.update(done - bar.n)
        now = time.perf_counter()
        if now - said[0] >= SAY_EVERY:
            said[0] = now
            job.say(f"Measuring the objects of '{labels.name}': {done:,} of "
                    f"{plural(total, 'object')} (napari's activity panel, bottom right).")

    def removed(event):
        if getattr(event.value, "unique_id", None) == job.key:
            if hidden is not None and hidden in viewer.layers:
                hidden.visible = True
            job.cancelled = (f"The Labels layer '{labels.name}' was removed during the Run: "
                             "nothing was kept.")
            job.say(job.cancelled)
            job.cancel()

    def finished():
        bar.close()
        viewer.layers.events.removed.disconnect(removed)

    worker.yielded.connect(count)
    worker.finished.connect(finished)
    viewer.layers.events.removed.connect(removed)
    names = {**run.names, "labels": labels.name}

    def done(fields):
        seconds = time.perf_counter() - start
        return take_result(viewer, labels, {**fields, "sources": names, "paths": run.paths},
                           seconds)

    return JOBS.start(job, f"Measuring the objects of '{labels.name}'… (progress: napari's "
                      "activity panel, bottom right)", done, "The analysis stopped",
                      "Cancelled: nothing was kept.")


def take_result(viewer, labels, fields: dict, seconds: float | None = None) -> str | None:
    """A finished Run (``seconds`` long; None: an analysis opened from a folder) becomes the
    layer's analysis, whether or not a dock is open: the model writes the layer's features;
    napari selects an object that has pictures (one away from the border, when there is one).
    Returns the status line's words (None when the layer is gone)."""
    if labels not in viewer.layers:
        show_warning("PF-SDM: the Labels layer was removed during the run; nothing was kept.")
        return None
    n = len(fields["table"])
    if seconds is not None:
        fields["message"] = f"{plural(n, 'object')} measured in {seconds:.1f} s. " \
                            f"{fields['message']}"
    if "groups" not in fields:  # a run: the layer's own groups (e.g. the sample's)
        groups = labels.metadata.get("groups") or {}
        fields["groups"] = {int(k): str(v) for k, v in groups.items()}
    analysis = REGISTRY.new_run(labels, fields, viewer)
    warn = analysis.tracking_message.startswith("Warning")
    what = "opened" if seconds is None else "measured"
    (show_warning if warn else show_info)(f"PF-SDM: {plural(n, 'object')} {what}.")
    _select_first(viewer, labels, analysis)
    return analysis.message


def _select_first(viewer, labels, analysis: Analysis) -> None:
    """Select an object of the frame shown that has pictures, preferring the one napari
    selects, then objects away from the border."""
    frame = current_frame(viewer.dims, labels, analysis.time_lapse)
    present = [lab for lab in analysis.labels_in(frame) if not analysis.error_of(frame, lab)]
    inside = [lab for lab in present if not analysis.touches_border(frame, lab)]
    if present and labels.selected_label not in (inside or present):
        labels.selected_label = int((inside or present)[0])
    analysis.select(frame, labels.selected_label)
