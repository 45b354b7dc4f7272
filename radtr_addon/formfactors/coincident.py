"""Coincident back-to-back faces: a wall modelled as two faces at the same place facing away
from each other.

Two triangles are such a pair when their normals are opposite (dot below -1 + 1e-6) and
either their three corners coincide or they are coplanar and the centroid of one lies inside
the other, all within ``TOLERANCE`` of the scene's diagonal. Every method lights each face
from its own side only; the GPU methods draw back faces a little deeper, so that where the
two coincide the front face is seen (``tiled.TiledRenderer.back_face_bias``).
"""
from __future__ import annotations

import numpy as np

from ..sampling import bounding_box

#: Distances below this fraction of the scene's diagonal count as the same place.
TOLERANCE = 1e-6
#: Centroid-in-triangle tests allowed per pair of opposite planes before that pair is skipped.
MAX_TESTS = 1 << 22


def back_to_back_pairs(vertices: np.ndarray, triangles: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(k, 2) triangle ids (i, j), i < j, of the coincident back-to-back pairs found
    (zero-area triangles, whose normals are not unit vectors, take no part)."""
    ok = np.flatnonzero(np.abs(np.linalg.norm(normals, axis=1) - 1.0) < 1e-3)
    if not len(ok):
        return np.zeros((0, 2), np.int64)
    corners, normals = vertices[triangles[ok]], normals[ok]     # (m, 3, 3), (m, 3)
    step = TOLERANCE * (bounding_box(vertices)[1] or 1.0)
    pairs = [_same_corners(corners, normals, step), _coplanar_overlap(corners, normals, step)]
    out = np.unique(np.sort(ok[np.concatenate(pairs)], axis=1), axis=0)
    return out.reshape(-1, 2)


def twins(vertices: np.ndarray, triangles: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Per triangle (n,), the triangle with the same three corners facing the other way, or
    -1: the two sides of one two-sided face (an emitter's back, a face modelled twice)."""
    twin = np.full(len(triangles), -1, np.int64)
    ok = np.flatnonzero(np.abs(np.linalg.norm(normals, axis=1) - 1.0) < 1e-3)
    if len(ok):
        step = TOLERANCE * (bounding_box(vertices)[1] or 1.0)
        i, j = ok[_same_corners(vertices[triangles[ok]], normals[ok], step)].T
        twin[i], twin[j] = j, i
    return twin


def _opposite(normals, i, j):
    return np.einsum("ij,ij->i", normals[i], normals[j]) < -1 + 1e-6


def _same_corners(corners, normals, step) -> np.ndarray:
    q = np.round(corners / step).astype(np.int64)
    order = np.lexsort((q[..., 2], q[..., 1], q[..., 0]), axis=-1)     # corners in a canonical order
    q = np.take_along_axis(q, order[..., None], axis=1).reshape(len(q), 9)
    _, group, counts = np.unique(q, axis=0, return_inverse=True, return_counts=True)
    group = group.ravel()
    ids = np.flatnonzero(counts[group] > 1)
    if not len(ids):
        return np.zeros((0, 2), np.int64)
    ids = ids[np.argsort(group[ids], kind="stable")]
    g = group[ids]
    pairs = []
    for start in np.flatnonzero(np.r_[True, g[1:] != g[:-1]]):
        members = ids[start:start + counts[g[start]]]
        a, b = np.triu_indices(len(members), 1)
        i, j = members[a], members[b]
        keep = _opposite(normals, i, j)
        pairs.append(np.stack([i[keep], j[keep]], axis=1))
    return np.concatenate(pairs) if pairs else np.zeros((0, 2), np.int64)


def _coplanar_overlap(corners, normals, step) -> np.ndarray:
    """Pairs on one plane facing away from each other where a centroid lies inside the other."""
    offset = np.einsum("ij,ij->i", normals, corners[:, 0])
    sign = np.where((normals[:, 0] > 0) | ((normals[:, 0] == 0) & ((normals[:, 1] > 0) |
                    ((normals[:, 1] == 0) & (normals[:, 2] > 0)))), 1.0, -1.0)
    key = np.column_stack([np.round(sign[:, None] * normals * 1e6), np.round(sign * offset / (4 * step))])
    key = key.astype(np.int64)                                  # rows compared by bytes: no -0.0
    _, plane = np.unique(key, axis=0, return_inverse=True)
    plane = plane.ravel()
    both = np.intersect1d(plane[sign > 0], plane[sign < 0])
    pairs = []
    for p in both:
        members = np.flatnonzero(plane == p)
        up, down = members[sign[members] > 0], members[sign[members] < 0]
        if not len(up) or not len(down) or len(up) * len(down) > MAX_TESTS:
            continue
        for a, b in ((up, down), (down, up)):
            inside = _inside(corners[a].mean(axis=1), corners[b], normals[b], step)
            ia, ib = np.nonzero(inside)
            pairs.append(np.stack([a[ia], b[ib]], axis=1))
    return np.concatenate(pairs) if pairs else np.zeros((0, 2), np.int64)


def _inside(points, tris, normals, step) -> np.ndarray:
    """(p, t) whether point p lies inside triangle t (on its plane), edges widened by ``step``."""
    inside = np.ones((len(points), len(tris)), dtype=bool)
    for k in range(3):
        a, b = tris[:, k], tris[:, (k + 1) % 3]
        edge_normal = np.cross(b - a, normals)
        edge_normal /= np.maximum(np.linalg.norm(edge_normal, axis=1), 1e-300)[:, None]
        side = points @ edge_normal.T - np.einsum("ij,ij->i", a, edge_normal)[None, :]
        inside &= side <= step                               # cross(edge, n) points out
    return inside


def back_to_back_warning(scene) -> str | None:
    """A warning naming the objects with coincident back-to-back faces, or None."""
    pairs = back_to_back_pairs(scene.vertices, scene.triangles, scene.normals)
    if not len(pairs):
        return None
    names = np.asarray(scene.object_names, dtype=object)[scene.object_index[pairs]]
    objects = sorted({tuple(sorted(set(p))) for p in names.tolist()})
    where = "; ".join(" and ".join(f"'{n}'" for n in o) for o in objects[:5])
    more = f" (and {len(objects) - 5} more)" if len(objects) > 5 else ""
    return (f"{len(pairs):,} pairs of coincident back-to-back faces (two faces at the same place facing away from "
            f"each other) in {where}{more}: each face is lit from its front only, as a box resting on a floor or "
            f"a wall between two rooms should be; if light should pass there (a thin sheet), make it one face")
