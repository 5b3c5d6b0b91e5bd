"""Axis-number classification: vectors, splits, nested fusion weight, pixel baselines."""

import numpy as np
import pandas as pd
import pytest

import pixel_baseline as pb
from napari_pfsdm.analysis import classification as cl
from napari_pfsdm.data.gastruloids import make_gastruloids


@pytest.fixture(scope="module")
def small_set():
    """20 objects x 6 frames, half multi-axes."""
    return make_gastruloids(n_objects=20, n_frames=6, size=96, multi_fraction=0.5, seed=11)


@pytest.fixture(scope="module")
def small_table(small_set):
    return cl.measure_movies(small_set.labels, small_set.intensity)


def test_parse_frames():
    assert cl.parse_frames("0-3") == [0, 1, 2, 3]
    assert cl.parse_frames("0-2, 5,5") == [0, 1, 2, 5]
    assert cl.parse_frames(None, 3) == [0, 1, 2]
    assert cl.parse_frames(range(2)) == [0, 1]
    with pytest.raises(ValueError, match="outside"):
        cl.parse_frames("0-9", 5)
    with pytest.raises(ValueError, match="could not read"):
        cl.parse_frames("a-b")


def test_feature_matrix_is_frame_major():
    rows = []
    for obj in (0, 1):
        for frame in (0, 1, 2):
            rows.append({"object": obj, "frame": frame, "shape_a": 10 * obj + frame,
                         "shape_b": 100 + 10 * obj + frame, "intensity_a": -frame})
    table = pd.DataFrame(rows).sample(frac=1.0, random_state=0)  # order must not matter
    x, objects = cl.feature_matrix(table, "shape", frames=[0, 2])
    assert list(objects) == [0, 1]
    np.testing.assert_array_equal(x, [[0, 100, 2, 102], [10, 110, 12, 112]])
    xi, _ = cl.feature_matrix(table, "intensity", frames="1-2")
    np.testing.assert_array_equal(xi, [[-1, -2], [-1, -2]])
    with pytest.raises(ValueError, match="not in the table"):
        cl.feature_matrix(table, "shape", frames=[5])
    with pytest.raises(ValueError, match="no 'other_"):
        cl.feature_matrix(table, "other")
    bad = table.copy()
    bad.loc[bad.index[0], "shape_a"] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        cl.feature_matrix(bad, "shape")


def test_measure_movies_table(small_set, small_table):
    assert len(small_table) == 20 * 6
    assert set(small_table["object"]) == set(range(20))
    assert (small_table["error"] == "").all()
    sub = cl.measure_movies(small_set.labels[:2], small_set.intensity[:2], frames="4-5")
    assert sorted(sub["frame"].unique()) == [4, 5]
    # measuring a subset of frames gives the same numbers as measuring all of them
    full = small_table[small_table["object"] < 2].set_index(["object", "frame"])
    part = sub.set_index(["object", "frame"])
    cols = [c for c in part.columns if c.startswith("shape_")]
    np.testing.assert_allclose(part[cols], full.loc[part.index, cols])


def test_splits_are_stratified_and_disjoint():
    y = np.array([1] * 5 + [0] * 15)
    splits = cl.make_splits(y, n_splits=5, test_size=0.2, n_repeats=3, seed=0)
    assert len(splits) == 15
    tests = set()
    for train, test in splits:
        assert np.intersect1d(train, test).size == 0
        assert np.union1d(train, test).size == 20
        assert len(test) == 4
        assert y[test].sum() == 1  # 5/20 of 4 test objects
        assert y[train].sum() == 4
        tests.add(tuple(sorted(test)))
    assert len(tests) > 10  # the repeats use different seeds
    with pytest.raises(ValueError, match="at least 2"):
        cl.make_splits(np.array([1] + [0] * 9))


def test_evaluate_rejects_a_leaking_split():
    y = np.array([0, 1] * 5)
    fp = cl.logistic_model(np.eye(10), np.eye(10), y)
    with pytest.raises(ValueError, match="both the training and the test"):
        cl.evaluate(fp, y, [(np.arange(8), np.arange(6, 10))])


def test_best_alpha_and_fuse():
    y = np.array([0, 0, 1, 1])
    ps = np.array([0.1, 0.2, 0.9, 0.8])  # perfect
    pi = np.array([0.9, 0.8, 0.1, 0.2])  # perfectly wrong
    # every alpha > 0.5 is perfect: the tie goes to the one nearest 0.5
    assert cl.best_alpha(ps, pi, y) == 0.55
    assert cl.best_alpha(pi, ps, y) == 0.45
    assert cl.best_alpha(ps, 0.5 * pi + 0.25, y) == 0.5
    assert cl.best_alpha(ps, ps, y) == 0.5  # all tie: nearest to 0.5
    np.testing.assert_allclose(cl.fuse(ps, pi, 0.25), 0.25 * ps + 0.75 * pi)


def _recording(fit_predict, calls):
    def wrapped(train_idx, predict_idx):
        calls.append((np.array(train_idx), np.array(predict_idx)))
        return fit_predict(train_idx, predict_idx)

    return wrapped


@pytest.mark.parametrize("inner", ["cv", "holdout"])
def test_nested_alpha_never_sees_test_labels(inner):
    rng = np.random.default_rng(0)
    n = 40
    y = np.array([1] * 12 + [0] * 28)
    xs = rng.normal(size=(n, 5)) + 0.8 * y[:, None]
    xi = rng.normal(size=(n, 5)) + 0.5 * y[:, None]
    splits = cl.make_splits(y, n_splits=3, n_repeats=1, seed=2)
    changed_optimistic = False
    for train, test in splits:
        base = cl.evaluate(cl.logistic_model(xs, xi, y), y, [(train, test)], inner=inner)
        calls = []
        for trial in range(3):
            y_perm = y.copy()
            y_perm[test] = np.random.default_rng(trial).permutation(y[test])
            if trial == 0:
                y_perm[test] = 1 - y[test]  # flip every test label
            fp = _recording(cl.logistic_model(xs, xi, y_perm), calls)
            res = cl.evaluate(fp, y_perm, [(train, test)], inner=inner)
            nested = res.loc[res["features"] == "fusion (nested)", "alpha"].item()
            ref = base[base["features"] == "fusion (nested)"]
            assert nested == ref["alpha"].item()
            opt = res.loc[res["features"].str.startswith("fusion (optimistic"), "alpha"].item()
            ref_opt = base[base["features"].str.startswith("fusion (opt")]
            changed_optimistic |= opt != ref_opt["alpha"].item()
        # no model was ever trained on a test object
        for tr, _ in calls:
            assert np.intersect1d(tr, test).size == 0
    assert changed_optimistic  # the optimistic alpha does look at the test labels


def test_small_set_late_frames_far_above_chance(small_set, small_table):
    y = small_set.multi_axis.astype(int)
    splits = cl.make_splits(y, n_splits=5, n_repeats=2, seed=0)
    xs, objects = cl.feature_matrix(small_table, "shape", frames="4-5")
    xi, _ = cl.feature_matrix(small_table, "intensity", frames="4-5")
    assert list(objects) == list(range(20))
    summary = cl.summarize(cl.evaluate(cl.logistic_model(xs, xi, y), y, splits))
    assert list(summary.index) == list(cl.FEATURE_SETS)
    assert summary.loc["fusion (nested)", "balanced_accuracy_mean"] >= 0.8
    assert summary.loc["shape", "balanced_accuracy_mean"] >= 0.75
    assert summary.loc["intensity", "balanced_accuracy_mean"] >= 0.65
    # the optimistic (test-tuned) fusion can only be as good or better than the nested one
    assert (
        summary.loc["fusion (optimistic, test-tuned)", "balanced_accuracy_mean"]
        >= summary.loc["fusion (nested)", "balanced_accuracy_mean"]
    )


def test_pixel_stacks_are_centred(small_set):
    seg, img = pb.pixel_stacks(small_set.labels, small_set.intensity, frames="0-1", size=24)
    assert seg.shape == img.shape == (20, 2, 24, 24)
    assert seg.dtype == np.float32
    yy, xx = np.mgrid[0:24, 0:24]
    for s in seg[:, 0]:
        cy, cx = (s * yy).sum() / s.sum(), (s * xx).sum() / s.sum()
        assert abs(cy - 11.5) < 1.5 and abs(cx - 11.5) < 1.5
    assert np.all((seg >= 0) & (seg <= 1.0 + 1e-6))


def test_augment_rotates_every_frame_alike():
    rng = np.random.default_rng(0)
    x = np.zeros((2, 3, 16, 16), dtype=np.float32)
    x[:, :, 6:10, 6:10] = 1.0  # a centred square: rotation keeps the mass near the centre
    x[:, :, 7, 12:14] = 1.0  # plus an off-centre spot
    out = pb.augment(x, 3, rng)
    assert out.shape == (8, 3, 16, 16)
    np.testing.assert_array_equal(out[:2], x)
    for a in out[2:]:
        for f in range(1, 3):
            np.testing.assert_allclose(a[f], a[0])  # same transform on every frame
        assert abs(a[0].sum() - x[0, 0].sum()) < 0.25 * x[0, 0].sum()


def test_sklearn_pixel_baseline_late_frames_above_chance(small_set):
    y = small_set.multi_axis.astype(int)
    seg, img = pb.pixel_stacks(small_set.labels, small_set.intensity, frames="4-5", size=24)
    splits = cl.make_splits(y, n_splits=3, n_repeats=1, seed=0)
    fp = pb.sklearn_pixel_model(seg, img, y, n_augment=2)
    summary = cl.summarize(cl.evaluate(fp, y, splits, inner="holdout"))
    assert summary.loc["fusion (optimistic, test-tuned)", "balanced_accuracy_mean"] > 0.6


@pytest.mark.skipif(not pb.torch_available(), reason="torch is not installed")
def test_cnn_baseline_runs(small_set):
    y = small_set.multi_axis.astype(int)
    seg, img = pb.pixel_stacks(small_set.labels, small_set.intensity, frames="4-5", size=16)
    fp = pb.cnn_model(seg, img, y, epochs=2, width=4)
    ps, pi = fp(np.arange(14), np.arange(14, 20))
    assert ps.shape == pi.shape == (6,)
    assert np.all((ps >= 0) & (ps <= 1)) and np.all((pi >= 0) & (pi <= 1))


def test_report_writes_table_and_plots(tmp_path):
    from gastruloid_report import run

    results = run(tmp_path, n_objects=20, n_frames=6, size=80, frames="3-5", quick=True,
                  pixel=False, cnn=False, verbose=False)
    assert list(results["features"]) == 2 * list(cl.FEATURE_SETS)
    assert list(dict.fromkeys(results["method"])) == [
        "PF-SDM + logistic", "size + contrast (ref.)"
    ]
    assert (results["time_s"] > 0).all()
    for name in ("gastruloid_results.csv", "gastruloid_accuracy.png", "gastruloid_pca.png"):
        assert (tmp_path / name).stat().st_size > 500
    back = pd.read_csv(tmp_path / "gastruloid_results.csv")
    np.testing.assert_allclose(back["balanced_accuracy_mean"], results["balanced_accuracy_mean"])


def test_report_over_seeds_summarises_each_seed(tmp_path):
    from gastruloid_report import run_seeds

    summary = run_seeds(tmp_path, [3, 4], n_objects=20, n_frames=6, size=80, frames="3-5",
                        quick=True, pixel=False, cnn=False, verbose=False)
    per_seed = [pd.read_csv(tmp_path / f"seed{k}" / "gastruloid_results.csv") for k in (3, 4)]
    row = summary[(summary.method == "PF-SDM + logistic")
                  & (summary.features == "fusion (nested)")].iloc[0]
    values = [r[(r.method == "PF-SDM + logistic") & (r.features == "fusion (nested)")]
              ["balanced_accuracy_mean"].iloc[0] for r in per_seed]
    assert row.n_seeds == 2
    assert row.balanced_accuracy_mean == pytest.approx(np.mean(values))
    assert row.balanced_accuracy_sd_over_seeds == pytest.approx(np.std(values, ddof=1))
    assert (tmp_path / "gastruloid_seeds.csv").exists()


def test_speed_summary_names_the_ratios():
    from gastruloid_report import speed_summary

    res = pd.DataFrame({"method": ["PF-SDM + logistic", "size + contrast (ref.)", "pixels + CNN"],
                        "time_s": [2.0, 0.5, 30.0]})
    line = speed_summary(res)
    assert "15.0x faster than pixels + CNN" in line
    assert "size + contrast" not in line  # the reference is not a competitor
    assert speed_summary(res.iloc[1:]) == ""


def _disk(shape, center, radius):
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    return (yy - center[0]) ** 2 + (xx - center[1]) ** 2 <= radius**2


def test_size_contrast_features_measure_growth_and_contrast():
    labels = np.zeros((2, 3, 96, 96), dtype=np.uint16)
    for t, r in enumerate((10, 15, 20)):
        labels[:, t][:, _disk((96, 96), (48, 48), r)] = 1
    intensity = np.ones(labels.shape, dtype=np.float32)
    spot = _disk((96, 96), (48, 56), 3)
    intensity[1][:, spot] = 20.0  # object 1: one bright pole
    growth, contrast = cl.size_contrast_features(labels, intensity * 3.0, "0-2")
    assert growth.shape == (2, 2) and contrast.shape == (2, 3)
    # equivalent radius doubles from frame 0 to 2: growth = log 2 (rasterisation aside)
    np.testing.assert_allclose(growth[:, 1], np.log(2.0), atol=0.01)
    np.testing.assert_allclose(growth[:, 0], np.log(1.5), atol=0.01)
    np.testing.assert_allclose(contrast[0], 1.0)  # uniform reporter
    assert np.all(contrast[1] < 0.5)  # a bright pole: the mean is far below the peak
    # the gain does not matter
    _, c1 = cl.size_contrast_features(labels, intensity, "0-2")
    np.testing.assert_allclose(c1, contrast)


def test_size_contrast_features_bad_input():
    labels = np.zeros((1, 2, 32, 32), dtype=np.uint16)
    labels[0, 0, 10:20, 10:20] = 1
    intensity = np.ones(labels.shape)
    with pytest.raises(ValueError, match="empty at frame 1"):
        cl.size_contrast_features(labels, intensity, "0-1")
    with pytest.raises(ValueError, match="at least two frames"):
        cl.size_contrast_features(labels, intensity, "0")
    labels[0, 1] = labels[0, 0]
    intensity[0, 1, 12, 12] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        cl.size_contrast_features(labels, intensity, "0-1")
    with pytest.raises(ValueError, match="same shape"):
        cl.size_contrast_features(labels, intensity[:, :, :16], "0-1")
