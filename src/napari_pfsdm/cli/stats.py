"""``pfsdm stats``: does a measure differ between groups, at a time or over time?"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from .common import UserError, add_force, add_groups, file_argument, say
from .tables import follow_objects, with_groups


def cmd_stats(args: argparse.Namespace) -> int:
    """Run ``pfsdm stats``: one value per object, the tests between groups, in words and as a
    table."""
    from ..analysis.group_stats import compare_groups, object_values, value_words
    from ..analysis.groups import group_columns
    from ..io import read_table, write_table

    out = args.output  # checked with the inputs before the command ran (cli.main)
    if not Path(args.table).is_file():
        raise UserError(f"{args.table}: no such table")
    table = read_table(args.table)
    table = follow_objects(table, None, args.quiet, command="stats")
    table, groups = with_groups(table, args.groups, args.quiet, args.group_column)
    summary = None if args.at is not None else (args.summary or "mean")
    keep = [c for c in group_columns(groups) if c != "group"]
    values = object_values(table, args.measure, at=args.at, summary=summary, keep=keep)
    what = value_words(table, args.measure, summary or "at", args.at)
    test = compare_groups(values, what=what)
    for line in test.sentences():
        say(line, args.quiet)
    write_table(test.table(), out, {}, table_type="group_statistics", extra={
        "table": str(args.table), "groups": str(args.groups), "group_column": args.group_column,
        "measure": args.measure, "at": args.at, "summary": summary, "value": what})
    say(f"wrote {out}: the test between all groups, every pair (Holm-corrected) and every "
         "group's median", args.quiet)
    if args.objects:
        write_table(values, args.objects, {}, table_type="object_values",
                        extra={"table": str(args.table), "value": what})
        say(f"wrote {args.objects}: one row per object ({len(values)})", args.quiet)
    return 0


def _number(text: str) -> float:
    """``--at``: a finite number (the table's times bound it: a time no object has is refused
    naming the table's times)."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"--at must be a time (a number); got {text!r}")
    return value


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``pfsdm stats`` to ``sub`` (the subcommands of
    :func:`~napari_pfsdm.cli.build_parser`), ``cmd_*`` as its ``func``."""
    from ..analysis.group_stats import SUMMARIES

    fmt = argparse.RawDescriptionHelpFormatter
    p = sub.add_parser(
        "stats", formatter_class=fmt,
        help="do the groups differ in a measure, at a time or in its change over time?",
        description="""\
Give each object one value of a measure (a column of the table: area, circularity,
shape_PC1 of 'pfsdm trajectories', …): its value at a time (--at, in the table's time unit,
or the frame when it has no times; a time imaged twice: their mean), or a summary of its time
course (--summary slope: the change per unit of time, e.g. growth in µm² per day; mean, first,
last). Then test whether the groups differ: Kruskal-Wallis for three groups or more,
Mann-Whitney for two, every pair by Mann-Whitney with Holm's correction, with effect sizes
(epsilon squared; the rank-biserial correlation of a pair) and each group's median and count.
Objects, not frames, are the units.

examples:
  pfsdm stats features.csv --groups groups.csv --group-column clone --measure area --at 30 \\
      -o area_day30.csv
  pfsdm stats features.csv --groups groups.csv --measure area --summary slope -o growth.csv \\
      --objects growth_per_object.csv
""")
    file_argument(p, "table", role="input", kind="table", name="table", metavar="TABLE.csv",
                  help="a table of 'pfsdm measure' (or 'pfsdm trajectories')")
    p.add_argument("--measure", required=True, metavar="COLUMN", help="the column tested")
    when = p.add_mutually_exclusive_group()
    when.add_argument("--at", type=_number, metavar="TIME",
                      help="the objects' values at this time (the table's time unit)")
    when.add_argument("--summary", choices=SUMMARIES,
                      help="a summary of each object's time course (default mean)")
    add_groups(p, required=True)
    file_argument(p, "-o", "--output", role="output", kind="table", required=True,
                  metavar="STATS.csv", help="the tests and the groups' medians")
    file_argument(p, "--objects", role="output", kind="table", metavar="VALUES.csv",
                  help="also write each object's value")
    add_force(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=cmd_stats)
