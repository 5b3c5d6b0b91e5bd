"""``pfsdm classify`` and ``pfsdm predict``: the objects' groups (two or more) from their
features at chosen frames, and a model of one table applied to another."""

from __future__ import annotations

import argparse

from .common import (
    UserError,
    add_force,
    add_groups,
    file_argument,
    fraction_number,
    note,
    say,
    seed_number,
    selected_frames,
    whole_number,
)
from .tables import follow_objects, with_groups


def _prepared(args: argparse.Namespace, path: str, command: str = "predict"):
    """The table at ``path`` with its groups (``args.groups``, ``args.group_column``), its
    objects followed over several frames, and the frames chosen."""
    from ..batch.reports import load_features

    table = load_features(path)
    table, groups = with_groups(table, args.groups, args.quiet, args.group_column)
    frames = selected_frames(args.frames, table) if args.frames else None
    if frames is None or len(frames) > 1:  # one object over several frames: its id follows it
        table = follow_objects(table, None, args.quiet, command=command)
    return table, groups, frames


def _object_groups(table) -> dict[str, str]:
    """Object id (``movie/track`` or ``movie/label``) → group, for the objects with one."""
    from ..analysis.reduction import object_ids

    ids = object_ids(table).to_numpy()
    return {o: g for o, g in zip(ids, table["group"], strict=True) if g}


def _ticker(what: str, quiet: bool):
    def tick(done: int, total: int) -> None:
        if done == total or done % max(1, total // 5) == 0:
            note(f"{what}: step {done}/{total}", quiet)

    return tick


def _evaluation(args: argparse.Namespace, table, frames, what: str = "predicting",
                curve: bool = True):
    """The cross-validated prediction of the groups (analysis.outcome.predict_outcome)."""
    from ..analysis.outcome import predict_outcome

    try:
        return predict_outcome(table, _object_groups(table), frames, n_splits=args.splits,
                               n_repeats=args.repeats, seed=args.seed, curve=curve,
                               test_size=args.test_size, progress=_ticker(what, args.quiet))
    except ValueError as exc:
        raise UserError(str(exc)) from None


def _times_of(table, frames) -> str:
    """`` (days 2, 5, 8)``: the frames' times when the table has them (the first movie's)."""
    from ..analysis.physical import time_unit_of

    if "time" not in table.columns:
        return ""
    first = table[table["movie"] == table["movie"].iloc[0]] if "movie" in table else table
    at = first.drop_duplicates("frame").set_index("frame")["time"]
    shown = ", ".join(f"{at[f]:g}" for f in frames if f in at.index)
    unit = time_unit_of(table)
    words = f"{unit}s" if unit == "day" else (unit or "time")
    return f" ({words} {shown})" if shown else ""


def _print_scores(pred, quiet: bool, table) -> None:
    """The balanced accuracy of each family and of the fusion, and the confusion matrix."""
    from ..analysis.outcome import FAMILY_WORDS

    counts = pred.probabilities.loc[pred.probabilities["group"] != "", "group"].value_counts()
    say(f"{pred.n_scored} objects with a group ("
         + ", ".join(f"{counts.get(g, 0)} {g}" for g in pred.groups)
         + f"), frames {', '.join(map(str, pred.frames))}{_times_of(table, pred.frames)}, "
         f"{int(pred.summary.loc['fused', 'n_splits'])} stratified splits, each object with "
         "all its frames on one side", quiet)
    for method, row in pred.summary.iterrows():
        words = "fused (weights chosen inside each training split)" if method == "fused" \
            else FAMILY_WORDS.get(method.replace(" alone", ""), method) + (
                " alone" if method.endswith("alone") else "")
        sd = f" ± {row['std']:.2f}" if method != "chance" else ""
        say(f"  {words:>52}: balanced accuracy {row['mean']:.2f}{sd}", quiet)
    say("confusion matrix of the fused model (rows: true group, columns: predicted; counts "
         "over the test splits):", quiet)
    say(pred.confusion.to_string(), quiet)


def _family_rows(pred):
    """One row per family (and the fusion, chance): what ``classify -o`` writes."""
    import pandas as pd

    from ..analysis.outcome import FAMILY_WORDS

    rows = []
    for method, row in pred.summary.iterrows():
        family = method.replace(" alone", "")
        rows.append({"family": FAMILY_WORDS.get(family, family), "balanced_accuracy":
                     float(row["mean"]), "sd": float(row["std"]), "splits": int(row["n_splits"]),
                     "objects": pred.n_scored, "groups": len(pred.groups)})
    return pd.DataFrame(rows)


def cmd_classify(args: argparse.Namespace) -> int:
    """Run ``pfsdm classify``: how well each feature family and their fusion tell the groups
    apart (balanced accuracy, confusion matrix)."""
    from ..io import write_table

    table, groups, frames = _prepared(args, args.features, command="classify")
    pred = _evaluation(args, table, frames, what="classifying", curve=False)
    _print_scores(pred, args.quiet, table)
    if args.output:
        write_table(_family_rows(pred), args.output, {}, table_type="classification",
                        extra={"features": str(args.features), "groups": str(args.groups),
                               "group_column": args.group_column, "frames": pred.frames,
                               "confusion": {"groups": list(pred.groups),
                                             "counts": pred.confusion.to_numpy().tolist()}})
        say(f"wrote {args.output}: one row per family with its balanced_accuracy", args.quiet)
    return 0


def cmd_predict(args: argparse.Namespace) -> int:
    """Run ``pfsdm predict``: each object's probability of every group, out of fold; or, with
    ``--on``, of another table's objects from a model of this table's."""
    from ..core.table_options import table_options
    from ..io import write_table

    out = args.output  # checked with the inputs before the command ran (cli.main)
    table, groups, frames = _prepared(args, args.features)
    if args.on:
        return _predict_other(args, table, frames, out)
    pred = _evaluation(args, table, frames)
    _print_scores(pred, args.quiet, table)
    summary = pred.summary.reset_index().rename(columns={"index": "method"})
    probs = _with_keys(pred.probabilities, table)
    write_table(probs, out, table_options(table), table_type="predictions",
                    extra={"features": str(args.features), "groups": str(args.groups),
                           "frames": pred.frames, "channels": pred.channels,
                           "balanced_accuracy": summary.to_dict("records"),
                           "confusion": {"groups": list(pred.groups),
                                         "counts": pred.confusion.to_numpy().tolist()},
                           "curve": pred.curve.to_dict("records")})
    say(f"wrote {out}: predicted and {', '.join(pred.columns())} for {len(probs)} objects "
         "(out-of-fold for those with a group)", args.quiet)
    return 0


def _with_keys(probabilities, table):
    """The probabilities with the key columns of each object's first row (movie, track_id,
    label) before them."""
    from ..analysis.reduction import object_ids

    keys = [c for c in ("movie", "track_id", "label") if c in table.columns]
    first = table[keys].assign(object=object_ids(table).to_numpy()).drop_duplicates("object")
    out = probabilities.merge(first[["object", *keys]], on="object", how="left")
    return out[["object", *keys, *[c for c in probabilities.columns if c != "object"]]]


def _predict_other(args: argparse.Namespace, table, frames, out) -> int:
    """``pfsdm predict TRAIN --on OTHER``: the model of TRAIN's labelled objects applied to
    OTHER's objects."""
    from ..analysis.outcome import fit_outcome
    from ..batch.reports import load_features
    from ..core.table_options import table_options
    from ..io import write_table

    try:
        model = fit_outcome(table, _object_groups(table), frames, seed=args.seed)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    other = load_features(args.on)
    if len(model.frames) > 1:
        other = follow_objects(other, None, args.quiet, command="predict")
    try:
        got = model.predict(other, say=lambda m: note(f"warning: {m}"))
    except ValueError as exc:
        raise UserError(f"{args.on}: {exc}") from None
    write_table(got, out, table_options(other), table_type="predictions", extra={
        "trained_on": str(args.features), "groups": str(args.groups),
        "predicted": str(args.on), "frames": model.frames, "channels": model.channels,
        "weights": list(model.weights)})
    counts = got["predicted"].value_counts()
    say(f"wrote {out}: {len(got)} objects of {args.on} predicted by the model of "
         f"{args.features} (" + ", ".join(f"{counts.get(g, 0)} {g}" for g in model.groups)
         + ")", args.quiet)
    return 0


def _add_common(p: argparse.ArgumentParser, frames_required: bool) -> None:
    file_argument(p, "features", role="input", kind="table", name="table",
                  metavar="FEATURES.csv", help="table from 'pfsdm measure'")
    p.add_argument("--frames", required=frames_required, metavar="RANGE",
                   help="frames whose features are used, e.g. 0-5 or 0,5,10"
                        + ("" if frames_required else " (default: all)"))
    p.add_argument("--splits", type=whole_number("--splits", 2, 1000), default=5,
                   help="splits per repeat (default 5)")
    p.add_argument("--repeats", type=whole_number("--repeats", 1, 1000), default=2,
                   help="repeats (default 2)")
    p.add_argument("--test-size", type=fraction_number("--test-size"), default=0.2,
                   help="the share of the objects each split tests (default 0.2)")
    p.add_argument("--seed", type=seed_number, default=0,
                   help="seed of the random splits (default 0)")


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``pfsdm classify`` and ``pfsdm predict`` to ``sub`` (the subcommands of
    :func:`~napari_pfsdm.cli.build_parser`, or the demo's own), ``cmd_*`` as its ``func``."""
    fmt = argparse.RawDescriptionHelpFormatter
    p = sub.add_parser(
        "classify", formatter_class=fmt,
        help="how well shape, reporter and classic measures tell the groups apart",
        description="""\
How well each family of features tells the objects' groups apart (two groups or more: clones,
genotypes, an outcome such as single vs multiple axes) from their features at chosen frames:
the shape, the reporter and the classic measures (area, circularity, ...) each alone, and their
late fusion with weights chosen inside each training split. Scored by the balanced accuracy
over repeated stratified splits (each object, with all its frames, on one side of every
split) against chance (1 / groups), with the fused model's confusion matrix.

example:
  pfsdm classify features.csv --groups groups.csv --group-column clone --frames 0-3 \\
      -o scores.csv
""")
    _add_common(p, frames_required=True)
    add_groups(p, required=True)
    file_argument(p, "-o", "--output", role="output", kind="table", metavar="SCORES.csv",
                  help="also write the scores: one row per family with its balanced_accuracy "
                       "(the confusion matrix in SCORES.csv.json)")
    add_force(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=cmd_classify)

    p = sub.add_parser(
        "predict", formatter_class=fmt,
        help="each object's probability of every group; or of another table's objects",
        description="""\
Predict each object's group from its features at the chosen frames: the shape, the reporter
and the classic measures (area, circularity, ...) fused late with weights chosen inside each
training split only. Prints the balanced accuracy of the fusion, of each family alone and of
chance, and the confusion matrix; writes each object's predicted group and p_<group> for every
group (out-of-fold for the objects with a group, predicted for the others).

With --on OTHER.csv, a model of all the objects of FEATURES.csv that have a group predicts
the objects of OTHER.csv (a second microscope, a new plate): one row per object of OTHER
(movie, label or track_id, predicted, p_<group>). OTHER must be measured with the same
options; when the classic measures' sizes are in pixels of different or unknown pixel sizes,
a warning says so.

examples:
  pfsdm predict features.csv --groups groups.csv --frames 0-5 -o predictions.csv
  pfsdm predict labA.csv --groups groups.csv --group-column clone --frames 0-3 \\
      --on labB.csv -o labB_predicted.csv
""")
    _add_common(p, frames_required=False)
    add_groups(p, required=True, use="objects without a group are predicted only")
    file_argument(p, "--on", role="input", kind="table", name="--on", metavar="OTHER.csv",
                  help="predict this table's objects with a model of FEATURES.csv's")
    file_argument(p, "-o", "--output", role="output", kind="table", required=True,
                  metavar="PREDICTIONS.csv")
    add_force(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=cmd_predict)
