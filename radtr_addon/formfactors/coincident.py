"""Coincident back-to-back faces: two faces at the same place facing away from each other.

Every method lights each face from its own side only; the GPU methods draw back faces a
little deeper, so that where two coincide the front face is seen
(``tiled.TiledRenderer.back_face_bias``). A face resting on another (a box on a floor, a
cabinet's back against a wall) is such a place too, and an ordinary one: the hierarchical
solver models it as a contact. Only a face modelled twice, the same three corners facing
away from each other (``twins``, within ``TOLERANCE`` of the scene's diagonal), is named
to the user: it is a two-sided sheet, or a duplicate an edit left behind, and each costs
its own patches."""
from __future__ import annotations

import numpy as np

from ..sampling import bounding_box

#: Distances below this fraction of the scene's diagonal count as the same place.
TOLERANCE = 1e-6


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


def back_to_back_warning(scene) -> str | None:
    """A warning naming the objects with faces modelled twice, back to back, or None."""
    twin = twins(scene.vertices, scene.triangles, scene.normals)
    first = np.flatnonzero(twin > np.arange(len(twin)))           # each pair once
    if not len(first):
        return None
    pairs = np.stack([first, twin[first]], axis=1)
    names = np.asarray(scene.object_names, dtype=object)[scene.object_index[pairs]]
    objects = sorted({tuple(sorted(set(p))) for p in names.tolist()})
    where = "; ".join(" and ".join(f"'{n}'" for n in o) for o in objects[:5])
    more = f" (and {len(objects) - 5} more)" if len(objects) > 5 else ""
    return (f"{len(pairs):,} faces modelled twice, back to back (the same corners facing away from each other), "
            f"in {where}{more}: each side is lit from its front only, as the two sides of an opaque sheet are; "
            f"if one of each pair is a duplicate, delete it (it costs its own patches)")
