"""A table as the commands read it: its groups attached, the rows without features left
out (and said), its objects followed over time (tracks, or labels that follow them)."""

from __future__ import annotations

from typing import Any

from .common import Step, UserError, note


def with_groups(table, path: str, quiet: bool = False, column: str | None = None):
    """The table with its ``group`` column (the groups file's ``column``) and the file's other
    grouping columns, from the groups file at ``path``, and the groups; rows of the file that
    were left out or match no object are named on stderr (even with ``-q``: they are
    warnings, not progress)."""
    import warnings

    from ..analysis.groups import attach_groups, read_groups

    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always", UserWarning)
        groups = read_groups(path, column)
        out = attach_groups(table, groups)
    for w in said:
        if issubclass(w.category, UserWarning):
            note(f"warning: {path}: {w.message}")
        else:  # pragma: no cover - not ours: shown as Python shows it
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    return out, groups


def _left_out_note(left, total: int, what: str, quiet: bool) -> None:
    """Say on stderr how many rows were left out and which (frame, label, reason)."""
    if not len(left):
        return
    shown = [f"frame {r['frame']} label {r['label']}"
             f"{' of ' + r['movie'] if r.get('movie') else ''} ({r['reason']})"
             for r in left.head(3).to_dict("records")]
    more = f" and {len(left) - 3} more" if len(left) > 3 else ""
    note(f"left out {len(left)} of {total} {what} without features: {'; '.join(shown)}{more}"
          " (all listed in the output's .json file)", quiet)


def measured_rows(table, channels, what: str, quiet: bool, need: int = 2):
    """The rows with ``channels`` features, the rows left out; refuses fewer than ``need``."""
    from ..analysis.features import split_failed

    ok, left = split_failed(table, tuple(channels))
    _left_out_note(left, len(table), what, quiet)
    if len(ok) < need:
        reasons = sorted(set(left["reason"]))[:3]
        raise UserError(
            f"only {len(ok)} of {len(table)} {what} have features; at least {need} are needed"
            + (f" (the others: {'; '.join(reasons)})" if reasons else "")
        )
    return ok, left


def _untracked_movies(table) -> list[tuple[str, Any]]:
    """(movie name, TrackingCheck) of each movie whose label ids do not follow objects."""
    from ..analysis.tracking import check_tracking

    need = {"frame", "label", "area", "centroid_y", "centroid_x"}
    if len(table) == 0 or not need <= set(table.columns):
        return []  # nothing to check (a table not from 'pfsdm measure' has no centroids)
    movies = table.groupby("movie", sort=False) if "movie" in table.columns else [("", table)]
    found = []
    for name, rows in movies:
        check = check_tracking(rows)
        if not check.tracked:
            found.append((str(name), check))
    return found


def _which_movies(bad: list[tuple[str, Any]]) -> str:
    """``"movie01: "``, ``"3 movies (movie01, movie02, …); in movie01: "`` or ``""``."""
    if not bad or not bad[0][0]:
        return ""
    if len(bad) == 1:
        return f"{bad[0][0]}: "
    names = ", ".join(n for n, _ in bad[:3]) + (", …" if len(bad) > 3 else "")
    return f"{len(bad)} movies ({names}); in {bad[0][0]}: "


def warn_untracked(table, quiet: bool) -> None:
    """Say on stderr which movies' labels are not tracked (measure --link none)."""
    bad = _untracked_movies(table)
    if bad:
        first = bad[0][1].message.split(". Link")[0]
        note(f"warning: {_which_movies(bad)}{first}. "
              "Trajectories by label would be meaningless: measure again with --link auto, or "
              "link the table with 'pfsdm trajectories --link centroid'", quiet)


def follow_objects(table, link: str | None, quiet: bool, command: str = "trajectories"):
    """The table whose object ids follow objects over time: its ``track_id`` when it has one,
    a linked copy with ``--link centroid|laptrack``; refuses untracked labels otherwise."""
    from ..analysis.tracking import link as link_table
    from ..core.table_schema import NO_TRACK, TRACK_COLUMN

    if link in ("centroid", "laptrack") or (link == "auto" and _untracked_movies(table)):
        link = "centroid" if link == "auto" else link
        with Step(f"linking {len(table):,} objects into tracks ({link})", quiet):
            table = link_table(table, method=link)
        n = table.loc[table[TRACK_COLUMN] != NO_TRACK, TRACK_COLUMN].nunique()
        note(f"linked by {link}: {n} tracks; trajectories follow them", quiet)
        return table
    if TRACK_COLUMN in table.columns:
        n_off = int((table[TRACK_COLUMN] == NO_TRACK).sum())
        if n_off:
            note(f"left out {n_off} of {len(table)} rows that belong to no track "
                  f"({TRACK_COLUMN} = {NO_TRACK})", quiet)
        return table[table[TRACK_COLUMN] != NO_TRACK].reset_index(drop=True) \
            if n_off else table
    bad = _untracked_movies(table)
    if not bad:
        return table
    first = bad[0][1].message.split(". Link")[0]
    where = _which_movies(bad)
    if link == "labels":
        note(f"warning: {where}{first}; drawing by label anyway (--link labels)", quiet)
        return table
    if command == "classify":
        raise UserError(
            f"{where}{first}, so an object's features over several frames would mix "
            "different objects. Measure again with 'pfsdm measure ... --link auto' (it links "
            "them into a track_id column), then name the tracks in the groups file "
            "(movie,track_id,group); or classify one frame at a time")
    raise UserError(
        f"{where}{first}, so trajectories drawn by label would jump between objects. Link "
        "them: add --link centroid here (the linking 'pfsdm measure' does by default), or "
        "--link labels to draw by label anyway")
