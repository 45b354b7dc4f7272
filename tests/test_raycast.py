"""Embree ray form factors: unbiased against closed forms, deterministic, closed scenes sum to 1."""
import numpy as np
import pytest
from geometry import PARALLEL_UNIT_SQUARES, PERPENDICULAR_UNIT_SQUARES, cube, squares

from radtr_addon.formfactors.closed_form import point_to_polygon, polygon_to_polygon
from radtr_addon.formfactors.raycast import EmbreeRays
from radtr_addon.hierarchy import subdivide
from radtr_addon.scene import PatchScene


@pytest.mark.parametrize("perpendicular, exact", [(False, PARALLEL_UNIT_SQUARES), (True, PERPENDICULAR_UNIT_SQUARES)])
def test_square_to_square_within_three_sigma_at_4096_rays(perpendicular, exact):
    s = squares(perpendicular=perpendicular)
    rays = EmbreeRays(s, 4096)
    rows = rays.rows([0, 1])                 # the two triangles of the first square, equal areas
    f = [r.values[r.indices >= 2].sum() for r in rows]
    tris = s.vertices[s.triangles]
    exact_tri = [sum(polygon_to_polygon(tris[i], tris[j]) for j in (2, 3)) for i in (0, 1)]
    assert np.mean(exact_tri) == pytest.approx(exact, rel=1e-5)
    sigma = np.sqrt(sum(e * (1 - e) / 4096 for e in exact_tri)) / 2
    assert abs(np.mean(f) - exact) < 3 * sigma


def test_same_seed_same_rows_other_seed_other_rows():
    s = squares()
    a, b, c = (EmbreeRays(s, 256, seed=k).row(0) for k in (0, 0, 1))
    assert np.array_equal(a.values, b.values)
    assert not np.array_equal(a.values, c.values)


def test_closed_cube_rows_sum_to_one():
    leaves = subdivide(cube(), 1 / 8, 1).leaves
    rows = EmbreeRays(leaves, 1024).rows(np.arange(leaves.n))
    assert max(abs(r.values.sum() - 1) for r in rows) < 1e-3
    assert max(r.escaped + r.blocked for r in rows) < 1e-3


def test_reciprocity_holds_statistically():
    leaves = subdivide(squares(perpendicular=True), 1 / 4, 1).leaves
    rows = EmbreeRays(leaves, 16384).rows(np.arange(leaves.n))
    m = np.zeros((leaves.n, leaves.n))
    for i, r in enumerate(rows):
        m[i, r.indices] = r.values
    af = leaves.areas[:, None] * m
    big = m > 0.05
    np.testing.assert_allclose(af[big], af.T[big], rtol=0.1)


def test_point_to_patch_is_the_closed_form_times_what_is_visible():
    s = squares()
    rays = EmbreeRays(s, 16)
    p, n = np.array([0.5, 0.5, 0.0]), np.array([0.0, 0.0, 1.0])
    tri = s.vertices[s.triangles[2]]
    assert rays.point_to_patch(p, n, 2) == pytest.approx(point_to_polygon(p, n, tri), rel=1e-3)
    # a blocker half way up covering everything
    v = np.vstack([s.vertices, [[-5, -5, 0.5], [5, -5, 0.5], [0, 5, 0.5]]])
    blocked = PatchScene(v, np.vstack([s.triangles, [[8, 9, 10]]]), 0.5, 0.0, 0, 0)
    assert EmbreeRays(blocked, 16).point_to_patch(p, n, 2) == 0.0


def test_centroid_origins_match_the_point_closed_form():
    e = 1e-3
    v = np.array([[0.5 - e, 0.5 - e, 0], [0.5 + 2 * e, 0.5 - e, 0], [0.5 - e, 0.5 + 2 * e, 0],
                  [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]])
    s = PatchScene(v, [[0, 1, 2], [3, 5, 4], [3, 6, 5]], 0.5, 0.0, 0, 0)
    f = EmbreeRays(s, 65536, origins="centroid").row(0).values.sum()
    assert f == pytest.approx(0.239456, abs=3 * np.sqrt(0.24 * 0.76 / 65536))


def test_final_gather_at_a_point_matches_the_closed_form():
    """Irradiance at the centre below an emitting unit square: F(point -> square) x B."""
    from geometry import squares

    from radtr_addon.formfactors.closed_form import point_to_polygon
    from radtr_addon.reconstruct import gather

    s = squares()
    B = np.zeros((s.n, 3))
    B[2:] = [1.0, 2.0, 3.0]                        # the top square (facing down) shines
    point, normal = np.array([0.5, 0.5, 0.0]), np.array([0.0, 0.0, 1.0])
    exact = point_to_polygon(point, normal, np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1.0]]))
    H = gather(s, B, point[None], normal[None], rays=16384)
    sigma = np.sqrt(exact * (1 - exact) / 16384)
    np.testing.assert_allclose(H[0], exact * np.array([1.0, 2.0, 3.0]), atol=3 * sigma * 3)


def test_final_gather_takes_direct_light_from_the_closed_form():
    """An emitting square seen whole: the direct part is exact with any ray count."""
    from geometry import squares

    from radtr_addon.formfactors.closed_form import point_to_polygon, point_to_triangles
    from radtr_addon.reconstruct import gather

    s = squares()
    s.emission[2:] = [1.0, 2.0, 3.0]
    points = np.array([[0.5, 0.5, 0.0], [0.1, 0.8, 0.0], [2.0, 0.5, 0.3]])
    normals = np.array([[0, 0, 1.0], [0, 0, 1.0], [-1.0, 0, 0]])
    top = np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1.0]])
    exact = [point_to_polygon(p, n, top) for p, n in zip(points, normals)]
    H = gather(s, s.emission.copy(), points, normals, rays=4)
    np.testing.assert_allclose(H, np.outer(exact, [1.0, 2.0, 3.0]), rtol=1e-5)   # points lifted 1e-6 x diagonal
    tris = s.vertices[s.triangles]
    np.testing.assert_allclose(point_to_triangles(points, normals, tris)[:, 2:].sum(axis=1), exact, rtol=1e-9)
    assert np.all(point_to_triangles(points, normals, tris)[:2, :2] == 0)   # coplanar with the floor


@pytest.mark.parametrize("normals", ["none", "origins", "targets", "one target normal", "both"])
def test_clear_between_compiled_equals_numpy_form_and_sees_a_slab(normals, monkeypatch):
    """Shadow rays between points above and below a slab (the unit square z = 0.5 in a unit
    box's middle), with each end's normal given or not: the compiled rays and numpy's form
    agree ray for ray, and a ray is blocked exactly when its segment crosses the slab."""
    from radtr_addon import compiled

    if compiled.kernel("clear_rays") is None:
        pytest.skip("numba cannot build the kernel here (the warning says why)")
    slab = PatchScene(np.array([[0, 0, 0.5], [1, 0, 0.5], [1, 1, 0.5], [0, 1, 0.5]], float),
                      [[0, 1, 2], [0, 2, 3]], 0.5, 0.0, 0, 0)
    caster = EmbreeRays(slab, 1)
    rng = np.random.default_rng(2)
    a = np.c_[rng.uniform(-0.5, 1.5, (2000, 2)), rng.uniform(0.0, 0.45, 2000)]
    b = np.c_[rng.uniform(-0.5, 1.5, (2000, 2)), rng.uniform(0.55, 1.0, 2000)]
    up = np.tile([0.0, 0.0, 1.0], (2000, 1))
    n_a, n_b = {"none": (None, None), "origins": (up, None), "targets": (None, -up),
                "one target normal": (None, np.array([0.0, 0.0, -1.0])), "both": (up, -up)}[normals]
    got = caster.clear_between(a, b, n_a, n_b)
    with monkeypatch.context() as m:
        m.setattr(compiled, "kernel", lambda name: None)
        assert np.array_equal(caster.clear_between(a, b, n_a, n_b), got)
    s = (0.5 - a[:, 2]) / (b[:, 2] - a[:, 2])
    x = a + s[:, None] * (b - a)
    crosses = np.all((x[:, :2] > 0) & (x[:, :2] < 1), axis=1)
    clear_of_edges = np.all(np.minimum(np.abs(x[:, :2]), np.abs(x[:, :2] - 1)) > 1e-3, axis=1)
    assert np.array_equal(got[clear_of_edges], ~crosses[clear_of_edges])
    assert 0.2 < crosses.mean() < 0.8
