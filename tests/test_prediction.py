"""Predicting a group from early frames (napari_pfsdm.analysis.prediction) on cases whose
answer is known."""

import numpy as np
import pandas as pd
import pytest

from napari_pfsdm import measure
from napari_pfsdm.analysis.outcome import predict_outcome
from napari_pfsdm.errors import InputError


@pytest.fixture(scope="module")
def two_sizes():
    """Ten small and ten large ellipses per frame, three frames, ids kept; group by size."""
    rng = np.random.default_rng(3)
    cell, n = 64, 20
    labels = np.zeros((3, cell * 4, cell * 5), np.uint16)
    yy, xx = np.mgrid[0:cell, 0:cell] - (cell - 1) / 2
    groups = {}
    for k in range(n):
        big = k % 2 == 1
        groups[k + 1] = "large" if big else "small"
        r, c = divmod(k, 5)
        for t in range(3):
            a = (24 if big else 12) * rng.uniform(0.9, 1.1)
            b = a / rng.uniform(1.2, 1.8)
            th = rng.uniform(0, np.pi)
            u = xx * np.cos(th) + yy * np.sin(th)
            v = -xx * np.sin(th) + yy * np.cos(th)
            labels[t, r * cell:(r + 1) * cell, c * cell:(c + 1) * cell][
                (u / a) ** 2 + (v / b) ** 2 <= 1] = k + 1
    return measure(labels), groups


def test_a_group_that_size_separates_is_found_by_the_classic_measures_and_the_fusion(two_sizes):
    table, groups = two_sizes
    pred = predict_outcome(table, groups, frames=[0, 1], n_splits=5, n_repeats=1, seed=0)
    assert pred.groups == ("large", "small") and pred.frames == [0, 1]
    assert list(pred.summary.index) == ["fused", "shape alone", "classic alone", "chance"]
    assert pred.summary.loc["classic alone", "mean"] == 1.0  # area alone tells them apart
    assert pred.summary.loc["fused", "mean"] >= 0.9
    assert pred.summary.loc["chance", "mean"] == 0.5
    assert pred.summary.loc["fused", "n_splits"] == 5
    # every object gets both probabilities, summing to one, on the right side of 0.5
    probs = pred.probabilities.set_index("object")
    np.testing.assert_allclose(probs["p_large"] + probs["p_small"], 1.0)
    right = [(probs.loc[str(k), "p_large"] > 0.5) == (g == "large") for k, g in groups.items()]
    assert np.mean(right) >= 0.9
    assert (probs["predicted"] == np.where(probs["p_large"] > 0.5, "large", "small")).all()
    # the confusion matrix counts every test prediction once
    assert pred.confusion.to_numpy().sum() == 5 * int(np.ceil(0.2 * len(groups)))
    # how early: one point per last frame used
    assert pred.curve["last_frame"].tolist() == [0, 1]


def test_objects_without_a_group_are_predicted_too(two_sizes):
    table, groups = two_sizes
    known = {k: g for k, g in groups.items() if k <= 16}
    pred = predict_outcome(table, known, frames=[0], n_splits=3, n_repeats=1, curve=False)
    probs = pred.probabilities.set_index("object")
    assert set(probs.index) == {str(k) for k in groups}
    for k in (17, 18, 19, 20):  # never seen with a group: predicted from their size
        assert (probs.loc[str(k), "p_large"] > 0.5) == (groups[k] == "large")
        assert probs.loc[str(k), "group"] == ""
    assert pred.curve.empty
    # on the table's rows: each row its object's probabilities, the options kept
    rows = pred.on_rows(table.iloc[::-1])
    assert rows.attrs["pfsdm"] == table.attrs["pfsdm"]
    np.testing.assert_array_equal(
        rows["p_large"].to_numpy(),
        probs.loc[table["label"].astype(str).to_numpy()[::-1], "p_large"])
    scored_some = pred.on_rows(table.assign(label=table["label"] + 100))
    assert scored_some[pred.columns()].isna().all().all()  # objects it did not score


def test_bad_groups_are_refused_in_words(two_sizes):
    table, groups = two_sizes
    with pytest.raises(InputError, match="at least two groups among the table's objects, got 1"):
        predict_outcome(table, dict.fromkeys(groups, "x"))
    with pytest.raises(InputError, match="has 1 object"):
        predict_outcome(table, {1: "small", 2: "large", 3: "small"})
    with pytest.raises(InputError, match="frames \\[7\\] are not in the table"):
        predict_outcome(table, groups, frames=[0, 7])
    assert isinstance(table, pd.DataFrame)


def four_clones(seed: int = 0, per_group: int = 15, movies: int = 1) -> tuple:
    """A study of four groups with known differences: the groups' areas lie 3 spreads apart
    (the classic measures tell them apart), two shape columns carry them weakly, the reporter
    not at all; ``movies`` movies whose labels repeat (1, 2, … in each)."""
    rng = np.random.default_rng(seed)
    rows, groups = [], {}
    for m in range(movies):
        for k in range(4 * per_group):
            g = k % 4
            groups[(f"m{m}", k + 1)] = f"clone{g}"
            own = rng.normal(0, 20)
            for t in range(3):
                row = {"movie": f"m{m}", "frame": t, "label": k + 1, "error": "",
                       "area": 300 + 60 * g + own + 5 * rng.normal(),
                       "circularity": 0.8 + 0.02 * rng.normal(),
                       "intensity_mean": 1 + 0.1 * rng.normal()}
                for r in range(3):
                    for n in range(4):
                        row[f"shape_r{r:02d}_n{n:02d}"] = rng.normal() + 0.8 * (n == 2) * (g % 2)
                        row[f"intensity_r{r:02d}_n{n:02d}"] = rng.normal()
                rows.append(row)
    return pd.DataFrame(rows), groups


def test_four_groups_are_predicted_above_chance_and_the_fusion_keeps_the_best_family():
    table, groups = four_clones()
    by_object = {f"m0/{lab}": g for (_, lab), g in groups.items()}
    pred = predict_outcome(table, by_object, n_repeats=2, curve=False)
    s = pred.summary["mean"]
    assert pred.groups == ("clone0", "clone1", "clone2", "clone3")
    assert s["chance"] == 0.25 and s["classic alone"] >= 0.7  # the best rule: 0.9
    assert s["fused"] >= s.drop(["fused", "chance"]).max() - 0.05  # within noise
    assert s["intensity alone"] < 0.5  # the reporter says nothing here
    truth = pred.confusion.to_numpy()
    assert truth.shape == (4, 4) and np.trace(truth) > 0.75 * truth.sum()


def test_no_object_is_on_both_sides_of_a_split():
    """Random groups, every object's frames nearly the same and unlike any other's: a split
    that put one object's frames on both sides would recognise the object and score ~1; with
    objects kept whole the score stays near chance."""
    rng = np.random.default_rng(1)
    rows, groups = [], {}
    for k in range(60):
        own = rng.normal(0, 1, 12)
        groups[k + 1] = f"g{rng.integers(3)}"
        for t in range(4):
            row = {"frame": t, "label": k + 1, "error": "", "area": 100 + rng.normal()}
            row.update({f"shape_r00_n{n:02d}": own[n] + 0.01 * rng.normal() for n in range(12)})
            rows.append(row)
    table = pd.DataFrame(rows)
    pred = predict_outcome(table, groups, n_repeats=3, curve=False)
    assert pred.summary.loc["fused", "mean"] < 0.6


def test_objects_of_several_movies_are_keyed_by_movie():
    table, groups = four_clones(per_group=6, movies=2)
    # the same label in the two movies is two objects, of different groups here
    named = {f"m{m}/{lab}": (g if m == 0 else f"clone{(int(g[-1]) + 1) % 4}")
             for (mv, lab), g in groups.items() for m in (int(mv[1:]),)}
    pred = predict_outcome(table, named, n_repeats=1, curve=False)
    probs = pred.probabilities.set_index("object")
    assert len(probs) == 2 * 24 and probs.loc["m1/1", "group"] != probs.loc["m0/1", "group"]
    rows = pred.on_rows(table)
    assert rows.groupby(["movie", "label"])["p_clone0"].nunique().max() == 1


def test_a_model_of_one_table_predicts_another():
    from napari_pfsdm.analysis.outcome import fit_outcome
    from napari_pfsdm.core.table_options import set_options

    train, groups = four_clones(seed=0)
    other, truth = four_clones(seed=5)
    record = {"n_fourier": 3, "weights": [1.0, 1.0, 1.0], "space_unit": "µm",
              "pixel_size": [0.5, 0.5]}
    set_options(train, dict(record))
    set_options(other, dict(record))
    model = fit_outcome(train, {f"m0/{lab}": g for (_, lab), g in groups.items()})
    got = model.predict(other)
    assert list(got.columns[:3]) == ["object", "movie", "label"]
    assert {f"p_clone{g}" for g in range(4)} <= set(got.columns)
    right = got["predicted"].to_numpy() == np.array([truth[("m0", lab)] for lab in got["label"]])
    assert right.mean() > 0.7  # new objects, predicted from a model that never saw them
    set_options(other, {**record, "n_fourier": 5})
    with pytest.raises(InputError, match="other options than the training table.*n_fourier"):
        model.predict(other)
    said: list[str] = []
    set_options(other, {"n_fourier": 3, "weights": [1.0, 1.0, 1.0], "pixel_size": [0.65, 0.65]})
    set_options(train, {"n_fourier": 3, "weights": [1.0, 1.0, 1.0], "pixel_size": [0.5, 0.5]})
    fit_outcome(train, {f"m0/{lab}": g for (_, lab), g in groups.items()}).predict(
        other, say=said.append)
    assert said and "pixel sizes differ" in said[0]


def test_the_command_line_writes_each_objects_probabilities(two_sizes, tmp_path, capsys):
    import json

    from napari_pfsdm.cli import main
    from napari_pfsdm.io import write_table

    table, groups = two_sizes
    write_table(table, tmp_path / "features.csv", table.attrs["pfsdm"],
                    table_type="features")
    (tmp_path / "groups.csv").write_text(
        "label,group\n" + "".join(f"{k},{g}\n" for k, g in groups.items() if k <= 16))
    rc = main(["predict", str(tmp_path / "features.csv"), "--groups",
               str(tmp_path / "groups.csv"), "--frames", "0-1", "-o",
               str(tmp_path / "pred.csv"), "--repeats", "1"])
    assert rc == 0
    said = capsys.readouterr().out
    assert "classic measures alone: balanced accuracy 1.00" in said
    assert "chance: balanced accuracy 0.50" in said and "confusion matrix" in said
    pred = pd.read_csv(tmp_path / "pred.csv")  # plain CSV
    assert len(pred) == 20 and {"p_large", "p_small", "predicted", "label"} <= set(pred.columns)
    ids = pred["object"].astype(str).tolist()
    for k in (17, 18, 19, 20):  # no group given: predicted from their size
        p = pred["p_large"].iat[ids.index(str(k))]
        assert (p > 0.5) == (groups[k] == "large")
    side = json.loads((tmp_path / "pred.csv.json").read_text())
    assert side["frames"] == [0, 1] and side["balanced_accuracy"][0]["method"] == "fused"
    assert main(["classify", str(tmp_path / "features.csv"), "--groups",
                 str(tmp_path / "groups.csv"), "--frames", "0-1", "-o",
                 str(tmp_path / "scores.csv"), "--repeats", "1", "-q"]) == 0
    scores = pd.read_csv(tmp_path / "scores.csv")
    assert scores["family"].tolist() == ["fused", "shape", "classic measures", "chance"]
    assert scores.set_index("family").loc["classic measures", "balanced_accuracy"] == 1.0
    (tmp_path / "one.csv").write_text("label,group\n1,small\n2,small\n")
    rc = main(["predict", str(tmp_path / "features.csv"), "--groups", str(tmp_path / "one.csv"),
               "-o", str(tmp_path / "pred2.csv")])
    assert rc == 2 and "at least two groups" in capsys.readouterr().err


def _same(got, want, where: str = "") -> None:
    """``got`` equals the recorded ``want``: floats to 1e-10 (accuracies and weights, on
    grids far coarser, so exactly), NaN where NaN, everything else exactly."""
    if isinstance(want, dict):
        assert sorted(got) == sorted(want), where
        for k in want:
            _same(got[k], want[k], f"{where}/{k}")
    elif isinstance(want, list):
        assert isinstance(got, list) and len(got) == len(want), where
        for i, (g, w) in enumerate(zip(got, want, strict=True)):
            _same(g, w, f"{where}[{i}]")
    elif isinstance(want, float) or isinstance(got, float):
        if np.isnan(want):
            assert np.isnan(got), where
        else:
            assert abs(got - want) <= 1e-10, f"{where}: {got!r} != {want!r}"
    else:
        assert got == want, f"{where}: {got!r} != {want!r}"


@pytest.mark.parametrize("part", ["evaluate", "predict"])
def test_the_fusion_protocol_gives_the_recorded_results(part):
    """``classification.evaluate`` (inner CV and hold-out, three seeds) and ``predict_outcome``
    (the default call, another seed, two channels, objects without a group, the montage):
    every split's accuracies and weights, the summaries, the curves and the probabilities
    recorded in tests/data (tests/recorded.py)."""
    import json

    from recorded import FUSION_FILE, fusion_runs

    want = json.loads(FUSION_FILE.read_text(encoding="utf-8"))[part]
    _same(fusion_runs(part), want, part)


def test_fusion_weights_search_the_simplex_and_ties_go_to_equal_weights():
    from napari_pfsdm.analysis.prediction import best_weights, fuse, weight_grid

    grid = weight_grid(3)
    assert len(grid) == 15 and grid[0] == (0.0, 0.0, 1.0)
    assert all(abs(sum(w) - 1) < 1e-12 and min(w) >= 0 for w in grid)
    y = np.array([0, 0, 1, 1])
    good = np.array([0.1, 0.2, 0.9, 0.8])
    bad = 1 - good
    # only channel 0 is right: every weight giving it more than half is perfect; of those,
    # (0.75, 0.25, 0) and (0.75, 0, 0.25) are nearest equal weights, the first in the grid wins
    assert best_weights([good, bad, bad], y, grid) == (0.75, 0.0, 0.25)
    # all three alike: all weights tie, equal-ish weights win
    assert best_weights([good, good, good], y, grid) == (0.25, 0.25, 0.5)
    np.testing.assert_allclose(fuse([good, bad, bad], (0.5, 0.25, 0.25)),
                               0.5 * good + 0.5 * bad)
