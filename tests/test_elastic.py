"""The elastic outline term (core.elastic): closed forms, a hand-worked DTW, invariances."""

from __future__ import annotations

import numpy as np
import pytest

from napari_pfsdm import pfsdm
from napari_pfsdm.core.elastic import (
    _mirrored,
    banded_dtw,
    elastic_distance_between,
    elastic_distance_matrix,
    elastic_distance_pairs,
)
from napari_pfsdm.core.elastic_signature import N_CHANNELS, TURNING_ARCS, outline_signature
from napari_pfsdm.errors import InputError


def test_signature_of_a_circle_is_its_closed_form():
    # turning over an arc a of a circle: 2π a; centroid distance / its mean: 1
    t = 2 * np.pi * np.arange(512) / 512
    circle = np.column_stack([3 + 2 * np.cos(t), -1 + 2 * np.sin(t)])
    sig = outline_signature(circle)
    want = 2 * np.pi * np.array(TURNING_ARCS)
    n_arcs = len(TURNING_ARCS)
    assert np.allclose(sig[:n_arcs], want[:, None], atol=1e-12)
    assert np.allclose(sig[n_arcs], 1.0, atol=1e-12)
    assert np.allclose(sig[-1], 0.0, atol=1e-3)  # log of the thickness over its mean


def test_signature_of_an_ellipse_centroid_channel():
    # r(t)/mean r for an ellipse sampled uniformly in arc length: peaks of a/mean r at the
    # ends of the major axis, b/mean r at the minor one
    t = np.linspace(0, 2 * np.pi, 4000, endpoint=False)
    pts = np.column_stack([2 * np.cos(t), np.sin(t)])
    sig = outline_signature(pts, smoothing=0)
    seg = np.hypot(*np.diff(np.vstack([pts, pts[:1]]), axis=0).T)
    r = np.hypot(*pts.T)
    mean_r = (r * seg).sum() / seg.sum()  # mean over arc length
    centroid = sig[len(TURNING_ARCS)]
    assert centroid.max() == pytest.approx(2 / mean_r, rel=1e-3)
    assert centroid.min() == pytest.approx(1 / mean_r, rel=1e-3)



def test_the_smoothed_channels_are_scipys_gaussian_filter_sampled_at_the_points():
    # the channels of a lopsided outline, filtered by scipy's own Gaussian (wrapping round
    # the outline) and taken at every 4th of its 256 points, in the signature's order
    from scipy import ndimage as ndi

    from napari_pfsdm.core.elastic_signature import SMOOTHING

    t = 2 * np.pi * np.arange(256) / 256
    rho = 1 + 0.3 * np.cos(3 * t) + 0.2 * np.sin(t)
    raw = np.column_stack([rho * np.cos(t), rho * np.sin(t)])
    closed = np.vstack([raw, raw[:1]])
    s = np.r_[0, np.cumsum(np.hypot(*np.diff(closed, axis=0).T))]
    u = np.arange(256) * s[-1] / 256  # 256 points uniform in arc length, as the signature
    pts = np.column_stack([np.interp(u, s, closed[:, 0]), np.interp(u, s, closed[:, 1])])
    x, y = pts.T
    cross = x * np.roll(y, -1) - np.roll(x, -1) * y
    area = cross.sum() / 2
    centre = np.array([((x + np.roll(x, -1)) * cross).sum(),
                       ((y + np.roll(y, -1)) * cross).sum()]) / (6 * area)
    q = pts - centre
    r = np.hypot(*q.T)
    want = [ndi.gaussian_filter1d(r / r.mean(), SMOOTHING, mode="wrap")[::4]]
    k = round(TURNING_ARCS[-1] * 256)
    uu, vv = q - np.roll(q, k, axis=0), np.roll(q, -k, axis=0) - q
    turn = np.arctan2(uu[:, 0] * vv[:, 1] - uu[:, 1] * vv[:, 0], (uu * vv).sum(axis=1))
    want.insert(0, ndi.gaussian_filter1d(turn, SMOOTHING, mode="wrap")[::4])
    sig = outline_signature(pts)
    n_arcs = len(TURNING_ARCS)
    assert np.allclose(sig[n_arcs - 1], want[0], atol=1e-12)
    assert np.allclose(sig[n_arcs], want[1], atol=1e-12)
    # started 8 points later (2 signature points): the columns shift by 2, the numbers stay
    assert np.allclose(outline_signature(np.roll(pts, -8, axis=0)), np.roll(sig, -2, axis=1),
                       atol=1e-9)

def test_local_thickness_of_an_ellipse():
    # the largest disk inside x²/4 + y² ≤ 1 touching at (±2, 0) has the radius of curvature
    # there, b²/a = 1/2; at (0, ±1) it is the disk of radius b = 1 (it meets the far side)
    from napari_pfsdm.core.elastic_signature import local_thickness

    t = 2 * np.pi * np.arange(1024) / 1024
    r = local_thickness(np.column_stack([2 * np.cos(t), np.sin(t)]))
    assert r[0] == pytest.approx(0.5, rel=0.02) and r[512] == pytest.approx(0.5, rel=0.02)
    assert r[256] == pytest.approx(1.0, rel=1e-3) and r[768] == pytest.approx(1.0, rel=1e-3)
    assert r.min() == pytest.approx(0.5, rel=0.02) and r.max() == pytest.approx(1.0, rel=1e-3)
    # clockwise vertices with ccw=False: the same radii
    assert np.allclose(local_thickness(np.column_stack([2 * np.cos(t), -np.sin(t)]),
                                       ccw=False), r)


def _pulse_pair(n: int = 18) -> tuple[np.ndarray, np.ndarray]:
    """Channel 0: a pulse of width 3 (points 5–7) against one of width 7 (points 3–9)."""
    a, b = np.zeros((1, N_CHANNELS, n)), np.zeros((1, N_CHANNELS, n))
    a[0, 0, 5:8] = 1.0
    b[0, 0, 3:10] = 1.0
    return a, b


@pytest.mark.parametrize(("band", "cost"), [(0, 4), (1, 2), (2, 0), (8, 0)])
def test_hand_worked_pulse(band, cost):
    # rigidly the narrow pulse leaves 4 points of the wide one unmatched (L1 cost 1 each);
    # a band of ±B lets it stretch by 2B points, so 4 − 2B remain, and none from B = 2 on
    a, b = _pulse_pair()
    got = elastic_distance_pairs(a, b, band=band, n_shifts=2 * a.shape[2], half_steps=False)
    assert got[0] == pytest.approx(cost / a.shape[2], abs=1e-12)


def test_half_point_offset_costs_nothing_with_half_steps():
    # a sampled half a point later than b: each a(i) is the midpoint of b(i) and b(i + 1)
    b = np.random.default_rng(2).normal(size=(3, N_CHANNELS, 64))
    a = 0.5 * (b + np.roll(b, -1, axis=-1))
    # (the DTW's costs are summed in single precision: zero to its rounding)
    assert np.abs(elastic_distance_pairs(a, b)).max() < 1e-6
    assert np.abs(elastic_distance_pairs(b, a)).max() < 1e-6
    assert np.all(elastic_distance_pairs(a, b, half_steps=False) > 0.1)


def test_banded_dtw_hand_worked():
    # n = 3, band ±1: costs of matching i to i + d, d = −1, 0, 1 (outside the grid: inf)
    c = np.array([[[np.inf, 2, 1], [3, 5, 1], [1, 4, np.inf]]], float)
    # paths: (0,0)-(1,1)-(2,2): 2+5+4 = 11; (0,0)-(0,1)-(1,2)-(2,2): 2+1+1+4 = 8;
    # (0,0)-(1,0)-(2,1)-(2,2): 2+3+1+4 = 10; (0,0)-(0,1)-(1,1)-...: ≥ 2+1+5; best 8
    assert banded_dtw(c)[0] == pytest.approx(8.0)


def _brute(a: np.ndarray, b: np.ndarray, band: int, half: bool = True) -> float:
    """min over both orientations and the local minima over cyclic shifts s of the rigid cost
    Σ_i ‖a(i) − b(i + s)‖², of the numpy banded DTW / n, with the half-point matches."""
    n = a.shape[1]
    d = np.arange(-band, band + 1)
    i = np.arange(n)[:, None]
    mid = lambda x: 0.5 * (x + np.roll(x, -1, axis=-1))  # noqa: E731
    best = np.inf
    for bb in (b, _mirrored(b)):
        rigid = np.array([((a - np.roll(bb, -s, axis=1)) ** 2).sum() for s in range(n)])
        flat = 1e-9 * ((a * a).sum() + (b * b).sum())
        for s in range(n):
            if rigid[s] > rigid[s - 1] + flat or rigid[s] > rigid[(s + 1) % n] + flat:
                continue
            j = (i + d[None, :] + s) % n
            cost = np.abs(a[:, i] - bb[:, j]).sum(axis=0)
            if half:
                cost = np.minimum.reduce([
                    cost, np.abs(a[:, i] - mid(bb)[:, j]).sum(axis=0),
                    np.abs(mid(a)[:, i] - bb[:, j]).sum(axis=0)])
            best = min(best, banded_dtw(cost[None])[0])
    return best / n


@pytest.mark.parametrize(("n", "band"), [(24, 4), (64, 8), (32, 0)])
def test_compiled_dp_matches_a_numpy_reference(n, band):
    rng = np.random.default_rng(3 + n)
    a, b = rng.normal(size=(2, 5, N_CHANNELS, n))
    b[0] = np.roll(a[0], 3, axis=-1) + 0.05 * b[0]  # one near pair: a deep valley
    got = elastic_distance_pairs(a, b, band=band, n_shifts=2 * n)  # every valley
    # the pair in the order the library puts it (smaller sum of squares first)
    want = [_brute(y, x, band) if (y * y).sum() < (x * x).sum() else _brute(x, y, band)
            for x, y in zip(a, b, strict=True)]
    assert np.allclose(got, want, rtol=1e-6, atol=0)  # single-precision costs
    # the default keeps the 5 lowest valleys: never below them all
    assert np.all(elastic_distance_pairs(a, b, band=band) >= got * (1 - 1e-6))


def test_compiled_dp_without_half_steps_matches_the_reference():
    rng = np.random.default_rng(4)
    a, b = rng.normal(size=(2, 4, N_CHANNELS, 32))
    got = elastic_distance_pairs(a, b, band=4, n_shifts=64, half_steps=False)
    want = [_brute(y, x, 4, half=False) if (y * y).sum() < (x * x).sum()
            else _brute(x, y, 4, half=False) for x, y in zip(a, b, strict=True)]
    assert np.allclose(got, want, rtol=1e-6, atol=0)


def test_start_point_and_mirror_of_a_signature_are_free():
    rng = np.random.default_rng(5)
    s = rng.normal(size=(4, N_CHANNELS, 64))
    shifted = np.roll(s, 17, axis=-1)
    assert np.abs(elastic_distance_pairs(s, shifted)).max() < 1e-12
    assert np.abs(elastic_distance_pairs(s, _mirrored(np.roll(s, 5, axis=-1)))).max() < 1e-12


def test_matrix_is_symmetric_and_its_entries_are_the_pairs():
    rng = np.random.default_rng(7)
    s = rng.normal(size=(9, N_CHANNELS, 32))
    d = elastic_distance_matrix(s)
    assert np.allclose(d, d.T, atol=1e-12) and np.all(np.diag(d) == 0)
    i, j = np.triu_indices(9, 1)
    assert np.allclose(d[i, j], elastic_distance_pairs(s[i], s[j]))
    other = elastic_distance_matrix(s[:3], s)
    assert np.allclose(other, d[:3])
    s[4] = np.nan
    d = elastic_distance_matrix(s)
    assert np.isnan(d[4]).all() and np.isnan(d[:, 4]).all() and np.isfinite(d[0, 1])


def _shape(yy, xx, cy, cx, scale=1.0, turn=0.0, mirror=False) -> np.ndarray:
    r = np.hypot(yy - cy, xx - cx) / scale
    t = np.arctan2(yy - cy, xx - cx) - turn
    if mirror:
        t = -t
    return r < 40 + 9 * np.cos(3 * t) + 5 * np.sin(2 * t)


def test_invariances_on_rasters():
    yy, xx = np.mgrid[:220, :220]
    base = _shape(yy, xx, 110, 110)
    copies = {
        "translated": _shape(yy, xx, 97, 121),
        "rotated 90°": np.rot90(base),
        "rotated 0.6 rad": _shape(yy, xx, 110, 110, turn=0.6),
        "mirrored": base[:, ::-1],
        "mirrored, rotated": _shape(yy, xx, 110, 110, turn=1.1, mirror=True),
        "rescaled 1.8": _shape(yy, xx, 110, 110, scale=1.8),
    }
    other = (abs(yy - 110) < 30) & (abs(xx - 110) < 60)  # a rectangle
    sig = lambda m: outline_signature(pfsdm(m).contour.normalized)  # noqa: E731
    s0 = sig(base)[None]
    far = elastic_distance_pairs(s0, sig(other)[None])[0]
    for name, mask in copies.items():
        d = elastic_distance_pairs(s0, sig(mask)[None])[0]
        # exact copies (integer moves, 90° turns, mirrors) are at 0; the others differ by the
        # pixel staircase and by start points that fall between the signature's points
        assert d < 0.15 * far, name
    assert elastic_distance_pairs(s0, sig(base[:, ::-1])[None])[0] < 1e-3 * far


def test_bad_input_is_refused():
    with pytest.raises(InputError):
        outline_signature(np.zeros((5, 2)))
    with pytest.raises(InputError):
        outline_signature(np.random.default_rng(0).normal(size=(40, 2)), n_points=60)
    with pytest.raises(InputError):
        elastic_distance_pairs(np.zeros((2, N_CHANNELS, 64)), np.zeros((3, N_CHANNELS, 64)))
    with pytest.raises(InputError):
        elastic_distance_matrix(np.zeros((2, 3, 64)))


def test_nearest_is_the_shortcut_with_every_candidate_computed():
    from napari_pfsdm.core.elastic import elastic_nearest

    rng = np.random.default_rng(13)
    n, k, mu = 40, 4, 0.7
    s = rng.normal(size=(n, N_CHANNELS, 32))
    s[n // 2:] = s[: n // 2] + 0.3 * rng.normal(size=(n // 2, N_CHANNELS, 32))  # near pairs
    sq = rng.random((n, n))
    for scale in (1.0, 30.0):  # the other terms small, then large, against μ d_E
        other = scale * (sq + sq.T)
        np.fill_diagonal(other, np.inf)
        full = other + mu * elastic_distance_matrix(s)
        np.fill_diagonal(full, np.inf)
        for n_cand in (6, 15, n - 1):
            cand = np.argsort(other, axis=1, kind="stable")[:, :n_cand]
            base = np.take_along_axis(other, cand, 1)
            idx, dist, computed, exact = elastic_nearest(s, cand, base, mu, k)
            # the k least totals among the candidates, ties by number: what sorting gives
            tot = np.take_along_axis(full, cand, 1)
            want = np.take_along_axis(cand, np.lexsort((cand, tot), axis=1)[:, :k], 1)
            assert np.array_equal(idx, want)
            assert np.allclose(dist, np.take_along_axis(full, idx, 1), rtol=1e-6)
            assert np.all(computed <= n_cand)
            # a row said exact has the k nearest of all objects
            truth = np.argsort(full, axis=1, kind="stable")[:, :k]
            assert np.array_equal(idx[exact], truth[exact])
        assert exact.all()  # every other object a candidate
    # with the other terms large, a candidate whose base exceeds the k-th total ends the row
    assert computed.mean() < n / 2
    cand[0, 2:] = -1  # fewer than k candidates
    idx, dist, _, _ = elastic_nearest(s, cand, np.where(cand >= 0, base, np.inf), mu, k)
    assert idx[0, 2:].tolist() == [-1, -1] and np.isinf(dist[0, 2:]).all()


def test_between_is_the_matrix_entries():
    rng = np.random.default_rng(11)
    s = rng.normal(size=(8, N_CHANNELS, 32))
    s[6] = np.nan
    d = elastic_distance_matrix(s)
    ii, jj = rng.integers(0, 8, size=(2, 30))
    got = elastic_distance_between(s, ii, jj)
    assert np.allclose(got, d[ii, jj], equal_nan=True, atol=0)


# --------------------------------------------------------------------------- in the library
def _labels() -> np.ndarray:
    yy, xx = np.mgrid[:90, :330]
    lab = np.zeros((90, 330), int)
    lab[10:60, 10:60] = 1  # a square
    lab[20:45, 75:140] = 2  # a bar
    lab[((yy - 45) / 30) ** 2 + ((xx - 180) / 20) ** 2 < 1] = 3  # an ellipse
    lab[_shape(yy, xx, 45, 260) & (np.abs(xx - 260) < 55)] = 4  # a lobed shape
    return lab


def test_distance_matrix_adds_the_elastic_term_from_results_and_tables():
    import napari_pfsdm as P
    from napari_pfsdm.core.distances import ELASTIC_WEIGHT
    from napari_pfsdm.core.distances import distance_matrix as core_matrix

    lab = _labels()
    res = [pfsdm(lab == k) for k in range(1, 5)]
    sig = np.stack([r.signature for r in res])
    base = core_matrix(res)
    mu = 0.3
    want = base + mu * elastic_distance_matrix(sig)
    assert ELASTIC_WEIGHT == 0  # opt-in: the default distance is unchanged
    assert np.allclose(core_matrix(res, elastic_weight=mu), want, atol=1e-12)
    table = P.measure(lab, elastic_signature="table")
    assert table.attrs["pfsdm"]["elastic_smoothing"] == res[0].options["elastic_smoothing"]
    cols = [c for c in table.columns if c.startswith("elastic_")]
    assert len(cols) == sig[0].size
    assert np.allclose(table[cols].to_numpy().reshape(sig.shape), sig, atol=1e-12)
    assert np.allclose(P.distance_matrix(table, elastic_weight=mu), want, atol=1e-9)
    old = table.drop(columns=cols)
    with pytest.raises(InputError, match="elastic"):
        P.distance_matrix(old, elastic_weight=mu)
    assert np.allclose(P.distance_matrix(old), base, atol=1e-9)
    with pytest.raises(InputError, match="elastic_weight"):
        core_matrix(res, elastic_weight=-1)


def test_signature_follows_the_smoothing_option():
    lab = _labels() == 4
    a, b = pfsdm(lab), pfsdm(lab, elastic_smoothing=0.0)
    assert b.options["elastic_smoothing"] == 0.0
    assert np.allclose(b.signature, outline_signature(b.contour.normalized, smoothing=0))
    assert np.allclose(a.signature, outline_signature(a.contour.normalized, smoothing=4.0))
    assert not np.allclose(a.signature, b.signature)


def test_neighbours_with_the_elastic_term():
    import napari_pfsdm as P

    lab = _labels()
    table = P.measure(lab, elastic_signature="table")
    mu = 0.5
    d = P.distance_matrix(table, elastic_weight=mu)
    np.fill_diagonal(d, np.inf)
    # every other object a candidate: the exact order of the matrix
    idx, dist = P.nearest_neighbours(table, k=2, elastic_weight=mu, elastic_candidates=3)
    want = np.argsort(d, axis=1, kind="stable")[:, :2]
    assert np.array_equal(idx, want)
    assert np.allclose(dist, np.take_along_axis(d, want, 1), atol=1e-6)
