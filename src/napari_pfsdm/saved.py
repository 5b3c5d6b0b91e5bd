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
    from .io import atomic_write, check_overwrite, write_table, writer_name

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
    write_table(table, folder / files["features"], table_type="features")
    for channel, scores in pca.items():
        ratios = [float(r) for r in scores.attrs.get("explained_variance_ratio", [])]
        write_table(scores, folder / files[f"pca_{channel}"],
                        {"explained_variance_ratio": ratios, "pca_features": channel},
                        table_type="pca")
    write_table(pd.DataFrame({"object": list((groups or {}).keys()),
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
    write_table(pd.DataFrame([r + [-1] * (len(cols) - len(r)) for r in rows],
                                 columns=cols), folder / files["boxes"], table_type="boxes")
    sources = {}
    for key, array in (("labels", labels), ("reporter", intensity)):
        if array is not None:
            sources[key] = {"name": (names or {}).get(key), "path": (paths or {}).get(key),
                            **fingerprint(array)}
    manifest = {"written_by": f"napari-pfsdm {writer_name().split()[-1]}", "format": FORMAT,
                "files": files, "sources": sources, "rows": len(table),
                "checksums": _checksums(folder, files)}
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
    from .io import read_table

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
    form = manifest.get("format") if isinstance(manifest, dict) else None
    if not _written_by_us(manifest_path) or form != FORMAT:
        raise InputError(f"{manifest_path} was not written by this napari-pfsdm (format "
                         f"{form!r}); save the analysis again")
    _check_manifest(manifest, manifest_path)
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
    _warn_changed(folder, manifest)
    table = _read(folder / files["features"], read_table)
    from .analysis.tables import check_table_cells
    from .core.table_schema import check_feature_table

    where = str(folder / files["features"])
    if not {"frame", "label"} <= set(table.columns):
        raise InputError(f"{where} has no frame and label columns: it is not the analysis's "
                         "table; save the analysis again")
    check_feature_table(table, ["shape"], where=where)  # its columns and cells, as measured
    check_table_cells(table, ["shape"], where=where)
    if len(table) != manifest.get("rows", len(table)):
        raise InputError(f"{folder / files['features']} holds {len(table)} rows but the "
                         f"analysis saved {manifest['rows']}: it is not this analysis's table "
                         "(replaced or edited?); save the analysis again")
    if labels is not None:  # the table's objects are the labels' objects, frame by frame
        from .analysis.label_images import check_labels_match

        check_labels_match(labels, table, where=f"the labels of {folder}")
    pca, explained = {}, {}
    for key, name in files.items():
        if key.startswith("pca_"):
            pca[key[4:]], explained[key[4:]] = _read_scores(folder / name, table)
    groups = _read_groups(folder / files["groups"], table)
    boxes = _read_boxes(folder / files["boxes"], table, labels)
    return SavedAnalysis(table, pca, groups, boxes, manifest, explained, labels)


# ------------------------------------------------------------------------------------------
# every file of a saved folder checked as it is read: refused or read with a warning in
# words, never a raw exception
# ------------------------------------------------------------------------------------------

def _checksums(folder: Path, files: dict) -> dict[str, list]:
    """Size and SHA-256 of each file of the analysis and of its sidecar, as saved."""
    from .io.sidecar import sidecar_path, size_and_digest

    out = {}
    for name in files.values():
        for path in (folder / name, sidecar_path(folder / name)):
            if path.is_file():
                out[path.name] = list(size_and_digest(path))
    return out


def _check_manifest(manifest: Any, path: Path) -> None:
    """Refuse, in words, a manifest whose fields are not what :func:`save_analysis` writes:
    ``files`` names of files inside the folder (never a path out of it) for the features,
    groups and boxes; ``sources`` a mapping of fingerprints; ``rows`` a count."""
    def bad(what: str) -> InputError:
        return InputError(f"{path} is damaged or was edited ({what}); save the analysis again")

    if not isinstance(manifest, dict):
        raise bad("it is not a set of named fields")
    files = manifest.get("files")
    if not isinstance(files, dict) or not {"features", "groups", "boxes"} <= set(files):
        raise bad("its 'files' do not name the features, groups and boxes tables")
    for key, name in files.items():
        if (not isinstance(name, str) or not name or Path(name).name != name
                or name in (".", "..") or not name.endswith((".csv", ".parquet"))):
            raise bad(f"its file {key!r} is {name!r}, not a table's name inside the folder")
    sources = manifest.get("sources", {})
    if not isinstance(sources, dict) or not all(
            isinstance(v, dict) and isinstance(v.get("shape"), list)
            and isinstance(v.get("sha256"), str) for v in sources.values()):
        raise bad("its 'sources' are not the data's fingerprints")
    rows = manifest.get("rows", 0)
    if not isinstance(rows, int) or isinstance(rows, bool) or rows < 0:
        raise bad(f"its row count is {rows!r}")
    checks = manifest.get("checksums", {})
    if not isinstance(checks, dict) or not all(
            isinstance(v, list) and len(v) == 2 for v in checks.values()):
        raise bad("its checksums are not sizes and SHA-256 digests")


def _warn_changed(folder: Path, manifest: dict) -> None:
    """Say (a ``UserWarning``) which files changed since the analysis was saved: they are
    read with their own checks, and refused when they do not fit the analysis."""
    import warnings

    from .io.sidecar import size_and_digest

    changed = []
    for name, (size, digest) in (manifest.get("checksums") or {}).items():
        path = folder / name
        if not path.is_file() or list(size_and_digest(path)) != [size, digest]:
            changed.append(name)
    if changed:
        warnings.warn(f"{', '.join(changed)} in {folder} changed since the analysis was "
                      "saved (edited by hand or by another program?); opened as they are now",
                      UserWarning, stacklevel=3)


def _read(path: Path, reader: Any) -> pd.DataFrame:
    """A table of the folder read by ``reader``; any reader's error in words naming it."""
    try:
        return reader(path)
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - a damaged file: pandas', pyarrow's, json's
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"{path} cannot be read ({first[:160]}); save the analysis "
                         "again") from None


def _keys(table: pd.DataFrame) -> pd.MultiIndex:
    cols = [c for c in ("movie", "frame", "label") if c in table.columns]
    return pd.MultiIndex.from_frame(table[cols].astype(str))


def _whole(df: pd.DataFrame, cols: list[str], path: Path) -> None:
    """Refuse a table whose ``cols`` are not whole numbers (an edited cell), naming it."""
    for c in cols:
        if c not in df.columns:
            raise InputError(f"{path} has no column {c!r}: it is not the analysis's file; "
                             "save the analysis again")
        v = pd.to_numeric(df[c], errors="coerce").to_numpy(float)
        if not (np.isfinite(v).all() and np.array_equal(v, np.round(v))):
            raise InputError(f"{path}: column {c!r} holds values that are not whole numbers "
                             "(an edited cell?); save the analysis again")


def _read_scores(path: Path, table: pd.DataFrame) -> tuple[pd.DataFrame, list[float]]:
    """A channel's PCA scores: rows of the table's objects, numbers in every PC column."""
    from .io import read_table

    scores = _read(path, read_table)
    _whole(scores, [c for c in ("frame", "label") if c in table.columns], path)
    if _keys(scores).has_duplicates:
        raise InputError(f"{path} has two rows of scores for one object (an edited file?); "
                         "save the analysis again")
    unknown = ~_keys(scores).isin(_keys(table))
    if unknown.any():
        row = scores[unknown].iloc[0]
        raise InputError(f"{path} has scores of objects the analysis's table does not have "
                         f"(frame {row['frame']}, label {row['label']}, and "
                         f"{int(unknown.sum()) - 1} more): it is not this analysis's file; "
                         "save the analysis again")
    pcs = [c for c in scores.columns if "_PC" in str(c)]
    if not pcs or not all(pd.api.types.is_numeric_dtype(scores[c]) for c in pcs):
        raise InputError(f"{path} has no principal-component columns of numbers (an edited "
                         "file?); save the analysis again")
    ratios = (scores.attrs.get("pfsdm") or {}).get("explained_variance_ratio", [])
    try:
        ratios = [float(r) for r in ratios]
    except (TypeError, ValueError):
        raise InputError(f"the sidecar of {path} holds explained variances that are not "
                         "numbers; save the analysis again") from None
    return scores, ratios


def _read_groups(path: Path, table: pd.DataFrame) -> dict:
    """Object → group: objects are whole numbers (track ids or labels) of the table; groups
    of objects it does not have are left out with a warning."""
    import warnings

    from .core.table_schema import TRACK_COLUMN
    from .io import read_table

    g = _read(path, read_table)
    if not len(g):
        return {}
    _whole(g, ["object"], path)
    if "group" not in g.columns:
        raise InputError(f"{path} has no column 'group': it is not the analysis's groups "
                         "file; save the analysis again")
    groups = {int(o): str(v) for o, v in zip(g["object"], g["group"], strict=True)}
    key = TRACK_COLUMN if TRACK_COLUMN in table.columns else "label"
    unknown = sorted(set(groups) - set(table[key].astype(int)))
    if unknown:
        warnings.warn(f"{path} gives groups to {len(unknown)} object(s) the table does not "
                      f"have ({', '.join(map(str, unknown[:5]))}); they are left out",
                      UserWarning, stacklevel=3)
        groups = {o: v for o, v in groups.items() if o not in set(unknown)}
    return groups


def _read_boxes(path: Path, table: pd.DataFrame, labels: Any) -> dict:
    """``(frame, label)`` → bounding box, for the table's objects, inside the labels."""
    import warnings

    from .io import read_table

    b = _read(path, read_table)
    starts = [c for c in b.columns if str(c).startswith("start")]
    _whole(b, ["frame", "label", *starts, *("stop" + str(c)[5:] for c in starts)], path)
    known = set(zip(table["frame"].astype(int), table["label"].astype(int), strict=True))
    shape = None if labels is None else tuple(labels.shape[-len(starts):]) if starts else ()
    boxes, dropped = {}, 0
    for row in b.itertuples(index=False):
        values = row._asdict()
        first = [int(values[c]) for c in starts]
        last = [int(values["stop" + c[5:]]) for c in starts]
        key = (int(values["frame"]), int(values["label"]))
        inside = shape is None or all(0 <= a < z <= n for a, z, n in
                                      zip(first, last, shape, strict=True))
        if key not in known or (first and first[0] >= 0 and not inside):
            dropped += 1
            continue
        boxes[key] = None if not first or first[0] < 0 else tuple(
            slice(a, z) for a, z in zip(first, last, strict=True))
    if dropped:
        warnings.warn(f"{path}: {dropped} bounding box(es) of objects the table does not have "
                      "or outside the labels are left out (they are found again when needed)",
                      UserWarning, stacklevel=3)
    return boxes
