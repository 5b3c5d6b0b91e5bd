"""A times file: each movie's frames' times, as a lab writes them (``movie,frame,time``), read
with its faults said in words. Read by ``pfsdm measure --times FILE`` and the napari plugin's
study dock."""

from __future__ import annotations

import csv
import math
from pathlib import Path

from ..errors import InputError

__all__ = ["read_times_file"]


def read_times_file(path: str | Path) -> dict[str, dict[int, float]]:
    """``{movie: {frame: time}}`` from a CSV with the columns ``movie``, ``frame`` and
    ``time`` (any others are ignored), refused in words when a column is missing or a cell is
    not a number."""
    path = Path(path)
    with open(path, newline="", encoding="utf-8-sig") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise InputError(f"{path} holds no rows: give one row per movie and frame (movie, "
                         "frame, time)")
    missing = [c for c in ("movie", "frame", "time") if c not in rows[0]]
    if missing:
        raise InputError(f"{path} has no {', '.join(missing)} column: a times file has one "
                         "row per movie and frame with the columns movie, frame, time "
                         f"(its columns: {', '.join(rows[0])})")
    out: dict[str, dict[int, float]] = {}
    for i, row in enumerate(rows, start=2):
        try:
            frame, value = int(str(row["frame"]).strip()), float(str(row["time"]).strip())
        except ValueError:
            raise InputError(f"{path}, line {i}: frame must be a whole number and time a "
                             f"number; got frame {row['frame']!r}, time {row['time']!r}") from None
        if not math.isfinite(value):
            raise InputError(f"{path}, line {i}: time {row['time']!r} is not a finite number")
        out.setdefault(str(row["movie"]).strip(), {})[frame] = value
    return out
