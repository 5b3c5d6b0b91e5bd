"""The two SDFs against closed-form solutions."""

import numpy as np
import pytest
from scipy.special import i0e, k0e

from napari_pfsdm.core.sdf import ExactSDF, ViscousSDF


def circle(n=256, radius=1.0):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return radius * np.column_stack([np.cos(t), np.sin(t)])


def random_points(rng, n, rmin, rmax):
    rho = rng.uniform(rmin, rmax, n)
    ang = rng.uniform(0, 2 * np.pi, n)
    return rho, np.column_stack([rho * np.cos(ang), rho * np.sin(ang)])


@pytest.mark.parametrize("nu", [0.02, 0.05, 0.2])
def test_viscous_sdf_of_disk_matches_bessel_solution(nu, rng):
    sdf = ViscousSDF(circle(), viscosity=nu)
    rho, pts = random_points(rng, 400, 0.0, 0.999)
    # w = I0(rho/nu) / I0(R/nu) inside, phi = nu log w  (negative inside)
    expected = nu * (np.log(i0e(rho / nu) / i0e(1 / nu)) + (rho - 1) / nu)
    np.testing.assert_allclose(sdf(pts), expected, atol=2e-4)
    rho, pts = random_points(rng, 200, 1.001, 2.0)
    expected = -nu * (np.log(k0e(rho / nu) / k0e(1 / nu)) - (rho - 1) / nu)
    np.testing.assert_allclose(sdf(pts), expected, atol=2e-4)


def test_viscous_sdf_is_smooth_at_the_centre_and_close_to_exact_near_boundary(rng):
    sdf = ViscousSDF(circle(), viscosity=0.05)
    g = sdf.gradient(np.array([[0.0, 0.0], [0.5, 0.0]]))
    assert np.linalg.norm(g[0]) < 1e-6  # the exact SDF has a kink there, the viscous none
    # d/drho of nu log I0(rho/nu) = I1/I0(rho/nu)
    from scipy.special import i1e
    assert g[1, 0] == pytest.approx(i1e(10) / i0e(10), abs=1e-5)
    _, pts = random_points(rng, 100, 0.9, 0.99)
    assert np.abs(sdf(pts) - ExactSDF(circle())(pts)).max() < 0.01


def test_exact_sdf_of_disk_and_gradient(rng):
    sdf = ExactSDF(circle(2048, radius=0.8))
    rho, pts = random_points(rng, 500, 0.0, 2.0)
    np.testing.assert_allclose(sdf(pts), rho - 0.8, atol=1e-5)
    g = sdf.gradient(pts)
    # the polygon normal differs from the radial direction by at most half a vertex angle
    np.testing.assert_allclose(g, pts / rho[:, None], atol=np.pi / 2048)


def test_exact_sdf_of_ellipse_against_closed_form(rng):
    a, b = 1.0, 0.4
    t = np.linspace(0, 2 * np.pi, 4096, endpoint=False)
    sdf = ExactSDF(np.column_stack([a * np.cos(t), b * np.sin(t)]))
    pts = rng.uniform(-1.3, 1.3, (300, 2))
    # closed form: minimise |p - (a cos s, b sin s)| over s by Newton from a dense start
    s = np.linspace(0, 2 * np.pi, 20000, endpoint=False)
    dense = np.column_stack([a * np.cos(s), b * np.sin(s)])
    k = np.argmin(((pts[:, None, :] - dense[None]) ** 2).sum(-1), axis=1)
    u = s[k]
    for _ in range(20):
        x, y = a * np.cos(u), b * np.sin(u)
        dx, dy = -a * np.sin(u), b * np.cos(u)
        f = (x - pts[:, 0]) * dx + (y - pts[:, 1]) * dy
        df = (dx * dx + dy * dy + (x - pts[:, 0]) * (-a * np.cos(u))
              + (y - pts[:, 1]) * (-b * np.sin(u)))
        u = u - f / df
    dist = np.hypot(a * np.cos(u) - pts[:, 0], b * np.sin(u) - pts[:, 1])
    inside = (pts[:, 0] / a) ** 2 + (pts[:, 1] / b) ** 2 < 1
    np.testing.assert_allclose(sdf(pts), np.where(inside, -dist, dist), atol=2e-5)


def test_viscous_rejects_non_positive_viscosity():
    with pytest.raises(ValueError, match="viscosity"):
        ViscousSDF(circle(), viscosity=0.0)


def _distance_to_all_edges(polygon: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """The polygon's distance the slow way: the minimum over every edge."""
    best = np.full(len(pts), np.inf)
    for a, b in zip(polygon, np.roll(polygon, -1, axis=0), strict=True):
        e = b - a
        t = np.clip((pts - a) @ e / (e @ e), 0, 1)
        best = np.minimum(best, np.linalg.norm(pts - a - t[:, None] * e, axis=1))
    return best


@pytest.mark.parametrize("n_vertices", [256, 1024])  # brute-force and KD-tree nearest vertex
def test_exact_sdf_of_a_wiggly_polygon_against_all_edges(n_vertices, rng):
    from skimage.measure import points_in_poly

    t = 2 * np.pi * np.arange(n_vertices) / n_vertices
    radius = 1 + 0.3 * np.cos(3 * t) + 0.1 * np.sin(7 * t)  # star-shaped, concave in places
    polygon = radius[:, None] * np.column_stack([np.cos(t), np.sin(t)])
    pts = rng.uniform(-1.6, 1.6, (3000, 2))
    phi = ExactSDF(polygon)(pts)
    # the nearest point is sought on the two edges of the nearest vertex: not always the
    # minimum over all edges, but within 1e-3 of the outline's size (0.1 px at 100 px)
    np.testing.assert_allclose(np.abs(phi), _distance_to_all_edges(polygon, pts), atol=1e-3)
    np.testing.assert_array_equal(phi < 0, points_in_poly(pts, polygon))


def test_exact_sdf_does_not_depend_on_where_the_polygon_lies(rng):
    """Single precision in the nearest-vertex search must not cost accuracy far from 0."""
    polygon = circle(256, radius=30.0)
    pts = rng.uniform(-45, 45, (2000, 2))
    near = ExactSDF(polygon)(pts)
    far = ExactSDF(polygon + 1e4)(pts + 1e4)
    np.testing.assert_allclose(far, near, atol=1e-6)
    np.testing.assert_allclose(np.abs(near), _distance_to_all_edges(polygon, pts), atol=1e-2)
