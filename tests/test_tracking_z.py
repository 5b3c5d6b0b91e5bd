"""Identity through time for objects of Z-stacks: z counts (nuclei above one another)."""

import numpy as np
import pandas as pd

from napari_pfsdm.analysis.tracking import check_tracking, link


def _stacked_nuclei(n_pairs: int = 8, n_frames: int = 6) -> pd.DataFrame:
    """A hand-made table: pairs of nuclei at the same (y, x), 20 voxels apart in z, each
    drifting 1 voxel per frame in x; the label ids are the true ones."""
    radius = 5.0
    rows = []
    for t in range(n_frames):
        for k in range(n_pairs):
            y, x = 30.0 * (k // 4), 30.0 * (k % 4) + t
            for level, z in enumerate((10.0, 30.0)):
                rows.append({"frame": t, "label": 1 + 2 * k + level,
                             "volume": 4 / 3 * np.pi * radius**3,
                             "centroid_z": z, "centroid_y": y, "centroid_x": x})
    return pd.DataFrame(rows)


def test_true_ids_of_stacked_nuclei_are_called_tracked():
    table = _stacked_nuclei()
    check = check_tracking(table)
    assert check.verdict == "tracked", check.message
    # by hand: every label moves 1 voxel a frame, a fifth of a radius of 5
    assert check.median_jump == 1.0
    # without z the same ids look like swaps between the two nuclei of each pair
    flat = check_tracking(table.drop(columns=["centroid_z"]))
    assert flat.median_jump == 1.0 and not flat.tracked


def test_linking_stacked_nuclei_keeps_each_track_on_one_nucleus():
    rng = np.random.default_rng(0)
    table = _stacked_nuclei()
    # rows in a different order in every frame (the order of a table says nothing of identity)
    table = pd.concat([g.sample(frac=1, random_state=int(t)) for t, g in table.groupby("frame")],
                      ignore_index=True)
    shuffled = table.copy()
    for t in shuffled["frame"].unique():  # a new numbering in every frame
        rows = np.flatnonzero(shuffled["frame"] == t)
        shuffled.loc[rows, "label"] = rng.permutation(shuffled.loc[rows, "label"].to_numpy())
    tracks = link(shuffled)["track_id"].to_numpy()
    truth = table["label"].to_numpy()  # the true id of each row (rows keep their order)
    per_track = pd.Series(truth).groupby(tracks).nunique()
    assert len(per_track) == 16 and (per_track == 1).all()
