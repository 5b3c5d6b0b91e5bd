"""An analysis kept in a folder, to reopen later or elsewhere (no Qt, no napari).

:func:`save_analysis` writes one folder: the feature table (with the run's options and any
predicted probabilities), the PCA scores of each channel, the groups, each object's bounding
box, and ``analysis.json`` (what the folder holds, the layers' names, the source files' paths
and the data's fingerprints). :func:`open_analysis` reads it back and, given the label (and
reporter) arrays, refuses in plain words when they are not the data the analysis was made
from. The napari plugin's Save analysis… and Open analysis… buttons call them.

Examples
--------
>>> import tempfile
>>> import napari_pfsdm as pf
>>> from napari_pfsdm.data.gastruloids import make_timelapse_montage
>>> labels, reporter, groups = make_timelapse_montage(seed=0, n_frames=2)
>>> table = pf.measure(labels)
>>> folder = save_analysis(tempfile.mkdtemp(), table, labels=labels, groups=groups)
>>> again = open_analysis(folder, labels=labels)
>>> len(again.table) == len(table), again.groups == {int(k): v for k, v in groups.items()}
(True, True)
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .errors import InputError

__all__ = ["ANALYSIS_FILE", "SavedAnalysis", "fingerprint", "open_analysis", "save_analysis"]

#: The folder's manifest.
ANALYSIS_FILE = "analysis.json"
#: The manifest's format (raised when what it holds changes meaning).
FORMAT = 1


def fingerprint(array: Any) -> dict[str, Any]:
    """Shape, dtype and SHA-256 of an array's values (read frame by frame: numpy, dask or
    zarr), what tells whether data are those an analysis was made from.

    >>> a = np.zeros((2, 3), np.uint8)
    >>> b = a.copy(); b[1, 2] = 1
    >>> fingerprint(a) == fingerprint(a.copy()), fingerprint(a) == fingerprint(b)
    (True, False)
    """
    shape = tuple(int(n) for n in array.shape)
    digest = hashlib.sha256()
    digest.update(repr(shape).encode())
    frames = range(shape[0]) if len(shape) > 2 else [None]
    dtype = None
    for t in frames:
        part = np.ascontiguousarray(np.asarray(array if t is None else array[t]))
        dtype = part.dtype
        digest.update(part.tobytes())
    return {"shape": list(shape), "dtype": str(dtype), "sha256": digest.hexdigest()}


@dataclass
class SavedAnalysis:
    """What :func:`open_analysis` read.

    Attributes
    ----------
    table : DataFrame
        The feature table, its options in ``attrs["pfsdm"]``.
    pca : dict
        Channel → PCA scores (``frame``, ``label``, ``shape_PC1`` …; ``attrs``
        ``explained_variance_ratio``).
    groups : dict
        Object (track id or label) → group name.
    boxes : dict
        ``(frame, label)`` → bounding box (tuple of slices).
    manifest : dict
        ``analysis.json``: sources (names, paths, fingerprints), what was saved.
    explained : dict
        Channel → the fraction of the variance each PC explains.
    labels : array or None
        The labels the analysis was checked against (given, or read from their file).
    """

    table: pd.DataFrame
    pca: dict = field(default_factory=dict)
    groups: dict = field(default_factory=dict)
    boxes: dict = field(default_factory=dict)
    manifest: dict = field(default_factory=dict)
    explained: dict = field(default_factory=dict)
    labels: Any = None

    @property
    def sources(self) -> dict:
        return self.manifest.get("sources", {})


def _written_by_us(path: Path) -> bool:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError):
        return False
    return isinstance(data, dict) and str(data.get("written_by", "")).startswith("napari-pfsdm")


def save_analysis(folder: str | os.PathLike, table: pd.DataFrame, *, labels: Any = None,
                  intensity: Any = None, pca: dict | None = None, groups: dict | None = None,
                  boxes: dict | None = None, names: dict | None = None,
                  paths: dict | None = None, force: bool = False) -> Path:
    """Write an analysis into ``folder`` (made when missing); returns the folder.

    Parameters
    ----------
    folder : str or PathLike
    table : DataFrame
        The feature table (with its options; ``p_<group>`` columns are kept).
    labels, intensity : array_like, optional
        The label movie and reporter the table was measured from: their fingerprints are
        saved, so that :func:`open_analysis` can refuse other data.
    pca : dict, optional
        Channel → PCA scores (as :func:`napari_pfsdm.analysis.reduction.pca_scores` gives).
    groups : dict, optional
        Object → group name.
    boxes : mapping, optional
        ``(frame, label)`` → bounding box (slices), as the plugin keeps them.
    names, paths : dict, optional
        ``{"labels": …, "reporter": …}``: the layers' names and the files they came from.
    force : bool
        Replace files of the same names that napari-pfsdm did not write.

    Raises
    ------
    ValueError
        A file of the folder exists and napari-pfsdm did not write it (without ``force``).
    """
    from .io import atomic_write, check_overwrite, write_table_csv, writer_name

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    pca = pca or {}
    files = {"features": "features.csv", "groups": "groups.csv", "boxes": "boxes.csv",
             **{f"pca_{k}": f"pca_{k}.csv" for k in pca}}
    for name in files.values():  # all or nothing
        check_overwrite(folder / name, force=force, what="file")
    manifest_path = folder / ANALYSIS_FILE
    if manifest_path.exists() and not force and not _written_by_us(manifest_path):
        raise InputError(f"{manifest_path} exists and napari-pfsdm did not write it; nothing "
                         "was saved. Choose another folder, or remove that file")
    write_table_csv(table, folder / files["features"], table_type="features")
    for channel, scores in pca.items():
        ratios = [float(r) for r in scores.attrs.get("explained_variance_ratio", [])]
        write_table_csv(scores, folder / files[f"pca_{channel}"],
                        {"explained_variance_ratio": ratios, "pca_features": channel},
                        table_type="pca")
    write_table_csv(pd.DataFrame({"object": list((groups or {}).keys()),
                                  "group": list((groups or {}).values())}),
                    folder / files["groups"], table_type="groups")
    keys = list(boxes or {})
    rows = []
    for frame, label in keys:
        box = boxes[(frame, label)]
        rows.append([frame, label, *([s.start for s in box] + [s.stop for s in box]
                                     if box is not None else [])])
    ndim = max((len(r) - 2 for r in rows), default=0)
    cols = ["frame", "label"] + [f"start{i}" for i in range(ndim // 2)] + \
        [f"stop{i}" for i in range(ndim // 2)]
    write_table_csv(pd.DataFrame([r + [-1] * (len(cols) - len(r)) for r in rows],
                                 columns=cols), folder / files["boxes"], table_type="boxes")
    sources = {}
    for key, array in (("labels", labels), ("reporter", intensity)):
        if array is not None:
            sources[key] = {"name": (names or {}).get(key), "path": (paths or {}).get(key),
                            **fingerprint(array)}
    manifest = {"written_by": f"napari-pfsdm {writer_name().split()[-1]}", "format": FORMAT,
                "files": files, "sources": sources, "rows": len(table)}
    atomic_write(manifest_path, lambda h: h.write(json.dumps(manifest, indent=1)))
    return folder


def open_analysis(folder: str | os.PathLike, *, labels: Any = None,
                  intensity: Any = None, read_labels: bool = False) -> SavedAnalysis:
    """Read an analysis saved by :func:`save_analysis`.

    Parameters
    ----------
    folder : str or PathLike
    labels, intensity : array_like, optional
        The data to reopen it on: refused when they are not the data it was made from.
    read_labels : bool
        Without ``labels``, read them from the file the analysis names (and check them).

    Raises
    ------
    ValueError
        Not an analysis folder, a file of it missing, or data that changed (what differs and
        what to do, in words).
    """
    from .io import read_table_csv

    folder = Path(folder)
    manifest_path = folder / ANALYSIS_FILE
    if not manifest_path.is_file():
        raise InputError(f"{folder} is not a saved analysis (it has no {ANALYSIS_FILE}); "
                         "choose the folder that Save analysis wrote")
    try:
        manifest = json.loads(manifest_path.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as err:
        raise InputError(f"{manifest_path} is damaged ({err}); save the analysis again") \
            from None
    if not _written_by_us(manifest_path) or manifest.get("format") != FORMAT:
        raise InputError(f"{manifest_path} was not written by this napari-pfsdm (format "
                         f"{manifest.get('format')!r}); save the analysis again")
    if labels is None and read_labels:
        path = manifest.get("sources", {}).get("labels", {}).get("path")
        if not path or not Path(path).exists():
            raise InputError(f"the labels' file ({path or 'not recorded'}) cannot be found: "
                             "open the labels first, then open the analysis on them")
        from .batch.io import open_movie

        labels = np.asarray(open_movie(path))
    for key, array in (("labels", labels), ("reporter", intensity)):
        saved = manifest.get("sources", {}).get(key)
        if array is None or saved is None:
            continue
        now = fingerprint(array)
        if now["shape"] != saved["shape"]:
            raise InputError(f"the {key} are not those the analysis was made from: their shape "
                             f"is {tuple(now['shape'])}, the analysis's "
                             f"{tuple(saved['shape'])}. Open it on the data it was made from "
                             f"({saved.get('path') or saved.get('name') or 'see analysis.json'})"
                             ", or run the analysis again")
        if now["sha256"] != saved["sha256"]:
            raise InputError(f"the {key} changed since the analysis was saved (the same shape, "
                             "other values: edited labels?). Run the analysis again on them, "
                             "or open the saved data "
                             f"({saved.get('path') or saved.get('name') or 'see analysis.json'})")
    files = manifest.get("files", {})
    missing = [name for name in files.values() if not (folder / name).is_file()]
    if missing:
        raise InputError(f"{folder} lacks {', '.join(missing)}: the analysis is incomplete; "
                         "save it again")
    table = read_table_csv(folder / files["features"])
    pca, explained = {}, {}
    for key, name in files.items():
        if key.startswith("pca_"):
            scores = read_table_csv(folder / name)
            ratios = (scores.attrs.get("pfsdm") or {}).get("explained_variance_ratio", [])
            explained[key[4:]] = [float(r) for r in ratios]
            pca[key[4:]] = scores
    g = read_table_csv(folder / files["groups"])
    groups = {int(o): str(v) for o, v in zip(g["object"], g["group"], strict=True)} \
        if len(g) else {}
    b = read_table_csv(folder / files["boxes"])
    starts = [c for c in b.columns if c.startswith("start")]
    boxes = {}
    for row in b.itertuples(index=False):
        values = row._asdict()
        first = [int(values[c]) for c in starts]
        last = [int(values["stop" + c[5:]]) for c in starts]
        key = (int(values["frame"]), int(values["label"]))
        boxes[key] = None if not first or first[0] < 0 else tuple(
            slice(a, z) for a, z in zip(first, last, strict=True))
    return SavedAnalysis(table, pca, groups, boxes, manifest, explained, labels)
