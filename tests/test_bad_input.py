"""Bad input to pfsdm: a clear ValueError or a documented behaviour."""

import warnings

import numpy as np
import pytest

import napari_pfsdm as P


def ellipse(shape=(80, 80), center=(40, 40), axes=(25, 12)):
    yy, xx = np.mgrid[: shape[0], : shape[1]]
    return ((yy - center[0]) / axes[0]) ** 2 + ((xx - center[1]) / axes[1]) ** 2 < 1


def test_empty_mask():
    with pytest.raises(ValueError, match="empty"):
        P.pfsdm(np.zeros((32, 32), bool))


def test_one_pixel_object():
    m = np.zeros((32, 32), bool)
    m[10, 10] = True
    with pytest.raises(ValueError, match="too small"):
        P.pfsdm(m)


def test_three_d_input_is_a_volume_and_four_d_is_refused():
    # a 3-D array is a Z×Y×X volume (docs/design.md §6); a stack of 2-D frames goes to
    # measure(labels) with its axes ('tyx' by default)
    res = P.pfsdm(np.ones((4, 32, 32), bool))
    assert res.ndim == 3 and res.diagnostics["touches_border"]
    with pytest.raises(ValueError, match="2-D mask .* or a 3-D volume"):
        P.pfsdm(np.ones((2, 3, 32, 32), bool))


def test_object_touching_the_border_is_described_and_flagged():
    m = ellipse(center=(10, 40))  # cut by the top edge
    res = P.pfsdm(m)
    assert res.diagnostics["touches_border"]
    assert res.contour.points[:, 0].min() == pytest.approx(-0.5, abs=0.6)
    assert not P.pfsdm(ellipse()).diagnostics["touches_border"]


def test_holes_are_filled_and_counted():
    m = ellipse()
    holed = m & ~ellipse(center=(40, 40), axes=(6, 4))
    res = P.pfsdm(holed)
    assert res.diagnostics["n_holes"] == 1
    np.testing.assert_allclose(res.embedding, P.pfsdm(m).embedding, atol=1e-12)


def test_several_components_keep_the_largest_with_a_warning_or_raise():
    m = ellipse()
    m[2:6, 2:8] = True
    with pytest.warns(UserWarning, match="separate pieces"):
        res = P.pfsdm(m)
    assert res.diagnostics["n_components"] == 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        np.testing.assert_allclose(res.embedding, P.pfsdm(ellipse()).embedding, atol=1e-12)
    with pytest.raises(ValueError, match="separate pieces"):
        P.pfsdm(m, components="raise")


def test_a_measurement_in_another_thread_keeps_this_threads_warnings(monkeypatch):
    # the plugin measures in a worker thread; warnings.catch_warnings there would swap the
    # whole process's warning handler, and the main thread's warnings caught meanwhile are lost
    import threading

    from napari_pfsdm.core import contour

    labels = np.zeros((1, 80, 80), np.int32)
    labels[0][ellipse()] = 1
    labels[0, 2:6, 2:8] = 1  # a second piece: measure keeps the largest quietly
    inside, go = threading.Event(), threading.Event()
    fill_holes = contour.fill_holes

    def paused(crop):
        if threading.current_thread() is not threading.main_thread() and not inside.is_set():
            inside.set()
            go.wait(10)
        return fill_holes(crop)

    monkeypatch.setattr(contour, "fill_holes", paused)
    tables = []
    thread = threading.Thread(target=lambda: tables.append(P.measure(labels)))
    thread.start()
    assert inside.wait(30)
    with pytest.warns(UserWarning, match="separate pieces"):
        go.set()
        thread.join(30)
        P.pfsdm(labels[0] > 0)
    assert tables[0]["n_components"].tolist() == [2]


def test_nan_in_intensity_inside_the_object():
    m = ellipse()
    inten = np.ones(m.shape)
    inten[40, 40] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        P.pfsdm(m, inten)
    inten[40, 40] = 1
    inten[0, 0] = np.nan  # outside the object: ignored
    assert np.isfinite(P.pfsdm(m, inten).intensity_embedding).all()


def test_mismatched_intensity_shape():
    with pytest.raises(ValueError, match="same pixels"):
        P.pfsdm(ellipse(), np.ones((80, 81)))


def test_unknown_options_are_named():
    with pytest.raises(ValueError, match="mapping"):
        P.pfsdm(ellipse(), mapping="conformal")
    with pytest.raises(ValueError, match="sdf"):
        P.pfsdm(ellipse(), sdf="fast")
    with pytest.raises(ValueError, match="normalization"):
        P.pfsdm(ellipse(), normalization="l1")
    with pytest.raises(ValueError, match="n_fourier"):
        P.pfsdm(ellipse(), n_fourier=40, n_angles=64)
