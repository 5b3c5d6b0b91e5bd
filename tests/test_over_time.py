"""A measure against time: per object and per group, worked by hand and against pandas."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from napari_pfsdm.analysis.over_time import numeric_columns, over_time, plot_over_time


def _table() -> pd.DataFrame:
    rng = np.random.default_rng(0)
    rows = []
    for track in range(1, 7):
        for t in range(5):
            rows.append({"frame": t, "label": 10 * t + track, "track_id": track,
                         "area": 100 + 10 * track + t * (3 if track <= 3 else -2)
                         + rng.normal(),
                         "group": "up" if track <= 3 else "down"})
    return pd.DataFrame(rows)


def test_objects_are_their_tracks_and_groups_their_mean_and_sd():
    table = _table()
    lines, groups = over_time(table, "area")
    assert lines["object"].nunique() == 6  # the labels change every frame, the tracks do not
    one = lines[lines["object"] == "track2"]
    assert one["frame"].tolist() == [0, 1, 2, 3, 4] and one["label"].tolist() == [2, 12, 22,
                                                                                   32, 42]
    want = table.groupby(["group", "frame"])["area"].agg(["mean", "std", "count"])
    got = groups.set_index(["group", "frame"])
    np.testing.assert_allclose(got["mean"], want["mean"])
    np.testing.assert_allclose(got["sd"], want["std"])
    assert (got["n"] == 3).all()


def test_groups_from_a_mapping_and_non_numbers_left_out():
    table = _table().drop(columns="group")
    table.loc[3, "area"] = np.nan
    lines, groups = over_time(table, "area", groups={1: "a", 2: "a"})
    assert len(lines) == 29 and set(groups["group"]) == {"a"}
    assert groups.loc[groups["frame"] == 3, "n"].item() == 1  # track 1's frame 3 was NaN


def test_a_column_that_cannot_be_drawn_is_refused_with_the_ones_that_can():
    with pytest.raises(ValueError, match="no column 'volume'.*area"):
        over_time(_table(), "volume")
    with pytest.raises(ValueError, match="does not hold numbers"):
        over_time(_table(), "group")
    assert numeric_columns(_table()) == ["area"]


def test_the_drawing_has_a_line_per_object_and_a_band_per_group():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ax = plt.figure().add_subplot()
    plot_over_time(ax, _table(), "area", selected=["track5"])
    grey = [line for line in ax.get_lines() if line.get_linewidth() == 0.7]
    means = [line for line in ax.get_lines() if line.get_linewidth() == 2]
    red = [line for line in ax.get_lines() if line.get_color() == "#ff3c3c"]
    assert len(grey) == 6 and len(means) == 2 and len(ax.collections) == 2
    np.testing.assert_allclose(red[0].get_ydata(), _table().query("track_id == 5")["area"])
    assert ax.get_ylabel() == "area" and ax.get_xlabel() == "frame"
