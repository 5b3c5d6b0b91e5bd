"""Write the report of a run: one self-contained HTML file (``pfsdm report``, the plugin's
"Report…" button).

The page itself is :func:`napari_pfsdm.analysis.report.report_html`; this module writes it as
every output of napari-pfsdm is written: atomically (a half-written file never replaces a
good one) and never over a file that napari-pfsdm did not write unless ``force`` is given. It
sits above the analysis and the file layers (tests/test_layering.py) so that the command line
and the napari plugin call the same function.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from .analysis.report import REPORT_COLUMNS, report_html
from .errors import InputError
from .io import atomic_write, check_overwrite

__all__ = ["write_report"]


def write_report(
    path: str | os.PathLike,
    table: pd.DataFrame,
    *,
    groups: Mapping | pd.DataFrame | None = None,
    predictions=None,
    prediction_info: Mapping[str, Any] | None = None,
    labels=None,
    title: str | None = None,
    columns: Sequence[str] = REPORT_COLUMNS,
    source: str | None = None,
    force: bool = False,
    elastic_weight: float | None = None,
) -> Path:
    """Write the report of ``table`` to ``path`` (one HTML file that opens offline).

    The keywords are those of :func:`~napari_pfsdm.analysis.report.report_html`: ``groups``
    (object → group, or a groups table), ``predictions`` (a ``Prediction`` from
    ``predict_outcome``, or a predictions table with ``prediction_info``, its sidecar),
    ``labels`` (the label movie, for the outlines), ``title``, ``columns`` (measures over
    time), ``source`` (shown under the title), ``elastic_weight`` (the distance of its
    "Nearest shapes"). ``force`` replaces a file napari-pfsdm did not write.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        ``path`` exists and napari-pfsdm did not write it (without ``force``); its folder does
        not exist or cannot be written; the table is not a feature table.

    Examples
    --------
    >>> from napari_pfsdm import measure
    >>> from napari_pfsdm.data.gastruloids import make_timelapse_montage
    >>> labels, _, groups = make_timelapse_montage(n_frames=3, seed=0)
    >>> import tempfile, pathlib
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "report.html"
    >>> write_report(out, measure(labels), groups=groups, labels=labels).name
    'report.html'
    """
    path = Path(path)
    if path.is_dir():
        raise InputError(f"the report {path} is a folder; give a file name such as "
                         f"{path / 'report.html'}")
    check_overwrite(path, force=force, what="report", table=False)
    text = report_html(table, groups=groups, predictions=predictions,
                       prediction_info=prediction_info, labels=labels, title=title,
                       columns=columns, source=source, elastic_weight=elastic_weight)
    return atomic_write(path, lambda handle: handle.write(text))
