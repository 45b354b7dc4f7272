"""Closed-form form factors against the catalogue, each other, reciprocity and the sum rule."""
import numpy as np
import pytest
from geometry import PARALLEL_UNIT_SQUARES, PERPENDICULAR_UNIT_SQUARES

from radtr_addon.formfactors.closed_form import (
    clip_to_halfspace,
    parallel_rectangles,
    perpendicular_rectangles,
    point_to_polygon,
    polygon_factor,
    polygon_factor_numpy,
    polygon_normal_area,
    polygon_to_polygon,
)


def rect(x0, x1, y0, y1, z=0.0, facing_up=True):
    p = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]], float)
    return p if facing_up else p[::-1]


def test_catalogue_values_for_unit_squares():
    assert parallel_rectangles(1, 1, 1) == pytest.approx(PARALLEL_UNIT_SQUARES, abs=1e-6)
    assert perpendicular_rectangles(1, 1, 1) == pytest.approx(PERPENDICULAR_UNIT_SQUARES, abs=1e-6)


def test_point_below_square_centre_is_four_corner_terms():
    x = y = 0.5                       # corner formula for a differential element under a corner
    corner = (x / np.sqrt(1 + x * x) * np.arctan(y / np.sqrt(1 + x * x))
              + y / np.sqrt(1 + y * y) * np.arctan(x / np.sqrt(1 + y * y))) / (2 * np.pi)
    f = point_to_polygon([0.5, 0.5, 0], [0, 0, 1], rect(0, 1, 0, 1, 1.0, False))
    assert f == pytest.approx(4 * corner, rel=1e-12)


@pytest.mark.parametrize("a, b, c", [(1, 1, 1), (2, 3, 0.5), (0.1, 5, 2), (10, 10, 0.01)])
def test_polygon_to_polygon_parallel(a, b, c):
    f = polygon_to_polygon(rect(0, a, 0, b), rect(0, a, 0, b, c, facing_up=False))
    assert f == pytest.approx(parallel_rectangles(a, b, c), rel=1e-9)


@pytest.mark.parametrize("length, width, height", [(1, 1, 1), (1, 2, 3), (5, 0.2, 0.7)])
def test_polygon_to_polygon_perpendicular_sharing_an_edge(length, width, height):
    floor = rect(0, width, 0, length)
    wall = np.array([[0, 0, 0], [0, length, 0], [0, length, height], [0, 0, height]], float)  # faces +x
    f = polygon_to_polygon(floor, wall)
    assert f == pytest.approx(perpendicular_rectangles(length, width, height), rel=1e-7)


def test_reciprocity_for_arbitrary_triangles():
    rng = np.random.default_rng(3)
    for _ in range(10):
        t1 = rng.random((3, 3))
        t2 = rng.random((3, 3)) + [0, 0, 1.5]
        n1, a1 = polygon_normal_area(t1)
        n2, a2 = polygon_normal_area(t2)
        f12, f21 = polygon_to_polygon(t1, t2), polygon_to_polygon(t2, t1)
        assert a1 * f12 == pytest.approx(a2 * f21, rel=1e-7, abs=1e-14)


def test_sum_rule_inside_a_closed_cube():
    faces = [rect(0, 1, 0, 1, 1.0, False), np.array([[0, 0, 0], [0, 0, 1], [1, 0, 1], [1, 0, 0]], float),
             np.array([[0, 1, 0], [1, 1, 0], [1, 1, 1], [0, 1, 1]], float),
             np.array([[0, 0, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1]], float),
             np.array([[1, 0, 0], [1, 0, 1], [1, 1, 1], [1, 1, 0]], float)]
    floor = rect(0, 1, 0, 1)
    assert sum(point_to_polygon([0.3, 0.6, 0], [0, 0, 1], f) for f in faces) == pytest.approx(1.0, abs=1e-12)
    assert sum(polygon_to_polygon(floor, f) for f in faces) == pytest.approx(1.0, abs=1e-9)


def test_polygon_straddling_the_horizon_counts_only_its_upper_part():
    wall = np.array([[1, -1, -1], [1, 1, -1], [1, 1, 1], [1, -1, 1]], float)[::-1]
    upper = clip_to_halfspace(wall, np.zeros(3), np.array([0, 0, 1.0]))
    assert len(upper) == 4 and upper[:, 2].min() == 0
    whole = point_to_polygon([0, 0, 0], [0, 0, 1], wall)
    assert whole == pytest.approx(point_to_polygon([0, 0, 0], [0, 0, 1], upper), rel=1e-12)
    assert 0 < whole < 0.5


def test_surfaces_behind_each_other_see_nothing():
    assert polygon_to_polygon(rect(0, 1, 0, 1), rect(0, 1, 0, 1, -1.0)) == 0.0
    assert point_to_polygon([0, 0, 0], [0, 0, 1], rect(0, 1, 0, 1, -1.0, False)) == 0.0
    assert polygon_to_polygon(rect(0, 1, 0, 1), rect(2, 3, 0, 1)) == 0.0   # coplanar


@pytest.mark.parametrize("factor", [polygon_factor, polygon_factor_numpy], ids=["compiled", "numpy"])
def test_polygon_factor_pair_by_pair_equals_the_clipped_contour_integral(factor):
    """Both forms of the batched pair form factor (compiled where numba builds, numpy) equal
    ``point_to_polygon`` (clip, then the contour sum, one pair at a time) at random points,
    normals and triangles: a third of the triangles straddle the point's horizon, half are
    seen from their back (0)."""
    from radtr_addon.compiled import kernel

    if factor is polygon_factor and kernel("polygon_factor") is None:
        pytest.skip("numba cannot build the kernel here (the warning says why)")
    rng = np.random.default_rng(3)
    points, tris = rng.normal(size=(400, 5, 3)), rng.normal(size=(400, 3, 3))
    normals = rng.normal(size=(400, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    facing = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    F = factor(points, normals, tris)
    ref = [[point_to_polygon(points[m, p], normals[m], tris[m]) if (points[m, p] - tris[m, 0]) @ facing[m] > 0
            else 0.0 for p in range(5)] for m in range(400)]
    h = np.einsum("mkc,mc->mk", tris, normals)[:, None] - np.einsum("mpc,mc->mp", points, normals)[..., None]
    assert 0.2 < ((h > 0).any(-1) & ~(h > 0).all(-1)).mean() and 0.3 < (F > 0).mean() < 0.6
    assert np.allclose(F, np.minimum(ref, 1.0), rtol=0, atol=1e-12)
