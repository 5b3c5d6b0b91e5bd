"""Time done right: detecting untracked labels, linking them, a Tracks layer as identities,
``track_id`` through CSV and the command line (napari_pfsdm.analysis.tracking)."""

from __future__ import annotations

import json
import sys

import numpy as np
import pandas as pd
import pytest
import tifffile

import napari_pfsdm as pf
from napari_pfsdm.analysis import tracking as tk
from napari_pfsdm.analysis.reduction import object_ids, pca_scores
from napari_pfsdm.cli import main
from napari_pfsdm.core.table_schema import NO_TRACK, TRACK_COLUMN
from napari_pfsdm.data.moving_blobs import centroid_table as centroids
from napari_pfsdm.data.moving_blobs import make_moving_blobs, relabel
from napari_pfsdm.io import read_table, write_table


@pytest.fixture(scope="module")
def movie():
    # 12 objects, 2 entering and 2 leaving the field, one division: 20 frames of 256 x 256
    return make_moving_blobs(12, 20, 256, radius=(12.0, 18.0), entering=2, leaving=2, seed=3)


def truth_ids(movie, labels, table) -> np.ndarray:
    return table.merge(movie.truth(labels), on=["frame", "label"], how="left")[
        "true_id"].to_numpy()


def true_links(frame: np.ndarray, ident: np.ndarray) -> set[tuple[int, int]]:
    order = np.lexsort((frame, ident))
    same = (ident[order][1:] == ident[order][:-1]) & (ident[order][1:] >= 0)
    return set(zip(order[:-1][same].tolist(), order[1:][same].tolist(), strict=True))


@pytest.mark.parametrize("method", ["overlap", "centroid"])
def test_linking_follows_entering_leaving_and_dividing_objects(movie, method):
    # the expected tracks come from the movie's true identities, not from the linker: every
    # object one track (overlap linking loses the last sliver of one leaving object: 2), an
    # entering object a track no earlier frame has, and of two daughters one continues the
    # mother's track while the other starts a new one
    labels = relabel(movie.labels, "shuffled", seed=11)
    table = centroids(labels)
    truth = table.merge(movie.truth(labels), on=["frame", "label"], how="left")
    linked = tk.link(table, labels if method == "overlap" else None, method=method)
    t = truth.assign(track=linked[TRACK_COLUMN].to_numpy())
    per_object = t.groupby("true_id")["track"].nunique()
    assert len(per_object) == 14 and per_object.max() <= (2 if method == "overlap" else 1)
    assert (per_object == 1).sum() >= 13
    assert movie.parents == {13: 8, 14: 8}  # the division the movie was made with
    mother = set(t.loc[t.true_id == 8, "track"])
    daughters = [set(t.loc[t.true_id == d, "track"]) for d in (13, 14)]
    assert sorted(len(mother & d) for d in daughters) == [0, 1]
    present = [set(np.unique(f)) - {0} for f in movie.labels]
    entering = [i for s in range(19) for i in present[s + 1] - present[s] - {13, 14}]
    assert entering  # objects enter the field
    for obj in entering:
        first = t.loc[t.true_id == obj, "frame"].min()
        assert not set(t.loc[t.true_id == obj, "track"]) & set(t.loc[t.frame < first, "track"])


@pytest.mark.parametrize("how, tracked", [("tracked", True), ("shuffled", False),
                                          ("new_ids", False), ("scan_order", False)])
def test_check_tracking_flags_renumbered_labels(movie, how, tracked):
    table = centroids(relabel(movie.labels, how, seed=7))
    check = tk.check_tracking(table)
    assert check.tracked is tracked
    assert check.verdict == ("tracked" if tracked else "untracked")
    if how == "tracked":  # entering, leaving and the division do not make it "untracked"
        assert check.median_jump_radii < 0.3 and check.jumping < 0.05
        assert check.switched < 0.01
        assert check.persistence > 0.9
        assert "follow objects" in check.message
    else:
        assert "do not follow objects" in check.message and "Link" in check.message
    if how == "scan_order":  # most ids stay put; those that move land on another object
        assert check.median_jump_radii < 0.5 and check.switched > 0.1
    if how == "shuffled":  # the median label jumps across the field
        assert check.median_jump > 40 and check.median_jump_radii > 3
        assert "px" in check.message and "object radii" in check.message
    if how == "new_ids":
        assert check.persistence == 0 and check.n_steps == 0


def test_check_tracking_edge_cases():
    one = pd.DataFrame({"frame": [0, 0], "label": [1, 2], "area": [50.0, 60.0],
                        "centroid_y": [5.0, 20.0], "centroid_x": [5.0, 5.0]})
    assert tk.check_tracking(one).verdict == "one frame"
    assert tk.check_tracking(one.iloc[:0]).verdict == "no objects"
    with pytest.raises(ValueError, match="centroid_y"):
        tk.check_tracking(one.drop(columns="centroid_y"))
    # per movie: a label of movie A and the same label of movie B are not one object
    two = pd.concat([one.assign(movie="a"), one.assign(movie="b", frame=1,
                                                       centroid_y=[300.0, 100.0])])
    assert tk.check_tracking(two).verdict == "one frame"


@pytest.mark.parametrize("how", ["shuffled", "new_ids"])
def test_overlap_linking_recovers_identities(movie, how):
    labels = relabel(movie.labels, how, seed=11)
    table = centroids(labels)
    truth = truth_ids(movie, labels, table)
    linked = tk.add_track_ids(table, tk.link_labels(labels))
    track = linked[TRACK_COLUMN].to_numpy()
    frame = table["frame"].to_numpy()
    true, pred = true_links(frame, truth), true_links(frame, track)
    assert len(true) == 203 and len(table) == 217
    # every link joins the same object (the one "false" link is the division: one daughter
    # continues the mother's track); all but the last sliver of a leaving object are found
    assert len(pred - true) == 1
    assert len(pred & true) == 202
    assert (track >= 1).all() and track[0] == 1


def test_overlap_linking_bridges_a_missed_frame():
    labels = np.zeros((4, 40, 40), np.uint16)
    labels[:, 5:15, 5:15] = np.array([1, 1, 0, 1])[:, None, None]  # missed in frame 2
    labels[:, 25:35, 25:35] = np.array([2, 3, 4, 5])[:, None, None]
    out = tk.link_labels(labels)
    a = out.loc[out["label"] == 1, TRACK_COLUMN]
    assert a.nunique() == 1 and len(a) == 3
    assert out.loc[out["label"] > 1, TRACK_COLUMN].nunique() == 1
    assert tk.link_labels(labels, max_gap=0).loc[lambda d: d["label"] == 1,
                                                 TRACK_COLUMN].nunique() == 2


def _blinking(n_frames: int, present: list[int]) -> tuple[np.ndarray, pd.DataFrame]:
    """One 10 x 10 square standing still, present only in the frames ``present`` (the other
    frames hold no object at all), as a label movie and as its table."""
    labels = np.zeros((n_frames, 40, 40), np.uint16)
    labels[present, 5:15, 5:15] = 1
    table = pd.DataFrame({"frame": present, "label": 1, "area": 100.0,
                          "centroid_y": 9.5, "centroid_x": 9.5})
    return labels, table


LINKERS = ["overlap", "centroid", "laptrack"]


def _linked(method: str, labels: np.ndarray, table: pd.DataFrame, max_gap: int) -> list[int]:
    if method == "laptrack":
        pytest.importorskip("laptrack")
    out = tk.link(table, labels if method == "overlap" else None, method=method,
                  max_gap=max_gap)
    return out[TRACK_COLUMN].tolist()


@pytest.mark.parametrize("method", LINKERS)
def test_every_linker_closes_a_gap_over_an_empty_frame(method):
    # the object is in frames 0 and 2; frame 1 holds no object at all (centroid
    # linking, the default, must give [1, 1] as overlap linking does, not [1, 2])
    labels, table = _blinking(3, [0, 2])
    assert _linked(method, labels, table, max_gap=1) == [1, 1]
    assert _linked(method, labels, table, max_gap=0) == [1, 2]  # no gap closing asked


@pytest.mark.parametrize("method", LINKERS)
def test_every_linker_closes_gaps_of_exactly_max_gap_frames(method):
    # frames 0, 3 (two empty frames between) and 7 (three empty frames before it)
    labels, table = _blinking(8, [0, 3, 7])
    assert _linked(method, labels, table, max_gap=2) == [1, 1, 2]
    assert _linked(method, labels, table, max_gap=3) == [1, 1, 1]
    assert _linked(method, labels, table, max_gap=1) == [1, 2, 3]


def test_link_labels_refuses_non_movies():
    with pytest.raises(ValueError, match=r"\(T, Y, X\)"):
        tk.link_labels(np.zeros((10, 10), int))
    with pytest.raises(ValueError, match="whole numbers"):
        tk.link_labels(np.zeros((2, 10, 10), float))


def test_centroid_linking_from_the_table(movie):
    labels = relabel(movie.labels, "shuffled", seed=5)
    table = centroids(labels)
    truth = truth_ids(movie, labels, table)
    track = tk.link(table, method="centroid")[TRACK_COLUMN].to_numpy()
    frame = table["frame"].to_numpy()
    true, pred = true_links(frame, truth), true_links(frame, track)
    assert len(pred & true) >= len(true) - 3
    assert len(pred - true) <= 2
    with pytest.raises(ValueError, match="needs the label images"):
        tk.link(table, method="overlap")
    with pytest.raises(ValueError, match="one of centroid, overlap, laptrack"):
        tk.link(table, method="nearest")


def test_laptrack_linking_or_a_message_saying_how_to_install(movie, monkeypatch):
    table = centroids(relabel(movie.labels, "shuffled", seed=5))
    try:
        import laptrack  # noqa: F401
    except ImportError:
        with pytest.raises(ImportError, match="pip install laptrack"):
            tk.link(table, method="laptrack")
        return
    ref = tk.link(table, method="centroid")[TRACK_COLUMN].to_numpy()
    got = tk.link(table, method="laptrack")[TRACK_COLUMN].to_numpy()
    frame = table["frame"].to_numpy()
    assert len(true_links(frame, got) ^ true_links(frame, ref)) <= 4
    monkeypatch.setitem(sys.modules, "laptrack", None)
    with pytest.raises(ImportError, match="pip install laptrack"):
        tk.link(table, method="laptrack")


def test_link_per_movie_restarts_track_ids(movie):
    table = centroids(relabel(movie.labels, "shuffled", seed=2))
    both = pd.concat([table.assign(movie="a"), table.assign(movie="b")], ignore_index=True)
    track = tk.link(both, method="centroid")[TRACK_COLUMN].to_numpy()
    half = len(table)
    np.testing.assert_array_equal(track[:half], track[half:])
    assert object_ids(tk.link(both, method="centroid")).nunique() == 2 * len(set(track[:half]))


def test_link_movie_auto(movie):
    tracked = centroids(movie.labels)
    out, check, used = tk.link_movie(tracked, movie.labels, "auto")
    assert check.tracked and used == ""
    np.testing.assert_array_equal(out[TRACK_COLUMN], out["label"])
    shuffled = relabel(movie.labels, "shuffled", seed=1)
    out, check, used = tk.link_movie(centroids(shuffled), shuffled, "auto")
    assert not check.tracked and used == tk.DEFAULT_LINK == "centroid"
    assert list(out.columns[:3]) == ["frame", "label", TRACK_COLUMN]
    assert TRACK_COLUMN not in tk.link_movie(tracked, None, "labels")[0].columns


def _packed_movie(side: int = 6, frames: int = 6, cell: int = 26, seed: int = 0):
    """An epithelium: side × side cells filling the field (each pixel belongs to its nearest
    cell centre, centres on a jittered lattice), each centre wandering a tenth of a cell per
    frame; ids shuffled in every frame. Returns the labels and each (frame, label)'s true
    cell."""
    rng = np.random.default_rng(seed)
    grid = (np.stack(np.mgrid[:side, :side], -1).reshape(-1, 2) + 0.5) * cell
    seeds = grid + rng.uniform(-0.2, 0.2, grid.shape) * cell
    n = side * cell
    yy, xx = np.mgrid[:n, :n]
    labels = np.zeros((frames, n, n), np.uint16)
    truth = {}
    for t in range(frames):
        at = seeds + rng.normal(0, 0.1 * cell, seeds.shape)
        nearest = np.argmin((yy[..., None] - at[:, 0]) ** 2 + (xx[..., None] - at[:, 1]) ** 2,
                            axis=-1)
        ids = rng.permutation(len(seeds)) + 1
        labels[t] = ids[nearest]
        truth.update({(t, int(ids[k])): k for k in range(len(seeds))})
    return labels, truth


def test_touching_fraction_counts_objects_that_share_an_edge():
    labels = np.zeros((2, 6, 6), np.uint8)
    labels[:, 0:2, 0:2], labels[:, 0:2, 2:4] = 1, 2  # touch
    labels[:, 4:6, 4:6] = 3  # alone
    labels[1, 2, 0] = 4  # touches 1 from below
    assert tk.touching_fraction(labels[0]) == pytest.approx(2 / 3)
    assert tk.touching_fraction(labels) == pytest.approx((2 + 3) / (3 + 4))
    assert np.isnan(tk.touching_fraction(np.zeros((4, 4), int)))


def test_auto_links_packed_cells_by_overlap_and_finds_their_tracks():
    labels, truth = _packed_movie()
    assert tk.touching_fraction(labels) == 1.0
    table = centroids(labels)
    out, check, used = tk.link_movie(table, labels, "auto")
    assert not check.tracked and used == "overlap"
    true = np.array([truth[(f, lab)] for f, lab in zip(out["frame"], out["label"],
                                                         strict=True)])
    # one track per true cell, and one true cell per track
    pairs = set(zip(out[TRACK_COLUMN], true, strict=True))
    assert len(pairs) == out[TRACK_COLUMN].nunique() == len(set(true)) == 36
    # without the labels (the table alone), auto links by centroids, as before
    assert tk.link_movie(table, None, "auto")[2] == "centroid"


def tracks_layer_data(movie) -> np.ndarray:
    """(track_id, t, y, x) at each true object's centroid, track ids 100 + true id."""
    table = centroids(movie.labels)
    return np.column_stack([100 + table["label"], table["frame"], table["centroid_y"],
                            table["centroid_x"]]).astype(float)


@pytest.mark.parametrize("with_labels", [True, False])
def test_tracks_layer_as_identity_source(movie, with_labels):
    labels = relabel(movie.labels, "shuffled", seed=9)
    table = centroids(labels)
    truth = truth_ids(movie, labels, table)
    data = tracks_layer_data(movie)
    # the tracker lost object 3 (no track reaches it); a point outside the field is ignored
    data = data[data[:, 0] != 103]
    data = np.vstack([data, [[999, 0, -50.0, 10.0]]])
    ids = tk.track_ids_from_tracks(data, table, labels if with_labels else None)
    assert (ids[truth == 3] == NO_TRACK).all()
    ok = truth != 3
    # points at the centroid of a non-convex blob may fall outside it: nearly all rows hit
    assert np.mean(ids[ok] == 100 + truth[ok]) > (0.97 if with_labels else 0.999)
    assert ((ids[ok] == 100 + truth[ok]) | (ids[ok] == NO_TRACK)).all()


def test_tracks_layer_conflicts_and_bad_data():
    table = pd.DataFrame({"frame": [0, 0], "label": [1, 2], "area": [100.0, 100.0],
                          "centroid_y": [10.0, 10.0], "centroid_x": [10.0, 40.0]})
    # two tracks at the same object: the nearer wins; the other reaches nothing
    data = [[1, 0, 10.0, 11.0], [2, 0, 10.0, 14.0]]
    assert tk.track_ids_from_tracks(data, table).tolist() == [1, NO_TRACK]
    # too far from any centroid (default tolerance: the median radius, 5.6 px)
    assert tk.track_ids_from_tracks([[1, 0, 10.0, 25.0]], table).tolist() == [NO_TRACK] * 2
    assert tk.track_ids_from_tracks([[1, 0, 10.0, 25.0]], table,
                                    max_distance=16).tolist() == [1, NO_TRACK]
    with pytest.raises(ValueError, match="4 columns"):
        tk.track_ids_from_tracks(np.zeros((3, 5)), table)


def test_track_id_round_trips_through_csv(tmp_path, movie):
    table = tk.link(centroids(relabel(movie.labels, "shuffled")), method="centroid")
    table.loc[3, TRACK_COLUMN] = NO_TRACK
    path = tmp_path / "t.csv"
    write_table(table, path, {"n_fourier": 4})
    back = read_table(path)
    assert back[TRACK_COLUMN].dtype == np.int64
    np.testing.assert_array_equal(back[TRACK_COLUMN], table[TRACK_COLUMN])
    assert pd.read_csv(path)[TRACK_COLUMN].dtype == np.int64  # plain pandas too
    # a hand-edited file with an empty cell: no track, still whole numbers
    text = path.read_text().splitlines()
    cells = text[1].split(",")
    cells[list(table.columns).index(TRACK_COLUMN)] = ""
    path.write_text("\n".join([text[0], ",".join(cells), *text[2:]]) + "\n")
    back = read_table(path)
    assert back[TRACK_COLUMN].dtype == np.int64 and back[TRACK_COLUMN].iloc[0] == NO_TRACK


def test_trajectories_follow_tracks():
    from napari_pfsdm import measure

    labels = np.zeros((3, 64, 64), np.uint16)
    labels[:, 5:25, 5:25] = np.array([1, 2, 1])[:, None, None]  # ids swap in frame 1
    labels[:, 35:60, 30:45] = np.array([2, 1, 2])[:, None, None]
    table = tk.link(measure(labels, n_fourier=4, n_radii=6), labels)
    assert table.groupby(TRACK_COLUMN)["area"].nunique().tolist() == [1, 1]
    scores, _ = pca_scores(table, n_components=2)
    assert TRACK_COLUMN in scores.columns
    assert object_ids(scores).nunique() == 2
    assert object_ids(scores.drop(columns=TRACK_COLUMN)).nunique() == 2
    by_track = scores.groupby(object_ids(scores))["shape_PC1"].std()
    by_label = scores.groupby(object_ids(scores.drop(columns=TRACK_COLUMN)))["shape_PC1"].std()
    assert by_track.max() < 1e-9 < by_label.min()  # a track keeps its shape; a label does not


# ------------------------------------------------------------------------------------------
# the command line
# ------------------------------------------------------------------------------------------

CLI_OPTS = ["--n-fourier", "4", "--n-radii", "6", "--scheduler", "threads"]


@pytest.fixture(scope="module")
def cli_movie(tmp_path_factory):
    import tifffile

    movie = make_moving_blobs(6, 8, 160, radius=(10.0, 14.0), entering=1, leaving=1,
                              division=False, seed=4)
    folder = tmp_path_factory.mktemp("cli")
    shuffled = relabel(movie.labels, "shuffled", seed=3)
    tifffile.imwrite(folder / "shuffled.tif", shuffled)
    tifffile.imwrite(folder / "tracked.tif", movie.labels)
    return movie, shuffled, folder


def test_cli_warns_refuses_and_links(cli_movie, capsys):
    from napari_pfsdm.cli import main

    movie, shuffled, d = cli_movie
    assert main(["measure", str(d / "shuffled.tif"), "-o", str(d / "plain.csv"),
                 "--link", "labels", *CLI_OPTS]) == 0
    err = capsys.readouterr().err
    assert "do not follow objects" in err and "--link auto" in err
    assert TRACK_COLUMN not in read_table(d / "plain.csv").columns
    # trajectories by label would be meaningless: refused, in one plain line
    assert main(["trajectories", str(d / "plain.csv"), "-o", str(d / "pca.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "do not follow objects" in err[0] and "--link centroid" in err[0]
    assert not (d / "pca.csv").exists()
    # ... unless linked from the table, or drawn by label on purpose
    assert main(["trajectories", str(d / "plain.csv"), "-o", str(d / "pca.csv"),
                 "--link", "centroid", "--plot", str(d / "pca.png")]) == 0
    pca = read_table(d / "pca.csv")
    assert TRACK_COLUMN in pca.columns and (d / "pca.png").is_file()
    assert main(["trajectories", str(d / "plain.csv"), "-o", str(d / "pca_l.csv"), "--force",
                 "--link", "labels"]) == 0
    assert "drawing by label anyway" in capsys.readouterr().err
    # classify over several frames refuses too (one frame is fine: no identity over time)
    groups = d / "groups.csv"
    groups.write_text("label,group\n" + "".join(f"{i},{'ab'[i % 2]}\n" for i in range(1, 9)))
    assert main(["classify", str(d / "plain.csv"), "--groups", str(groups),
                 "--frames", "0-3"]) == 2
    assert "mix different objects" in capsys.readouterr().err


def test_cli_measure_links_untracked_labels_by_default(cli_movie, capsys):
    from napari_pfsdm.cli import main

    movie, shuffled, d = cli_movie
    assert main(["measure", str(d / "shuffled.tif"), "-o", str(d / "linked.csv"),
                 *CLI_OPTS]) == 0
    out = capsys.readouterr().out
    assert "linked by centroid" in out
    table = read_table(d / "linked.csv")
    assert list(table.columns[:4]) == ["movie", "frame", "label", TRACK_COLUMN]
    truth = truth_ids(movie, shuffled, table)
    # every track is one object and every object one track (no division here)
    assert (table.groupby(TRACK_COLUMN)["frame"].count().sum() == len(table))
    assert pd.crosstab(table[TRACK_COLUMN], truth).gt(0).sum(axis=1).max() == 1
    assert table[TRACK_COLUMN].nunique() == len(set(truth))
    assert main(["trajectories", str(d / "linked.csv"), "-o", str(d / "pca2.csv")]) == 0
    pca = read_table(d / "pca2.csv")
    measured = table["error"] == ""  # an object entering in the last frame is too small
    assert object_ids(pca).nunique() == table.loc[measured, TRACK_COLUMN].nunique() == 5
    # tracked labels: nothing to link, no track_id column (the labels are the identities)
    assert main(["measure", str(d / "tracked.tif"), "-o", str(d / "tracked.csv"),
                 *CLI_OPTS]) == 0
    assert TRACK_COLUMN not in read_table(d / "tracked.csv").columns


def test_the_check_counts_steps_jumps_and_switches_worked_by_hand():
    # area π·10² (radius 10). Frame 0: labels 1, 2; frame 1: 1, 2, 3; frame 2: 2, 3; label
    # 1 moves 28 px, next to label 2's place of frame 0 (a switch); no two centroids tie for
    # nearest; rows in no particular order
    rows = [(1, 2, 0.0, 30.0), (0, 1, 0.0, 0.0), (2, 3, 50.0, 3.0), (0, 2, 0.0, 30.0),
            (1, 1, 0.0, 28.0), (1, 3, 50.0, 0.0), (2, 2, 0.0, 34.0)]
    table = pd.DataFrame(rows, columns=["frame", "label", "centroid_y", "centroid_x"])
    table["area"] = np.pi * 100.0
    check = tk.check_tracking(table)
    # steps: 1 (0→1, 28 px), 2 (0→1, 0 px), 2 (1→2, 4 px), 3 (1→2, 3 px); 5 rows have a
    # next frame (2 in frame 0, 3 in frame 1)
    assert check.n_steps == 4 and check.persistence == pytest.approx(4 / 5)
    assert check.median_jump == pytest.approx(3.5)  # median of 0, 3, 4, 28
    assert check.median_jump_radii == pytest.approx(0.35)
    assert check.switched == pytest.approx(1 / 4) and check.jumping == pytest.approx(1 / 4)


def test_identity_has_one_vocabulary_at_every_door(tmp_path):
    """The option ``link`` (core.params.LINK_OPTION) is what pfsdm measure --link, the table
    commands' --link, the plugin's Identity choice and link_movie take, and what the sidecar
    records."""
    import argparse

    from napari_pfsdm.cli import build_parser
    from napari_pfsdm.core.params import LINK_OPTION
    from napari_pfsdm.napari._results import IDENTITY

    words = set(LINK_OPTION.choices)
    assert words == {"auto", "labels", "centroid", "overlap", "laptrack"}
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    for command in ("measure", "trajectories", "plot", "report"):
        link = next(a for a in sub.choices[command]._actions if a.dest == "link")
        # the table commands lack only what needs the label images
        assert set(link.choices) == (words if command == "measure" else words - {"overlap"})
    assert set(IDENTITY.values()) == words
    table = pf.measure(np.stack([_disk_frame(i) for i in range(3)]), n_fourier=4, n_radii=4)
    for word in words - {"laptrack", "overlap"}:
        tk.link_movie(table, None, word)
    with pytest.raises(pf.errors.InputError, match="link must be one of auto, labels"):
        tk.link_movie(table, None, "none")
    labels = np.stack([_disk_frame(i) for i in range(3)])
    tifffile.imwrite(tmp_path / "m.tif", labels, photometric="minisblack")
    assert main(["measure", str(tmp_path / "m.tif"), "-o", str(tmp_path / "f.csv"), "-q",
                 "--link", "centroid", "--n-fourier", "4", "--n-radii", "4"]) == 0
    side = json.loads((tmp_path / "f.csv.json").read_text())
    assert side["link"] == "centroid" and side["linked"] == {"m": "centroid"}


def _disk_frame(t):
    yy, xx = np.mgrid[:48, :64]
    frame = np.zeros((48, 64), np.uint8)
    frame[(yy - 24) ** 2 + (xx - 16 - 2 * t) ** 2 < 64] = 1
    frame[(yy - 24) ** 2 + (xx - 44) ** 2 < 49] = 2
    return frame
