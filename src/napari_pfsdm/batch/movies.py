"""Which movies: found on disk, named, and paired with their reporters.

:func:`find_movies` expands a file, folder or glob into movie paths (TIFF files, Zarr stores),
:func:`movie_name` names a movie for the ``movie`` column (:func:`unique_names` when two
would share a name), and :func:`pair_movies` matches label movies with intensity movies by
name into :class:`Movie` records; the same movie given twice is refused in plain words.
"""

from __future__ import annotations

import glob
import os
import re
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError

__all__ = ["TIFF_SUFFIXES", "Movie", "find_movies", "is_tiff", "is_zarr", "match_name",
           "movie_name", "pair_movies", "unique_names"]

TIFF_SUFFIXES = (".tif", ".tiff")
_ZARR_MARKERS = (".zarray", ".zgroup", "zarr.json")


def is_zarr(path: Path) -> bool:
    """Whether ``path`` is a Zarr store: a folder named ``.zarr`` or holding Zarr's metadata."""
    return path.is_dir() and (
        path.suffix.lower() == ".zarr" or any((path / m).exists() for m in _ZARR_MARKERS)
    )


def is_tiff(path: Path) -> bool:
    """Whether ``path`` is a TIFF file (by its name)."""
    return path.is_file() and path.suffix.lower() in TIFF_SUFFIXES


def movie_name(path: str | os.PathLike) -> str:
    """Name of a movie for the ``movie`` column: the file name without ``.ome.tif`` etc."""
    name = Path(path).name
    for suffix in (".ome.tiff", ".ome.tif", ".ome.zarr", ".tiff", ".tif", ".zarr"):
        if name.lower().endswith(suffix):
            return name[: -len(suffix)]
    return name


def match_name(name: str, names: list[str]) -> str | None:
    """The entry of ``names`` (as a lab writes movies in a spreadsheet: with or without a
    folder and an extension such as ``.tif``, in any case) that names the movie ``name``, or
    None; two entries that would both name it are refused.

    Examples
    --------
    >>> match_name("e01", ["plate1/E01.tif", "e02.tif"])
    'plate1/E01.tif'
    >>> match_name("e01", ["e1.tif"]) is None
    True
    """
    from ..analysis.groups import match_movies

    hits = [n for n, movie in match_movies(list(names), [name]).items() if movie == name]
    if len(hits) > 1:
        raise InputError(f"{', '.join(map(repr, hits))} all name the movie {name!r}: name each "
                         "movie once")
    return hits[0] if hits else None


def find_movies(spec: str | os.PathLike | list) -> list[Path]:
    """Expand a file, a folder, a glob pattern or a list of these into movie paths.

    A folder that is itself a Zarr store is one movie; any other folder contributes the
    TIFF files and Zarr stores directly inside it. The result is sorted by name.
    """
    if isinstance(spec, (list, tuple)):
        out: list[Path] = []
        for s in spec:
            out.extend(find_movies(s))
        return out
    text = str(spec)
    p = Path(text)
    if any(ch in text for ch in "*?["):
        hits = [Path(h) for h in sorted(glob.glob(text))]
        movies = [h for h in hits if is_zarr(h) or is_tiff(h)]
        if not movies:
            raise InputError(f"no TIFF or Zarr movie matches {text}")
        return movies
    if not p.exists():
        raise InputError(f"{p}: no such file or folder")
    if is_zarr(p) or p.is_file():
        return [p]
    if not p.is_dir():
        raise InputError(f"{p} is not a file or a folder (a pipe or a device?); give a TIFF "
                         "file, a Zarr store or a folder of them")
    movies = sorted(c for c in p.iterdir() if is_zarr(c) or is_tiff(c))
    if not movies:
        raise InputError(f"the folder {p} holds no TIFF (.tif/.tiff) or Zarr (.zarr) movie")
    return movies


_ROLE_WORDS = (
    "labels", "label", "masks", "mask", "segmentation", "seg", "intensity", "image", "img",
    "reporter", "raw",
)
_ROLE_RE = re.compile(r"(^|[_\-. ])(" + "|".join(_ROLE_WORDS) + r")(?=$|[_\-. ])", re.IGNORECASE)


def _pair_key(path: Path) -> str:
    return _ROLE_RE.sub(r"\1", movie_name(path)).strip("_-. ").lower()


@dataclass(frozen=True)
class Movie:
    """One movie of a batch: its name, its labels and (optionally) its intensity file."""

    name: str
    labels: Path
    intensity: Path | None = None


def _refuse_twice(paths: list[Path], what: str) -> None:
    """Refuse the same file (or store) given twice: its rows would be doubled."""
    seen: dict[Path, Path] = {}
    for p in paths:
        key = p.resolve()
        if key in seen:
            same = f"{seen[key]}" + (f" and {p}" if str(p) != str(seen[key]) else " twice")
            raise InputError(
                f"the same {what} movie is given twice ({same}): its objects would be "
                "measured and counted twice. Give each movie once")
        seen[key] = p


def unique_names(paths: list[Path]) -> list[str]:
    """One movie name per path (the ``movie`` column): the file name without its suffix, or,
    where files share it in different folders, as few of the folders before it as tell them
    apart (``plateA/e1``, ``plateB/e1``).

    Examples
    --------
    >>> unique_names([Path("/data/2024/plateA/e1.tif"), Path("/data/2024/plateB/e1.tif"),
    ...               Path("/data/2024/plateB/e2.tif")])
    ['plateA/e1', 'plateB/e1', 'e2']

    Raises
    ------
    InputError
        Two files would still get the same name (``e1.tif``, ``e1.tiff`` and ``e1.zarr`` in
        one folder): their rows could not be told apart, so they are refused by name.
    """
    names = [movie_name(p) for p in paths]
    if len(set(names)) != len(names):  # the same file name in several folders
        names = _short_names(paths, names)
    groups: dict[str, list[Path]] = {}
    for n, p in zip(names, paths, strict=True):
        groups.setdefault(n, []).append(p)
    clash = {n: ps for n, ps in groups.items() if len(ps) > 1}
    if clash:
        n, ps = next(iter(clash.items()))
        more = f" (and {len(clash) - 1} more such name{'s' if len(clash) > 2 else ''})" \
            if len(clash) > 1 else ""
        raise InputError(
            f"{', '.join(str(p) for p in ps)} would all be the movie {movie_name(ps[0])!r}"
            f"{more}: their rows "
            "could not be told apart in the table. Rename them so that their names differ "
            "before the suffix, or measure them into separate tables")
    return names


def _short_names(paths: list[Path], names: list[str]) -> list[str]:
    """Each name that several paths share, with as many of its folders as tell them apart."""
    out = list(names)
    shared = {n for n in names if names.count(n) > 1}
    for name in shared:
        at = [i for i, n in enumerate(names) if n == name]
        parents = [Path(os.path.abspath(paths[i])).parent.parts for i in at]
        for depth in range(1, max(len(p) for p in parents) + 1):
            tried = ["/".join((*p[len(p) - depth:], name)) for p in parents]
            if len(set(tried)) == len(tried):
                break
        for i, t in zip(at, tried, strict=True):
            out[i] = t
    return out


def pair_movies(labels: list[Path], intensity: list[Path] | None = None) -> list[Movie]:
    """Match label movies with intensity movies.

    One label movie pairs with one intensity movie whatever their names. Otherwise movies
    pair by name, ignoring words such as ``labels``, ``mask``, ``seg``, ``intensity``,
    ``image`` (``gastruloid01_labels.tif`` ↔ ``gastruloid01_reporter.tif``).

    A file that is among the intensity movies is not a label movie, so that a folder holding
    both (``movies/`` with ``movies/*_reporter.tif``) can be given as the labels.
    """
    labels = [Path(p) for p in labels]
    _refuse_twice(labels, "label")
    if intensity:
        intensity = [Path(q) for q in intensity]
        _refuse_twice(intensity, "intensity")
        given = {Path(q).resolve() for q in intensity}
        kept = [p for p in labels if Path(p).resolve() not in given]
        labels = kept or labels  # the same single file as both: leave it to the checks
    names = unique_names(labels)
    if not intensity:
        return [Movie(n, p) for n, p in zip(names, labels, strict=True)]
    if len(labels) == 1 and len(intensity) == 1:
        return [Movie(names[0], labels[0], intensity[0])]
    by_key: dict[str, Path] = {}
    for q in intensity:
        k = _pair_key(q)
        if k in by_key:
            raise InputError(f"two intensity movies have the same name: {by_key[k]} and {q}")
        by_key[k] = q
    out = []
    missing = []
    for n, p in zip(names, labels, strict=True):
        q = by_key.pop(_pair_key(p), None)
        if q is None:
            missing.append(p.name)
        out.append(Movie(n, p, q))
    if missing or by_key:
        extra = ", ".join(sorted(q.name for q in by_key.values()))
        raise InputError(
            "cannot pair labels with intensity movies by name: "
            + (f"no intensity for {', '.join(missing)}" if missing else "")
            + ("; " if missing and extra else "")
            + (f"no labels for {extra}" if extra else "")
            + " (name them alike, e.g. movie01_labels.tif and movie01_intensity.tif)"
        )
    return out
