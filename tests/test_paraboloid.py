"""Paraboloid (hemisphere) form factors: projection weights, splitting, horizon clipping."""
import numpy as np
import pytest
from geometry import PARALLEL_UNIT_SQUARES, PERPENDICULAR_UNIT_SQUARES, area_mean_ff, cube, squares

from radtr_addon.formfactors.closed_form import point_to_polygon
from radtr_addon.formfactors.paraboloid import ParaboloidRenderer, disk_weights, grid_barycentrics
from radtr_addon.hierarchy import subdivide
from radtr_addon.scene import PatchScene, triangle_geometry


def test_disk_pixels_weigh_the_same_and_sum_to_one():
    w = disk_weights(64)
    inside = w[w > 0]
    assert inside.sum() == pytest.approx(1.0, abs=1e-12)
    assert np.ptp(inside) == 0
    assert len(inside) == pytest.approx(np.pi * 32 ** 2, rel=0.01)


@pytest.mark.parametrize("n", [1, 2, 5])
def test_grid_tiles_the_parent_with_its_winding(n):
    uv = grid_barycentrics(n).reshape(-1, 3, 2).astype(float)
    corners = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    pts = corners[0] + uv[..., :1] * corners[1] + uv[..., 1:] * corners[2]
    normals, areas = triangle_geometry(pts.reshape(-1, 3), np.arange(pts.size // 3).reshape(-1, 3))
    assert len(areas) == n * n
    assert areas.sum() == pytest.approx(0.5, rel=1e-6)  # float32 barycentrics
    np.testing.assert_allclose(normals, [[0, 0, 1]] * (n * n))


def exact_point_rows(renderer, scene):
    """Closed-form F from each patch's eye point to every other triangle (unoccluded scenes)."""
    tris = scene.vertices[scene.triangles]
    exact = np.zeros((scene.n, scene.n))
    for i in range(scene.n):
        eye = renderer.eye(i) + renderer.center
        for j in range(scene.n):
            if j != i:
                exact[i, j] = point_to_polygon(eye, scene.normals[i], tris[j])
    return exact


def dense(rows, n):
    m = np.zeros((len(rows), n))
    for i, r in enumerate(rows):
        m[i, r.indices] = r.values
    return m


def test_splitting_removes_the_straight_edge_error_on_big_triangles(gpu):
    """Inside a cube of 12 triangles the plain projection misses 40 % of some rows."""
    s = cube()
    errors = {}
    for name, kw in {"none": {"split": "none"}, "uniform 4": {"split": "uniform", "split_level": 4},
                     "uniform 16": {"split": "uniform", "split_level": 16}, "adaptive": {"split": "adaptive"}}.items():
        r = ParaboloidRenderer(s, 256, **kw)
        exact = exact_point_rows(r, s)
        errors[name] = np.sqrt(np.mean((dense(r.rows(np.arange(s.n)), s.n) - exact)[exact > 0] ** 2))
    print("paraboloid 256 RMS row error, cube of 12 triangles:", errors)
    assert errors["none"] > 0.03                       # measured 0.051
    assert errors["uniform 4"] < errors["none"] / 5    # 0.0055
    assert errors["uniform 16"] < errors["uniform 4"] / 5
    assert errors["adaptive"] < 1e-3                   # 0.00034


@pytest.mark.parametrize("perpendicular, exact", [(False, PARALLEL_UNIT_SQUARES), (True, PERPENDICULAR_UNIT_SQUARES)])
@pytest.mark.parametrize("split", ["uniform", "adaptive"])
def test_square_to_square_within_one_percent(gpu, perpendicular, exact, split):
    ff = area_mean_ff(squares(perpendicular=perpendicular),
                      lambda s: ParaboloidRenderer(s, 256, split, split_level=8), 1 / 128)
    assert ff == pytest.approx(exact, rel=0.01)


@pytest.mark.parametrize("res", [128, 256, 512])
def test_closed_cube_rows_sum_to_one(gpu, res):
    leaves = subdivide(cube(), 1 / 16, 1).leaves
    rows = ParaboloidRenderer(leaves, res).rows(np.arange(0, leaves.n, 7))
    sums = np.array([r.values.sum() for r in rows])
    np.testing.assert_allclose(sums, 1.0, atol=0.01)
    assert max(r.escaped + r.blocked for r in rows) < 0.01


def test_triangle_across_the_horizon_is_clipped_not_folded(gpu):
    """A big triangle reaching far below the patch's tangent plane counts only its upper part."""
    e = 1e-3
    v = np.array([[0, 0, 0], [e, 0, 0], [0, e, 0], [2, -3, -3], [2, 3, -3], [2, 0, 3]], float)
    s = PatchScene(v, [[0, 1, 2], [3, 5, 4]], 0.5, 0.0, 0, 0)
    assert s.normals[1, 0] < 0                          # faces the patch
    for split in ("none", "adaptive"):
        r = ParaboloidRenderer(s, 512, split)
        exact = point_to_polygon(r.eye(0) + r.center, s.normals[0], v[[3, 5, 4]])
        got = r.row(0).values.sum()
        print(f"split {split}: {got:.5f} vs exact {exact:.5f}")
        if split == "adaptive":
            assert got == pytest.approx(exact, rel=0.01)
        assert got <= exact * 1.01                      # never the folded-over lower part


def test_back_faces_count_as_blocked(gpu):
    s = squares()
    flipped = PatchScene(s.vertices, np.vstack([s.triangles[:2], s.triangles[2:, ::-1]]), 0.5, 0.0, 0, 0)
    row = ParaboloidRenderer(flipped, 128).row(0)
    assert row.values.sum() == 0
    assert row.blocked > 0.15
