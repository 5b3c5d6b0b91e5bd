"""``pfsdm classify`` and ``pfsdm predict``: a later outcome (two groups) from the objects'
features at chosen frames."""

from __future__ import annotations

import argparse

from .common import (
    UserError,
    _add_force,
    _fraction,
    _note,
    _say,
    _seed,
    _whole,
    file_argument,
    selected_frames,
)
from .tables import _follow_objects, _measured, _with_groups


def _check_groups(table, groups, path: str) -> None:
    """Say in plain words when the groups file does not name the table's objects."""
    from ..analysis.classification import format_frames

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
    """Run ``pfsdm predict``: each object's probability of a group, out of fold."""
    from ..analysis.prediction import predict_outcome
    from ..analysis.reduction import object_ids
    from ..batch.reports import load_features
    from ..core.table_options import table_options
    from ..io import write_table_csv

    out = args.output  # checked with the inputs before the command ran (cli.main)
    table = load_features(args.features)
    table, _ = _with_groups(table, args.groups, args.quiet)
    frames = selected_frames(args.frames, table) if args.frames else None
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
    """Run ``pfsdm classify``: the balanced accuracy of shape, reporter and their fusion."""
    import numpy as np

    from ..analysis import classification as clf
    from ..analysis.reduction import object_ids
    from ..batch.reports import load_features
    from ..core.table_schema import has_channel
    from ..io import write_table_csv

    table = load_features(args.features)
    table, groups = _with_groups(table, args.groups, args.quiet)
    frames = selected_frames(args.frames, table)
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


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``pfsdm classify`` and ``pfsdm predict`` to ``sub`` (the subcommands of
    :func:`~napari_pfsdm.cli.build_parser`, or the demo's own), ``cmd_*`` as its ``func``."""
    fmt = argparse.RawDescriptionHelpFormatter
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
    file_argument(p, "features", role="input", kind="table", name="table",
                  metavar="FEATURES.csv", help="table from 'pfsdm measure'")
    file_argument(p, "--groups", role="input", kind="file", required=True, metavar="GROUPS.csv",
                   help="CSV with a 'group' column (two groups) and 'label'/'movie' columns")
    p.add_argument("--frames", required=True, metavar="RANGE",
                   help="frames whose features are used, e.g. 0-10 or 0,5,10")
    p.add_argument("--positive", metavar="GROUP",
                   help="the group to detect (default: the second name alphabetically)")
    p.add_argument("--splits", type=_whole("--splits", 2, 1000), default=5,
                   help="splits per repeat (default 5)")
    p.add_argument("--test-size", type=_fraction("--test-size"), default=0.2,
                   help="test fraction (default 0.2)")
    p.add_argument("--repeats", type=_whole("--repeats", 1, 1000), default=3,
                   help="repeats (default 3)")
    p.add_argument("--seed", type=_seed, default=0,
                   help="seed of the random splits (default 0)")
    file_argument(p, "-o", "--output", role="output", kind="table", metavar="SCORES.csv",
                  help="also write the score table")
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
    file_argument(p, "features", role="input", kind="table", name="table",
                  metavar="FEATURES.csv", help="table from 'pfsdm measure'")
    file_argument(p, "--groups", role="input", kind="file", required=True, metavar="GROUPS.csv",
                   help="CSV with a 'group' column (two groups) and 'label'/'track_id'/"
                        "'movie' columns; objects without a group are predicted only")
    p.add_argument("--frames", metavar="RANGE",
                   help="frames whose features are used, e.g. 0-5 (default: all)")
    p.add_argument("--splits", type=_whole("--splits", 2, 1000), default=5,
                   help="splits per repeat (default 5)")
    p.add_argument("--repeats", type=_whole("--repeats", 1, 1000), default=2,
                   help="repeats (default 2)")
    p.add_argument("--seed", type=_seed, default=0,
                   help="seed of the random splits (default 0)")
    file_argument(p, "-o", "--output", role="output", kind="table", required=True,
                  metavar="PREDICTIONS.csv")
    _add_force(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=cmd_predict)
