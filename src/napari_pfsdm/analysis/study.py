"""Several movies as one study: one table with a ``movie`` column, each movie's times and pixel
size, its objects followed through time (what the napari plugin's Study dock and a script do
with movies already in memory; ``pfsdm measure`` does the same from files).

Examples
--------
>>> import numpy as np
>>> a = np.zeros((2, 32, 32), np.uint8); a[:, 8:20, 8:24] = 1
>>> b = np.zeros((2, 40, 40), np.uint8); b[:, 8:26, 8:30] = 1
>>> t = measure_study({"a": a, "b": b}, times={"a": [0, 2], "b": [0, 3]}, time_unit="h",
...                   pixel_sizes={"a": 1.0, "b": 0.5}, n_fourier=4, n_radii=4)
>>> t[["movie", "frame", "time", "area"]].values.tolist()
[['a', 0, 0.0, 192.0], ['a', 1, 2.0, 192.0], ['b', 0, 0.0, 99.0], ['b', 1, 3.0, 99.0]]
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import pandas as pd

from ..core import units
from ..core.params import PFSDMParams, as_params
from ..core.table_options import plain, set_options, table_options
from ..core.units import check_times
from ..errors import InputError
from .features import measure
from .physical import add_times

__all__ = ["measure_study"]


def measure_study(
    movies: Mapping[str, Any],
    reporters: Mapping[str, Any] | None = None,
    *,
    times: Mapping[str, Any] | Any = None,
    time_unit: str | None = None,
    pixel_sizes: Mapping[str, Any] | None = None,
    space_unit: str | None = None,
    link: str = "auto",
    progress: Callable[[int, int, str], None] | None = None,
    params: PFSDMParams | None = None,
    **options: Any,
) -> pd.DataFrame:
    """One feature table of several label movies (T, Y, X), keyed by movie.

    Parameters
    ----------
    movies : mapping
        Movie name → label movie (numpy, dask or zarr; T × Y × X, or one Y × X image).
    reporters : mapping, optional
        Movie name → its reporter, of the same shape; a movie without one has none (a
        reporter is never taken from another movie).
    times : mapping or sequence, optional
        Movie name → its frames' times, or one sequence for every movie; all movies have
        times, or none.
    time_unit, space_unit : str, optional
        The units of the times and of the pixel sizes (µm when not given).
    pixel_sizes : mapping, optional
        Movie name → its pixel size (one number, square pixels); all movies, or none.
    link : str
        How objects keep their identity (:data:`~napari_pfsdm.core.params.LINK_OPTION`), per
        movie.
    progress : callable(done, total, movie), optional
        Objects measured, over every movie.
    params, **options
        The method's options.
    """
    from .label_images import count_objects
    from .tracking import link_movie

    p = as_params(params, options)
    names = list(movies)
    if not names:
        raise InputError("no movies to measure: choose at least one Labels layer")
    reporters = dict(reporters or {})
    unknown = sorted(set(reporters) - set(names))
    if unknown:
        raise InputError(f"reporters given for movies that are not measured: {unknown}")
    times_of = _per_movie("times", times, names)
    sizes_of = _per_movie("pixel sizes", pixel_sizes, names)
    unit = (units.space_unit(space_unit or "µm")[0]) if sizes_of else None
    t_unit = units.time_unit(time_unit)[0] if time_unit else None
    totals = {n: count_objects(np.asarray(m)) for n, m in movies.items()}
    total, done = sum(totals.values()), 0
    tables = []
    for name in names:
        labels = movies[name]

        def tick(k: int, _n, _name: str = name, _at: int = done) -> None:
            if progress is not None:
                progress(_at + k, total, _name)

        table = measure(labels, reporters.get(name), params=p,
                        pixel_size=sizes_of.get(name), space_unit=unit if sizes_of else None,
                        progress=tick)
        done += totals[name]
        if name in times_of:
            n_frames = labels.shape[0] if np.ndim(labels) == 3 else 1
            table = add_times(table, check_times(times_of[name], n_frames), t_unit)
        if link != "labels" and np.ndim(labels) == 3 and len(table):
            table = link_movie(table, labels, link)[0]
        table.insert(0, "movie", name)
        tables.append(table)
    record = dict(table_options(tables[0]) or {})
    out = pd.concat([plain(t) for t in tables], ignore_index=True)
    if "track_id" in out.columns:
        out["track_id"] = out["track_id"].fillna(-1).astype(np.int64)
    for key in ("pixel_size", "space_unit", "pixel_sizes"):
        record.pop(key, None)
    if sizes_of:
        record["space_unit"] = unit
        record["pixel_sizes"] = {n: [float(v)] * 2 for n, v in _sides(sizes_of).items()}
    if times_of:
        record["time_unit"] = t_unit
    return set_options(out, record)


def _per_movie(what: str, given: Any, names: list[str]) -> dict[str, Any]:
    """``given`` per movie: a mapping (every movie, or none), or one value for all."""
    if given is None:
        return {}
    if not isinstance(given, Mapping):
        return dict.fromkeys(names, given)
    have = [n for n in names if given.get(n) is not None]
    if have and len(have) < len(names):
        lack = [n for n in names if n not in have]
        raise InputError(f"{what} are given for {', '.join(have[:3])} but not for "
                         f"{', '.join(lack[:3])}: one table cannot mix them; give them for "
                         "every movie, or for none")
    return {n: given[n] for n in have}


def _sides(sizes: Mapping[str, Any]) -> dict[str, float]:
    """Each movie's pixel side (a square pixel: one number)."""
    out = {}
    for name, size in sizes.items():
        values = np.ravel(np.asarray(size, float))
        out[name] = float(values[-1])
    return out
