"""PFSDMTransformer: scikit-learn's conventions, and the same numbers as the feature table."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.linear_model import LogisticRegression
from sklearn.model_selection import cross_val_score
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

import napari_pfsdm as P
from napari_pfsdm.analysis.transformer import PFSDMTransformer
from napari_pfsdm.errors import InputError
from shapes_fixture import BASE_SHAPES, raster


def masks(n_per_class: int = 1, size: int = 120):
    rng = np.random.default_rng(0)
    out, y = [], []
    for k, outline in enumerate(BASE_SHAPES.values()):
        for _ in range(n_per_class):
            out.append(raster(outline, size, angle=rng.uniform(0, 2 * np.pi),
                              mirror=bool(rng.integers(2)), scale=rng.uniform(0.7, 1.1)))
            y.append(k)
    return out, np.array(y)


def test_rows_and_names_are_the_feature_tables():
    objs, _ = masks()
    labels = np.zeros((120, 120 * len(objs)), np.uint16)
    for k, m in enumerate(objs):
        labels[:, 120 * k:120 * (k + 1)][m] = k + 1
    table = P.measure(labels, n_fourier=6, n_radii=8)
    t = PFSDMTransformer(n_fourier=6, n_radii=8).fit(objs)
    names = t.get_feature_names_out()
    assert list(names) == [c for c in table.columns if c.startswith("shape_r")]
    np.testing.assert_allclose(t.transform(objs), table[list(names)].to_numpy(float),
                               rtol=1e-9, atol=1e-12)
    assert t.n_features_out_ == len(names) == 8 * 7


def test_weighted_rows_give_pf_sdm_distances():
    objs, _ = masks()
    x = PFSDMTransformer(weighted=True).fit_transform(objs)
    euclid = np.sqrt(((x[:, None, :] - x[None, :, :]) ** 2).sum(-1))
    ref = P.distance_matrix([P.pfsdm(m) for m in objs], invariance="magnitude",
                            boundary_weight=0)
    np.testing.assert_allclose(euclid, ref, rtol=1e-9, atol=1e-12)


def test_clone_params_and_a_pipeline():
    t = PFSDMTransformer(n_fourier=5, mapping="bijective")
    c = clone(t)
    assert c is not t and c.get_params() == t.get_params()
    assert c.set_params(n_fourier=7).n_fourier == 7
    objs, y = masks(4, size=96)
    pipe = make_pipeline(PFSDMTransformer(n_fourier=6, n_radii=8), StandardScaler(),
                         LogisticRegression(max_iter=2000))
    scores = cross_val_score(pipe, objs, y, cv=2)
    assert scores.mean() > 0.9  # five very different shapes


def test_the_parameters_are_the_option_records():
    """The signature is generated from core.params.OPTIONS: scikit-learn's get_params, repr
    and set_params see one keyword per option, with its default."""
    from napari_pfsdm.core.params import OPTIONS

    assert PFSDMTransformer().get_params() == {**{o.name: o.default for o in OPTIONS},
                                               "spacing": None, "weighted": False}
    assert repr(PFSDMTransformer(n_fourier=5, weighted=True)) == \
        "PFSDMTransformer(n_fourier=5, weighted=True)"
    with pytest.raises(TypeError, match="unexpected keyword argument.*n_fourer"):
        PFSDMTransformer(n_fourer=5)
    bad = clone(PFSDMTransformer()).set_params(n_radii=0)  # stored as given, refused in fit
    with pytest.raises(InputError, match="n_radii must be a whole number from 1 to 512"):
        bad.fit(masks()[0])


def test_a_bad_mask_is_named():
    objs, _ = masks()
    objs[2] = np.zeros_like(objs[2])
    with pytest.raises(ValueError, match="mask 2: "):
        PFSDMTransformer().fit_transform(objs)
