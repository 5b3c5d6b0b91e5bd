"""Do the groups differ (napari_pfsdm.analysis.group_stats, pfsdm stats): one value per object,
the tests against scipy's, Holm's correction and effect sizes by hand."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from scipy.stats import kruskal, mannwhitneyu

from napari_pfsdm.analysis.group_stats import compare_groups, holm, object_values
from napari_pfsdm.cli import main
from napari_pfsdm.core.table_options import set_options
from napari_pfsdm.errors import InputError
from napari_pfsdm.io import write_table

DAYS = [2.0, 5.0, 8.0, 12.0, 12.0, 16.0]  # one day imaged twice


def study(seed: int = 0, per_group: int = 8) -> pd.DataFrame:
    """Four clones of organoids growing at known rates (µm² per day) from known sizes; each
    organoid a movie of one object."""
    rng = np.random.default_rng(seed)
    rates = {"wt": 100.0, "A": 100.0, "B": 400.0, "C": 800.0}
    rows = []
    for g, rate in rates.items():
        for k in range(per_group):
            start = 2000 + 200 * rng.normal()
            for t, day in enumerate(DAYS):
                rows.append({"movie": f"{g}_{k:02d}", "frame": t, "time": day, "label": 1,
                             "area": start + rate * day + 50 * rng.normal(), "error": "",
                             "group": g, "clone": g, "lab": "LabA"})
    table = pd.DataFrame(rows)
    return set_options(table, {"space_unit": "µm", "time_unit": "day",
                               "pixel_sizes": {m: [3.165, 3.165] for m in table["movie"]}})


def test_growth_rates_are_each_objects_least_squares_slope():
    table = study()
    v = object_values(table, "area", summary="slope", keep=["lab"])
    one = table[table["movie"] == "B_03"]
    assert v.set_index("movie").loc["B_03", "value"] == pytest.approx(
        np.polyfit(one["time"], one["area"], 1)[0])
    assert len(v) == 32 and (v["n_times"] == 5).all() and (v["lab"] == "LabA").all()
    at = object_values(table, "area", at=12)
    both = one[one["time"] == 12]["area"].mean()  # day 12 imaged twice: the mean
    assert at.set_index("movie").loc["B_03", "value"] == pytest.approx(both)
    with pytest.raises(InputError, match="no object has a time \\(day\\) of 11"):
        object_values(table, "area", at=11)


def test_the_tests_are_scipys_with_holms_correction_and_rank_biserial_effects():
    v = object_values(study(), "area", summary="slope")
    test = compare_groups(v, what="growth")
    samples = [v.loc[v["group"] == g, "value"].to_numpy() for g in ("A", "B", "C", "wt")]
    h, p = kruskal(*samples)
    assert test.overall["test"] == "Kruskal-Wallis"
    assert test.overall["statistic"] == pytest.approx(h) and test.overall["p_value"] == \
        pytest.approx(p)
    assert test.overall["effect_size"] == pytest.approx(h / (32 - 1))
    pairs = test.pairs.set_index(["first", "second"])
    u, p_ab = mannwhitneyu(samples[0], samples[1], alternative="two-sided")
    assert pairs.loc[("A", "B"), "U"] == u and pairs.loc[("A", "B"), "p_value"] == p_ab
    # by hand: every pair of objects, A's rate against B's (all of B's grow faster)
    assert pairs.loc[("A", "B"), "effect_size"] == -1.0
    raw = test.pairs["p_value"].to_numpy()
    order = np.argsort(raw)
    expected = np.minimum(1, np.maximum.accumulate((6 - np.arange(6)) * raw[order]))
    np.testing.assert_allclose(np.sort(test.pairs["p_holm"].to_numpy()), np.sort(expected))
    # the known differences are found, the equal clones are not told apart
    assert pairs.loc[("A", "wt"), "p_holm"] > 0.05
    assert (pairs.drop(index=("A", "wt"))["p_holm"] < 0.05).all()
    words = " ".join(test.sentences())
    assert "the groups differ (Kruskal-Wallis" in words and "B > A" in words


def test_two_groups_use_mann_whitney():
    v = object_values(study(), "area", summary="slope")
    test = compare_groups(v[v["group"].isin(["A", "C"])])
    assert test.overall["test"] == "Mann-Whitney U" and len(test.pairs) == 1
    assert holm(np.array([0.5])).tolist() == [0.5]
    with pytest.raises(InputError, match="two groups with at least two objects"):
        compare_groups(v[v["group"] == "A"])


def test_pfsdm_stats_prints_the_findings_and_writes_the_table(tmp_path, capsys):
    table = study().drop(columns=["group", "clone", "lab"])
    write_table(table, tmp_path / "f.csv", table.attrs["pfsdm"], table_type="features")
    pd.DataFrame({"movie": [f"{m}.tif" for m in table["movie"].unique()],
                  "clone": [m.split("_")[0] for m in table["movie"].unique()],
                  "lab": "LabA"}).to_csv(tmp_path / "groups.csv", index=False)
    assert main(["stats", str(tmp_path / "f.csv"), "--groups", str(tmp_path / "groups.csv"),
                 "--group-column", "clone", "--measure", "area", "--summary", "slope",
                 "-o", str(tmp_path / "s.csv"), "--objects", str(tmp_path / "o.csv")]) == 0
    said = capsys.readouterr().out
    assert "change of area per day (µm² per day): the groups differ (Kruskal-Wallis" in said
    stats = pd.read_csv(tmp_path / "s.csv")
    assert stats["comparison"].tolist()[:2] == ["all groups", "A vs B"]
    assert {"p_holm", "effect_size", "median", "n"} <= set(stats.columns)
    objects = pd.read_csv(tmp_path / "o.csv")
    assert len(objects) == 32 and {"clone", "lab", "value"} <= set(objects.columns)
    side = json.loads((tmp_path / "s.csv.json").read_text())
    assert side["measure"] == "area" and side["summary"] == "slope"
    # --at is bounded by the table's times: a time no object has is refused, naming them
    assert main(["stats", str(tmp_path / "f.csv"), "--groups", str(tmp_path / "groups.csv"),
                 "--group-column", "clone", "--measure", "area", "--at", str(10**40),
                 "-o", str(tmp_path / "t.csv"), "-q"]) == 2
    assert "no object has a time (day) of 1e+40; the table's are" in capsys.readouterr().err
