"""Linking per-frame labels into tracks: overlap matching, centroid LAP (built in), laptrack.

Movies from :func:`napari_pfsdm.data.moving_blobs.make_moving_blobs` (512 × 512, 40 frames,
25 deforming, drifting, touching blobs, 4 entering and 4 leaving the field, one division: about
a thousand objects), relabelled as per-frame segmentation numbers them (ids shuffled every
frame). Each method links the relabelled movie; the truth is the generator's identities.

Scored per method, over all seeds of a scenario:

* ``recovered``: fraction of the true links (an object's consecutive appearances, and mother
  → daughters at the division) that the method makes;
* ``false``: links the method makes between two different objects (identity switches), and
  their fraction of its links;
* ``agree``: fraction of rows whose track and true object are each other's majority (the
  target: ≥ 95 % with ids shuffled every frame);
* ``s/movie``: linking time per movie (the table's centroids are measured beforehand).

The second table checks :func:`napari_pfsdm.analysis.tracking.check_tracking` on tracked,
shuffled, new-id and scan-order labels of the same movies: the evidence for its thresholds.

Run: ``PYTHONPATH=src python benchmarks/linking.py [--seeds 3] [--quick]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd

from napari_pfsdm.analysis import tracking as tk
from napari_pfsdm.data.moving_blobs import (
    RELABELLINGS,
    centroid_table,
    make_moving_blobs,
    relabel,
)

SCENARIOS = {
    "drifting, touching, 1 division": dict(),
    "+ 2 % of objects missed per frame": dict(dropout=0.02),
    "fast (speed 5, drift 3 px/frame)": dict(speed=5.0, drift=3.0),
    "faster (speed 9, drift 4 px/frame)": dict(speed=9.0, drift=4.0),
    "crowded (70 objects, radius 20-32 px)": dict(n_objects=70, radius=(20.0, 32.0)),
    "small and fast (radius 6-12, speed 6)": dict(radius=(6.0, 12.0), speed=6.0, drift=2.0),
}


def _links(frame: np.ndarray, ident: np.ndarray) -> set[tuple[int, int]]:
    """Pairs of row indices: consecutive appearances of each identity."""
    order = np.lexsort((frame, ident))
    same = ident[order][1:] == ident[order][:-1]
    ok = same & (ident[order][1:] >= 0)
    return set(zip(order[:-1][ok].tolist(), order[1:][ok].tolist(), strict=True))


def score(table: pd.DataFrame, true_id: np.ndarray, track: np.ndarray,
          parents: dict[int, int]) -> dict[str, float]:
    frame = table["frame"].to_numpy()
    true = _links(frame, true_id)
    for daughter, mother in parents.items():  # division links: mother's last -> daughter's first
        m = np.flatnonzero(true_id == mother)
        d = np.flatnonzero(true_id == daughter)
        if len(m) and len(d):
            true.add((int(m[np.argmax(frame[m])]), int(d[np.argmin(frame[d])])))
    pred = _links(frame, track)
    pred = {(a, b) if frame[a] < frame[b] else (b, a) for a, b in pred}
    hit = len(pred & true)
    false = len(pred - true)
    # one-to-one majority agreement of rows
    df = pd.DataFrame({"t": true_id, "p": track})
    maj_p = df.groupby("t")["p"].agg(lambda s: s.value_counts().index[0])
    maj_t = df.groupby("p")["t"].agg(lambda s: s.value_counts().index[0])
    agree = np.mean((df["p"].map(maj_t).to_numpy() == df["t"].to_numpy())
                    & (df["t"].map(maj_p).to_numpy() == df["p"].to_numpy())
                    & (track >= 0))
    return {"true": len(true), "hit": hit, "false": false, "pred": len(pred),
            "agree_rows": float(agree) * len(df), "rows": len(df)}


def methods(radius: float) -> dict:
    return {
        "overlap IoU≥0.1, gap 1": lambda lab, tab: tk.add_track_ids(
            tab, tk.link_labels(lab))["track_id"].to_numpy(),
        "overlap IoU≥0.1, no gap": lambda lab, tab: tk.add_track_ids(
            tab, tk.link_labels(lab, max_gap=0))["track_id"].to_numpy(),
        "overlap IoU≥0.3, gap 1": lambda lab, tab: tk.add_track_ids(
            tab, tk.link_labels(lab, min_iou=0.3))["track_id"].to_numpy(),
        "centroid LAP ≤1 radius, gap 1": lambda lab, tab: tk.link_centroids(
            tab, method="centroid", max_distance=radius),
        "centroid LAP ≤2 radii, no gap": lambda lab, tab: tk.link_centroids(
            tab, method="centroid", max_gap=0),
        "centroid LAP ≤2 radii, gap 1 (default)": lambda lab, tab: tk.link_centroids(
            tab, method="centroid"),
        "laptrack ≤1 radius, gap 1": lambda lab, tab: tk.link_centroids(
            tab, method="laptrack", max_distance=radius),
        "laptrack ≤2 radii, gap 1": lambda lab, tab: tk.link_centroids(
            tab, method="laptrack", max_distance=2 * radius),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="one seed, first scenario")
    args = ap.parse_args()
    seeds = range(1 if args.quick else args.seeds)
    scenarios = dict(list(SCENARIOS.items())[:1]) if args.quick else SCENARIOS
    link_rows, check_rows = [], []
    for name, kw in scenarios.items():
        acc: dict[str, dict] = {}
        for seed in seeds:
            movie = make_moving_blobs(seed=seed, **kw)
            for how in RELABELLINGS:
                lab = relabel(movie.labels, how, seed=seed + 100)
                c = tk.check_tracking(centroid_table(lab))
                check_rows.append({"scenario": name, "labels": how, "seed": seed,
                                   "verdict": c.verdict, "median jump px": c.median_jump,
                                   "median jump radii": c.median_jump_radii,
                                   "jumping": c.jumping, "switched": c.switched,
                                   "persistence": c.persistence})
            lab = relabel(movie.labels, "shuffled", seed=seed + 100)
            tab = centroid_table(lab)
            truth = movie.truth(lab)
            true_id = tab.merge(truth, on=["frame", "label"], how="left")["true_id"].to_numpy()
            radius = float(np.sqrt(np.median(tab["area"]) / np.pi))
            for mname, fn in methods(radius).items():
                t0 = time.perf_counter()
                track = fn(lab, tab)
                dt = time.perf_counter() - t0
                s = score(tab, true_id, np.asarray(track), movie.parents)
                a = acc.setdefault(mname, {"time": 0.0})
                for k, v in s.items():
                    a[k] = a.get(k, 0) + v
                a["time"] += dt
        n = len(seeds)
        for mname, a in acc.items():
            link_rows.append({
                "scenario": name, "method": mname,
                "rows": int(a["rows"] / n),
                "recovered": f"{a['hit'] / a['true']:.3f}",
                "false links": f"{a['false'] / n:.1f} ({a['false'] / max(a['pred'], 1):.2%})",
                "agree": f"{a['agree_rows'] / a['rows']:.3f}",
                "s/movie": f"{a['time'] / n:.3f}",
            })
    with pd.option_context("display.width", 200, "display.max_colwidth", 40):
        print(f"Linking movies with ids shuffled every frame ({len(seeds)} seed(s) per "
              "scenario; 'rows' per movie; 'false links' per movie)")
        print(pd.DataFrame(link_rows).to_string(index=False))
        print()
        ch = pd.DataFrame(check_rows)
        summary = ch.groupby(["scenario", "labels"], sort=False).agg(
            verdicts=("verdict", lambda s: ", ".join(sorted(set(s)))),
            median_jump_px=("median jump px", "median"),
            median_jump_radii=("median jump radii", "median"),
            jumping_max=("jumping", "max"),
            switched_min=("switched", "min"), switched_max=("switched", "max"),
            persistence_min=("persistence", "min"), persistence_max=("persistence", "max"))
        print(f"check_tracking (untracked when switched > {tk.MAX_SWITCHED} or persistence < "
              f"{tk.MIN_PERSISTENCE}; 'jumping': steps > {tk.JUMP_RADII} object radius)")
        print(summary.round(3).to_string())


if __name__ == "__main__":
    main()
