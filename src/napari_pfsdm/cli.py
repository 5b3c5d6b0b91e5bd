"""The ``pfsdm`` command line: measure movies, compare shapes, plot trajectories, classify.

Run ``pfsdm --help`` or ``pfsdm COMMAND --help``. Every command runs without a display.
Errors a user can fix (a missing file, labels and intensity of different sizes, a raw image
given as labels, an output folder that cannot be written, an output name that would replace a
file pfsdm did not write) print one line starting with ``pfsdm: error:`` and exit with status
2, without a traceback (``--debug`` shows it); no partial output file is left behind. Those are
the :class:`~napari_pfsdm.errors.InputError` raised where the input is wrong (and its
subclass :class:`~napari_pfsdm.errors.RunFault`: a worker killed, a cluster lost), plus the
file system's ``OSError`` and a missing optional package; any other exception is a bug of
napari-pfsdm: pfsdm says so, where to report it, and exits with status 1. Tables are
plain CSV with their options in a ``.csv.json`` sidecar (Parquet for a ``.parquet`` name).
Messages and progress go to stderr
(``-q`` silences them); results and summaries to stdout.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from .errors import InputError

__all__ = ["build_parser", "main"]

EXIT_USAGE = 2
EXIT_BUG = 1


#: An error the user can fix; printed as one line (the one class: errors.InputError).
UserError = InputError

#: Where a bug is reported: the README's wording ("Reporting a problem"); a test holds them equal.
BUG_REPORT = ("please report it on the issue tracker of the napari-pfsdm repository (its "
              "Issues page), with the command and the output of the same command run with "
              "--debug")


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------

def _say(msg: str, quiet: bool = False) -> None:
    if not quiet:
        print(msg, flush=True)


def _note(msg: str, quiet: bool = False) -> None:
    """A message about the run (progress, rows left out) on stderr."""
    if not quiet:
        print(f"pfsdm: {msg}", file=sys.stderr, flush=True)


class _Step:
    """Says on stderr what a step is doing and, when it took more than a second, how long:
    every step that can pass a few seconds on a large table is announced."""

    def __init__(self, what: str, quiet: bool):
        self.what, self.quiet = what, quiet

    def __enter__(self) -> _Step:
        self.t0 = time.perf_counter()
        _note(f"{self.what} …", self.quiet)
        return self

    def __exit__(self, kind, *rest) -> None:
        dt = time.perf_counter() - self.t0
        if kind is None and dt > 1.0:
            _note(f"{self.what}: done in {dt:.1f} s", self.quiet)


def _check_output(
    path: str | os.PathLike, what: str = "output", *, force: bool = False,
    inputs: Sequence[str | os.PathLike] = (),
) -> Path:
    """Fail early (before any long work) when ``path`` cannot or must not be written."""
    from .io import check_overwrite

    p = Path(path)
    folder = p.parent if str(p.parent) else Path(".")
    if p.is_dir():
        raise UserError(f"the {what} {p} is a folder; give a file name such as {p / 'out.csv'}")
    if not folder.is_dir():
        raise UserError(f"cannot write the {what} {p}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise UserError(f"cannot write the {what} {p}: the folder {folder} is not writable")
    for q in inputs:
        if Path(q).exists() and p.exists() and os.path.samefile(p, q):
            raise UserError(f"the {what} {p} is also an input; choose another output name")
    check_overwrite(p, force=force, what=what, table=what not in ("plot", "report"))
    if p.suffix.lower() == ".parquet":  # a missing package fails now, not after the work
        from .io import require_pyarrow

        require_pyarrow(p, "writing")
    return p


def _check_parts(parts: Path) -> None:
    """Refuse a parts folder name that is taken by something other than a folder."""
    if (parts.exists() or parts.is_symlink()) and not parts.is_dir():
        raise UserError(
            f"{parts} already exists and is not a folder, but pfsdm keeps the finished movies' "
            "parts in a folder of that name; nothing was changed. Move that file, or give "
            "another folder with --parts")


def _with_groups(table, path: str, quiet: bool = False):
    """The table with its ``group`` column from the groups file at ``path``, and the groups;
    rows of the file that were left out or match no object are named on stderr (even with
    ``-q``: they are warnings, not progress)."""
    import warnings

    from .analysis.reduction import attach_groups, read_groups

    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always", UserWarning)
        groups = read_groups(path)
        out = attach_groups(table, groups)
    for w in said:
        if issubclass(w.category, UserWarning):
            _note(f"warning: {path}: {w.message}")
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
    _note(f"left out {len(left)} of {total} {what} without features: {'; '.join(shown)}{more}"
          " (all listed in the output's .json file)", quiet)


def _measured(table, channels, what: str, quiet: bool, need: int = 2):
    """The rows with ``channels`` features, the rows left out; refuses fewer than ``need``."""
    from .analysis.features import split_failed

    ok, left = split_failed(table, tuple(channels))
    _left_out_note(left, len(table), what, quiet)
    if len(ok) < need:
        reasons = sorted(set(left["reason"]))[:3]
        raise UserError(
            f"only {len(ok)} of {len(table)} {what} have features; at least {need} are needed"
            + (f" (the others: {'; '.join(reasons)})" if reasons else "")
        )
    return ok, left


def _progress_printer(quiet: bool):
    """A ``progress(movie, done, total)`` callback drawing one tqdm bar per movie on stderr
    (redrawn at most every 0.2 s on a terminal, every 5 s in a log file); None when quiet."""
    if quiet:
        return None
    from tqdm import tqdm

    bars: dict = {}
    interval = 0.2 if sys.stderr.isatty() else 5.0

    def show(name: str, done: int, total: int) -> None:
        bar = bars.get(name)
        if bar is None:
            bar = bars[name] = tqdm(total=total, desc=name[:28], unit="frame", file=sys.stderr,
                                    mininterval=interval, dynamic_ncols=True)
        bar.update(done - bar.n)
        if done >= total:
            bar.close()

    return show


def _measure_options(args: argparse.Namespace) -> dict[str, Any]:
    """The method options given on the command line (those left out take the defaults)."""
    from .core.params import OPTIONS

    return {o.name: getattr(args, o.name) for o in OPTIONS
            if getattr(args, o.name, None) is not None}


def _option_type(opt: Any) -> Callable[[str], Any]:
    """argparse's ``type`` of a method option: the text parsed and checked by the record, so
    that a bad value gets the same words as from Python (``Option.message``)."""
    def parse(text: str) -> Any:
        try:
            return opt.parse(text)
        except InputError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    parse.__name__ = opt.name
    return parse


def _add_method_options(p: argparse.ArgumentParser) -> None:
    """One ``--name`` per option of the record (core.params.OPTIONS): its help, choices and
    default, generated."""
    from .core.params import OPTIONS

    g = p.add_argument_group(
        "method options (the same as in the napari widget; leave them out for the defaults)"
    )
    only = {"2d": "2-D only: ", "3d": "3-D only: ", "both": ""}
    for opt in OPTIONS:
        kw: dict[str, Any] = {"dest": opt.name, "type": _option_type(opt),
                              "help": f"{only[opt.dims]}{opt.help} (default {opt.default})"}
        if opt.choices:
            kw["choices"] = opt.choices
        else:
            kw["metavar"] = "N" if opt.kind is int else "X"
        g.add_argument(opt.flag, **kw)


def _add_compute_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("where the work runs")
    g.add_argument("--scheduler", default="processes", metavar="WHERE",
                   help="'processes' (default: one process per core of this machine), "
                        "'threads', 'sync' (one at a time, for debugging), or the address of a "
                        "dask scheduler to run on a cluster, e.g. tcp://10.0.0.5:8786")
    g.add_argument("--workers", type=_whole("--workers", 1), metavar="N",
                   help="local workers (default: the number of cores)")
    g.add_argument("--frames-per-task", dest="frames_per_task",
                   type=_whole("--frames-per-task", 1), metavar="N",
                   help="whole frames measured per task (default: tasks planned by objects, "
                        "as the local process pool plans them)")


# --------------------------------------------------------------------------------------------
# commands
# --------------------------------------------------------------------------------------------

def cmd_measure(args: argparse.Namespace) -> int:
    from .analysis.features import warnings_summary
    from .batch.movies import find_movies, pair_movies
    from .batch.run import default_parts_dir, run_batch

    if not args.labels:
        if args.intensity and len(args.intensity) > 1:
            raise UserError(
                f"no label movie given: -i/--intensity took all of {' '.join(args.intensity)}. "
                "Put the labels first, e.g.: pfsdm measure labels.tif -i reporter.tif "
                "-o features.csv"
            )
        raise UserError("give the label movie(s) to measure, e.g.: pfsdm measure labels.tif "
                        "-o features.csv")
    from .core.params import PFSDMParams

    params = PFSDMParams.from_options(_measure_options(args))  # fails before any file opens
    if args.axes is not None and args.axes.lower() not in ("yx", "tyx", "zyx", "tzyx"):
        raise UserError(f"--axes must be yx, tyx, zyx or tzyx (t time, z y x space); got "
                        f"{args.axes!r}")
    if args.axes is not None:
        args.axes = args.axes.lower()
    if args.spacing is not None and args.axes not in ("zyx", "tzyx"):
        raise UserError("--spacing is for 3-D objects: say which axes the files have, "
                        "--axes zyx (a Z-stack) or --axes tzyx (a time-lapse of Z-stacks)")
    if args.axes is not None:
        params.check_dimension(3 if "z" in args.axes else 2)
    labels = find_movies(args.labels)
    intensity = find_movies(args.intensity) if args.intensity else None
    out = _check_output(args.output, force=args.force,
                        inputs=[*labels, *(intensity or [])])
    _check_parts(Path(args.parts) if args.parts else default_parts_dir(out))
    movies = pair_movies(labels, intensity)
    _say(f"measuring {len(movies)} movie(s) -> {out}", args.quiet)
    t0 = time.perf_counter()
    table = run_batch(
        movies, out,
        scheduler=args.scheduler, num_workers=args.workers,
        frames_per_task=args.frames_per_task,
        parts_dir=args.parts,
        progress=_progress_printer(args.quiet),
        log=lambda m: _say("  " + m, args.quiet),
        allow_empty=args.allow_empty,
        params=params,
        link=args.link,
        axes=args.axes,
        spacing=args.spacing,
        allow_missing_chunks=args.allow_missing_chunks,
        series=args.series,
    )
    dt = time.perf_counter() - t0
    _say(f"wrote {out} (options in {out.name}.json): {len(table)} objects from "
         f"{len(movies)} movie(s) in {dt:.1f} s", args.quiet)
    summary = warnings_summary(table)
    if summary:
        _say(summary[0].upper() + summary[1:], args.quiet)
    if args.link == "none":
        _warn_untracked(table, args.quiet)
    parts = Path(args.parts) if args.parts else default_parts_dir(out)
    _say(f"per-movie parts kept in {parts} (a re-run skips finished movies)", args.quiet)
    return 0


def _untracked_movies(table) -> list[tuple[str, Any]]:
    """(movie name, TrackingCheck) of each movie whose label ids do not follow objects."""
    from .analysis.tracking import check_tracking

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


def _warn_untracked(table, quiet: bool) -> None:
    """Say on stderr which movies' labels are not tracked (measure --link none)."""
    bad = _untracked_movies(table)
    if bad:
        first = bad[0][1].message.split(". Link")[0]
        _note(f"warning: {_which_movies(bad)}{first}. "
              "Trajectories by label would be meaningless: measure again with --link auto, or "
              "link the table with 'pfsdm trajectories --link centroid'", quiet)


def _select_frames(table, frames: str | None):
    if frames is None:
        return table
    from .analysis.classification import format_frames, parse_frames

    sel = parse_frames(frames)
    sub = table[table["frame"].isin(sel)]
    if sub.empty:
        raise UserError(f"no rows in frames {frames}: the table has frames "
                        f"{format_frames(table['frame'])}; choose frames among these")
    return sub


# when a map is drawn from the neighbour graph, and how: one set of numbers for the command
# line and the plugin (napari_pfsdm.analysis.reduction)
from .analysis.reduction import FULL_MATRIX_LIMIT, MAP_NEIGHBOURS, TSNE_SLOW  # noqa: E402

#: Column that carries a row's position in the feature file through the selections.
_FILE_ROW = "_pfsdm_file_row"


def _nearest(table, k: int, args: argparse.Namespace):
    """Each object's k nearest, itself excluded (napari_pfsdm.nearest_neighbours)."""
    from .analysis.neighbours import nearest_neighbours

    return nearest_neighbours(
        table, k=k, intensity_weight=args.intensity_weight,
        boundary_weight=args.boundary_weight)


def _graph_of_matrix(matrix, k: int):
    """The k-nearest-neighbour graph of a full matrix (itself excluded)."""
    import numpy as np

    d = np.array(matrix, dtype=float)
    np.fill_diagonal(d, np.inf)
    part = np.argpartition(d, k - 1, axis=1)[:, :k]
    order = np.take_along_axis(part, np.argsort(np.take_along_axis(d, part, 1), axis=1), 1)
    return order, np.take_along_axis(d, order, axis=1)


def _median_distance(table, args: argparse.Namespace, size: int = 400) -> float:
    """The median distance between two objects, from ``size`` random objects (seed 0): the
    unit of re-ranking's tie-break (analysis.rerank.TIE_BREAK)."""
    import numpy as np

    from .analysis.tables import distance_matrix
    from .core.table_options import carry_options

    rng = np.random.default_rng(0)
    pick = np.sort(rng.choice(len(table), size=min(size, len(table)), replace=False))
    sub = carry_options(table, table.iloc[pick].reset_index(drop=True))
    d = distance_matrix(sub, intensity_weight=args.intensity_weight,
                        boundary_weight=args.boundary_weight)
    return float(np.median(d[~np.eye(len(d), dtype=bool)]))


_MAP_NAMES = {"tsne": "t-SNE", "umap": "UMAP", "spectral": "spectral embedding"}


def _draw_map(args, table, n: int, *, matrix=None, graph=None) -> None:
    """``--mds``: classical MDS of the full matrix up to FULL_MATRIX_LIMIT objects; above, a map
    of the neighbour graph (given, or from the matrix; ``--map``), and the output says so."""
    from .analysis.reduction import graph_coordinates, mds_coordinates
    from .batch.reports import plot_mds

    if n <= FULL_MATRIX_LIMIT:
        if matrix is None:
            from .analysis.tables import distance_matrix

            with _Step(f"computing the {n:,} x {n:,} distances of the map", args.quiet):
                matrix = distance_matrix(table, intensity_weight=args.intensity_weight,
                                         boundary_weight=args.boundary_weight)
                if args.rerank:
                    from .analysis.rerank import rerank

                    matrix = rerank(matrix, args.rerank, k=min(args.rerank_k, n - 1))
        with _Step(f"drawing the 2-D MDS map of {n:,} objects", args.quiet):
            plot_mds(mds_coordinates(matrix), table, args.mds)
        _say(f"wrote {args.mds} (classical MDS of the full matrix)", args.quiet)
        return
    k = min(MAP_NEIGHBOURS, n - 1)
    if graph is None:
        graph = _graph_of_matrix(matrix, k)
    idx, dist = graph[0][:, :k], graph[1][:, :k]
    name = _MAP_NAMES[args.map]
    if args.map == "tsne" and n > TSNE_SLOW:
        _note(f"t-SNE of {n:,} objects takes minutes (50,000: ~8 min here); --map umap "
              "draws it in under a minute (pip install \"napari-pfsdm[umap]\")", args.quiet)
    with _Step(f"drawing the 2-D map of {n:,} objects from their {k} nearest neighbours "
               f"({name})", args.quiet):
        coords = graph_coordinates(idx, dist, args.map)
        plot_mds(coords, table, args.mds, axis_name=name.split()[0],
                 title=f"PF-SDM {k}-nearest-neighbour graph, {name}")
    _say(f"wrote {args.mds}: a {name} map of the {k}-nearest-neighbour graph, not MDS "
         f"(above {FULL_MATRIX_LIMIT:,} objects the map is drawn from the neighbours, "
         "without the full matrix)", args.quiet)


def cmd_compare(args: argparse.Namespace) -> int:
    import numpy as np
    import pandas as pd

    from .analysis.reduction import distance_table
    from .analysis.tables import distance_matrix
    from .batch.reports import load_features
    from .core.table_options import carry_options, table_options
    from .io import write_table_csv

    out = _check_output(args.output, force=args.force, inputs=[args.features])
    if args.mds:
        _check_output(args.mds, "plot", force=args.force, inputs=[args.features])
    if args.neighbours is not None and args.neighbours < 1:
        raise UserError(f"--neighbours must be a whole number >= 1, got {args.neighbours}")
    if args.neighbours is not None and args.rerank == "transduction":
        raise UserError("--rerank transduction needs the full matrix (it inverts an n x n "
                        "matrix); with --neighbours use --rerank diffusion or mutual")
    table = load_features(args.features)
    rows = pd.Series(np.arange(len(table)), index=table.index, name=_FILE_ROW)
    table = carry_options(table, pd.concat([table, rows], axis=1))  # one step: no fragments
    table = _select_frames(table, args.frames).reset_index(drop=True)
    if args.groups:
        table, _ = _with_groups(table, args.groups, args.quiet)
    channels = ["shape"] + (["intensity"] if args.intensity_weight else [])
    table, left = _measured(table, channels, "objects", args.quiet)
    n = len(table)
    if args.rerank and n < 3:
        raise UserError(f"--rerank needs at least 3 objects, the table has {n}")
    if args.neighbours is not None:
        return _compare_neighbours(args, table, left, out)
    if n > args.max_objects:
        raise UserError(
            f"{len(table)} objects would give a {len(table)}x{len(table)} matrix; choose frames "
            f"with --frames (e.g. --frames 0), ask for each object's nearest neighbours "
            f"instead (--neighbours 10: no matrix, any size), or raise --max-objects"
        )
    with _Step(f"computing {n:,} x {n:,} distances", args.quiet):
        matrix = distance_matrix(table, intensity_weight=args.intensity_weight,
                                 boundary_weight=args.boundary_weight)
    if args.rerank:
        from .analysis.rerank import rerank

        with _Step(f"re-ranking them ({args.rerank})", args.quiet):
            matrix = rerank(matrix, args.rerank, k=min(args.rerank_k, n - 1))
    dist = distance_table(table, matrix)
    opts = table_options(table)
    opts["intensity_weight"] = args.intensity_weight
    opts["boundary_weight"] = args.boundary_weight
    opts["rerank"] = args.rerank or "none"
    if args.rerank:
        opts["rerank_k"] = min(args.rerank_k, n - 1)
    with _Step(f"writing {out}", args.quiet):
        write_table_csv(dist, out, opts, index=True, table_type="distances",
                        extra={"features": str(args.features),
                               "left_out": left.to_dict("records")})
    _say(f"wrote {out}: {n} x {n} PF-SDM distances", args.quiet)
    if args.mds:
        _draw_map(args, table, n, matrix=matrix)
    return 0


def _compare_neighbours(args: argparse.Namespace, table, left, out: Path) -> int:
    """``compare --neighbours K``: the edge list of each object's K nearest (re-ranked on the
    graph with --rerank), never the n x n matrix."""
    from .analysis.reduction import neighbour_table
    from .core.table_options import table_options
    from .io import write_table_csv

    n = len(table)
    k = args.neighbours
    if k > n - 1:
        raise UserError(f"--neighbours {k}: the table has {n} objects, so each has at most "
                        f"{n - 1} neighbours; ask for fewer")
    rk = min(args.rerank_k, n - 1)
    k_graph = k
    if args.rerank:  # 3 k: most objects' re-ranked neighbours provably the full matrix's
        k_graph = max(k_graph, min(n - 1, 3 * rk))
    if args.mds and n > FULL_MATRIX_LIMIT:
        k_graph = max(k_graph, min(n - 1, MAP_NEIGHBOURS))
    with _Step(f"finding the {k_graph} nearest neighbours of {n:,} objects", args.quiet):
        idx, dist = _nearest(table, k_graph, args)
    extra: dict[str, Any] = {}
    graph = (idx, dist)
    m = max(k, min(n - 1, MAP_NEIGHBOURS)) if args.mds and n > FULL_MATRIX_LIMIT else k
    if args.rerank:
        from .analysis.rerank import rerank_neighbours

        scale = _median_distance(table, args)
        with _Step(f"re-ranking them ({args.rerank}, k = {rk}) on the neighbour graph",
                   args.quiet):
            ridx, rdist, exact = rerank_neighbours(
                idx, dist, args.rerank, k=rk, scale=scale, n_neighbours=m, return_exact=True)
        share = float(exact.mean())
        _note(f"re-ranked on the {k_graph}-neighbour graph: for {share:.0%} of the objects "
              "the neighbours are provably those of re-ranking the full matrix", args.quiet)
        extra.update(rerank_graph_neighbours=k_graph, rerank_scale=scale,
                     rerank_certified_share=share)
        graph = (ridx, rdist)
    edges = neighbour_table(table, graph[0][:, :k], graph[1][:, :k],
                            rows=table[_FILE_ROW].to_numpy())
    opts = table_options(table)
    opts["intensity_weight"] = args.intensity_weight
    opts["boundary_weight"] = args.boundary_weight
    opts["rerank"] = args.rerank or "none"
    if args.rerank:
        opts["rerank_k"] = rk
    opts["neighbours"] = k
    with _Step(f"writing {out}", args.quiet):
        write_table_csv(edges, out, opts, table_type="neighbours", extra={
            "features": str(args.features),
            "row": "the object's row in the features table (0 = its first data row)",
            "left_out": left.to_dict("records"), **extra})
    _say(f"wrote {out}: the {k} nearest neighbours of each of {n:,} objects "
         f"({len(edges):,} rows{', re-ranked' if args.rerank else ''})", args.quiet)
    if args.mds:
        _draw_map(args, table, n, graph=graph)
    return 0


def cmd_trajectories(args: argparse.Namespace) -> int:
    import pandas as pd

    from .analysis.shape_space import ShapePCA
    from .batch.reports import load_features, plot_trajectories
    from .core.table_options import table_options
    from .core.table_schema import has_channel, pc_columns
    from .io import write_table_csv

    out = _check_output(args.output, force=args.force, inputs=[args.features])
    if args.plot:
        _check_output(args.plot, "plot", force=args.force, inputs=[args.features])
        if max(args.show) > args.components:
            raise UserError(f"--show {args.show[0]} {args.show[1]} names a component above "
                            f"--components {args.components}; show components from 1 to "
                            f"{args.components}, or raise --components")
    table = load_features(args.features)
    table = _follow_objects(table, args.link, args.quiet)
    if args.groups:
        table, _ = _with_groups(table, args.groups, args.quiet)
    has_int = has_channel(table.columns, "intensity")
    channels = {"shape": ["shape"], "intensity": ["intensity"],
                "both": ["shape", "intensity"] if has_int else ["shape"]}[args.channel]
    if "intensity" in channels and not has_int:
        raise UserError("the table has no intensity features; measure with --intensity IMAGE")
    table, left = _measured(table, list(dict.fromkeys(["shape", *channels])), "rows",
                            args.quiet)
    scores = None
    explained = {}
    reference = None
    if args.reference:  # a fitted shape space: the reference's axes (analysis.shape_space)
        reference = load_features(args.reference)
        reference, _ = _measured(reference, list(dict.fromkeys(["shape", *channels])),
                                 "reference rows", args.quiet)
    what = f" in the space of {args.reference}" if args.reference else ""
    with _Step(f"PCA of {len(table):,} rows ({', '.join(channels)}){what}", args.quiet):
        for ch in channels:
            space = ShapePCA(n_components=args.components, channel=ch).fit(
                table if reference is None else reference)
            s, ev = space.transform(table), space.explained_variance_ratio_
            explained[ch] = ev
            scores = s if scores is None else pd.concat(
                [scores, s[pc_columns(s.columns, ch)]], axis=1)
    opts = table_options(table)
    write_table_csv(scores, out, opts, table_type="pca", extra={
        "features": str(args.features),
        **({"reference": str(args.reference)} if args.reference else {}),
        "explained_variance": {ch: ev.tolist() for ch, ev in explained.items()},
        "left_out": left.to_dict("records")})
    ev_txt = ", ".join(
        f"{ch}: " + " ".join(f"{100 * v:.2g}%" for v in ev) for ch, ev in explained.items()
    )
    _say(f"wrote {out}: {len(scores)} rows; variance explained by the PCs: {ev_txt}", args.quiet)
    if args.plot:
        with _Step(f"drawing {args.plot}", args.quiet):
            plot_trajectories(scores, args.plot, components=tuple(args.show),
                              explained=explained)
        _say(f"wrote {args.plot}", args.quiet)
    return 0


def cmd_plot(args: argparse.Namespace) -> int:
    """Draw one column of a table against time: each object's line, each group's mean ± sd."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .analysis.over_time import numeric_columns, plot_over_time
    from .io import read_table_csv, save_figure, write_table_csv

    out = _check_output(args.output, "plot", force=args.force, inputs=[args.table])
    if args.values:
        _check_output(args.values, force=args.force, inputs=[args.table])
    if not Path(args.table).is_file():
        raise UserError(f"{args.table}: no such table")
    try:
        table = read_table_csv(args.table)
    except ValueError as exc:
        raise UserError(f"{args.table}: {exc}") from None
    if "frame" not in table.columns or "label" not in table.columns:
        raise UserError(f"{args.table} has no frame and label columns: give a table from "
                        "'pfsdm measure' or 'pfsdm trajectories'")
    if args.column not in numeric_columns(table, raw=True):
        raise UserError(f"{args.table} has no column of numbers called {args.column!r}; "
                        f"columns that can be drawn: {', '.join(numeric_columns(table)[:25])}")
    table = _follow_objects(table, args.link, args.quiet, command="plot")
    if args.groups:
        table, _groups = _with_groups(table, args.groups, args.quiet)
    fig = plt.figure(figsize=(7, 4.5))
    ax = fig.add_subplot()
    lines = plot_over_time(ax, table, args.column, selected=args.objects or ())
    unknown = sorted(set(args.objects or ()) - set(lines["object"]))
    if unknown:
        raise UserError(f"no object called {', '.join(unknown)}; objects are named as in "
                        f"the table's tracks, e.g. {', '.join(lines['object'].unique()[:3])}")
    ax.set_title(f"{args.column} over time ({lines['object'].nunique():,} objects)", fontsize=9)
    fig.tight_layout()
    save_figure(fig, out, dpi=120)
    plt.close(fig)
    _say(f"wrote {out}", args.quiet)
    if args.values:
        write_table_csv(lines, args.values, table_type="over_time",
                        extra={"table": str(args.table), "column": args.column})
        _say(f"wrote {args.values}: {len(lines):,} rows", args.quiet)
    return 0


def _report_labels(paths: Sequence[str], table, quiet: bool):
    """The label movie(s) of ``pfsdm report --labels``: one array (a table of one movie), or
    movie name -> array (the file names give the movies' names, as 'pfsdm measure' does)."""
    from .batch.io import open_movie
    from .batch.movies import movie_name

    movies = sorted(set(table["movie"].astype(str))) if "movie" in table.columns else []
    opened = {movie_name(p): open_movie(p) for p in paths}
    if len(opened) < len(paths):
        raise UserError("two --labels files have the same movie name; give each movie once")
    if len(movies) > 1 or (movies and len(paths) > 1):
        unknown = sorted(set(opened) - set(movies))
        if unknown:
            raise UserError(f"--labels {', '.join(unknown)}: no such movie in the table (its "
                            f"movies: {', '.join(movies[:5])}{' …' if len(movies) > 5 else ''})"
                            "; give the label movies the table was measured from")
        missing = sorted(set(movies) - set(opened))
        if missing:
            _note(f"no --labels for {len(missing)} movie(s) ({', '.join(missing[:3])}"
                  f"{' …' if len(missing) > 3 else ''}): their objects are drawn as "
                  "'not in the labels'", quiet)
        return opened
    if len(paths) > 1:
        raise UserError(f"{len(paths)} --labels files for a table of one movie; give one")
    return next(iter(opened.values()))


def cmd_report(args: argparse.Namespace) -> int:
    """Write one self-contained HTML report of a feature table."""
    from .batch.reports import load_features
    from .io import read_sidecar, read_table_csv
    from .report import write_report

    inputs = [args.features, *(args.labels or ()),
              *([args.groups] if args.groups else []),
              *([args.predictions] if args.predictions else [])]
    out = _check_output(args.output, "report", force=args.force, inputs=inputs)
    if out.suffix.lower() not in (".html", ".htm"):
        raise UserError(f"the report {out} is one HTML file: give a name ending in .html, "
                        "e.g. -o report.html")
    table = load_features(args.features)
    table = _follow_objects(table, args.link, args.quiet, command="report")
    if args.groups:
        table, _ = _with_groups(table, args.groups, args.quiet)
    labels = None
    if args.labels:
        from .analysis.report import check_labels

        labels = _report_labels(args.labels, table, args.quiet)
        check_labels(labels, table)
    predictions = info = None
    if args.predictions:
        if not Path(args.predictions).is_file():
            raise UserError(f"{args.predictions}: no such predictions file")
        try:
            predictions = read_table_csv(args.predictions)
        except ValueError as exc:
            raise UserError(f"{args.predictions}: {exc}") from None
        if not any(str(c).startswith("p_") for c in predictions.columns):
            raise UserError(f"{args.predictions} has no p_<group> columns: give the table "
                            "written by 'pfsdm predict'")
        info = read_sidecar(args.predictions) or {}
        if not info.get("curve"):
            _note(f"{args.predictions} has no accuracy curve in its .json sidecar: the "
                  "report shows the probabilities' summary only", args.quiet)
    with _Step(f"writing the report of {len(table):,} rows", args.quiet):
        write_report(out, table, labels=labels, predictions=predictions,
                     prediction_info=info, title=args.title, source=str(args.features),
                     force=args.force)
    size = out.stat().st_size
    _say(f"wrote {out} ({size / 1e6:.1f} MB; one file, opens offline in any browser)",
         args.quiet)
    return 0


def _follow_objects(table, link: str | None, quiet: bool, command: str = "trajectories"):
    """The table whose object ids follow objects over time: its ``track_id`` when it has one,
    a linked copy with ``--link centroid|laptrack``; refuses untracked labels otherwise."""
    from .analysis.tracking import link as link_table
    from .core.table_schema import NO_TRACK, TRACK_COLUMN

    if link in ("centroid", "laptrack"):
        with _Step(f"linking {len(table):,} objects into tracks ({link})", quiet):
            table = link_table(table, method=link)
        n = table.loc[table[TRACK_COLUMN] != NO_TRACK, TRACK_COLUMN].nunique()
        _note(f"linked by {link}: {n} tracks; trajectories follow them", quiet)
        return table
    if TRACK_COLUMN in table.columns:
        n_off = int((table[TRACK_COLUMN] == NO_TRACK).sum())
        if n_off:
            _note(f"left out {n_off} of {len(table)} rows that belong to no track "
                  f"({TRACK_COLUMN} = {NO_TRACK})", quiet)
        return table[table[TRACK_COLUMN] != NO_TRACK].reset_index(drop=True) \
            if n_off else table
    bad = _untracked_movies(table)
    if not bad:
        return table
    first = bad[0][1].message.split(". Link")[0]
    where = _which_movies(bad)
    if link == "none":
        _note(f"warning: {where}{first}; drawing by label anyway (--link none)", quiet)
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
        "--link none to draw by label anyway")


def _check_groups(table, groups, path: str) -> None:
    """Say in plain words when the groups file does not name the table's objects."""
    from .analysis.classification import format_frames

    named = sorted(set(groups["group"]))
    matched = sorted(set(table["group"]) - {""})
    if len(named) != 2:
        raise UserError(f"classify needs exactly two groups; {path} gives {len(named)}: "
                        f"{', '.join(named) or '(none)'}")
    if len(matched) == 2:
        return
    keys = [k for k in ("movie", "label") if k in groups.columns]
    have = {k: sorted(set(table[k].astype(str))) for k in keys}
    desc = "; ".join(
        f"the table's {k}s are {format_frames(map(int, v)) if k == 'label' else ', '.join(v[:5])}"
        for k, v in have.items()
    )
    missing = sorted(set(named) - set(matched))
    raise UserError(
        f"{path} names groups {' and '.join(named)}, but no measured object of the table "
        f"belongs to {' or '.join(missing)} ({desc}; the groups file gives "
        f"{', '.join(f'{k} ' + ', '.join(sorted(set(groups[k]))[:5]) for k in keys)}): "
        "its labels/movies must be those of the table"
    )


def _check_class_sizes(y, names: list[str], positive: str, test_size: float) -> None:
    """Refuse, in plain words, splits that scikit-learn cannot make."""
    import math

    n = len(y)
    n1 = int(y.sum())
    counts = {positive: n1, next(g for g in names if g != positive): n - n1}
    n_test = math.ceil(test_size * n)
    n_train = n - n_test
    small = [g for g, c in counts.items() if c < 2]
    txt = ", ".join(f"{c} {g}" for g, c in counts.items())
    if small:
        raise UserError(f"classify needs at least 2 objects in each group; there are {txt}. "
                        "Measure more objects or choose frames where more are present")
    if n_test < 2 or n_train < 2:
        raise UserError(
            f"{n} objects ({txt}) are too few for a {test_size:.0%} test split: it would hold "
            f"{n_test} object(s), and each side of a split needs one of each group. Measure "
            "more objects, or change --test-size (e.g. --test-size 0.5)"
        )


def cmd_predict(args: argparse.Namespace) -> int:
    from .analysis import classification as clf
    from .analysis.prediction import predict_outcome
    from .analysis.reduction import object_ids
    from .batch.reports import load_features
    from .core.table_options import table_options
    from .io import write_table_csv

    out = _check_output(args.output, force=args.force, inputs=[args.features])
    table = load_features(args.features)
    table, _ = _with_groups(table, args.groups, args.quiet)
    frames = clf.parse_frames(args.frames) if args.frames else None
    if frames is None or len(frames) > 1:
        table = _follow_objects(table, None, args.quiet, command="predict")
    table = table.assign(object=object_ids(table).to_numpy())
    groups = {o: g for o, g in zip(table["object"], table["group"], strict=True) if g}

    def tick(done: int, total: int) -> None:
        if done == total or done % max(1, total // 5) == 0:
            _note(f"predicting: step {done}/{total}", args.quiet)

    pred = predict_outcome(table, groups, frames, object_col="object", n_splits=args.splits,
                           n_repeats=args.repeats, seed=args.seed, progress=tick)
    summary = pred.summary.reset_index().rename(columns={"index": "method"})
    write_table_csv(pred.probabilities, out, table_options(table), table_type="predictions",
                    extra={"features": str(args.features), "groups": str(args.groups),
                           "frames": pred.frames, "channels": pred.channels,
                           "balanced_accuracy": summary.to_dict("records"),
                           "curve": pred.curve.to_dict("records")})
    for row in summary.itertuples():
        _say(f"{row.method:>16}: balanced accuracy {row.mean:.2f} ± {row.std:.2f}",
             args.quiet)
    _say(f"wrote {out}: {', '.join(pred.columns())} for {len(pred.probabilities)} objects "
         "(out-of-fold for those with a group)", args.quiet)
    return 0


def cmd_classify(args: argparse.Namespace) -> int:
    import numpy as np

    from .analysis import classification as clf
    from .analysis.reduction import object_ids
    from .batch.reports import load_features
    from .core.table_schema import has_channel
    from .io import write_table_csv

    if args.output:
        _check_output(args.output, force=args.force, inputs=[args.features])
    table = load_features(args.features)
    table, groups = _with_groups(table, args.groups, args.quiet)
    frames = clf.parse_frames(args.frames)
    if not table["frame"].isin(frames).any():
        raise UserError(f"no rows in frames {args.frames}: the table has frames "
                        f"{clf.format_frames(table['frame'])}; choose frames among these")
    table = table[table["frame"].isin(frames)]
    if len(frames) > 1:  # one object over several frames: its id must follow it
        table = _follow_objects(table, None, args.quiet, command="classify")
    _check_groups(table, groups, args.groups)
    table = table[table["group"] != ""].copy()
    table["object"] = object_ids(table)
    has_int = has_channel(table.columns, "intensity")
    ok, left = _measured(table, ["shape", "intensity"] if has_int else ["shape"], "rows",
                         args.quiet, need=0)
    # an object is used only when it has features in every chosen frame
    bad_objects = set(object_ids(left)) if len(left) else set()
    seen = ok.groupby("object")["frame"].nunique()
    incomplete = set(seen.index[seen < len(frames)]) | (set(table["object"]) - set(seen.index))
    dropped = sorted(bad_objects | incomplete)
    if incomplete - bad_objects:
        shown = ", ".join(sorted(incomplete - bad_objects)[:5])
        _note(f"left out {len(incomplete - bad_objects)} object(s) absent from some of frames "
              f"{clf.format_frames(frames)}: {shown}", args.quiet)
    table = ok[~ok["object"].isin(dropped)]
    names = sorted(set(groups["group"]))
    positive = args.positive or names[1]
    if positive not in names:
        raise UserError(f"--positive {positive!r} is not one of the groups {names}")
    group_of = table.drop_duplicates("object").set_index("object")["group"]
    objects = sorted(group_of.index)
    y = (group_of.loc[objects].to_numpy() == positive).astype(int)
    _check_class_sizes(y, names, positive, args.test_size)
    xs, objects = clf.feature_matrix(table, "shape", frames, object_col="object")
    xi = clf.feature_matrix(table, "intensity", frames, object_col="object")[0] if has_int else xs
    y = (group_of.loc[objects].to_numpy() == positive).astype(int)
    splits = clf.make_splits(y, n_splits=args.splits, test_size=args.test_size,
                             n_repeats=args.repeats, seed=args.seed)

    def tick(done: int, total: int) -> None:
        if done == total or done % max(1, total // 5) == 0:
            _note(f"classifying: split {done}/{total}", args.quiet)

    scores = clf.evaluate(clf.logistic_model(xs, xi, y), y, splits, seed=args.seed,
                          progress=tick)
    summary = clf.summarize(scores)
    if not has_int:
        summary = summary.loc[["shape"]]
    n1 = int(y.sum())
    other = names[0] if positive == names[1] else names[1]
    _say(f"{len(y)} objects ({n1} {positive}, {len(y) - n1} {other}), frames "
         f"{clf.format_frames(frames)}, {len(splits)} stratified splits "
         f"({args.test_size:.0%} test)", args.quiet)
    with np.printoptions(precision=3):
        import pandas as pd

        with pd.option_context("display.width", 120, "display.precision", 3):
            print(summary.to_string())
    if "fusion (optimistic, test-tuned)" in summary.index:
        _say("note: 'optimistic' tunes the fusion weight on the test split as the paper did; "
             "'nested' is the honest estimate", args.quiet)
    if args.output:
        out = summary.reset_index().rename(columns={"index": "features"})
        write_table_csv(out, args.output, {}, table_type="classification", extra={
            "features": str(args.features), "frames": frames, "positive": positive,
            "splits": len(splits), "objects_left_out": dropped,
            "left_out": left.to_dict("records")})
        _say(f"wrote {args.output}", args.quiet)
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    import numpy as np
    import pandas as pd
    import tifffile

    out = Path(args.output)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create the folder {out}: {exc.strerror}") from exc
    from .io import written_by_pfsdm

    # a folder an earlier demo filled (its features.csv is pfsdm's): the demo may replace its
    # own outputs there, plots of older versions (written without pfsdm's PNG mark) included
    own_folder = written_by_pfsdm(out / "features.csv")
    _check_output(out / "features.csv")
    _check_output(out / "mds.png", force=own_folder)  # drawn by the demo itself, below
    failed = []

    def synthetic_five_shapes() -> Any:
        from .experiments import synthetic_five_shapes

        return synthetic_five_shapes

    def gastruloid_report() -> Any:
        from .experiments import gastruloid_report

        return gastruloid_report

    steps = [
        ("synthetic five-shape benchmark", synthetic_five_shapes),
        ("gastruloid axis-number report", gastruloid_report),
    ]
    if args.quick_only:
        steps = []

    for title, load in steps:
        try:
            mod = load()
        except ImportError as exc:
            _say(f"== {title} ==")
            _say(f"   skipped: experiments.{load.__name__} is not available ({exc})")
            continue
        _say(f"== {title} ({mod.__name__}.run) ==")
        try:
            mod.run(out, quick=True)
        except Exception as exc:  # keep going: the other parts of the demo still run
            print(f"pfsdm: warning: {title} failed: {type(exc).__name__}: {exc}",
                  file=sys.stderr)
            failed.append(title)

    _say("== synthetic gastruloid time-lapse: measure, trajectories, distances ==")
    try:
        from .data.gastruloids import make_timelapse_montage
    except ImportError as exc:
        raise UserError(f"the bundled synthetic data is not available ({exc})") from exc
    labels, intensity, groups = make_timelapse_montage(seed=0)
    tifffile.imwrite(out / "montage_labels.tif", labels, compression="zlib")
    tifffile.imwrite(out / "montage_intensity.tif", intensity, compression="zlib")
    pd.DataFrame({"label": list(groups), "group": list(groups.values())}).to_csv(
        out / "groups.csv", index=False)
    _say(f"   wrote {out / 'montage_labels.tif'}, {out / 'montage_intensity.tif'} "
         f"({labels.shape[0]} frames, {len(groups)} objects) and {out / 'groups.csv'}")
    common = (["--quiet"] if args.quiet else []) + (["--force"] if own_folder else [])
    # what 'pfsdm measure montage_labels.tif --intensity montage_intensity.tif' does, with a
    # bar that counts objects as their frames are measured (every frame holds all objects)
    from .batch.movies import Movie
    from .batch.run import run_batch

    n_frames, per_frame = int(labels.shape[0]), len(groups)
    _say(f"measuring {out / 'montage_labels.tif'} with its reporter -> {out / 'features.csv'}",
         args.quiet)
    bar = None
    if not args.quiet:
        from tqdm import tqdm

        bar = tqdm(total=n_frames * per_frame, desc="measuring", unit="object",
                   file=sys.stderr, dynamic_ncols=True)

    def objects_done(name: str, done: int, total: int) -> None:
        if bar is not None:
            bar.update(done * per_frame - bar.n)
            if done >= total:
                bar.close()  # before the messages about the finished movie

    t0 = time.perf_counter()
    try:
        table = run_batch([Movie("montage", out / "montage_labels.tif",
                                 out / "montage_intensity.tif")], out / "features.csv",
                          scheduler=args.scheduler, frames_per_task=2, progress=objects_done,
                          log=lambda m: _say("  " + m, args.quiet), link="auto")
    finally:
        if bar is not None:
            bar.close()
    _say(f"wrote {out / 'features.csv'} (options in features.csv.json): {len(table)} objects "
         f"in {time.perf_counter() - t0:.1f} s", args.quiet)
    last = n_frames - 1
    rc = main(["trajectories", str(out / "features.csv"), "-o", str(out / "pca.csv"),
               "--plot", str(out / "pca.png"), "--groups", str(out / "groups.csv"),
               *common])
    rc = rc or main(["compare", str(out / "features.csv"), "-o", str(out / "distances.csv"),
                     "--frames", str(last), "--groups", str(out / "groups.csv"),
                     "--intensity-weight", "0.5", *common])
    if rc:
        return rc
    # the map of the last frame, titled with what it shows
    from .analysis.features import drop_failed
    from .analysis.reduction import attach_groups, mds_coordinates, read_groups
    from .analysis.tables import distance_matrix
    from .batch.reports import load_features, plot_mds

    table = load_features(out / "features.csv")
    shown = attach_groups(drop_failed(table[table["frame"] == last]).reset_index(drop=True),
                          read_groups(out / "groups.csv"))
    plot_mds(mds_coordinates(distance_matrix(shown, intensity_weight=0.5)), shown,
             out / "mds.png",
             title=f"PF-SDM distances (shape + 0.5 × intensity), 2-D MDS\n"
                   f"frame {last} (the last) of the time-lapse, {len(shown)} objects")
    _say(f"wrote {out / 'mds.png'} (classical MDS of frame {last}'s distances)", args.quiet)
    files = sorted(p.name for p in out.iterdir() if p.is_file())
    _say(f"demo done: {out} holds {', '.join(files)}")
    _ = np  # numpy imported for symmetry with the other commands
    if failed:
        print(f"pfsdm: error: demo parts failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


# --------------------------------------------------------------------------------------------
# parser
# --------------------------------------------------------------------------------------------

DESCRIPTION = """\
PF-SDM shape analysis of segmented objects, from the command line.

Typical session (a folder of label movies, one TIFF or Zarr per movie):

  pfsdm measure movies/ -o features.csv               one row per movie, frame and object
  pfsdm trajectories features.csv -o pca.csv --plot pca.png --groups groups.csv
  pfsdm compare features.csv --frames 0 -o distances.csv --mds mds.png
  pfsdm classify features.csv --groups groups.csv --frames 0-10
  pfsdm report features.csv -o report.html --groups groups.csv --labels labels.tif
  pfsdm demo -o results/                               all of it on bundled synthetic data

A groups.csv has a 'group' column and 'label' and/or 'movie' columns, e.g.
  movie,group
  gastruloid01,single-axis
"""


def _whole(flag: str, low: int) -> Callable[[str], int]:
    """argparse's ``type`` of a count: a whole number of at least ``low``, else one line
    saying so (``--workers 0`` was once taken as the default without a word)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < low:
            raise argparse.ArgumentTypeError(
                f"{flag} must be a whole number of at least {low}; got {text!r}")
        return value

    parse.__name__ = flag.lstrip("-")
    return parse


def _fraction(flag: str) -> Callable[[str], float]:
    """argparse's ``type`` of a fraction strictly between 0 and 1."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not 0.0 < value < 1.0:
            raise argparse.ArgumentTypeError(
                f"{flag} must be a number strictly between 0 and 1; got {text!r}")
        return value

    parse.__name__ = flag.lstrip("-")
    return parse


def _series_index(text: str) -> int:
    """``--series``: a whole number (negative counts from the last series)."""
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--series must be a whole number (0 = the first series); got {text!r}") from None


def _add_groups_link_force_quiet(p: argparse.ArgumentParser) -> None:
    """``--groups``, ``--link``, ``--force`` and ``-q`` as the table-reading commands take them."""
    p.add_argument("--groups", metavar="GROUPS.csv",
                   help="CSV with a 'group' column and 'label', 'track_id' and/or 'movie'")
    p.add_argument("--link", choices=("centroid", "laptrack", "none"),
                   help="as for 'pfsdm trajectories'")
    _add_force(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")


def _add_force(p: argparse.ArgumentParser) -> None:
    p.add_argument("--force", action="store_true",
                   help="replace output files even when pfsdm did not write them (by default "
                        "an existing file that is not a pfsdm table or plot is never replaced)")


def build_parser() -> argparse.ArgumentParser:
    """The argparse parser of ``pfsdm`` (used by :func:`main` and for the docs)."""
    from ._version import __version__

    fmt = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(prog="pfsdm", description=DESCRIPTION, formatter_class=fmt)
    parser.add_argument("--version", action="version", version=f"pfsdm {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show the full Python traceback on errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser(
        "measure", formatter_class=fmt,
        help="measure the shape (and reporter) of every object in label movies",
        description="""\
Measure every object of every frame of label movies into one CSV table.

LABELS are segmentations: each object one whole number, 0 = background; a 2-D image (Y, X) or
a time-lapse (T, Y, X). Give TIFF files (.tif/.tiff), Zarr arrays (.zarr) or OME-Zarr images
(the full-resolution level is read), a folder of these, or a glob such as 'plate1/*.tif'
(quote it). Several movies give one table with a 'movie' column (the file name).

The optional --intensity images (e.g. a Brachyury::mCherry reporter) must have the same size
as the labels; with several movies they pair by name: movie01_labels.tif <-> movie01_intensity.tif.

Long runs can be resumed: each finished movie is saved in FEATURES.csv.parts/; run the same
command again after an interruption and finished movies are skipped.

Objects are followed over time: labels from per-frame segmentation (cellpose, StarDist), whose
ids change between frames, are detected and linked by their centroids into a track_id
column (--link; 'pfsdm trajectories' follows it). Labels that already follow the
objects (from a tracker) are kept as they are.

examples:
  pfsdm measure embryo01_labels.tif --intensity embryo01_reporter.tif -o features.csv
  pfsdm measure 'plate1/*_labels.zarr' --intensity 'plate1/*_reporter.zarr' -o plate1.csv
  pfsdm measure archive/ -o archive.csv --scheduler tcp://10.0.0.5:8786
""")
    # "*" rather than "+": a labels file swallowed by -i gets a message that says so
    p.add_argument("labels", nargs="*", metavar="LABELS",
                   help="label movie(s): TIFF, Zarr or OME-Zarr files, folders or globs")
    p.add_argument("-i", "--intensity", nargs="+", metavar="IMAGE",
                   help="reporter movie(s) of the same size as the labels")
    p.add_argument("-o", "--output", required=True, metavar="FEATURES.csv",
                   help="the feature table to write (plain CSV; the options go into "
                        "FEATURES.csv.json beside it: keep the two together). A name "
                        "ending in .parquet writes Parquet (faster for large tables; pip "
                        "install \"napari-pfsdm[parquet]\"), which every command reads too")
    p.add_argument("--allow-empty", dest="allow_empty", action="store_true",
                   help="write an empty table when the labels hold no object (default: an "
                        "error, as labels with only background are usually the wrong file)")
    p.add_argument("--allow-missing-chunks", dest="allow_missing_chunks", action="store_true",
                   help="measure Zarr movies whose chunk files are not all on disk, reading "
                        "the missing ones as the fill value (empty), with a warning per frame "
                        "(default: an error, as a store that lost files in a copy looks "
                        "just the same)")
    p.add_argument("--series", type=_series_index, metavar="N",
                   help="the image series to read from TIFF files that hold several (OME-TIFF "
                        "positions, a thumbnail beside the image; 0 = the first); such a file "
                        "is refused without it")
    _add_force(p)
    p.add_argument("--link", choices=("auto", "none", "centroid", "overlap", "laptrack"),
                   default="auto",
                   help="follow objects over time (a track_id column): 'auto' (default) "
                        "checks each movie and, only when its label ids do not follow the "
                        "objects (per-frame segmentation), links them by their centroids "
                        "('centroid'); 'centroid', 'overlap' (of the label masks) or "
                        "'laptrack' (pip install laptrack) always link; 'none' never (a "
                        "warning says when the labels look untracked)")
    p.add_argument("--parts", metavar="DIR",
                   help="folder for per-movie results (default: FEATURES.csv.parts)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or messages")
    g3 = p.add_argument_group("3-D objects (Z-stacks)")
    g3.add_argument("--axes", metavar="AXES",
                    help="which axes the label files have: yx, tyx (a time-lapse of 2-D "
                         "frames: the default for 3-D files), zyx (one Z-stack of 3-D objects) "
                         "or tzyx (a time-lapse of Z-stacks; 4-D files must say so)")
    g3.add_argument("--spacing", nargs=3, type=float, metavar=("Z", "Y", "X"),
                    help="voxel size along Z, Y and X, e.g. --spacing 2 0.5 0.5 (µm); only "
                         "with --axes zyx or tzyx (default 1 1 1)")
    _add_method_options(p)
    _add_compute_options(p)
    p.set_defaults(func=cmd_measure)

    p = sub.add_parser(
        "compare", formatter_class=fmt,
        help="pairwise shape distances between objects (and a 2-D map of them)",
        description="""\
Pairwise PF-SDM distances between the objects of a feature table: 0 = same shape whatever its
position, size, rotation or mirror image. Writes a square CSV (rows and columns named
movie/t<frame>/l<label>) and, with --mds, a 2-D map where close points are similar shapes.

The default distance adds the pushed-forward SDF term and the boundary (outline) term;
--boundary-weight 0 keeps the SDF term alone. --rerank re-ranks the distances by the
collection's neighbourhoods: it helps retrieval in large collections (tens of objects per
kind), and can hurt with few objects per kind or when only the single nearest match counts.

examples:
  pfsdm compare features.csv --frames 0 -o distances.csv --mds mds.png
  pfsdm compare features.csv --frames 20-24 --intensity-weight 0.5 -o d.csv --groups groups.csv
  pfsdm compare features.csv -o reranked.csv --rerank --mds map.png
  pfsdm compare features.csv --neighbours 10 -o edges.csv --mds map.png
  pfsdm compare features.parquet --neighbours 10 --rerank -o edges.parquet

Many objects: --neighbours K writes each object's K nearest (an edge list, no n x n matrix);
above 2,000 objects the --mds map is drawn from the neighbour graph (t-SNE), and the output
says so. With --neighbours, --rerank re-ranks on the graph (diffusion or mutual).
""")
    p.add_argument("features", metavar="FEATURES.csv", help="table from 'pfsdm measure'")
    p.add_argument("-o", "--output", required=True, metavar="DISTANCES.csv",
                   help="the square distance table, or with --neighbours the edge list "
                        "(.parquet: written as Parquet)")
    p.add_argument("--neighbours", type=_whole("--neighbours", 1), metavar="K",
                   help="write each object's K nearest neighbours as an edge list (columns "
                        "row, neighbour, rank, distance and the frame/label keys of both "
                        "ends) instead of the n x n matrix: any number of objects")
    p.add_argument("--mds", metavar="PNG",
                   help="also draw a 2-D map of the distances: classical MDS up to "
                        f"{FULL_MATRIX_LIMIT:,} objects, above that t-SNE of each object's "
                        f"{MAP_NEIGHBOURS} nearest neighbours (--map)")
    p.add_argument("--map", choices=("tsne", "umap", "spectral"), default="tsne",
                   help=f"how the map of more than {FULL_MATRIX_LIMIT:,} objects is drawn from "
                        "the neighbour graph: 'tsne' (default; keeps kinds of shapes apart "
                        "best on MPEG-7), 'umap' (faster for tens of thousands of objects; pip "
                        "install \"napari-pfsdm[umap]\"), 'spectral' (fastest, mixes kinds)")
    p.add_argument("--frames", metavar="RANGE",
                   help="only these frames, e.g. 0, 0-10 or 0,5,10 (default: all rows)")
    from .analysis.rerank import RERANK_K, RERANK_METHODS
    from .core.params import option

    for name in ("intensity_weight", "boundary_weight"):  # ranges: core.params.WEIGHT_OPTIONS
        opt = option(name)
        p.add_argument(opt.flag, dest=name, type=_option_type(opt), default=opt.default,
                       metavar="W", help=f"{opt.help} (default {opt.default:g}; "
                                         f"{opt.allowed()})")
    p.add_argument("--rerank", nargs="?", const="diffusion", default=None,
                   choices=RERANK_METHODS, metavar="METHOD",
                   help="re-rank the distances (and the map) by the collection's "
                        f"neighbourhoods: {', '.join(RERANK_METHODS)} (default when given: "
                        "diffusion); for large collections, see 'pfsdm compare -h'")
    p.add_argument("--rerank-k", dest="rerank_k", type=_whole("--rerank-k", 1),
                   default=RERANK_K, metavar="K",
                   help=f"neighbours per object for --rerank (default {RERANK_K}: about the "
                        "number of objects per kind, at most); with --neighbours the graph "
                        "holds 3 K")
    p.add_argument("--groups", metavar="GROUPS.csv", help="colour the map by group")
    p.add_argument("--max-objects", type=_whole("--max-objects", 1), default=5000, metavar="N",
                   help="refuse larger matrices (default 5000; --neighbours has no limit)")
    _add_force(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=cmd_compare)

    p = sub.add_parser(
        "trajectories", formatter_class=fmt,
        help="PCA of all objects over time: one trajectory per object",
        description="""\
Principal component analysis of every (movie, frame, object) row. Each object becomes a
trajectory through shape space over time. Writes the PC scores (CSV) and, with --plot, a
figure with one line per object, coloured by time or by --groups (shape and reporter side by
side when the table has reporter features). Rings are weighted as in the distance, so
distances in the PCA space are PF-SDM distances.

An object is its track (the table's track_id column, from 'pfsdm measure --link') or, without
one, its label. Labels that do not follow objects between frames (each frame segmented and
numbered anew) are refused with a message: link them with --link centroid (as 'pfsdm
measure' does by default).

examples:
  pfsdm trajectories features.csv -o pca.csv --plot pca.png --groups groups.csv
  pfsdm trajectories cellpose_features.csv --link centroid -o pca.csv --plot pca.png
  pfsdm trajectories treated_features.csv --reference control_features.csv -o pca.csv
""")
    p.add_argument("features", metavar="FEATURES.csv", help="table from 'pfsdm measure'")
    p.add_argument("-o", "--output", required=True, metavar="PCA.csv")
    p.add_argument("--plot", metavar="PNG", help="draw the trajectories")
    p.add_argument("--groups", metavar="GROUPS.csv",
                   help="CSV with a 'group' column and 'label' and/or 'movie' columns")
    p.add_argument("--channel", choices=("shape", "intensity", "both"), default="both",
                   help="features to analyse (default both when the table has reporter ones)")
    p.add_argument("--components", type=_whole("--components", 1), default=3, metavar="K",
                   help="principal components to keep (default 3)")
    p.add_argument("--reference", metavar="REFERENCE.csv",
                   help="a feature table (e.g. a control movie's) whose PCA gives the axes: "
                        "FEATURES.csv is projected into that space; both must be measured "
                        "with the same options")
    p.add_argument("--show", type=_whole("--show", 1), nargs=2, default=(1, 2), metavar=("X", "Y"),
                   help="components drawn on the plot (default 1 2)")
    p.add_argument("--link", choices=("centroid", "laptrack", "none"),
                   help="link untracked labels from the table's centroids first "
                        "('centroid', or 'laptrack' when installed); 'none' draws by label "
                        "anyway. Default: follow the table's track_id, or its labels when "
                        "they follow the objects; refuse untracked labels")
    _add_force(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=cmd_trajectories)

    p = sub.add_parser(
        "classify", formatter_class=fmt,
        help="predict a later outcome (two groups) from early frames",
        description="""\
Predict each object's group (e.g. single-axis vs multi-axes) from its features at chosen
(early) frames, as in the paper: logistic regression with balanced class weights on shape and
on reporter features, and their late fusion, scored by repeated stratified shuffle splits.
Every object must be present, without error, in every chosen frame.

example:
  pfsdm classify features.csv --groups groups.csv --frames 0-10
""")
    p.add_argument("features", metavar="FEATURES.csv", help="table from 'pfsdm measure'")
    p.add_argument("--groups", required=True, metavar="GROUPS.csv",
                   help="CSV with a 'group' column (two groups) and 'label'/'movie' columns")
    p.add_argument("--frames", required=True, metavar="RANGE",
                   help="frames whose features are used, e.g. 0-10 or 0,5,10")
    p.add_argument("--positive", metavar="GROUP",
                   help="the group to detect (default: the second name alphabetically)")
    p.add_argument("--splits", type=_whole("--splits", 2), default=5,
                   help="splits per repeat (default 5)")
    p.add_argument("--test-size", type=_fraction("--test-size"), default=0.2,
                   help="test fraction (default 0.2)")
    p.add_argument("--repeats", type=_whole("--repeats", 1), default=3, help="repeats (default 3)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("-o", "--output", metavar="SCORES.csv", help="also write the score table")
    _add_force(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=cmd_classify)

    p = sub.add_parser(
        "predict", formatter_class=fmt,
        help="each object's probability of a group, from shape, reporter and classic measures",
        description="""\
Predict each object's group from its features at the chosen frames: the shape, the reporter
and the classic measures (area, circularity, ...) as three channels, fused late with weights
chosen inside each training split only. Prints the balanced accuracy of the fusion, of each
channel alone and of chance over repeated stratified splits; writes each object's p_<group>
(out-of-fold for the objects with a group, predicted for the others) with the scores and the
accuracy against the last frame used in its .csv.json.

example:
  pfsdm predict features.csv --groups groups.csv --frames 0-5 -o predictions.csv
""")
    p.add_argument("features", metavar="FEATURES.csv", help="table from 'pfsdm measure'")
    p.add_argument("--groups", required=True, metavar="GROUPS.csv",
                   help="CSV with a 'group' column (two groups) and 'label'/'track_id'/"
                        "'movie' columns; objects without a group are predicted only")
    p.add_argument("--frames", metavar="RANGE",
                   help="frames whose features are used, e.g. 0-5 (default: all)")
    p.add_argument("--splits", type=_whole("--splits", 2), default=5,
                   help="splits per repeat (default 5)")
    p.add_argument("--repeats", type=_whole("--repeats", 1), default=2, help="repeats (default 2)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("-o", "--output", required=True, metavar="PREDICTIONS.csv")
    _add_force(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=cmd_predict)

    p = sub.add_parser(
        "plot", formatter_class=fmt,
        help="any measure against time: each object's line, each group's mean ± sd",
        description="""\
Draw one column of a table (from 'pfsdm measure', or the PC scores of 'pfsdm trajectories')
against the frame: one thin line per object (its track), with --groups each group's mean ± sd
as a band, and the objects named with --objects in red. --values writes what is drawn as a
CSV (object, frame, label, value, group).

examples:
  pfsdm plot features.csv --column area -o area.png --groups groups.csv
  pfsdm plot pca.csv --column shape_PC1 -o pc1.png --objects track3 track7
""")
    p.add_argument("table", metavar="TABLE.csv", help="table with frame, label and the column")
    p.add_argument("--column", required=True, help="the column drawn (a column of numbers)")
    p.add_argument("-o", "--output", required=True, metavar="PNG")
    p.add_argument("--objects", nargs="+", metavar="OBJECT",
                   help="objects drawn in red, named as the table's tracks (track3, or "
                        "movie/track3 with several movies; a label without track_id)")
    p.add_argument("--values", metavar="CSV", help="also write the values drawn")
    _add_groups_link_force_quiet(p)
    p.set_defaults(func=cmd_plot)

    p = sub.add_parser(
        "report", formatter_class=fmt,
        help="one self-contained HTML report of a run, to share",
        description="""\
Write one HTML file that opens offline in any browser and can be mailed as it is: the run's
options (with what each means), the counts (objects, frames, tracks, rows left out and why),
each object's trajectory in the PCA plane per group, a few measures over time (each group's
mean ± sd), what PC1 … PC3 mean (the classic measure each follows, their loadings, the real
objects at -2σ … +2σ), the prediction curve with --predictions, and a gallery of the most
extreme objects per PC. Figures are inside the file; nothing is fetched from the internet.
The outlines of objects need the label movie (--labels).

examples:
  pfsdm report features.csv -o report.html --groups groups.csv --labels labels.tif
  pfsdm report features.csv -o report.html --predictions predictions.csv --title "Batch 3"
""")
    p.add_argument("features", metavar="FEATURES.csv", help="table from 'pfsdm measure'")
    p.add_argument("-o", "--output", required=True, metavar="REPORT.html")
    p.add_argument("--labels", nargs="+", metavar="LABELS.tif",
                   help="the label movie(s) the table was measured from (TIFF or Zarr), to "
                        "draw the objects' outlines; several movies are matched by file name")
    p.add_argument("--predictions", metavar="PREDICTIONS.csv",
                   help="the table of 'pfsdm predict' (its .json sidecar holds the accuracy "
                        "curve)")
    p.add_argument("--title", metavar="TEXT", help="the report's title")
    _add_groups_link_force_quiet(p)
    p.set_defaults(func=cmd_report)

    p = sub.add_parser(
        "demo", formatter_class=fmt,
        help="run everything on bundled synthetic data (no display needed)",
        description="""\
Run the whole analysis on bundled synthetic data and write tables and plots into a folder:
the five-shape benchmark, the gastruloid axis-number report, and a synthetic gastruloid
time-lapse measured from TIFF files -> features.csv, pca.csv/pca.png, distances.csv/mds.png.
""")
    p.add_argument("-o", "--output", default="results", metavar="DIR",
                   help="output folder (default: results)")
    p.add_argument("--scheduler", default="processes", metavar="WHERE",
                   help="as for 'pfsdm measure' (default processes)")
    p.add_argument("--quick-only", action="store_true",
                   help="skip the two benchmark reports; only the time-lapse part")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=cmd_demo)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``pfsdm`` with ``argv`` (default: the command line); return the exit status.

    0 on success; 2 for an error the user can fix (one plain ``pfsdm: error:`` line on stderr);
    1 for a bug (it says so and where to report it; ``--debug`` prints the traceback first, in
    both cases); 130 when interrupted.
    """
    import logging

    parser = build_parser()
    args = parser.parse_args(argv)
    if not args.debug:  # tifffile logs a damaged file's details; the error line says it
        logging.getLogger("tifffile").setLevel(logging.CRITICAL)
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("pfsdm: interrupted (finished movies are kept; run again to resume)",
              file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - sorted below into the user's and ours
        if args.debug:
            traceback.print_exc(file=sys.stderr)
        if _is_input_error(exc):
            msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            if isinstance(exc, OSError) and exc.filename and str(exc.filename) not in msg:
                msg = f"{exc.filename}: {msg}"
            print(f"pfsdm: error: {msg}", file=sys.stderr)
            return EXIT_USAGE
        text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        print(f"pfsdm: internal error (a bug of napari-pfsdm, not of your input): "
              f"{type(exc).__name__}{': ' + text if text else ''}", file=sys.stderr)
        print(f"pfsdm: {BUG_REPORT}"
              + ("" if args.debug else " (--debug prints the traceback)"), file=sys.stderr)
        return EXIT_BUG


def _is_input_error(exc: BaseException) -> bool:
    """Whether ``exc`` is the user's to fix (exit 2) rather than a bug (exit 1).

    An :class:`InputError` (raised where the input is wrong), an ``OSError`` (a file that cannot
    be read or written: missing, no permission, disk full) and an ``ImportError`` of an optional
    package that is not installed. An ``ImportError`` of napari-pfsdm's own modules, and every
    other exception (a plain ``ValueError`` from numpy included), is a bug.
    """
    if isinstance(exc, InputError | OSError):
        return True
    if isinstance(exc, ImportError):
        name = getattr(exc, "name", None) or ""
        return not name.startswith("napari_pfsdm")
    return False


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
