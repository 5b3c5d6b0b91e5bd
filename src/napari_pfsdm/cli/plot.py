"""``pfsdm plot``: one column of a table against time."""

from __future__ import annotations

import argparse
from pathlib import Path

from .common import UserError, add_groups_link_force_quiet, file_argument, say
from .tables import follow_objects, with_groups


def cmd_plot(args: argparse.Namespace) -> int:
    """Draw one column of a table against time: each object's line, each group's mean ± sd."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..analysis.over_time import numeric_columns, plot_over_time
    from ..analysis.plot_text import plot_text
    from ..io import read_table, save_figure, write_table

    out = args.output  # checked with the inputs before the command ran (cli.main)
    if not Path(args.table).is_file():
        raise UserError(f"{args.table}: no such table")
    try:
        table = read_table(args.table)
    except ValueError as exc:
        raise UserError(f"{args.table}: {exc}") from None
    if "frame" not in table.columns or "label" not in table.columns:
        raise UserError(f"{args.table} has no frame and label columns: give a table from "
                        "'pfsdm measure' or 'pfsdm trajectories'")
    if args.column not in numeric_columns(table, raw=True):
        raise UserError(f"{args.table} has no column of numbers called {args.column!r}; "
                        f"columns that can be drawn: {', '.join(numeric_columns(table)[:25])}")
    table = follow_objects(table, args.link, args.quiet, command="plot")
    if args.groups:
        table, _groups = with_groups(table, args.groups, args.quiet, args.group_column)
    fig = plt.figure(figsize=(7, 4.5))
    ax = fig.add_subplot()
    lines = plot_over_time(ax, table, args.column, selected=args.objects or ())
    unknown = sorted(set(args.objects or ()) - set(lines["object"]))
    if unknown:
        raise UserError(f"no object called {', '.join(unknown)}; objects are named as in "
                        f"the table's tracks, e.g. {', '.join(lines['object'].unique()[:3])}")
    ax.set_title(f"{plot_text(args.column)} over time ({lines['object'].nunique():,} objects)",
                 fontsize=9)
    fig.tight_layout()
    save_figure(fig, out, dpi=120)
    plt.close(fig)
    say(f"wrote {out}", args.quiet)
    if args.values:
        write_table(lines, args.values, table_type="over_time",
                        extra={"table": str(args.table), "column": args.column})
        say(f"wrote {args.values}: {len(lines):,} rows", args.quiet)
    return 0


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``pfsdm plot`` to ``sub`` (the subcommands of
    :func:`~napari_pfsdm.cli.build_parser`, or the demo's own), ``cmd_*`` as its ``func``."""
    fmt = argparse.RawDescriptionHelpFormatter
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
    file_argument(p, "table", role="input", kind="table", name="table", metavar="TABLE.csv",
                  help="table with frame, label and the column")
    p.add_argument("--column", required=True, help="the column drawn (a column of numbers)")
    file_argument(p, "-o", "--output", role="output", kind="plot", required=True, metavar="PNG")
    p.add_argument("--objects", nargs="+", metavar="OBJECT",
                   help="objects drawn in red, named as the table's tracks (track3, or "
                        "movie/track3 with several movies; a label without track_id)")
    file_argument(p, "--values", role="output", kind="table", metavar="CSV",
                  help="also write the values drawn")
    add_groups_link_force_quiet(p)
    p.set_defaults(func=cmd_plot)
