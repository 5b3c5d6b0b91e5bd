"""The synthetic benchmark's scoring and a tiny end-to-end run."""

import numpy as np
import pytest

import synthetic_five_shapes as SB

pytest.importorskip("pyefd")


def test_nn_accuracy_and_silhouette_on_a_hand_made_matrix():
    # two tight pairs far apart: silhouette = mean(1 - a/b) with a = 1, b = 10 -> 0.9
    pts = np.array([0.0, 1.0, 10.0, 11.0])
    d = np.abs(pts[:, None] - pts[None, :])
    labels = np.array([0, 0, 1, 1])
    sil, nn = SB.scores(d, labels)
    assert sil == pytest.approx(np.mean([1 - 1 / 10.5, 1 - 1 / 9.5, 1 - 1 / 9.5, 1 - 1 / 10.5]))
    assert nn == 1.0
    assert SB.nn_accuracy(d, np.array([0, 1, 0, 1])) == 0.0
    d_nan = d.copy()
    d_nan[0, 1] = np.nan
    assert all(np.isnan(SB.scores(d_nan, labels)))


def test_variant_grid_is_complete_and_starts_with_the_defaults():
    grid = SB.pfsdm_variants()
    assert grid[0] == {} and SB.pfsdm_variants(quick=True) == [{}]
    combos = {(v["mapping"], v["sdf"], v["normalization"], v["radii"])
              for v in grid[1:] if "mapping" in v}
    assert len(combos) == 3 * 2 * 2 * 2


def test_quick_run_on_a_tiny_set_writes_table_and_plot(tmp_path, capsys):
    table = SB.run(tmp_path, quick=True, n_per_class=2, size=96)
    methods = ["PF-SDM (default)", *(r[0] for r in SB.REFERENCE_ROWS), "EFA (raw pyefd)", "EFA",
               "EFA (mirror-aware)", "GPA"]
    assert table["set"].tolist() == ["exact"] * 7 + ["perturbed"] * 7
    assert table["method"].tolist() == methods * 2
    assert table["silhouette"].between(-1, 1).all()
    assert table["nn_accuracy"].between(0, 1).all()
    assert table.loc[table["method"] == "PF-SDM (default)", "is_default"].all()
    # exact copies: the invariant methods find every nearest neighbour in the same class
    exact = table[table["set"] == "exact"].set_index("method")
    assert exact.loc["GPA", "nn_accuracy"] == 1.0 and exact.loc["GPA", "silhouette"] > 0.7
    assert exact.loc["PF-SDM (default)", "nn_accuracy"] == 1.0
    assert (tmp_path / "synthetic_benchmark.csv").stat().st_size > 0
    assert (tmp_path / "synthetic_mds.png").read_bytes()[:4] == b"\x89PNG"
    out = capsys.readouterr().out
    assert "PF-SDM (default)" in out and "perturbed sil" in out
    d = table.attrs["matrices"][("perturbed", "GPA")]
    assert d.shape == (10, 10) and np.allclose(d, d.T)


def test_run_with_variants_and_one_set(tmp_path):
    table = SB.run(tmp_path, variants=[{"normalization": "ring"}], sets=["exact"],
                   invariances=["magnitude", "align"], n_per_class=2, size=96, plot=False,
                   verbose=False)
    pf = table[table["family"] == "PF-SDM"]
    assert pf["invariance"].tolist() == ["magnitude", "align"]
    assert pf["method"].str.contains("norm=ring").all()
    assert (pf["normalization"] == "ring").all() and not pf["is_default"].any()
    assert not (tmp_path / "synthetic_mds.png").exists()
    with pytest.raises(ValueError, match="Unknown set"):
        SB.run(tmp_path, sets=["noisy"], quick=True)
