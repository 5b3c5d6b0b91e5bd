"""``pfsdm compare``: the distances between the objects of a table (the matrix, or each
object's nearest neighbours) and a 2-D map of them."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

# when a map is drawn from the neighbour graph, and how: one set of numbers for the command
# line and the plugin (napari_pfsdm.analysis.reduction)
from ..analysis.reduction import FULL_MATRIX_LIMIT, MAP_NEIGHBOURS, TSNE_SLOW
from .common import (
    Step,
    UserError,
    add_elastic,
    add_force,
    add_groups,
    check_elastic,
    elastic_notice,
    file_argument,
    note,
    option_type,
    say,
    whole_number,
)
from .tables import measured_rows, with_groups

#: Column that carries a row's position in the feature file through the selections.
_FILE_ROW = "_pfsdm_file_row"


def _matrix_limit() -> int | None:
    """The most objects whose n x n distance matrix (with the copies its work makes, about
    four of 8 bytes per pair) fits in this machine's memory; None where it cannot be told."""
    import os

    try:
        memory = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return None
    return max(2, int((memory / 32) ** 0.5))


def _select_frames(table, frames: str | None):
    """The rows of ``frames`` (``--frames``, e.g. ``0-10``); all rows when None."""
    if frames is None:
        return table
    from .common import selected_frames

    return table[table["frame"].isin(selected_frames(frames, table))]


def _nearest(table, k: int, args: argparse.Namespace):
    """Each object's k nearest, itself excluded (napari_pfsdm.nearest_neighbours)."""
    from ..analysis.neighbours import nearest_neighbours

    return nearest_neighbours(
        table, k=k, intensity_weight=args.intensity_weight,
        boundary_weight=args.boundary_weight, elastic_weight=args.elastic_weight)


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

    from ..analysis.tables import distance_matrix
    from ..core.table_options import carry_options

    rng = np.random.default_rng(0)
    pick = np.sort(rng.choice(len(table), size=min(size, len(table)), replace=False))
    sub = carry_options(table, table.iloc[pick].reset_index(drop=True))
    d = distance_matrix(sub, intensity_weight=args.intensity_weight,
                        boundary_weight=args.boundary_weight,
                        elastic_weight=args.elastic_weight)
    return float(np.median(d[~np.eye(len(d), dtype=bool)]))


_MAP_NAMES = {"tsne": "t-SNE", "umap": "UMAP", "spectral": "spectral embedding"}


def _draw_map(args, table, n: int, *, matrix=None, graph=None) -> None:
    """``--mds``: classical MDS of the full matrix up to FULL_MATRIX_LIMIT objects; above, a map
    of the neighbour graph (given, or from the matrix; ``--map``), and the output says so."""
    from ..analysis.reduction import graph_coordinates, mds_coordinates
    from ..batch.reports import plot_mds

    if n <= FULL_MATRIX_LIMIT:
        if matrix is None:
            from ..analysis.tables import distance_matrix

            with Step(f"computing the {n:,} x {n:,} distances of the map", args.quiet):
                matrix = distance_matrix(table, intensity_weight=args.intensity_weight,
                                         boundary_weight=args.boundary_weight,
                                         elastic_weight=args.elastic_weight)
                if args.rerank:
                    from ..analysis.rerank import rerank

                    matrix = rerank(matrix, args.rerank, k=min(args.rerank_k, n - 1))
        with Step(f"drawing the 2-D MDS map of {n:,} objects", args.quiet):
            plot_mds(mds_coordinates(matrix), table, args.mds)
        say(f"wrote {args.mds} (classical MDS of the full matrix)", args.quiet)
        return
    k = min(MAP_NEIGHBOURS, n - 1)
    if graph is None:
        graph = _graph_of_matrix(matrix, k)
    idx, dist = graph[0][:, :k], graph[1][:, :k]
    name = _MAP_NAMES[args.map]
    if args.map == "tsne" and n > TSNE_SLOW:
        note(f"t-SNE of {n:,} objects takes minutes (50,000: ~8 min here); --map umap "
              "draws it in under a minute (pip install \"napari-pfsdm[umap]\")", args.quiet)
    with Step(f"drawing the 2-D map of {n:,} objects from their {k} nearest neighbours "
               f"({name})", args.quiet):
        coords = graph_coordinates(idx, dist, args.map)
        plot_mds(coords, table, args.mds, axis_name=name.split()[0],
                 title=f"PF-SDM {k}-nearest-neighbour graph, {name}")
    say(f"wrote {args.mds}: a {name} map of the {k}-nearest-neighbour graph, not MDS "
         f"(above {FULL_MATRIX_LIMIT:,} objects the map is drawn from the neighbours, "
         "without the full matrix)", args.quiet)


def cmd_compare(args: argparse.Namespace) -> int:
    """Run ``pfsdm compare``: the distance matrix (or the neighbours) and the map; with
    ``--elastic``, numba's first compile of the term's kernels said on stderr."""
    with elastic_notice(args):
        return _compare(args)


def _compare(args: argparse.Namespace) -> int:
    import numpy as np
    import pandas as pd

    from ..analysis.reduction import distance_table
    from ..analysis.tables import distance_matrix
    from ..batch.reports import load_features
    from ..core.table_options import carry_options, table_options
    from ..io import write_table

    out = Path(args.output)  # checked with the inputs before the command ran (cli.main)
    if args.neighbours is not None and args.neighbours < 1:
        raise UserError(f"--neighbours must be a whole number >= 1, got {args.neighbours}")
    if args.neighbours is not None and args.rerank == "transduction":
        raise UserError("--rerank transduction needs the full matrix (it inverts an n x n "
                        "matrix); with --neighbours use --rerank diffusion or mutual")
    table = load_features(args.features)
    check_elastic(table, args)
    rows = pd.Series(np.arange(len(table)), index=table.index, name=_FILE_ROW)
    table = carry_options(table, pd.concat([table, rows], axis=1))  # one step: no fragments
    table = _select_frames(table, args.frames).reset_index(drop=True)
    if args.groups:
        table, _ = with_groups(table, args.groups, args.quiet, args.group_column)
    channels = ["shape"] + (["intensity"] if args.intensity_weight else [])
    table, left = measured_rows(table, channels, "objects", args.quiet)
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
    with Step(f"computing {n:,} x {n:,} distances", args.quiet):
        matrix = distance_matrix(table, intensity_weight=args.intensity_weight,
                                 boundary_weight=args.boundary_weight,
                                 elastic_weight=args.elastic_weight)
    if args.rerank:
        from ..analysis.rerank import rerank

        with Step(f"re-ranking them ({args.rerank})", args.quiet):
            matrix = rerank(matrix, args.rerank, k=min(args.rerank_k, n - 1))
    dist = distance_table(table, matrix)
    opts = table_options(table)
    opts["intensity_weight"] = args.intensity_weight
    opts["boundary_weight"] = args.boundary_weight
    opts["elastic_weight"] = args.elastic_weight
    opts["rerank"] = args.rerank or "none"
    if args.rerank:
        opts["rerank_k"] = min(args.rerank_k, n - 1)
    with Step(f"writing {out}", args.quiet):
        write_table(dist, out, opts, index=True, table_type="distances",
                        extra={"features": str(args.features),
                               "left_out": left.to_dict("records")})
    say(f"wrote {out}: {n} x {n} PF-SDM distances", args.quiet)
    if args.mds:
        _draw_map(args, table, n, matrix=matrix)
    return 0


def _compare_neighbours(args: argparse.Namespace, table, left, out: Path) -> int:
    """``compare --neighbours K``: the edge list of each object's K nearest (re-ranked on the
    graph with --rerank), never the n x n matrix."""
    from ..analysis.reduction import neighbour_table
    from ..core.table_options import table_options
    from ..io import write_table

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
    with Step(f"finding the {k_graph} nearest neighbours of {n:,} objects", args.quiet):
        found = _nearest(table, k_graph, args)
    idx, dist = found
    extra: dict[str, Any] = {}
    if not found.exact:  # the elastic term's search
        note(f"the neighbours with the elastic term are {found.describe()}", args.quiet)
        extra.update(neighbours_exact=False,
                     neighbours_certified_share=float(found.certified.mean()),
                     neighbours_searched=dict(zip(("pool", "candidates"), found.depth,
                                                  strict=True)))
    graph = (idx, dist)
    m = max(k, min(n - 1, MAP_NEIGHBOURS)) if args.mds and n > FULL_MATRIX_LIMIT else k
    if args.rerank:
        from ..analysis.rerank import rerank_neighbours

        scale = _median_distance(table, args)
        with Step(f"re-ranking them ({args.rerank}, k = {rk}) on the neighbour graph",
                   args.quiet):
            ridx, rdist, exact = rerank_neighbours(
                idx, dist, args.rerank, k=rk, scale=scale, n_neighbours=m, return_exact=True)
        share = float(exact.mean())
        note(f"re-ranked on the {k_graph}-neighbour graph: for {share:.0%} of the objects "
              "the neighbours are provably those of re-ranking the full matrix", args.quiet)
        extra.update(rerank_graph_neighbours=k_graph, rerank_scale=scale,
                     rerank_certified_share=share)
        graph = (ridx, rdist)
    edges = neighbour_table(table, graph[0][:, :k], graph[1][:, :k],
                            rows=table[_FILE_ROW].to_numpy())
    opts = table_options(table)
    opts["intensity_weight"] = args.intensity_weight
    opts["boundary_weight"] = args.boundary_weight
    opts["elastic_weight"] = args.elastic_weight
    opts["rerank"] = args.rerank or "none"
    if args.rerank:
        opts["rerank_k"] = rk
    opts["neighbours"] = k
    with Step(f"writing {out}", args.quiet):
        write_table(edges, out, opts, table_type="neighbours", extra={
            "features": str(args.features),
            "row": "the object's row in the features table (0 = its first data row)",
            "left_out": left.to_dict("records"), **extra})
    say(f"wrote {out}: the {k} nearest neighbours of each of {n:,} objects "
         f"({len(edges):,} rows{', re-ranked' if args.rerank else ''})", args.quiet)
    if args.mds:
        _draw_map(args, table, n, graph=graph)
    return 0


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``pfsdm compare`` to ``sub`` (the subcommands of
    :func:`~napari_pfsdm.cli.build_parser`, or the demo's own), ``cmd_*`` as its ``func``; the
    weights' arguments from the one record (``core.params.WEIGHT_OPTIONS``)."""
    fmt = argparse.RawDescriptionHelpFormatter
    p = sub.add_parser(
        "compare", formatter_class=fmt,
        help="pairwise shape distances between objects (and a 2-D map of them)",
        description="""\
Pairwise PF-SDM distances between the objects of a feature table: 0 = same shape whatever its
position, size, rotation or mirror image. Writes a square CSV (rows and columns named
movie/t<frame>/l<label>) and, with --mds, a 2-D map where close points are similar shapes.

The default distance adds the pushed-forward SDF term and the boundary (outline) term;
--boundary-weight 0 keeps the SDF term alone. --elastic adds the elastic outline term, which
lets the outlines' correspondence bend: it helps retrieval among articulated or detailed
outlines (limbs, notches, appendages), does nothing for round nuclei and can hurt clustering of
whole silhouettes (the table measured with --elastic-signature table). --rerank re-ranks the
distances by the collection's neighbourhoods: it helps retrieval in large collections (tens of
objects per kind), and can hurt with few objects per kind or when only the single nearest
match counts.

examples:
  pfsdm compare features.csv --frames 0 -o distances.csv --mds mds.png
  pfsdm compare features.csv --frames 20-24 --intensity-weight 0.5 -o d.csv --groups groups.csv
  pfsdm compare features.csv -o reranked.csv --rerank --mds map.png
  pfsdm compare features.csv --elastic -o elastic.csv
  pfsdm compare features.csv --neighbours 10 -o edges.csv --mds map.png
  pfsdm compare features.parquet --neighbours 10 --rerank -o edges.parquet

Many objects: --neighbours K writes each object's K nearest (an edge list, no n x n matrix);
above 2,000 objects the --mds map is drawn from the neighbour graph (t-SNE), and the output
says so. With --neighbours, --rerank re-ranks on the graph (diffusion or mutual).
""")
    file_argument(p, "features", role="input", kind="table", name="table",
                  metavar="FEATURES.csv", help="table from 'pfsdm measure'")
    file_argument(p, "-o", "--output", role="output", kind="table", required=True,
                  metavar="DISTANCES.csv",
                   help="the square distance table, or with --neighbours the edge list "
                        "(.parquet: written as Parquet)")
    p.add_argument("--neighbours", type=whole_number("--neighbours", 1), metavar="K",
                   help="write each object's K nearest neighbours as an edge list (columns "
                        "row, neighbour, rank, distance and the frame/label keys of both "
                        "ends) instead of the n x n matrix: any number of objects")
    file_argument(p, "--mds", role="output", kind="plot", metavar="PNG",
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
    from ..analysis.rerank import RERANK_K, RERANK_METHODS
    from ..core.params import option

    for name in ("intensity_weight", "boundary_weight"):  # ranges: core.params.WEIGHT_OPTIONS
        opt = option(name)
        p.add_argument(opt.flag, dest=name, type=option_type(opt), default=opt.default,
                       metavar="W", help=f"{opt.help} (default {opt.default:g}; "
                                         f"{opt.allowed()})")
    add_elastic(p, "--neighbours: the search is approximate and says so")
    p.add_argument("--rerank", nargs="?", const="diffusion", default=None,
                   choices=RERANK_METHODS, metavar="METHOD",
                   help="re-rank the distances (and the map) by the collection's "
                        f"neighbourhoods: {', '.join(RERANK_METHODS)} (default when given: "
                        "diffusion); for large collections, see 'pfsdm compare -h'")
    p.add_argument("--rerank-k", dest="rerank_k", type=whole_number("--rerank-k", 1),
                   default=RERANK_K, metavar="K",
                   help=f"neighbours per object for --rerank (default {RERANK_K}: about the "
                        "number of objects per kind, at most); with --neighbours the graph "
                        "holds 3 K")
    add_groups(p, use="the map coloured by group")
    p.add_argument("--max-objects", type=whole_number("--max-objects", 1, _matrix_limit(),
                                                " (a larger matrix and its work would not "
                                                "fit in this machine's memory; use "
                                                "--neighbours K)"),
                   default=5000, metavar="N",
                   help="refuse larger matrices (default 5000, at most what this machine's "
                        "memory holds; --neighbours has no limit)")
    add_force(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=cmd_compare)
