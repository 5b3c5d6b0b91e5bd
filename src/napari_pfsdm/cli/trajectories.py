"""``pfsdm trajectories``: the PCA of every row, each object a trajectory through shape
space."""

from __future__ import annotations

import argparse

from .common import (
    TABLE_LINKS,
    Step,
    UserError,
    add_force,
    add_groups,
    file_argument,
    say,
    whole_number,
)
from .tables import follow_objects, measured_rows, with_groups


def cmd_trajectories(args: argparse.Namespace) -> int:
    """Run ``pfsdm trajectories``: the PC scores of every row, and their plot."""
    import pandas as pd

    from ..analysis.shape_space import ShapePCA
    from ..batch.reports import load_features, plot_trajectories
    from ..core.table_options import table_options
    from ..core.table_schema import has_channel, pc_columns
    from ..io import write_table

    out = args.output  # checked with the inputs before the command ran (cli.main)
    if args.plot:
        if max(args.show) > args.components:
            raise UserError(f"--show {args.show[0]} {args.show[1]} names a component above "
                            f"--components {args.components}; show components from 1 to "
                            f"{args.components}, or raise --components")
    table = load_features(args.features)
    table = follow_objects(table, args.link, args.quiet)
    if args.groups:
        table, _ = with_groups(table, args.groups, args.quiet, args.group_column)
    has_int = has_channel(table.columns, "intensity")
    channels = {"shape": ["shape"], "intensity": ["intensity"],
                "both": ["shape", "intensity"] if has_int else ["shape"]}[args.channel]
    if "intensity" in channels and not has_int:
        raise UserError("the table has no intensity features; measure with --intensity IMAGE")
    table, left = measured_rows(table, list(dict.fromkeys(["shape", *channels])), "rows",
                            args.quiet)
    scores = None
    explained = {}
    reference = None
    if args.reference:  # a fitted shape space: the reference's axes (analysis.shape_space)
        reference = load_features(args.reference)
        reference, _ = measured_rows(reference, list(dict.fromkeys(["shape", *channels])),
                                 "reference rows", args.quiet)
    what = f" in the space of {args.reference}" if args.reference else ""
    with Step(f"PCA of {len(table):,} rows ({', '.join(channels)}){what}", args.quiet):
        for ch in channels:
            space = ShapePCA(n_components=args.components, channel=ch).fit(
                table if reference is None else reference)
            s, ev = space.transform(table), space.explained_variance_ratio_
            explained[ch] = ev
            if len(ev) < args.components:  # the PCA keeps at most rows or features
                raise UserError(
                    f"--components {args.components}: the {len(table):,} rows of "
                    f"{'the reference' if reference is not None else 'the table'} give at "
                    f"most {len(ev)} {ch} components; ask for at most {len(ev)}")
            scores = s if scores is None else pd.concat(
                [scores, s[pc_columns(s.columns, ch)]], axis=1)
    opts = table_options(table)
    write_table(scores, out, opts, table_type="pca", extra={
        "features": str(args.features),
        **({"reference": str(args.reference)} if args.reference else {}),
        "explained_variance": {ch: ev.tolist() for ch, ev in explained.items()},
        "left_out": left.to_dict("records")})
    ev_txt = ", ".join(
        f"{ch}: " + " ".join(f"{100 * v:.2g}%" for v in ev) for ch, ev in explained.items()
    )
    say(f"wrote {out}: {len(scores)} rows; variance explained by the PCs: {ev_txt}", args.quiet)
    if args.plot:
        with Step(f"drawing {args.plot}", args.quiet):
            plot_trajectories(scores, args.plot, components=tuple(args.show),
                              explained=explained, time_unit=opts.get("time_unit"))
        say(f"wrote {args.plot}", args.quiet)
    return 0


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``pfsdm trajectories`` to ``sub`` (the subcommands of
    :func:`~napari_pfsdm.cli.build_parser`, or the demo's own), ``cmd_*`` as its ``func``."""
    fmt = argparse.RawDescriptionHelpFormatter
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
    file_argument(p, "features", role="input", kind="table", name="table",
                  metavar="FEATURES.csv", help="table from 'pfsdm measure'")
    file_argument(p, "-o", "--output", role="output", kind="table", required=True,
                  metavar="PCA.csv")
    file_argument(p, "--plot", role="output", kind="plot", metavar="PNG",
                  help="draw the trajectories")
    add_groups(p, use="trajectories coloured by group")
    p.add_argument("--channel", choices=("shape", "intensity", "both"), default="both",
                   help="features to analyse (default both when the table has reporter ones)")
    p.add_argument("--components", type=whole_number("--components", 1), default=3, metavar="K",
                   help="principal components to keep (default 3)")
    file_argument(p, "--reference", role="input", kind="table", metavar="REFERENCE.csv",
                   help="a feature table (e.g. a control movie's) whose PCA gives the axes: "
                        "FEATURES.csv is projected into that space; both must be measured "
                        "with the same options")
    p.add_argument("--show", type=whole_number("--show", 1), nargs=2, default=(1, 2),
                   metavar=("X", "Y"),
                   help="components drawn on the plot (default 1 2)")
    p.add_argument("--link", choices=TABLE_LINKS,
                   help="how objects keep their identity: 'centroid' or 'laptrack' (when "
                        "installed) link the table's objects first, 'auto' only when their "
                        "labels do not follow them, 'labels' draws by label anyway. Default: "
                        "follow the table's track_id, or its labels when they follow the "
                        "objects; refuse untracked labels")
    add_force(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=cmd_trajectories)
