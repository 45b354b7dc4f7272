"""Patch hierarchy: area conserved, children inside parents, cluster membership consistent."""
import numpy as np
import pytest

from radtr_addon.errors import SceneError
from radtr_addon.hierarchy import estimate_leaf_count, subdivide
from radtr_addon.scene import PatchScene, triangle_geometry


def two_triangles():
    v = np.array([[0, 0, 0], [3, 0, 0], [3, 2, 0], [0, 2, 1.0]])
    return PatchScene(v, [[0, 1, 2], [0, 2, 3]], 0.5, [[1, 1, 1], [0, 0, 0]], [0, 1], 0)


def barycentric(p, tri):
    a, b, c = tri
    m = np.column_stack([b - a, c - a])
    uv, *_ = np.linalg.lstsq(m, (p - a).T, rcond=None)
    return np.vstack([1 - uv.sum(axis=0), uv])


@pytest.mark.parametrize("levels", [0, 1, 3])
def test_area_preserved_and_count_as_estimated(levels):
    s = two_triangles()
    h = subdivide(s, 0.3, levels)
    assert h.leaves.areas.sum() == pytest.approx(s.areas.sum(), rel=1e-12)
    assert h.leaves.n == estimate_leaf_count(s.areas, 0.3, levels)
    for r in range(levels):
        _, areas = triangle_geometry(h.leaves.vertices, h.level_triangles[r + 1])
        assert areas.max() <= 0.3 / 2 ** r * (1 + 1e-12)


def test_children_inside_parents_and_membership():
    s = two_triangles()
    h = subdivide(s, 0.2, 3)
    V = h.leaves.vertices
    for level in range(h.levels + 1):
        nodes = h.level_triangles[level]
        cl = h.cluster[level]
        # every leaf's vertices lie inside its level-l node
        for j in range(0, h.leaves.n, 7):
            bc = barycentric(V[h.leaves.triangles[j]], V[nodes[cl[j]]])
            assert bc.min() > -1e-9
        # areas of a node's leaves add up to the node's area
        _, node_area = triangle_geometry(V, nodes)
        np.testing.assert_allclose(np.bincount(cl, h.leaves.areas, len(nodes)), node_area, rtol=1e-12)
        # the representative is one of the node's leaves, and its centroid is the node's
        rep = h.representative[level]
        assert np.all(cl[rep] == np.arange(len(nodes)))
        np.testing.assert_allclose(h.leaves.centroids[rep], V[nodes].mean(axis=1), atol=1e-12)
    # nesting: leaves in one level-(l+1) node share one level-l node
    for level in range(h.levels):
        fine, coarse = h.cluster[level + 1], h.cluster[level]
        parent = np.full(fine.max() + 1, -1)
        parent[fine] = coarse
        assert np.all(parent[fine] == coarse)


def test_leaves_inherit_properties_and_orientation():
    s = two_triangles()
    h = subdivide(s, 0.1, 2)
    np.testing.assert_array_equal(h.leaves.emission, s.emission[h.source])
    np.testing.assert_allclose(h.leaves.normals, s.normals[h.source], atol=1e-12)


def test_midpoints_shared_between_neighbours():
    s = two_triangles()
    h = subdivide(s, 0.01, 1)
    # a conforming uniform split of 2 triangles k times has (V, E, F) obeying Euler's formula
    V = len(np.unique(h.leaves.triangles))
    edges = np.sort(np.concatenate([h.leaves.triangles[:, [0, 1]], h.leaves.triangles[:, [1, 2]],
                                    h.leaves.triangles[:, [2, 0]]]), axis=1)
    E = len(np.unique(edges, axis=0))
    assert V - E + h.leaves.n == 1


def test_refuses_too_many_patches_before_work():
    with pytest.raises(SceneError, match="patches"):
        subdivide(two_triangles(), 1e-9, 2)
