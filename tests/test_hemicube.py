"""Hemicube form factors (GPU offscreen, Mesa llvmpipe headless) against closed forms."""
import numpy as np
import pytest
from geometry import PARALLEL_UNIT_SQUARES, PERPENDICULAR_UNIT_SQUARES, area_mean_ff, cube, squares

from radtr_addon.formfactors.hemicube import HemicubeRenderer, rotated_frames, tangent_frames, tile_weights
from radtr_addon.hierarchy import subdivide
from radtr_addon.scene import PatchScene


def test_weight_table_matches_exact_face_totals():
    res = 512
    raw = tile_weights(res)  # normalised to 1; the exact split is 0.554126 : 4 x 0.111468
    top = raw[:, :res].sum()
    assert top == pytest.approx(0.554126 / (0.554126 + 4 * 0.111468), rel=1e-4)
    assert raw.sum() == pytest.approx(1.0, rel=1e-12)


def test_point_to_square(gpu):
    e = 1e-3
    v = np.array([[0.5 - e, 0.5 - e, 0], [0.5 + 2 * e, 0.5 - e, 0], [0.5 - e, 0.5 + 2 * e, 0],
                  [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]])
    s = PatchScene(v, [[0, 1, 2], [3, 5, 4], [3, 6, 5]], 0.5, 0.0, 0, 0)
    row = HemicubeRenderer(s, 128).rows([0])[0]
    assert row.values.sum() == pytest.approx(0.239456, rel=2e-3)
    assert row.values.sum() + row.escaped + row.blocked == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize("rotate", [False, True])
@pytest.mark.parametrize("perpendicular, exact", [(False, PARALLEL_UNIT_SQUARES), (True, PERPENDICULAR_UNIT_SQUARES)])
def test_square_to_square_within_one_percent(gpu, perpendicular, exact, rotate):
    ff = area_mean_ff(squares(perpendicular=perpendicular), lambda s: HemicubeRenderer(s, 256, rotate), 1 / 128)
    assert ff == pytest.approx(exact, rel=0.01)


def test_rotated_frames_stay_orthonormal_and_turn_by_the_angle():
    n = np.array([[0, 0, 1.0], [0.6, 0.8, 0], [1.0, 0, 0]])
    t0, _ = tangent_frames(n)
    t, b = rotated_frames(n, np.array([0.3, 1.0, 2.5]))
    np.testing.assert_allclose(np.einsum("ij,ij->i", t, b), 0, atol=1e-12)
    np.testing.assert_allclose(np.cross(t, b), n, atol=1e-12)
    np.testing.assert_allclose(np.einsum("ij,ij->i", t, t0), np.cos([0.3, 1.0, 2.5]), atol=1e-12)


def test_back_faces_count_as_blocked(gpu):
    leaves = subdivide(squares(), 1 / 32, 1).leaves
    tris = leaves.triangles.copy()
    top = leaves.normals[:, 2] < 0
    tris[top] = tris[top][:, ::-1]                  # the upper square now faces away
    s = PatchScene(leaves.vertices, tris, 0.5, 0.0, 0, 0)
    rows = HemicubeRenderer(s, 128).rows(np.flatnonzero(~top)[:4])
    assert all(r.values.sum() == 0 for r in rows)
    assert all(r.blocked > 0.15 for r in rows)


@pytest.mark.parametrize("res", [128, 256])
def test_closed_cube_rows_sum_to_one(gpu, res):
    s = cube()
    assert np.all(s.normals @ [0.5, 0.5, 0.5] - np.einsum("ij,ij->i", s.normals, s.centroids) > 0)
    leaves = subdivide(s, 1 / 16, 1).leaves
    rows = HemicubeRenderer(leaves, res).rows(np.arange(0, leaves.n, 5))
    sums = np.array([r.values.sum() for r in rows])
    np.testing.assert_allclose(sums, 1.0, atol=0.01)
    assert max(r.escaped + r.blocked for r in rows) < 0.01
