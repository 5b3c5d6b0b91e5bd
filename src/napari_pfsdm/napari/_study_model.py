"""The study dock's state and computations, without Qt or a viewer: several Labels layers
measured as one study (:func:`napari_pfsdm.analysis.study.measure_study`), keyed by
(movie, frame, label) everywhere.

What the dock asks of the viewer is passed in as plain values (layer names, shapes, scales,
arrays), so that everything here is tested without napari:

- :func:`reporter_for`: the Image layer that is a movie's reporter (its name the movie's name
  and a word, its shape the movie's) or none; never another movie's.
- :func:`parse_times`, :func:`times_per_movie`: the frames' times from a text or a times file.
- :func:`name_groups`: groups from the movies' names.
- :class:`Study`: the table, its shape space (one PCA over every movie's rows), each object's
  trajectory, a measure over time per group with the group statistics, the nearest shapes of
  an object across movies, the prediction of the groups, and each movie's ``layer.features``.

Examples
--------
>>> reporter_for("org01", (3, 8, 8), [("org01 reporter", (3, 8, 8)),
...                                   ("org02 reporter", (3, 8, 8))])
'org01 reporter'
>>> parse_times("2, 5,8 ;10")
[2.0, 5.0, 8.0, 10.0]
>>> name_groups(["c1_a", "c1 b", "c2_a"], "prefix")
{'c1_a': 'c1', 'c1 b': 'c1', 'c2_a': 'c2'}
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from ..errors import InputError

#: How groups are taken from the movies' names (the form's words → :func:`name_groups`').
NAME_RULES = {"none": "none", "first word of the name": "prefix"}
#: Up to this many movies the form names each one's reporter; beyond, it counts them.
NAMED_REPORTERS = 4
#: What separates a movie's name from the word that makes an Image layer its reporter.
SEPARATORS = (" ", "_", "-")
#: The measures offered first in the Over time tab (then every other number).
FIRST_MEASURES = ("area", "perimeter", "circularity", "eccentricity", "solidity",
                  "shape_PC1", "shape_PC2")
#: The group statistics' summaries offered (form's words → object_values' arguments).
STAT_CHOICES = ("at the last time", "slope")


# --------------------------------------------------------------------------- the form's inputs
def reporter_for(movie: str, shape: Sequence[int], images: Sequence[tuple[str, Sequence[int]]],
                 movies: Sequence[str] = ()) -> str | None:
    """The Image layer that is ``movie``'s reporter: its name is the movie's name followed by a
    separator (:data:`SEPARATORS`) and more (``org01 reporter``, ``org01_reporter``), or the
    movie's name itself, and its shape is the movie's; None when no image is.

    An image whose name also starts with a longer movie name of ``movies`` is that movie's
    (``org01_b reporter`` is never ``org01``'s). Among several, one whose name says
    ``reporter`` first, then the first.

    >>> reporter_for("a", (2, 4, 4), [("a reporter", (2, 4, 5)), ("ab reporter", (2, 4, 4))])
    >>> reporter_for("a", (2, 4, 4), [("a_b gfp", (2, 4, 4))], movies=["a", "a_b"])
    """
    def owner(name: str) -> str | None:  # the longest movie name the image's name extends
        low = name.lower()
        fits = [m for m in {*movies, movie} if low == m.lower()
                or any(low.startswith(m.lower() + s) for s in SEPARATORS)]
        return max(fits, key=len) if fits else None

    hits = [name for name, s in images
            if tuple(int(n) for n in s) == tuple(int(n) for n in shape) and owner(name) == movie]
    hits.sort(key=lambda n: "reporter" not in n.lower())
    return hits[0] if hits else None


def reporter_words(found: Mapping[str, str | None]) -> str:
    """What the form says of the movies' reporters: each one's (``org01 ← org01 reporter``,
    ``org02: none``), or beyond :data:`NAMED_REPORTERS` movies how many have one.

    >>> reporter_words({"a": "a reporter", "b": None})
    'a ← a reporter; b: none'
    >>> reporter_words({f"m{i}": (f"m{i} gfp" if i < 2 else None) for i in range(6)})
    '2 of 6 movies have a reporter: m0 ← m0 gfp; m1 ← m1 gfp (hover for each)'
    """
    if not found:
        return "(choose movies)"
    if len(found) <= NAMED_REPORTERS:
        return "; ".join(f"{m} ← {r}" if r else f"{m}: none" for m, r in found.items())
    have = {m: r for m, r in found.items() if r}
    named = "; ".join(f"{m} ← {r}" for m, r in list(have.items())[:2])
    return (f"{len(have)} of {len(found)} movies have a reporter"
            + (f": {named}{' …' if len(have) > 2 else ''}" if have else "") + " (hover for each)")


def parse_times(text: str) -> list[float]:
    """The times written in the form: numbers separated by commas, semicolons or spaces."""
    from ._physical import parse_numbers

    return list(parse_numbers(text, "the times", "2,5,8,10"))


def times_per_movie(file_times: Mapping[str, Mapping[int, float]],
                    frames: Mapping[str, int]) -> dict[str, list[float]]:
    """Each movie's times from a times file (``{movie: {frame: time}}``,
    :func:`napari_pfsdm.io.times_file.read_times_file`), its movie names matched to the
    layers' as a groups file's are (with or without folder and extension); refused in words
    when a movie or a frame has no time."""
    from ..analysis.groups import match_movies

    named = {movie: name for name, movie in match_movies(list(file_times), list(frames)).items()}
    out = {}
    for movie, n in frames.items():
        if movie not in named:
            shown = ", ".join(sorted(file_times)[:5])
            raise InputError(f"the times file names no movie {movie!r} (it names {shown}): "
                             "give every movie's frames")
        by_frame = file_times[named[movie]]
        absent = [t for t in range(n) if t not in by_frame]
        if absent:
            raise InputError(f"the times file has no time for frame {absent[0]} of {movie} "
                             f"({n} frames): give one per frame")
        out[movie] = [float(by_frame[t]) for t in range(n)]
    return out


def name_groups(movies: Sequence[str], rule: str) -> dict[str, str]:
    """Each movie's group from its name: ``"prefix"`` the part before the first ``_`` or
    space; ``"none"`` no groups (an empty mapping)."""
    if rule == "none":
        return {}
    if rule != "prefix":
        raise InputError(f"unknown rule for groups from names: {rule!r}")
    return {m: re.split(r"[_ ]", m, maxsplit=1)[0] for m in movies}


def pixel_size_of(scale: Sequence[float]) -> float:
    """A movie's pixel side from its layer's ``scale`` (the last two axes; square pixels)."""
    y, x = (float(v) for v in scale[-2:])
    if not np.isclose(y, x, rtol=1e-6):
        raise InputError(f"the layer's pixels are not square (scale {y:g} × {x:g}): the "
                         "study measures square pixels; resample the movie or set equal "
                         "scales")
    if not (np.isfinite(x) and x > 0):
        raise InputError(f"the layer's pixel size {x:g} is not a positive number")
    return x


@dataclass
class StudyInput:
    """What one Run measures."""

    movies: dict[str, Any]
    reporters: dict[str, Any] = field(default_factory=dict)
    times: dict[str, list[float]] | None = None
    time_unit: str | None = None
    pixel_sizes: dict[str, float] | None = None
    space_unit: str | None = None
    groups: pd.DataFrame | None = None  # a groups file's table (groups_table)
    name_groups: dict[str, str] = field(default_factory=dict)
    options: dict[str, Any] = field(default_factory=dict)


def run_study(given: StudyInput, progress: Callable[[int, int, str], None] | None = None
              ) -> Study:
    """Measure the study (in a worker) and make its :class:`Study`."""
    from ..analysis.groups import attach_groups
    from ..analysis.study import measure_study

    table = measure_study(given.movies, given.reporters, times=given.times,
                          time_unit=given.time_unit, pixel_sizes=given.pixel_sizes,
                          space_unit=given.space_unit, progress=progress, **given.options)
    if given.groups is not None:
        table = attach_groups(table, given.groups)
    elif given.name_groups:
        from ..core.table_options import carry_options

        table = carry_options(table, table.assign(
            group=table["movie"].map(given.name_groups).fillna("").astype(str)))
    return Study(table, dict(given.movies))


# --------------------------------------------------------------------------- the results
class Study:
    """One Run's results: the table of every movie and what the tabs show of it.

    Parameters
    ----------
    table : DataFrame
        :func:`~napari_pfsdm.analysis.study.measure_study`'s table (``movie`` first), with a
        ``group`` column when the study has groups.
    movies : mapping
        Movie name → its label movie (T × Y × X), for the outlines of the Similar tab.
    """

    def __init__(self, table: pd.DataFrame, movies: Mapping[str, Any]) -> None:
        from ..analysis.reduction import object_ids, pca_scores

        self.table = table.reset_index(drop=True)
        self.movies = dict(movies)
        self.objects = object_ids(self.table).to_numpy()
        errors = self.table["error"].fillna("").astype(str) if "error" in self.table \
            else pd.Series("", index=self.table.index)
        self.measured = (errors == "").to_numpy()
        self.scores, self.explained = (pca_scores(self.table, "shape", n_components=2)
                                       if self.measured.sum() >= 2 else (None, np.zeros(0)))
        self._keys = {(str(m), int(f), int(lab)): i for i, (m, f, lab) in enumerate(
            self.table[["movie", "frame", "label"]].itertuples(index=False))}
        self._search = None

    # ------------------------------------------------------------------ keys
    @property
    def has_groups(self) -> bool:
        return "group" in self.table and bool((self.table["group"] != "").any())

    def row_of(self, movie: str, frame: int, label: int) -> int | None:
        """The table's row of (movie, frame, label), or None."""
        return self._keys.get((str(movie), int(frame), int(label)))

    def key_of(self, row: int) -> tuple[str, int, int]:
        m, f, lab = self.table.loc[row, ["movie", "frame", "label"]]
        return str(m), int(f), int(lab)

    def groups_of_objects(self) -> dict[str, str]:
        """Object id (``movie/track7``) → its group, for the objects that have one."""
        if "group" not in self.table:
            return {}
        g = pd.Series(self.table["group"].to_numpy(), index=self.objects)
        g = g[g != ""]
        return g[~g.index.duplicated()].to_dict()

    def summary(self) -> str:
        """The Run in words: movies, objects, rows, groups, units."""
        from ..analysis.physical import space_unit_of, time_unit_of

        t = self.table
        groups = sorted(set(t["group"]) - {""}) if "group" in t else []
        space, time = space_unit_of(t), time_unit_of(t)
        words = (f"{t['movie'].nunique()} movies, {len(set(self.objects))} objects, "
                 f"{len(t)} object-frames")
        words += f"; groups: {', '.join(groups)}" if groups else "; no groups"
        words += f"; sizes in {space}" if space else "; sizes in pixels"
        words += f", time in {time}" if time else (", time = frame" if "time" not in t else "")
        failed = int((~self.measured).sum())
        return words + (f"; {failed} rows without features (see 'error')" if failed else "")

    # ------------------------------------------------------------------ the tabs
    def trajectories(self) -> pd.DataFrame:
        """One row per measured row: ``movie``, ``frame``, ``label``, ``object``, ``group``,
        ``time``, ``PC1``, ``PC2`` (the shape space of every movie's rows), in time order
        per object."""
        from ..analysis.physical import time_values

        if self.scores is None:
            raise InputError("the shape space needs at least two measured objects")
        rows = np.flatnonzero(self.measured)
        s = self.scores
        out = pd.DataFrame({
            "movie": s["movie"].astype(str).to_numpy(), "frame": s["frame"].to_numpy(),
            "label": s["label"].to_numpy(), "object": self.objects[rows],
            "group": (self.table["group"].to_numpy()[rows] if "group" in self.table
                      else np.full(len(rows), "")),
            "time": time_values(self.table)[rows],
            "PC1": s["shape_PC1"].to_numpy(float),
            "PC2": (s["shape_PC2"].to_numpy(float) if "shape_PC2" in s
                    else np.zeros(len(rows)))})
        return out.sort_values(["object", "time", "frame"], kind="stable").reset_index(drop=True)

    def measures(self) -> list[str]:
        """The numbers the Over time tab offers: the usual measures first."""
        from ..analysis.over_time import numeric_columns

        table = self.with_scores()
        numbers = [c for c in numeric_columns(table) if c not in ("failed",)]
        first = [c for c in FIRST_MEASURES if c in numbers]
        return first + [c for c in numbers if c not in first]

    def with_scores(self) -> pd.DataFrame:
        """The table with its shape PC scores (NaN on rows without features)."""
        from ..core.table_options import carry_options

        table = self.table.copy()
        if self.scores is not None:
            rows = np.flatnonzero(self.measured)
            for col in ("shape_PC1", "shape_PC2"):
                if col in self.scores:
                    values = np.full(len(table), np.nan)
                    values[rows] = self.scores[col].to_numpy(float)
                    table[col] = values
        return carry_options(self.table, table)

    def group_sentences(self, measure: str, how: str = STAT_CHOICES[0]) -> list[str]:
        """The group statistics of ``measure`` in words: each object's value at the table's
        last time (``how`` = "at the last time") or its slope over time, compared between
        the groups (:func:`napari_pfsdm.analysis.group_stats.compare_groups`)."""
        from ..analysis.group_stats import compare_groups, object_values, value_words
        from ..analysis.physical import time_values

        if not self.has_groups:
            raise InputError("no groups: give a groups file or groups from the layers' names "
                             "to compare them")
        table = self.with_scores()
        if how == "slope":
            values = object_values(table, measure, summary="slope")
            what = value_words(table, measure, "slope")
        else:
            last = float(np.max(time_values(table)))
            values = object_values(table, measure, at=last)
            what = value_words(table, measure, "at", at=last)
        return compare_groups(values, what=what).sentences()

    def similar(self, movie: str, frame: int, label: int, k: int = 7
                ) -> list[tuple[str, int, int, float, np.ndarray]]:
        """The object (movie, frame, label) and the ``k`` rows nearest its shape among every
        movie's, other objects only (each in its nearest frame): (movie, frame, label,
        PF-SDM distance, outline (row, col) centred), itself first at distance 0."""
        from ..analysis.neighbours import NeighbourSearch

        row = self.row_of(movie, frame, label)
        if row is None or not self.measured[row]:
            raise InputError(f"{movie}, frame {frame}, label {label} has no features")
        rows = np.flatnonzero(self.measured)
        if self._search is None:
            self._search = NeighbourSearch(self.table.iloc[rows])
        at = int(np.searchsorted(rows, row))
        idx, dist = self._search.rows([at], len(rows) - 1)
        valid = idx[0] >= 0
        order, dist = rows[idx[0][valid]], dist[0][valid]
        found, seen = [(row, 0.0)], {self.objects[row]}
        for r, d in zip(order, dist, strict=True):
            if self.objects[r] not in seen:
                seen.add(self.objects[r])
                found.append((int(r), float(d)))
            if len(found) > k:
                break
        return [(*self.key_of(r), d, self.outline(*self.key_of(r))) for r, d in found]

    def outline(self, movie: str, frame: int, label: int) -> np.ndarray:
        """The object's closed outline (row, col), centred (in pixels)."""
        from ..analysis.baselines import mask_contour

        data = self.movies[movie]
        plane = np.asarray(data[frame] if np.ndim(data) == 3 else data)
        mask = plane == label
        ys, xs = np.nonzero(mask)
        box = (slice(ys.min(), ys.max() + 1), slice(xs.min(), xs.max() + 1))
        line = mask_contour(mask[box])
        return np.vstack([line, line[:1]]) - line.mean(axis=0)

    def frames(self) -> list[int]:
        """The frames of the table (the prediction's choices)."""
        return sorted(int(f) for f in self.table["frame"].unique())

    def predict(self, frames: Sequence[int] | None = None, progress=None):
        """Each object's group predicted from its features at ``frames``
        (:func:`napari_pfsdm.analysis.outcome.predict_outcome`, objects keyed by movie)."""
        from ..analysis.outcome import predict_outcome

        groups = self.groups_of_objects()
        if len(set(groups.values())) < 2:
            raise InputError("prediction needs two or more groups: give a groups file or "
                             "groups from the layers' names")
        return predict_outcome(self.table, groups, frames=list(frames) if frames else None,
                               n_repeats=1, curve=False, progress=progress)

    def layer_features(self, movie: str) -> pd.DataFrame:
        """What ``movie``'s Labels layer carries in ``features``: its own rows, every frame,
        with ``frame`` and ``label`` columns and its shape PC scores
        (:func:`~._features.layer_features`)."""
        from ._features import layer_features

        mine = (self.table["movie"].astype(str) == movie).to_numpy()
        rows = self.table[mine].drop(columns=["movie"]).reset_index(drop=True)
        pca = {}
        if self.scores is not None:
            scores = self.scores[self.scores["movie"].astype(str) == movie]
            pca["shape"] = scores.drop(columns=["movie"]).reset_index(drop=True)
        return layer_features(rows, pca, None)
