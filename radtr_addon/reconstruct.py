"""Radiosity at points of the surfaces (mesh vertices) from a solved, patch-constant B.

A vertex shown with the area-weighted mean of the patches around it (what ``write`` stores by
default in ``radtr_radiosity``) is off wherever light changes across a patch: in corners and
contact shadows, the discretisation error that sets how exact a patch solution looks. A final
gather removes most of it. The irradiance at the point itself is

    H(p) = sum_emitters F(p -> j) V(p, j) E_j + sum_j F(p -> j) (B_j - E_j):

light straight from emitters, each emitting patch taken as a polygon light (``lights``: the
closed-form point-to-triangle form factor times the fraction V of shadow rays to stratified
points on it that arrive, no noise where an emitter is fully seen or hidden), plus the
reflected light, which varies slowly, from cosine-weighted Embree rays. A vertex where
another surface meets lies in that surface's plane, where half its rays would leave through
it; ``inset_points`` moves such points a little into their own triangles first.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .formfactors.raycast import EmbreeRays

#: Shadow rays per (point, emitter patch): a 4 x 4 stratified grid on the emitter.
SHADOW_SAMPLES = 16
#: Fraction of the way from a vertex to the mean centroid of its triangles.
INSET = 0.01


#: Faces meeting at a vertex at more than this angle (degrees) get a vertex each there, so
#: colours do not bleed across a box's edge (Blender's own default Auto Smooth angle).
CREASE_ANGLE = 30.0


@dataclass
class MeshPart:
    """The patches of one result mesh: their ids, its vertices and local triangles.

    A scene vertex where faces meet at a crease (``CREASE_ANGLE``) appears once per smooth
    group of the faces around it: a box's corner is three vertices, one per side."""

    patches: np.ndarray      # (t,) patch ids
    vertex_ids: np.ndarray   # (v,) scene vertex of each local vertex (repeated at creases)
    local: np.ndarray        # (t, 3) triangles in local vertex numbers
    normals: np.ndarray      # (v, 3) unit normal of each local vertex's smooth group


def mesh_part(scene, patches: np.ndarray, crease_angle: float = CREASE_ANGLE) -> MeshPart:
    """The result mesh of ``patches``: corners at one scene vertex share a local vertex when
    their faces are joined, at that vertex, by a chain of faces each within ``crease_angle``
    of the next."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    patches = np.asarray(patches)
    tris = scene.triangles[patches]
    corner_v = tris.ravel()
    corner_n = np.repeat(scene.normals[patches], 3, axis=0)
    order = np.argsort(corner_v, kind="stable")
    v_sorted = corner_v[order]
    starts = np.flatnonzero(np.r_[True, v_sorted[1:] != v_sorted[:-1]])
    sizes = np.diff(np.r_[starts, len(order)])
    # every pair of corners at the same vertex, joined where their faces are within the angle
    grp = np.repeat(np.arange(len(starts)), sizes)
    first = np.repeat(starts, sizes)
    count = sizes[grp]
    i = np.repeat(np.arange(len(order)), count)
    j = np.repeat(first, count) + (np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count))
    a, b = order[i], order[j]
    keep = np.einsum("ij,ij->i", corner_n[a], corner_n[b]) >= np.cos(np.radians(crease_angle))
    graph = coo_matrix((np.ones(int(keep.sum())), (a[keep], b[keep])), shape=(len(corner_v),) * 2)
    _, label = connected_components(graph, directed=False)
    # local vertices ordered by scene vertex, then group
    key = corner_v.astype(np.int64) * (len(corner_v) + 1) + label
    uniq, local = np.unique(key, return_inverse=True)
    vertex_ids = uniq // (len(corner_v) + 1)
    area = np.repeat(scene.areas[patches], 3)
    normals = np.zeros((len(uniq), 3))
    np.add.at(normals, local, corner_n * area[:, None])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    return MeshPart(patches, vertex_ids, local.reshape(-1, 3), normals)


def vertex_weights(tris: np.ndarray, n_vertices: int, areas: np.ndarray):
    """Sparse (v, t) matrix of the area-weighted mean at each vertex of per-triangle values:
    W @ values; kept by whoever averages the same mesh again and again (the flashlight)."""
    import scipy.sparse as sp

    W = sp.csr_matrix((np.repeat(areas, 3), (tris.ravel(), np.repeat(np.arange(len(tris)), 3))),
                      shape=(n_vertices, len(tris)))
    return sp.diags(1.0 / np.maximum(np.asarray(W.sum(axis=1)).ravel(), 1e-300)) @ W


def vertex_average(tris: np.ndarray, n_vertices: int, values: np.ndarray, areas: np.ndarray):
    """Per-vertex area-weighted mean of per-triangle ``values`` (t, c)."""
    return vertex_weights(tris, n_vertices, areas) @ values


class VertexRadiosity:
    """Radiosity at the vertices of a mesh part: the area mean of its patches (``rays`` = 0)
    or E + rho H with H from a final ``gather`` of ``rays`` cosine rays per vertex."""

    def __init__(self, scene, B: np.ndarray, rays: int = 0, seed: int = 0):
        self.scene, self.B, self.rays = scene, B, rays
        self.caster = EmbreeRays(scene, rays, seed) if rays > 0 else None
        self.seconds = 0.0                       # spent gathering

    def mean(self, part: MeshPart, values: np.ndarray) -> np.ndarray:
        """Area mean at the part's vertices of per-patch ``values`` (n, c)."""
        return vertex_average(part.local, len(part.vertex_ids), values[part.patches],
                              self.scene.areas[part.patches])

    def __call__(self, part: MeshPart) -> np.ndarray:
        if self.caster is None:
            return self.mean(part, self.B)
        t0 = time.perf_counter()
        s = self.scene
        normals = part.normals
        points = inset_points(s.vertices[part.vertex_ids], self.mean(part, s.centroids))
        H = gather(s, self.B, points, normals, caster=self.caster)
        out = self.mean(part, s.emission) + self.mean(part, s.rho) * H
        self.seconds += time.perf_counter() - t0
        return out


def inset_points(points: np.ndarray, centroids: np.ndarray, fraction: float = INSET) -> np.ndarray:
    """``points`` moved ``fraction`` of the way to ``centroids`` (the mean of their triangles')."""
    return points + fraction * (centroids - points)


def gather(scene, B: np.ndarray, points: np.ndarray, normals: np.ndarray, rays: int = 256,
           seed: int = 0, caster: EmbreeRays | None = None) -> np.ndarray:
    """Irradiance (k, 3) at ``points`` facing unit ``normals`` from the patches of ``scene`` at radiosity B."""
    from .lights import Light, irradiance_at

    caster = caster or EmbreeRays(scene, rays, seed)
    points, normals = np.asarray(points, float), np.asarray(normals, float)
    reflected = B - scene.emission
    H = np.zeros((len(points), 3))
    for k, row in enumerate(caster.point_rows(points, normals)):
        H[k] = row.values @ reflected[row.indices]
    emitters = np.flatnonzero(scene.emission.max(axis=1) > 0)
    if len(emitters):
        lights = [Light.polygon_light(f"patch {i}", caster.tris[i], scene.emission[i]) for i in emitters]
        H += irradiance_at(points + caster.epsilon * normals, normals, lights, caster, samples=SHADOW_SAMPLES,
                           cull=0.0)[0]
    return H
