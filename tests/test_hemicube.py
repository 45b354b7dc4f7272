"""Hemicube form factors (GPU offscreen, Mesa llvmpipe headless) against closed forms."""
import numpy as np
import pytest

from radtr_addon.formfactors.hemicube import HemicubeRenderer, tile_weights
from radtr_addon.hierarchy import subdivide
from radtr_addon.scene import PatchScene


def test_weight_table_matches_exact_face_totals():
    res = 512
    raw = tile_weights(res)  # normalised to 1; the exact split is 0.554126 : 4 x 0.111468
    top = raw[:, :res].sum()
    assert top == pytest.approx(0.554126 / (0.554126 + 4 * 0.111468), rel=1e-4)
    assert raw.sum() == pytest.approx(1.0, rel=1e-12)


@pytest.fixture(scope="module")
def gpu(addon):
    from radtr_addon.formfactors.gpu_context import ensure_gpu_context

    ensure_gpu_context()


def squares(top_z=1.0, perpendicular=False):
    """Unit square facing +z at z=0 and a second one facing it (or standing on its edge x=0)."""
    if perpendicular:
        v = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [0, 1, 1]]
        t = [[0, 1, 2], [0, 2, 3], [0, 3, 5], [0, 5, 4]]
    else:
        v = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, top_z], [1, 0, top_z], [1, 1, top_z], [0, 1, top_z]]
        t = [[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6]]
    return PatchScene(np.array(v, float), t, 0.5, 0.0, [0, 0, 1, 1], 0)


def area_mean_ff(scene, res, max_area):
    h = subdivide(scene, max_area, 1)
    L = h.leaves
    src = np.flatnonzero(h.source < 2)
    rows = HemicubeRenderer(L, res).rows(src)
    to_other = [r.values[h.source[r.indices] >= 2].sum() for r in rows]
    return np.dot(L.areas[src], to_other) / L.areas[src].sum()


def test_point_to_square(gpu):
    e = 1e-3
    v = np.array([[0.5 - e, 0.5 - e, 0], [0.5 + 2 * e, 0.5 - e, 0], [0.5 - e, 0.5 + 2 * e, 0],
                  [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]])
    s = PatchScene(v, [[0, 1, 2], [3, 5, 4], [3, 6, 5]], 0.5, 0.0, 0, 0)
    row = HemicubeRenderer(s, 128).rows([0])[0]
    assert row.values.sum() == pytest.approx(0.239456, rel=2e-3)
    assert row.values.sum() + row.escaped + row.blocked == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize("perpendicular, exact", [(False, 0.199825), (True, 0.200044)])
def test_square_to_square_within_one_percent(gpu, perpendicular, exact):
    assert area_mean_ff(squares(perpendicular=perpendicular), 256, 1 / 128) == pytest.approx(exact, rel=0.01)


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
    v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    t = [[a, b, c] for a, b, c, d in quads] + [[a, c, d] for a, b, c, d in quads]
    s = PatchScene(v, t, 0.5, 1.0, 0, 0)
    assert np.all(s.normals @ [0.5, 0.5, 0.5] - np.einsum("ij,ij->i", s.normals, s.centroids) > 0)
    leaves = subdivide(s, 1 / 16, 1).leaves
    rows = HemicubeRenderer(leaves, res).rows(np.arange(0, leaves.n, 5))
    sums = np.array([r.values.sum() for r in rows])
    np.testing.assert_allclose(sums, 1.0, atol=0.01)
    assert max(r.escaped + r.blocked for r in rows) < 0.01
