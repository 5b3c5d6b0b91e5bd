"""The shape space as a fitted model (napari_pfsdm.analysis.shape_space), against
scikit-learn's PCA and hand-worked cases."""

import numpy as np
import pandas as pd
import pytest
from sklearn.decomposition import PCA

from napari_pfsdm import measure
from napari_pfsdm.analysis.shape_space import ShapePCA, shape_modes
from napari_pfsdm.analysis.tables import weighted_features
from napari_pfsdm.errors import InputError


def _ellipses(aspects, size: int = 96, seed: int = 0) -> np.ndarray:
    """One ellipse per frame, of the given aspect ratios, turned at random."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:size, 0:size] - (size - 1) / 2
    frames = np.zeros((len(aspects), size, size), np.uint8)
    for t, q in enumerate(aspects):
        a = 30.0
        b = a / q
        th = rng.uniform(0, np.pi)
        u = xx * np.cos(th) + yy * np.sin(th)
        v = -xx * np.sin(th) + yy * np.cos(th)
        frames[t][(u / a) ** 2 + (v / b) ** 2 <= 1] = 1
    return frames


@pytest.fixture(scope="module")
def tables():
    reference = measure(_ellipses(np.linspace(1.0, 3.0, 9)))
    other = measure(_ellipses([1.3, 2.2, 2.8], seed=5))
    return reference, other


def _aligned(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``b``'s columns with the signs that best match ``a``'s (PCA signs are a convention)."""
    signs = np.sign(np.sum(a * b, axis=0))
    return b * np.where(signs == 0, 1, signs)


def test_fit_transform_is_scikit_learns_pca_of_the_weighted_features(tables):
    reference, other = tables
    space = ShapePCA(n_components=3).fit(reference)
    x_ref, x_other = weighted_features(reference), weighted_features(other)
    sk = PCA(n_components=3).fit(x_ref)
    ours = space.transform(reference)[["shape_PC1", "shape_PC2", "shape_PC3"]].to_numpy()
    np.testing.assert_allclose(ours, _aligned(ours, sk.transform(x_ref)), atol=1e-9)
    np.testing.assert_allclose(space.explained_variance_ratio_, sk.explained_variance_ratio_,
                               rtol=1e-9)
    # another movie projected into the reference's space: scikit-learn's transform too
    theirs = space.transform(other)[["shape_PC1", "shape_PC2", "shape_PC3"]].to_numpy()
    signs = np.sign(np.sum(ours * sk.transform(x_ref), axis=0))
    np.testing.assert_allclose(theirs, sk.transform(x_other) * signs, atol=1e-9)
    assert space.transform(other)["frame"].tolist() == [0, 1, 2]


def test_a_shape_space_is_a_scikit_learn_estimator(tables):
    from sklearn.base import clone

    reference, other = tables
    space = ShapePCA(n_components=2, regress_out=["area"])
    assert clone(space).get_params() == space.get_params()  # parameters stored as given
    assert space.set_params(n_components=3).n_components == 3
    space.fit(reference)
    assert space.get_feature_names_out().tolist() == ["shape_PC1", "shape_PC2", "shape_PC3"]
    with pytest.raises(InputError, match="at least two measured"):
        ShapePCA().fit(reference.iloc[:1])
    with pytest.raises(InputError, match="fit the shape space"):
        ShapePCA().transform(other)


def test_a_table_measured_with_other_options_is_refused_in_words(tables):
    reference, _ = tables
    space = ShapePCA(n_components=2).fit(reference)
    coarse = measure(_ellipses([1.5, 2.5]), n_fourier=6)
    with pytest.raises(InputError, match="n_fourier: reference 10, this table 6"):
        space.transform(coarse)


def test_loadings_read_as_rings_by_harmonics_and_elongation_is_harmonic_2(tables):
    reference, _ = tables
    space = ShapePCA(n_components=2).fit(reference)
    maps = space.loadings(1)
    opts = reference.attrs["pfsdm"]
    assert maps.shape == (opts["n_radii"], opts["n_fourier"] + 1)
    np.testing.assert_array_equal(maps.ravel(), space.components_[0])
    # the ellipses differ only in elongation: on PC1, harmonic 2 carries the most weight
    # after the ring means (harmonic 0, the thickness, which elongation changes too)
    power = (maps**2).sum(axis=0)
    assert int(np.argmax(power[1:])) + 1 == 2
    with pytest.raises(InputError, match="component must be 1"):
        space.loadings(7)


def test_regressing_out_a_measure_leaves_scores_uncorrelated_with_it(tables):
    reference, other = tables
    space = ShapePCA(n_components=2, regress_out=["area"]).fit(reference)
    scores = space.transform(reference)
    r = np.corrcoef(scores["shape_PC1"], reference["area"])[0, 1]
    assert abs(r) < 1e-8  # least-squares residuals are orthogonal to the regressor
    plain = ShapePCA(n_components=2).fit_transform(reference)
    assert abs(np.corrcoef(plain["shape_PC1"], reference["area"])[0, 1]) > 0.5
    with pytest.raises(InputError, match="no perimeter"):
        ShapePCA(regress_out=["perimeter"]).fit(reference.drop(columns=["perimeter"],
                                                                errors="ignore"))


def test_shape_modes_pick_the_objects_nearest_mean_plus_sigmas():
    scores = pd.DataFrame({"frame": [0, 0, 1, 1, 2], "label": [1, 2, 1, 2, 1],
                           "shape_PC1": [0.0, 1.0, 2.0, 3.0, 4.0]})
    modes = shape_modes(scores, 1)
    # by hand: mean 2, sd sqrt(2); targets 2 - 2.83, 2 - 1.41, 2, 3.41, 4.83
    np.testing.assert_allclose(modes["target"], 2 + np.sqrt(2) * np.array([-2, -1, 0, 1, 2]))
    assert modes["row"].tolist() == [0, 1, 2, 3, 4]
    assert modes[["frame", "label"]].values.tolist() == [[0, 1], [0, 2], [1, 1], [1, 2], [2, 1]]


def test_cli_trajectories_projects_into_a_reference_space(tables, tmp_path, capsys):
    from napari_pfsdm.cli import main
    from napari_pfsdm.io import write_table

    reference, other = tables
    write_table(reference, tmp_path / "control.csv", reference.attrs["pfsdm"],
                    table_type="features")
    write_table(other, tmp_path / "treated.csv", other.attrs["pfsdm"],
                    table_type="features")
    rc = main(["trajectories", str(tmp_path / "treated.csv"), "--reference",
               str(tmp_path / "control.csv"), "-o", str(tmp_path / "pca.csv"),
               "--channel", "shape", "--components", "2", "--link", "labels", "-q"])
    assert rc == 0
    scores = pd.read_csv(tmp_path / "pca.csv")
    sk = PCA(n_components=2).fit(weighted_features(reference))
    expected = sk.transform(weighted_features(other))
    got = scores[["shape_PC1", "shape_PC2"]].to_numpy()
    np.testing.assert_allclose(np.abs(got), np.abs(expected), atol=1e-6)
    # a reference measured otherwise: refused, exit 2, in words
    coarse = measure(_ellipses([1.5, 2.5, 2.0]), n_fourier=6)
    write_table(coarse, tmp_path / "coarse.csv", coarse.attrs["pfsdm"],
                    table_type="features")
    rc = main(["trajectories", str(tmp_path / "treated.csv"), "--reference",
               str(tmp_path / "coarse.csv"), "-o", str(tmp_path / "pca2.csv"),
               "--channel", "shape", "--link", "labels", "-q"])
    assert rc == 2
    assert "n_fourier" in capsys.readouterr().err
    assert not (tmp_path / "pca2.csv").exists()


# ------------------------------------------------------------ recorded and independent numbers
def _montage():
    from recorded import montage_table

    return montage_table()


@pytest.mark.parametrize("case", ["shape", "intensity", "shape_standardized",
                                  "intensity_standardized"])
def test_the_pca_of_the_recorded_montage_gives_the_recorded_numbers(case):
    """``pca_scores`` and ``ShapePCA`` on ``pf.measure`` of the montage (seed 0): the scores
    and explained-variance ratios recorded in tests/data (tests/recorded.py)."""
    from napari_pfsdm.analysis.reduction import pca_scores
    from napari_pfsdm.core.table_schema import pc_columns
    from recorded import PCA_CASES, PCA_FILE

    want = np.load(PCA_FILE)
    kw = PCA_CASES[case]
    table = _montage()
    scores, ratio = pca_scores(table, kw["channel"], kw["n_components"],
                               standardize=kw.get("standardize", False))
    got = scores[pc_columns(scores.columns, kw["channel"])].to_numpy()
    np.testing.assert_allclose(got, want[f"{case}_scores"], rtol=0, atol=1e-10)
    np.testing.assert_allclose(ratio, want[f"{case}_ratio"], rtol=0, atol=1e-10)
    assert scores[["frame", "label"]].values.tolist() == table[["frame", "label"]].values.tolist()
    space = ShapePCA(**kw)
    got = space.fit_transform(table)[pc_columns(scores.columns, kw["channel"])].to_numpy()
    np.testing.assert_allclose(got, want[f"{case}_scores"], rtol=0, atol=1e-10)
    np.testing.assert_allclose(space.explained_variance_ratio_, want[f"{case}_ratio"],
                               rtol=0, atol=1e-10)


def test_regressed_out_pca_of_the_recorded_montage_gives_the_recorded_numbers():
    from recorded import PCA_FILE, REGRESSED

    want = np.load(PCA_FILE)
    table = _montage()
    space = ShapePCA(n_components=4, regress_out=REGRESSED).fit(table)
    got = space.transform(table)[[f"shape_PC{k}" for k in range(1, 5)]].to_numpy()
    np.testing.assert_allclose(got, want["beyond_scores"], rtol=0, atol=1e-10)
    np.testing.assert_allclose(space.explained_variance_ratio_, want["beyond_ratio"],
                               rtol=0, atol=1e-10)


def test_the_plugins_pca_gives_the_recorded_numbers():
    pytest.importorskip("psygnal")
    from napari_pfsdm.napari._results import pca_scores as plugin_pca
    from recorded import PCA_FILE

    want = np.load(PCA_FILE)
    out = plugin_pca(_montage(), "shape")
    pcs = [f"shape_PC{k}" for k in range(1, 6)]
    assert list(out.columns) == ["frame", "label", *pcs]
    np.testing.assert_allclose(out[pcs].to_numpy(),
                               want["shape_scores"], rtol=0, atol=1e-10)
    np.testing.assert_allclose(out.attrs["explained_variance_ratio"], want["shape_ratio"],
                               rtol=0, atol=1e-10)


def _by_hand(table: pd.DataFrame, channel: str) -> tuple[np.ndarray, np.ndarray]:
    """The raw features and their weights, √(ring weight) × mode weight, from the options the
    table carries."""
    opts = table.attrs["pfsdm"]
    n_r, n_m = opts["n_radii"], opts["n_fourier"] + 1
    cols = [f"{channel}_r{r:02d}_n{m:02d}" for r in range(n_r) for m in range(n_m)]
    w = np.sqrt(np.asarray(opts["weights"]))[:, None] * np.asarray(opts["mode_weights"])[None]
    return table[cols].to_numpy(float), w.ravel()


def _signed(pca: PCA) -> np.ndarray:
    """+1/-1 per component: its largest loading (in absolute value) made positive."""
    c = pca.components_
    return np.sign(c[np.arange(len(c)), np.abs(c).argmax(axis=1)])


@pytest.mark.parametrize("channel", ["shape", "intensity"])
def test_shape_pca_is_scikit_learns_pca_of_the_weighted_matrix(channel):
    """On the montage's table: scores, components and ratios of scikit-learn's PCA of the
    weighted matrix built here, each component signed so that its largest loading is
    positive; standardised: scikit-learn's PCA of StandardScaler's output."""
    from sklearn.preprocessing import StandardScaler

    table = _montage()
    raw, w = _by_hand(table, channel)
    x = raw * w
    ref = PCA(n_components=5, svd_solver="full").fit(x)
    signs = _signed(ref)
    space = ShapePCA(n_components=5, channel=channel).fit(table)
    got = space.transform(table)[[f"{channel}_PC{k}" for k in range(1, 6)]].to_numpy()
    np.testing.assert_allclose(got, ref.transform(x) * signs, rtol=0, atol=1e-10)
    np.testing.assert_allclose(space.components_, ref.components_ * signs[:, None],
                               rtol=0, atol=1e-10)
    np.testing.assert_allclose(space.explained_variance_ratio_, ref.explained_variance_ratio_,
                               rtol=1e-10)
    z = StandardScaler().fit_transform(raw)
    ref = PCA(n_components=3, svd_solver="full").fit(z)
    space = ShapePCA(n_components=3, channel=channel, standardize=True).fit(table)
    got = space.transform(table)[[f"{channel}_PC{k}" for k in range(1, 4)]].to_numpy()
    np.testing.assert_allclose(got, ref.transform(z) * _signed(ref), rtol=0, atol=1e-10)
    np.testing.assert_allclose(space.explained_variance_ratio_, ref.explained_variance_ratio_,
                               rtol=1e-10)


def test_the_transformer_then_scikit_learns_pca_is_the_shape_space(tables):
    """Masks through ``PFSDMTransformer(weighted=True)`` and scikit-learn's PCA give the
    scores ShapePCA gives on the table measured from the same masks (signs aside)."""
    from sklearn.pipeline import make_pipeline

    from napari_pfsdm import PFSDMTransformer

    reference, _ = tables
    masks = _ellipses(np.linspace(1.0, 3.0, 9)).astype(bool)
    pipe = make_pipeline(PFSDMTransformer(weighted=True), PCA(n_components=3))
    theirs = pipe.fit_transform(list(masks))
    ours = ShapePCA(n_components=3).fit_transform(reference)[
        ["shape_PC1", "shape_PC2", "shape_PC3"]].to_numpy()
    np.testing.assert_allclose(ours, _aligned(ours, theirs), atol=1e-8)
