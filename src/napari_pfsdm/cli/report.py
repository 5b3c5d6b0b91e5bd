"""``pfsdm report``: one self-contained HTML report of a feature table."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from .common import (
    Step,
    UserError,
    add_elastic,
    add_groups_link_force_quiet,
    check_elastic,
    elastic_notice,
    file_argument,
    note,
    say,
)
from .tables import follow_objects, with_groups


def _report_labels(paths: Sequence[str], table, quiet: bool):
    """The label movie(s) of ``pfsdm report --labels``: one array (a table of one movie), or
    movie name -> array (the file names give the movies' names, as 'pfsdm measure' does)."""
    from ..batch.io import open_movie
    from ..batch.movies import movie_name

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
            note(f"no --labels for {len(missing)} movie(s) ({', '.join(missing[:3])}"
                  f"{' …' if len(missing) > 3 else ''}): their objects are drawn as "
                  "'not in the labels'", quiet)
        return opened
    if len(paths) > 1:
        raise UserError(f"{len(paths)} --labels files for a table of one movie; give one")
    return next(iter(opened.values()))


def cmd_report(args: argparse.Namespace) -> int:
    """Write one self-contained HTML report of a feature table."""
    from ..batch.reports import load_features
    from ..io import read_sidecar, read_table
    from ..report import write_report

    out = Path(args.output)  # checked with the inputs before the command ran (cli.main)
    if out.suffix.lower() not in (".html", ".htm"):
        raise UserError(f"the report {out} is one HTML file: give a name ending in .html, "
                        "e.g. -o report.html")
    table = load_features(args.features)
    check_elastic(table, args)
    table = follow_objects(table, args.link, args.quiet, command="report")
    if args.groups:
        table, _ = with_groups(table, args.groups, args.quiet, args.group_column)
    labels = None
    if args.labels:
        from ..analysis.report import check_labels
        from ..batch.movies import find_movies, movie_name

        paths = [str(p) for p in find_movies(args.labels)]  # files, folders or patterns
        labels = _report_labels(paths, table, args.quiet)
        names = ({movie_name(p): p for p in paths} if isinstance(labels, dict) else paths[0])
        check_labels(labels, table, names)  # by content: the objects of every frame
    predictions = info = None
    if args.predictions:
        if not Path(args.predictions).is_file():
            raise UserError(f"{args.predictions}: no such predictions file")
        try:
            predictions = read_table(args.predictions)
        except ValueError as exc:
            raise UserError(f"{args.predictions}: {exc}") from None
        if not any(str(c).startswith("p_") for c in predictions.columns):
            raise UserError(f"{args.predictions} has no p_<group> columns: give the table "
                            "written by 'pfsdm predict'")
        info = read_sidecar(args.predictions) or {}
        if not info.get("curve"):
            note(f"{args.predictions} has no accuracy curve in its .json sidecar: the "
                  "report shows the probabilities' summary only", args.quiet)
    with Step(f"writing the report of {len(table):,} rows", args.quiet), \
            elastic_notice(args):
        write_report(out, table, labels=labels, predictions=predictions,
                     prediction_info=info, title=args.title, source=str(args.features),
                     force=args.force, elastic_weight=args.elastic_weight)
    size = out.stat().st_size
    say(f"wrote {out} ({size / 1e6:.1f} MB; one file, opens offline in any browser)",
         args.quiet)
    return 0


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``pfsdm report`` to ``sub`` (the subcommands of
    :func:`~napari_pfsdm.cli.build_parser`, or the demo's own), ``cmd_*`` as its ``func``."""
    fmt = argparse.RawDescriptionHelpFormatter
    p = sub.add_parser(
        "report", formatter_class=fmt,
        help="one self-contained HTML report of a run, to share",
        description="""\
Write one HTML file that opens offline in any browser and can be mailed as it is: the run's
options (with what each means), the counts (objects, frames, tracks, rows left out and why),
each object's trajectory in the PCA plane per group, a few measures over time (each group's
mean ± sd), what PC1 … PC3 mean (the classic measure each follows, their loadings, the real
objects at -2σ … +2σ), the prediction curve with --predictions, a gallery of the most
extreme objects per PC, and a few objects' nearest shapes (with --elastic: under the distance
with the elastic outline term). Figures are inside the file; nothing is fetched from the
internet.
The outlines of objects need the label movie (--labels).

examples:
  pfsdm report features.csv -o report.html --groups groups.csv --labels labels.tif
  pfsdm report features.csv -o report.html --predictions predictions.csv --title "Batch 3"
""")
    file_argument(p, "features", role="input", kind="table", name="table",
                  metavar="FEATURES.csv", help="table from 'pfsdm measure'")
    file_argument(p, "-o", "--output", role="output", kind="report", required=True,
                  metavar="REPORT.html")
    file_argument(p, "--labels", role="input", kind="movie", nargs="+", metavar="LABELS.tif",
                   help="the label movie(s) the table was measured from (TIFF or Zarr files, "
                        "or a folder of them as 'pfsdm measure' takes it), to draw the objects' "
                        "outlines; several movies are matched by file name")
    file_argument(p, "--predictions", role="input", kind="table", metavar="PREDICTIONS.csv",
                   help="the table of 'pfsdm predict' (its .json sidecar holds the accuracy "
                        "curve)")
    p.add_argument("--title", metavar="TEXT", help="the report's title")
    add_elastic(p, "in the report's nearest shapes")
    add_groups_link_force_quiet(p)
    p.set_defaults(func=cmd_report)
