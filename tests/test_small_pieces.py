"""Small pieces held to closed forms or to a second way of computing the same thing. Each test
kills a mutant that survived the mutation test of the suite (scripts/mutation.py, issue 21):
the mutant named in the docstring passes every other test."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.special import gammaln, lpmv

import napari_pfsdm as P
from napari_pfsdm.analysis.interpretation import outline_measures
from napari_pfsdm.analysis.reduction import mds_coordinates
from napari_pfsdm.analysis.tracking import _median_radius
from napari_pfsdm.core.boundary import _refine
from napari_pfsdm.core.descriptor import _polar_to_cartesian
from napari_pfsdm.core.medial_axis import branch_paths
from napari_pfsdm.core.pushforward import FourierMap
from napari_pfsdm.core.sph_harm import legendre_table
from napari_pfsdm.errors import InputError
from napari_pfsdm.io_csv import read_table_csv


def disk(radius: float, size: int = 96) -> np.ndarray:
    yy, xx = np.mgrid[:size, :size] - (size - 1) / 2
    return yy**2 + xx**2 <= radius**2


def test_the_contour_length_is_its_polygon_perimeter():
    """Mutant: the closing point appended twice (``normalized[:2]``)."""
    c = P.pfsdm(disk(30)).contour
    p = c.normalized
    assert c.length == pytest.approx(np.hypot(*(np.roll(p, -1, axis=0) - p).T).sum(), rel=1e-12)
    assert c.length == pytest.approx(2 * np.pi, rel=0.01)  # a circle of radius 1


def test_the_polar_image_samples_pixel_centres():
    """f(r, θ) = r sampled on the rings r_i = (i + ½)/n_r is drawn as ρ, the distance of each
    pixel centre ((k + ½)/size · 2 − 1) from the disk's centre. Mutant: ``(k − ½)``."""
    n_r, n_t, size = 8, 32, 40
    polar = np.repeat(((np.arange(n_r) + 0.5) / n_r)[:, None], n_t, axis=1)
    img = _polar_to_cartesian(polar, size)
    c = (np.arange(size) + 0.5) / size * 2 - 1
    rho = np.hypot(*np.meshgrid(c, c, indexing="ij"))
    inner = (rho >= 0.5 / n_r) & (rho <= 1 - 0.5 / n_r)  # between the first and last ring
    np.testing.assert_allclose(img[inner], rho[inner], atol=1e-12)
    assert np.isnan(img[rho > 1]).all() and np.isfinite(img[rho <= 1]).all()


def test_a_3d_offset_given_to_pfsdm_reaches_the_volume():
    """Mutant: pfsdm() passing (0, 0, 0) instead of a 3-D object's offset."""
    zz, yy, xx = np.mgrid[:24, :24, :24] - 11.5
    ball = zz**2 + yy**2 + xx**2 < 8**2
    at_zero = P.pfsdm(ball, n_radii=4, sh_degree=4)
    moved = P.pfsdm(ball, n_radii=4, sh_degree=4, offset=(5.0, -2.0, 7.0))
    np.testing.assert_allclose(moved.center - at_zero.center, [5.0, -2.0, 7.0], atol=1e-9)


def test_the_fourier_map_in_chunks_is_the_map_at_once():
    """Mutant: chunks one point too long (``out[i : i + chunk + 1]``)."""
    rng = np.random.default_rng(4)
    coef = rng.normal(size=16) + 1j * rng.normal(size=16)
    fm = FourierMap(coef)
    uv = rng.uniform(-0.7, 0.7, size=(11, 2))
    np.testing.assert_allclose(fm(uv, chunk=3), fm(uv, chunk=4096), rtol=1e-13)


def test_the_fourier_maps_boundary_passes_through_its_nodes():
    """X(1, θ_k) at θ_k = 2πk/M are the M outline points the coefficients were made from
    (a_n = FFT(points)/M), linear in between. Mutant: the grid one node short (``m − 1``)."""
    t = 2 * np.pi * np.arange(12) / 12
    nodes = np.cos(t) * 2 + 1j * (np.sin(t) + 0.3 * np.sin(2 * t))
    fm = FourierMap(np.fft.fft(nodes) / 12)
    got = fm.boundary(t)
    np.testing.assert_allclose(got[:, 0] + 1j * got[:, 1], nodes, atol=1e-12)
    mid = fm.boundary(t[:2].mean()[None])[0]
    np.testing.assert_allclose(mid[0] + 1j * mid[1], nodes[:2].mean(), atol=1e-12)


def test_the_outline_term_refined_in_blocks_is_refined_at_once():
    """Mutant: the start shifts of a block one pair too long (``s[p0:p1 + 1]``), which only a
    collection of more than 65,536 pairs would meet with the default block."""
    rng = np.random.default_rng(0)
    a = rng.normal(size=(5, 8)) + 1j * rng.normal(size=(5, 8))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    ii, jj = np.triu_indices(5, 1)
    s = rng.uniform(0, 2 * np.pi, len(ii))
    mirror = rng.random(len(ii)) < 0.5
    whole = _refine(a, a, ii, jj, s, mirror)
    np.testing.assert_allclose(_refine(a, a, ii, jj, s, mirror, block=3), whole, rtol=1e-12)


def test_legendre_functions_are_scipys_normalised():
    """P̄_lm = sqrt((2l + 1)/(4π) (l − m)!/(l + m)!) |P_l^m| (scipy's lpmv), every degree up to
    the top one. Mutant: the recursion stopping one degree short."""
    x = np.linspace(-0.95, 0.95, 7)
    got = legendre_table(6, x)
    for ell in range(7):
        for m in range(ell + 1):
            norm = np.sqrt((2 * ell + 1) / (4 * np.pi)
                           * np.exp(gammaln(ell - m + 1) - gammaln(ell + m + 1)))
            np.testing.assert_allclose(np.abs(got[ell, m]), norm * np.abs(lpmv(m, ell, x)),
                                       rtol=1e-10, atol=1e-14)


def test_outline_measures_of_a_regular_polygon_are_its_closed_forms():
    """A regular N-gon: circularity 4πA/P² = π / (N tan(π/N)), aspect ratio 1, solidity 1; a
    2 × 1 rectangle: circularity 4π·2/36, aspect √(1/4) = 0.5. Not measurable: NaN."""
    for n in (5, 12, 64):
        t = 2 * np.pi * np.arange(n) / n
        m = outline_measures(np.c_[np.cos(t), np.sin(t)] * 3.0)
        assert m["circularity"] == pytest.approx(np.pi / (n * np.tan(np.pi / n)), rel=1e-12)
        assert m["aspect_ratio"] == pytest.approx(1.0, rel=1e-9)
        assert m["solidity"] == pytest.approx(1.0, rel=1e-12)
    rect = outline_measures(np.array([[0.0, 0.0], [0.0, 2.0], [1.0, 2.0], [1.0, 0.0]]))
    assert rect["circularity"] == pytest.approx(8 * np.pi / 36, rel=1e-12)
    assert rect["aspect_ratio"] == pytest.approx(0.5, rel=1e-12)
    flat = outline_measures(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]))  # no area
    assert all(np.isnan(v) for v in flat.values())
    assert all(np.isnan(v) for v in outline_measures(np.zeros((4, 2))).values())


def test_a_single_pixel_skeleton_is_one_branch():
    """Mutant: an isolated node (no neighbour) left without its branch."""
    paths = branch_paths(np.array([[3, 4]]))
    assert [p.tolist() for p in paths] == [[0, 0]]


def test_mds_of_fewer_objects_than_components_pads_with_zeros():
    """Mutant: the padding's width read from a third axis (``shape[2]``)."""
    np.testing.assert_array_equal(mds_coordinates(np.zeros((1, 1)), 2), [[0.0, 0.0]])
    xy = mds_coordinates(np.array([[0.0, 4.0], [4.0, 0.0]]), 3)
    np.testing.assert_allclose(np.abs(xy[:, 0]), [2.0, 2.0], atol=1e-12)
    np.testing.assert_allclose(xy[:, 1:], 0.0, atol=1e-7)


def test_the_linking_scale_without_areas_is_ten_pixels():
    """``_median_radius``: the radius of the median area's disk; 10 px for a table without
    areas or volumes. Mutant: ``and`` for ``or`` (it then looks for a volume column)."""
    table = pd.DataFrame({"frame": [0, 1], "label": [1, 1], "centroid_y": [1.0, 2.0],
                          "centroid_x": [1.0, 2.0]})
    assert _median_radius(table) == 10.0
    assert _median_radius(table.assign(area=[np.pi * 9, np.pi * 25])) == pytest.approx(
        np.sqrt(17))  # median area π·17: radius √17
    both = table.assign(area=[np.pi * 4, np.pi * 4], volume=[1e6, 1e6])
    assert _median_radius(both) == pytest.approx(2.0)  # the area wins over the volume


def test_a_parquet_file_given_as_a_table_is_named(tmp_path):
    """Mutant: the magic number compared with five bytes."""
    (tmp_path / "t.csv").write_bytes(b"PAR1" + b"\x15\x04" * 40)
    with pytest.raises(InputError, match="is a Parquet file, not a CSV table"):
        read_table_csv(tmp_path / "t.csv")


def test_a_character_cut_at_the_end_of_the_first_block_is_still_text(tmp_path):
    """The binary check reads 2,048 bytes; a two-byte "é" cut there is not a broken file, but
    a broken byte well before the end is. Mutant: the margin added instead of subtracted."""
    head = "movie,area\n"
    filler = "a" * (2047 - len(head) - len(",1\n"))  # "é" starts at byte 2047
    (tmp_path / "ok.csv").write_text(head + filler + ",1\né,2\n", encoding="utf-8")
    back = read_table_csv(tmp_path / "ok.csv")
    assert back["movie"].tolist() == [filler, "é"]
    (tmp_path / "bad.csv").write_bytes(b"movie,area\n\xff\xfe,1\n" + b"x,2\n" * 600)
    with pytest.raises(InputError, match="not a UTF-8 text file"):
        read_table_csv(tmp_path / "bad.csv")


def test_leading_singleton_axes_are_dropped_down_to_a_time_lapse(tmp_path):
    """A (1, 1, Y, X) array without axis names is a one-frame time-lapse (1, Y, X): only the
    axes beyond three go. Mutant: ``ndim + i`` (every leading singleton axis dropped)."""
    zarr = pytest.importorskip("zarr")
    from napari_pfsdm.batch import open_movie

    z = zarr.create_array(str(tmp_path / "m.zarr"), shape=(1, 1, 16, 20), dtype="uint8",
                          chunks=(1, 1, 16, 20), zarr_format=2)
    z[:] = 1
    assert open_movie(tmp_path / "m.zarr").shape == (1, 16, 20)
