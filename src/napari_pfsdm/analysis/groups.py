"""Objects' groups as a lab keeps them: a CSV of any grouping columns, movies named as the lab
names them.

A groups file has one row per object or per movie: key columns (``movie``, ``label``,
``track_id``: which objects) and one or more grouping columns (``group``, ``clone``,
``genotype``, ``lab``, …). The table's ``group`` column is the chosen one
(``--group-column``; ``group`` when the file has it, or its only grouping column); the others
travel with it. Movies match whatever the lab wrote: with or without a folder and an
extension such as ``.tif``, in any case (:func:`movie_key`). A file whose rows name no object
of the table is refused with examples of both sides' names.

Examples
--------
>>> import pandas as pd
>>> table = pd.DataFrame({"movie": ["e01", "e01", "e02"], "label": [1, 2, 1]})
>>> lab = pd.DataFrame({"movie": ["plate1/E01.tif", "e02.tif"], "clone": ["A", "B"],
...                     "lab": ["x", "y"]})
>>> out = attach_groups(table, groups_table(lab, "clone"))
>>> out[["movie", "label", "group", "clone", "lab"]].values.tolist()
[['e01', 1, 'A', 'A', 'x'], ['e01', 2, 'A', 'A', 'x'], ['e02', 1, 'B', 'B', 'y']]
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from ..core.table_options import carry_options
from ..core.table_schema import TRACK_COLUMN
from ..errors import InputError

__all__ = ["KEY_COLUMNS", "MOVIE_SUFFIXES", "attach_groups", "group_columns", "groups_table",
           "match_movies", "movie_key", "read_groups", "unmatched_groups"]

#: The columns of a groups file that say which objects a row is about.
KEY_COLUMNS = ("movie", "label", TRACK_COLUMN)
#: The endings of movie files, left out when a lab's movie name is matched.
MOVIE_SUFFIXES = (".ome.tiff", ".ome.tif", ".ome.zarr", ".tiff", ".tif", ".zarr", ".nd2",
                  ".czi", ".lif", ".png", ".jpg")


def movie_key(name: object) -> tuple[str, ...]:
    """How a movie's name is matched: its path parts, the last without a movie file's ending,
    in lower case.

    Examples
    --------
    >>> movie_key("plate1\\\\E01.ome.tif"), movie_key("e01")
    (('plate1', 'e01'), ('e01',))
    """
    parts = [p for p in str(name).strip().replace("\\", "/").lower().split("/") if p]
    if not parts:
        return ()
    for suffix in MOVIE_SUFFIXES:
        if parts[-1].endswith(suffix):
            parts[-1] = parts[-1][: -len(suffix)]
            break
    return tuple(parts)


def match_movies(names: list[str], movies: list[str]) -> dict[str, str]:
    """Which of the table's ``movies`` each of a groups file's movie ``names`` is: the one
    whose path parts end with the name's, or whose parts the name's end with (``e01.tif``,
    ``plate1/E01`` and ``/data/plate1/e01.tif`` all name the movie ``plate1/e01``); a name
    that fits several movies is refused, naming them; one that fits none is left out.

    Examples
    --------
    >>> match_movies(["E01.tif", "plateB/e1"], ["e01", "plateA/e1", "plateB/e1"])
    {'E01.tif': 'e01', 'plateB/e1': 'plateB/e1'}
    """
    keys = {m: movie_key(m) for m in movies}
    out = {}
    for name in dict.fromkeys(names):
        key = movie_key(name)
        hits = [m for m, k in keys.items() if key and k and
                (k[-len(key):] == key or key[-len(k):] == k)]
        if len(hits) > 1:
            raise InputError(f"the movie {name!r} of the groups file could be any of "
                             f"{', '.join(hits[:4])}: name it with its folder, e.g. "
                             f"{hits[0]!r}")
        if hits:
            out[name] = hits[0]
    return out


def group_columns(groups: pd.DataFrame) -> list[str]:
    """The grouping columns of a groups table: all but its keys."""
    return [c for c in groups.columns if c not in KEY_COLUMNS]


def read_groups(path: str | os.PathLike, group_column: str | None = None) -> pd.DataFrame:
    """Read a groups CSV (module docstring) into :func:`groups_table`'s form.

    Examples of valid files::

        label,group            movie,clone,lab             movie,label,group
        1,single-axis          clone1_a.tif,clone1,lab2    plate1,3,multi-axes
        2,multi-axes           clone2_b.tif,clone2,lab2

    Raises
    ------
    InputError
        A missing or unreadable file, no key column, no grouping column (or several without
        ``group_column``), a ``label`` that is not a whole number, or two rows for the same
        object.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{p}: no such groups file" if not p.exists() else
                         f"{p} is not a file (a folder or a pipe?); give a groups CSV file")
    try:
        groups = pd.read_csv(p, dtype=str, comment="#", keep_default_na=False,
                             encoding="utf-8-sig")
    except pd.errors.EmptyDataError:
        raise InputError(f"the groups file {p} is empty; write a header such as movie,group "
                         "and one row per movie or object") from None
    except (pd.errors.ParserError, UnicodeDecodeError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"the groups file {p} is not a readable CSV table ({first}); save it "
                         "as CSV (UTF-8) with a header such as movie,group") from None
    return groups_table(groups, group_column, where=f"the groups file {p.name}")


def groups_table(groups: pd.DataFrame, group_column: str | None = None, *,
                 where: str = "the groups") -> pd.DataFrame:
    """A groups table as the package uses it: the key columns as text (labels as whole
    numbers), ``group`` (the chosen grouping column's values) and every grouping column;
    rows with an empty key or group left out with a warning."""
    groups = groups.copy()
    groups.columns = [str(c).strip() for c in groups.columns]
    lower = {c.lower(): c for c in groups.columns}
    groups = groups.rename(columns={lower[k]: k for k in KEY_COLUMNS if k in lower})
    keys = [k for k in KEY_COLUMNS if k in groups.columns]
    others = group_columns(groups)
    if not keys:
        raise InputError(
            f"{where} has no 'movie', 'label' or 'track_id' column to say which objects a row "
            f"is about (its columns: {', '.join(groups.columns)}), e.g. movie,group then "
            "e01.tif,control")
    if group_column is not None:
        chosen = lower.get(group_column.strip().lower())
        if chosen is None or chosen in KEY_COLUMNS:
            raise InputError(f"{where} has no column {group_column!r} to group by; its "
                             f"grouping columns are {', '.join(others) or 'none'}")
    elif "group" in lower and lower["group"] not in KEY_COLUMNS:
        chosen = lower["group"]
    elif len(others) == 1:
        chosen = others[0]
    else:
        raise InputError(
            f"{where} has {'no grouping column' if not others else 'several grouping columns'}"
            f"{' (' + ', '.join(others) + ')' if others else ''}: "
            + ("choose one with --group-column (e.g. --group-column " + others[0] + ")"
               if others else "add one, e.g. a 'group' column"))
    out = groups[keys].copy()
    out["group"] = groups[chosen].astype(str).str.strip()
    for c in others:
        if c != "group":
            out[c] = groups[c].astype(str).str.strip()
    blank = (out[keys + ["group"]].apply(lambda col: col.str.strip() == "")).any(axis=1)
    if blank.any():
        rows = [str(i + 2) for i in np.flatnonzero(blank.to_numpy())]  # +2: header, from 1
        warnings.warn(
            f"{where}: row{'s' if len(rows) > 1 else ''} {', '.join(rows[:10])}"
            f"{' …' if len(rows) > 10 else ''} (counting the header as row 1) left out: a key "
            "or its group is empty", UserWarning, stacklevel=3)
        out = out[~blank.to_numpy()]
    for key in ("label", TRACK_COLUMN):
        if key not in keys:
            continue
        try:  # exact, whatever the size (ids up to 2**64 - 1): Python's int, not int64
            out[key] = [str(int(v)) for v in out[key].str.strip()]
        except ValueError:
            raise InputError(f"The {key!r} column of {where} must hold whole numbers.") \
                from None
    matched = out.assign(movie=out["movie"].map(movie_key)) if "movie" in keys else out
    if matched.duplicated(keys).any():
        raise InputError(f"{where} gives several rows to the same {'/'.join(keys)}")
    return out.reset_index(drop=True)


def _keyed(frame: pd.DataFrame, keys: list[str], movies: dict | None = None
           ) -> pd.DataFrame:
    """The key columns as matched, as text: the groups file's movies as the table's movies
    they name (``movies``, :func:`match_movies`; "" for none)."""
    out = pd.DataFrame(index=frame.index)
    for k in keys:
        col = frame[k].astype(str)
        out["_key_" + k] = col.map(lambda v: movies.get(v, "")) if (
            k == "movie" and movies is not None) else col
    return out


def attach_groups(table: pd.DataFrame, groups: pd.DataFrame) -> pd.DataFrame:
    """A feature table with ``group`` and the groups' other grouping columns (objects without
    a group get ``""``); refused when no row of ``groups`` names an object of the table,
    with examples of both sides' names."""
    keys = [k for k in KEY_COLUMNS if k in groups.columns]
    missing = [k for k in keys if k not in table.columns]
    if missing:
        raise InputError(
            f"the groups file has a {missing[0]!r} column but the feature table has none")
    extra = [c for c in groups.columns if c not in keys]
    left = table.drop(columns=[c for c in extra if c in table.columns
                               and c in ("group", *group_columns(groups))], errors="ignore")
    movies = match_movies(groups["movie"].astype(str).tolist(),
                          table["movie"].astype(str).unique().tolist()) \
        if "movie" in keys else None
    left_keys = _keyed(left, keys)
    right = pd.concat([_keyed(groups, keys, movies), groups[extra]], axis=1)
    merged = pd.concat([left.reset_index(drop=True), left_keys.reset_index(drop=True)],
                       axis=1).merge(right, on=list(left_keys.columns), how="left")
    out = merged.drop(columns=list(left_keys.columns))
    for c in extra:
        out[c] = out[c].fillna("")
    if len(table) and len(groups) and not (out["group"] != "").any():
        raise InputError(_no_match(table, groups, keys))
    unmatched = unmatched_groups(table, groups, movies)
    if unmatched:
        warnings.warn(
            f"{len(unmatched)} row{'s' if len(unmatched) > 1 else ''} of the groups file "
            f"match{'es' if len(unmatched) == 1 else ''} no object of the table and "
            f"{'are' if len(unmatched) > 1 else 'is'} not used: {'; '.join(unmatched[:5])}"
            f"{' …' if len(unmatched) > 5 else ''} (check the movie names and labels)",
            UserWarning, stacklevel=2)
    return carry_options(table, out)


def _no_match(table: pd.DataFrame, groups: pd.DataFrame, keys: list[str]) -> str:
    """Why a groups file names nothing of the table, with examples of both sides."""
    def shown(frame: pd.DataFrame) -> str:
        rows = frame[keys].astype(str).drop_duplicates().head(3)
        return "; ".join(", ".join(f"{k} {v}" for k, v in zip(keys, r, strict=True))
                         for r in rows.itertuples(index=False))

    return (f"no row of the groups file names an object of the table: the groups file has "
            f"{shown(groups)} …, the table has {shown(table)} …. Check the movie names (they "
            "match with or without folder and extension, in any case) and the labels")


def unmatched_groups(table: pd.DataFrame, groups: pd.DataFrame,
                     movies: dict | None = None) -> list[str]:
    """The rows of a groups table that name no object of ``table``, in words
    (``"movie e9, label 3 -> single-axis"``).

    Examples
    --------
    >>> t = pd.DataFrame({"label": [1, 2]})
    >>> unmatched_groups(t, pd.DataFrame({"label": ["1", "7"], "group": ["a", "b"]}))
    ['label 7 -> b']
    """
    keys = [k for k in KEY_COLUMNS if k in groups.columns and k in table.columns]
    if not keys or not len(groups):
        return []
    if "movie" in keys and movies is None:
        movies = match_movies(groups["movie"].astype(str).tolist(),
                              table["movie"].astype(str).unique().tolist())
    have = set(map(tuple, _keyed(table, keys).to_numpy().tolist()))
    wanted = _keyed(groups, keys, movies).to_numpy().tolist()
    out = []
    for key, row in zip(wanted, groups[keys + ["group"]].itertuples(index=False),
                        strict=True):
        if tuple(key) not in have:
            out.append(", ".join(f"{k} {v}" for k, v in zip(keys, row[:-1], strict=True))
                       + f" -> {row[-1]}")
    return out
