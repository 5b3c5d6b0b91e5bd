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
    got = groups.set_index(["group", "time"]).rename_axis(["group", "frame"])  # time = frame
    np.testing.assert_allclose(got["mean"], want["mean"])
    np.testing.assert_allclose(got["sd"], want["std"])
    assert (got["n"] == 3).all()


def test_groups_from_a_mapping_and_non_numbers_left_out():
    table = _table().drop(columns="group")
    table.loc[3, "area"] = np.nan
    lines, groups = over_time(table, "area", groups={1: "a", 2: "a"})
    assert len(lines) == 29 and set(groups["group"]) == {"a"}
    assert groups.loc[groups["time"] == 3, "n"].item() == 1  # track 1's frame 3 was NaN


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
    assert ax.get_ylabel() == "area (pixels)" and ax.get_xlabel() == "frame"


def test_pfsdm_plot_draws_the_column_and_writes_what_it_drew(tmp_path, capsys):
    from PIL import Image

    from napari_pfsdm.cli import main
    from napari_pfsdm.io import write_table

    table = _table()
    path = tmp_path / "t.csv"
    write_table(table.drop(columns="group"), path, table_type="features")
    pd.DataFrame({"track_id": [1, 2, 3, 4, 5, 6],
                  "group": ["up"] * 3 + ["down"] * 3}).to_csv(tmp_path / "g.csv", index=False)
    png, values = tmp_path / "area.png", tmp_path / "v.csv"
    assert main(["plot", str(path), "--column", "area", "-o", str(png), "--groups",
                 str(tmp_path / "g.csv"), "--objects", "track2", "--values", str(values),
                 "-q"]) == 0
    assert Image.open(png).size[0] > 400
    drawn = pd.read_csv(values)
    np.testing.assert_allclose(drawn.sort_values(["object", "frame"])["value"],
                               table.sort_values(["track_id", "frame"])["area"])
    assert main(["plot", str(path), "--column", "volume", "-o", str(tmp_path / "x.png")]) == 2
    assert "no column of numbers called 'volume'" in capsys.readouterr().err
    assert main(["plot", str(path), "--column", "area", "-o", str(tmp_path / "y.png"),
                 "--objects", "track99"]) == 2
    assert "no object called track99" in capsys.readouterr().err


def test_time_is_on_the_axis_and_frames_at_one_time_pool():
    """A table with uneven times, one time imaged twice: each group's mean is over every value
    at that time (both frames), the axis says the time and its unit, the measure its unit."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from napari_pfsdm.analysis.physical import add_times
    from napari_pfsdm.core.table_options import set_options

    table = pd.DataFrame({"frame": [0, 1, 2] * 2, "label": [1, 1, 1, 2, 2, 2],
                          "area": [1.0, 2.0, 4.0, 3.0, 5.0, 8.0], "group": "g"})
    table = set_options(table, {"space_unit": "µm"})
    table = add_times(table, [2, 12, 12], "day")
    lines, groups = over_time(table, "area")
    assert groups["time"].tolist() == [2.0, 12.0]
    assert groups["n"].tolist() == [2, 4]  # day 12: both frames of both objects
    assert groups["mean"].tolist() == [2.0, (2 + 4 + 5 + 8) / 4]
    ax = plt.figure().add_subplot()
    plot_over_time(ax, table, "area")
    assert ax.get_xlabel() == "time (day)" and ax.get_ylabel() == "area (µm²)"
