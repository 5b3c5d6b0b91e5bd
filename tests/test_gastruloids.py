"""The synthetic gastruloid generator: layout, determinism, ambiguity early, classes late."""

import numpy as np
import pytest
from scipy import ndimage as ndi
from skimage.measure import regionprops

from napari_pfsdm.data.gastruloids import make_gastruloids, make_timelapse_montage


@pytest.fixture(scope="module")
def gset():
    return make_gastruloids(n_objects=40, n_frames=6, size=80, multi_fraction=0.5, seed=3)


def _props(labels_2d):
    p = regionprops(labels_2d.astype(np.uint8))[0]
    return p.area, p.eccentricity, p.solidity


def _best_threshold_balanced_accuracy(values, y):
    """Best balanced accuracy of any single threshold (either direction) on one feature."""
    best = 0.5
    for thr in np.unique(values):
        pred = values >= thr
        for p in (pred, ~pred):
            tpr = p[y].mean()
            tnr = (~p[~y]).mean()
            best = max(best, (tpr + tnr) / 2)
    return best


def test_layout_and_types(gset):
    assert gset.labels.shape == (40, 6, 80, 80)
    assert gset.labels.dtype == np.uint16
    assert gset.intensity.shape == gset.labels.shape
    assert gset.intensity.dtype == np.float32
    assert gset.multi_axis.dtype == bool
    assert gset.multi_axis.sum() == 20
    assert set(np.unique(gset.labels)) == {0, 1}
    assert len(gset.params["objects"]) == 40
    for i, obj in enumerate(gset.params["objects"]):
        assert obj["multi_axis"] == gset.multi_axis[i]
        assert obj["n_axes"] == (1 if not obj["multi_axis"] else obj["n_axes"])
        assert obj["n_axes"] in ((2, 3) if obj["multi_axis"] else (1,))


def test_one_hole_free_component_inside_the_frame(gset):
    for movie in gset.labels:
        for frame in movie:
            _, n = ndi.label(frame)
            assert n == 1
            assert np.array_equal(ndi.binary_fill_holes(frame), frame.astype(bool))
            # never touches the border
            assert not frame[0].any() and not frame[-1].any()
            assert not frame[:, 0].any() and not frame[:, -1].any()


def test_deterministic_from_seed():
    a = make_gastruloids(n_objects=3, n_frames=4, size=64, seed=7)
    b = make_gastruloids(n_objects=3, n_frames=4, size=64, seed=7)
    c = make_gastruloids(n_objects=3, n_frames=4, size=64, seed=8)
    assert np.array_equal(a.labels, b.labels)
    assert np.array_equal(a.intensity, b.intensity)
    assert not np.array_equal(a.labels, c.labels)


def test_default_class_balance_is_the_papers():
    g = make_gastruloids(n_objects=78, n_frames=1, size=64, seed=0)
    assert g.multi_axis.sum() == round(78 * 0.15)


def test_early_frames_ambiguous_late_frames_separate(gset):
    """Area and eccentricity overlap between the classes at the first frames, not at the end."""
    y = gset.multi_axis
    early = np.array([[_props(m[t]) for t in (0, 1)] for m in gset.labels])  # (n, 2, 3)
    late = np.array([_props(m[-1]) for m in gset.labels])
    for t in range(2):
        for k in (0, 1):  # area, eccentricity
            v = early[:, t, k]
            # the class ranges overlap ...
            assert max(v[y].min(), v[~y].min()) < min(v[y].max(), v[~y].max())
            # ... and no threshold separates them well
            assert _best_threshold_balanced_accuracy(v, y) < 0.75
    # at the last frame the multi-axes objects are less convex than the single-axis ones
    assert _best_threshold_balanced_accuracy(late[:, 2], y) > 0.75
    assert np.median(late[y, 2]) < np.median(late[~y, 2])


def test_reporter_polarises_before_the_shape():
    """Distance between the reporter's centre of mass and the mask centroid grows first."""
    g = make_gastruloids(n_objects=12, n_frames=13, size=80, seed=5)
    offsets, elong = [], []
    for lab, img in zip(g.labels, g.intensity, strict=True):
        o, e = [], []
        for t in range(13):
            m = lab[t] > 0
            c_mask = np.array(ndi.center_of_mass(m))
            c_int = np.array(ndi.center_of_mass(np.where(m, img[t], 0)))
            r = np.sqrt(m.sum() / np.pi)
            o.append(np.linalg.norm(c_int - c_mask) / r)
            e.append(regionprops(m.astype(np.uint8))[0].eccentricity)
        offsets.append(o)
        elong.append(e)
    offsets, elong = np.median(offsets, axis=0), np.median(elong, axis=0)
    # at a third of the movie the reporter is clearly off-centre while the shape barely changed
    t = 4
    assert offsets[t] > 0.15 and offsets[t] > 2.5 * offsets[0]
    assert elong[t] - elong[0] < 0.3 * (elong[-1] - elong[0])


def test_montage():
    labels, intensity, groups = make_timelapse_montage(n_objects=6, n_frames=12, size=256, seed=0)
    assert labels.shape == intensity.shape == (12, 256, 256)
    assert labels.dtype == np.uint16 and intensity.dtype == np.float32
    assert set(groups) == set(range(1, 7))
    assert set(groups.values()) == {"single-axis", "multi-axes"}
    for t in range(12):
        assert set(np.unique(labels[t])) == set(range(7))
        for lab in range(1, 7):
            _, n = ndi.label(labels[t] == lab)
            assert n == 1
    # each label stays in place over time (stable ids)
    c0 = ndi.center_of_mass(labels[0] > 0, labels[0], range(1, 7))
    c1 = ndi.center_of_mass(labels[-1] > 0, labels[-1], range(1, 7))
    assert np.max(np.abs(np.array(c0) - np.array(c1))) < 40


@pytest.mark.parametrize(
    "kwargs",
    [{"n_objects": 0}, {"n_frames": 0}, {"size": 8}, {"multi_fraction": 1.5}],
)
def test_bad_arguments_say_what_to_do(kwargs):
    with pytest.raises(ValueError, match="must"):
        make_gastruloids(**kwargs)
