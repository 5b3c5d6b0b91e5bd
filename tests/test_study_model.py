"""The study dock's model without a viewer: several movies whose labels repeat, as one study."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from skimage.measure import regionprops

from napari_pfsdm.analysis.groups import read_groups
from napari_pfsdm.errors import InputError
from napari_pfsdm.io.times_file import read_times_file
from napari_pfsdm.napari._study_model import (
    StudyInput,
    name_groups,
    parse_times,
    pixel_size_of,
    reporter_for,
    run_study,
    times_per_movie,
)

TIMES = [2.0, 5.0, 5.0, 9.0]
PIXEL = 0.5


def _movie(size: float, n: int = 4, shift: int = 0) -> np.ndarray:
    yy, xx = np.mgrid[:72, :72]
    out = np.zeros((n, 72, 72), np.uint16)
    for t in range(n):
        r = size + t
        out[t][((yy - 22) / r) ** 2 + ((xx - 22 - shift) / (0.7 * r)) ** 2 <= 1] = 1
        out[t][((yy - 50) / (0.8 * r)) ** 2 + ((xx - 50) / (0.6 * r)) ** 2 <= 1] = 2
    return out


#: Clone "big": √2 times wider than "small", twice the area; three objects per clone… each
#: movie has labels 1 and 2.
MOVIES = {"small_a": _movie(6), "small_b": _movie(6, shift=2), "small_c": _movie(6.5),
          "big_a": _movie(6 * 2 ** 0.5), "big_b": _movie(6 * 2 ** 0.5, shift=1),
          "big_c": _movie(6.5 * 2 ** 0.5)}


@pytest.fixture(scope="module")
def study():
    given = StudyInput(movies=MOVIES, times=dict.fromkeys(MOVIES, TIMES), time_unit="day",
                       pixel_sizes=dict.fromkeys(MOVIES, PIXEL), space_unit="um",
                       name_groups=name_groups(list(MOVIES), "prefix"))
    seen = []
    out = run_study(given, progress=lambda done, total, movie: seen.append((done, total)))
    out.progress_seen = seen
    return out


def test_table_is_keyed_by_movie_in_microns_and_days(study):
    t = study.table
    for movie, data in MOVIES.items():
        rows = t[t["movie"] == movie]
        for frame in range(data.shape[0]):
            for prop in regionprops(data[frame]):
                got = rows[(rows["frame"] == frame) & (rows["label"] == prop.label)]
                assert got["area"].item() == pytest.approx(prop.area * PIXEL ** 2)
                assert got["time"].item() == TIMES[frame]
        assert set(rows["group"]) == {movie.split("_")[0]}
    # the progress counts the objects of every movie, not per movie
    total = sum(len(regionprops(f)) for d in MOVIES.values() for f in d)
    assert {tot for _d, tot in study.progress_seen} == {total}
    assert study.progress_seen[-1][0] == total
    assert study.row_of("big_b", 2, 1) is not None and study.row_of("big_b", 9, 1) is None
    assert study.key_of(study.row_of("big_b", 2, 1)) == ("big_b", 2, 1)


def test_trajectories_are_one_shape_space_over_every_movie(study):
    from napari_pfsdm.analysis.reduction import pca_scores

    paths = study.trajectories()
    assert len(paths) == len(study.table)
    ref, _ = pca_scores(study.table, "shape", n_components=2)
    merged = paths.merge(ref, on=["movie", "frame", "label"])
    np.testing.assert_allclose(merged["PC1"], merged["shape_PC1"])
    # label 1 of each movie is its own object
    assert paths[paths["label"] == 1]["object"].nunique() == len(MOVIES)


def test_group_statistics_find_the_built_in_difference(study):
    at_last = " ".join(study.group_sentences("area"))
    assert "the groups differ" in at_last and "day 9" in at_last and "µm²" in at_last
    # no difference in a shape-only measure of the same ellipses: both clones alike
    assert "the groups do not differ" in " ".join(study.group_sentences("eccentricity"))
    slope = " ".join(study.group_sentences("area", "slope"))
    assert "per day" in slope


def test_layer_features_are_the_movies_own_rows(study):
    f = study.layer_features("big_a")
    mine = study.table[study.table["movie"] == "big_a"]
    assert f["frame"].tolist() == mine["frame"].tolist()
    assert f["index"].tolist() == mine["label"].tolist()
    np.testing.assert_allclose(f["area"], mine["area"])
    assert "shape_PC1" in f and np.isfinite(f["shape_PC1"]).all()


def test_similar_searches_every_movie(study):
    found = study.similar("small_a", 3, 1, k=3)
    assert found[0][:4] == ("small_a", 3, 1, 0.0)
    movies = {f[0] for f in found[1:]}
    assert movies - {"small_a"}, found  # the nearest come from other movies too
    assert all(f[3] >= 0 for f in found)
    objects = [(f[0], f[2]) for f in found]
    assert len(set(objects)) == len(objects)  # each other object once


def test_prediction_tells_the_clones_apart(study):
    p = study.predict(frames=[3])
    assert set(p.groups) == {"small", "big"}
    assert p.n_scored == 2 * len(MOVIES)
    assert p.summary.loc["fused", "mean"] > 0.5
    assert int(p.confusion.to_numpy().sum()) > 0


def test_groups_file_with_another_column(tmp_path):
    path = tmp_path / "groups.csv"
    pd.DataFrame({"movie": ["small_a.tif", "big_a.tif"], "clone": ["s", "b"],
                  "lab": ["x", "y"]}).to_csv(path, index=False)
    movies = {m: MOVIES[m][:2] for m in ("small_a", "big_a")}
    st = run_study(StudyInput(movies=movies, groups=read_groups(path, "clone")))
    assert st.table.groupby("movie")["group"].first().to_dict() == {"small_a": "s",
                                                                    "big_a": "b"}
    assert set(st.table["lab"]) == {"x", "y"}
    assert "sizes in pixels" in st.summary()


def test_reporter_is_never_another_movies():
    shape = (4, 72, 72)
    images = [("org02 reporter", shape), ("org01 reporter", (4, 72, 70)),
              ("org01_b reporter", shape)]
    movies = ["org01", "org01_b", "org02"]
    assert reporter_for("org01", shape, images, movies) is None  # wrong shape, others' names
    assert reporter_for("org01_b", shape, images, movies) == "org01_b reporter"
    assert reporter_for("org02", shape, images, movies) == "org02 reporter"
    assert reporter_for("org0", shape, images, movies) is None  # a name's prefix is no match


def test_times_and_pixels_given_in_words(tmp_path):
    assert parse_times("2,5 ,8;10 12") == [2, 5, 8, 10, 12]
    with pytest.raises(InputError, match="'x' is not a number"):
        parse_times("2, x")
    path = tmp_path / "times.csv"
    path.write_text("movie,frame,time\nA.tif,0,1\nA.tif,1,3\nB,0,2\nB,1,2.5\n")
    times = times_per_movie(read_times_file(path), {"a": 2, "B": 2})
    assert times == {"a": [1.0, 3.0], "B": [2.0, 2.5]}
    with pytest.raises(InputError, match="no time for frame 2 of a"):
        times_per_movie(read_times_file(path), {"a": 3, "B": 2})
    with pytest.raises(InputError, match="names no movie 'c'"):
        times_per_movie(read_times_file(path), {"c": 2})
    assert pixel_size_of((1, 0.65, 0.65)) == 0.65
    with pytest.raises(InputError, match="not square"):
        pixel_size_of((1, 0.5, 0.65))
