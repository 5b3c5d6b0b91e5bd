"""Late fusion against the best single family, for two to five groups.

Run from the repository root::

    .venv/bin/python benchmarks/prediction_fusion.py [--seeds 8]

Synthetic feature tables like a four-clone organoid study (40 objects a group over 6 frames):
the classic measures carry the groups strongly (areas differ), the shape features weakly
(a few of 64 columns), the reporter not at all. ``predict_outcome`` scores each family alone
and their late fusion over repeated stratified splits; the fusion weights are chosen inside
each training split by the balanced accuracy (the paper's choice) or by the log-loss of
out-of-fold predictions (the default). Prints, per number of groups and choice, the mean over
seeds of the fused and the best single family's balanced accuracy and their difference (with
its spread over the seeds). The target: the fusion at least the best family within noise.
"""

from __future__ import annotations

import argparse

import numpy as np
import pandas as pd

from napari_pfsdm.analysis import outcome


def study(n_groups: int, seed: int, per_group: int = 20, frames: int = 4,
          classic: float = 45.0, shape: float = 1.0) -> tuple:
    """A table of ``n_groups`` groups; ``classic``: how far apart the groups' areas are (the
    objects' own sizes spread by 25), ``shape``: how strongly the shape columns carry them."""
    rng = np.random.default_rng(seed)
    n = n_groups * per_group
    group = np.repeat(np.arange(n_groups), per_group)
    size = rng.normal(0, 1, n) * 25  # each object its own size, then the group's
    rows = []
    for t in range(frames):
        for k in range(n):
            g = group[k]
            row = {"frame": t, "label": k + 1, "error": ""}
            for r in range(4):
                for m in range(8):
                    signal = shape * (0.45 * (m == 2) * np.cos(g + r)
                                      + 0.35 * (m == 3) * np.sin(2 * g))
                    row[f"shape_r{r:02d}_n{m:02d}"] = rng.normal() + signal
                    row[f"intensity_r{r:02d}_n{m:02d}"] = rng.normal()
            row["area"] = 400 + classic * g + size[k] + 12 * rng.normal() + 10 * t
            row["circularity"] = 0.8 + 0.05 * rng.normal()
            row["intensity_mean"] = 1 + 0.1 * rng.normal()
            rows.append(row)
    table = pd.DataFrame(rows)
    return table, {k + 1: f"g{group[k]}" for k in range(n)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=6)
    parser.add_argument("--groups", type=int, nargs="+", default=[2, 3, 4])
    args = parser.parse_args(argv)
    rows = []
    cases = {"families alike": (45.0, 1.0), "classic strong, shape none": (90.0, 0.0)}
    for case, (classic, shape) in cases.items():
        for k in args.groups:
            for score in ("balanced_accuracy", "log_loss"):
                rows += _runs(case, k, score, args.seeds, classic, shape)
                print(f"  {case}, {k} groups, {score}: done", flush=True)
    frame = pd.DataFrame(rows)
    frame["fused - best"] = frame["fused"] - frame["best family"]
    out = frame.groupby(["case", "groups", "weights by"]).agg(
        fused=("fused", "mean"), best_family=("best family", "mean"),
        difference=("fused - best", "mean"), difference_sd=("fused - best", "std"),
        chance=("chance", "mean"), seeds=("seed", "size"))
    with pd.option_context("display.width", 140, "display.precision", 3):
        print(out.to_string())
    return 0


def _runs(case, k, score, seeds, classic, shape) -> list[dict]:
    rows = []
    outcome.WEIGHT_SCORE = score
    for seed in range(seeds):
        table, groups = study(k, seed, classic=classic, shape=shape)
        pred = outcome.predict_outcome(table, groups, object_col="label", n_repeats=2,
                                       curve=False, seed=seed)
        s = pred.summary["mean"]
        alone = s.drop(["fused", "chance"])
        rows.append({"case": case, "groups": k, "weights by": score, "seed": seed,
                     "fused": s["fused"], "best family": alone.max(),
                     "best is": alone.idxmax(), "chance": s["chance"]})
    return rows


if __name__ == "__main__":
    raise SystemExit(main())
