"""Patch hierarchy by 4-way midpoint subdivision (the seed's ``subdivide``).

Round r (0-based, ``levels`` rounds) splits every triangle whose area exceeds
``max_area / 2**r`` into four by its edge midpoints, again and again until none does.
Of the four children the centre one stands for the group: it is the parent ("father")
node, and down a chain of centre children the *representative* leaf of a cluster.

Level 0 holds the input triangles; level r + 1 the triangles alive after round r; the last
level's triangles are the leaf patches. ``cluster[l][j]`` is the level-l node that leaf j
descends from, ``representative[l][g]`` the leaf at the end of node g's centre chain.
Midpoints are shared between neighbours that both split, so leaf meshes stay connected
(a neighbour that does not split leaves a T-junction).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import SceneError, SettingsError
from .scene import PatchScene, triangle_geometry

#: Subdivisions that would produce more leaf patches than this are refused up front.
MAX_PATCHES = 4_000_000
#: Peak bytes per leaf of ``subdivide`` itself (vertices, triangles, levels, the leaf scene;
#: measured 574 at 786,432 leaves), the least any solve of the leaves needs.
SUBDIVIDE_BYTES_PER_PATCH = 640


@dataclass
class Hierarchy:
    """Leaf patches plus the nodes and cluster membership of every level."""

    leaves: PatchScene
    source: np.ndarray                 # (n,) index of the input triangle of each leaf
    level_triangles: list[np.ndarray]  # per level (k_l, 3) vertex ids into leaves.vertices
    cluster: list[np.ndarray]          # per level (n,) node id of each leaf
    representative: list[np.ndarray]   # per level (k_l,) leaf id of each node's representative

    @property
    def levels(self) -> int:
        return len(self.level_triangles) - 1


def estimate_leaf_count(areas: np.ndarray, max_area: float, levels: int) -> int:
    """Leaf count the subdivision will produce (exact for this split rule)."""
    if levels == 0:
        return len(areas)
    final = max_area / 2 ** (levels - 1)
    splits = np.ceil(np.log(np.maximum(areas / final, 1.0)) / np.log(4.0) - 1e-12)
    return int(np.sum(4.0 ** np.maximum(splits, 0)))


def check_patch_memory(patches: int, max_area: float, levels: int, budget_bytes: int,
                       bytes_per_patch: int = SUBDIVIDE_BYTES_PER_PATCH, what: str = "subdividing"):
    """Raise SettingsError when ``patches`` leaves at ``bytes_per_patch`` (the chosen solve's
    work arrays per patch: ``solvers.patch_bytes``) need more than ``budget_bytes``."""
    need = patches * max(bytes_per_patch, SUBDIVIDE_BYTES_PER_PATCH)
    if need > budget_bytes:
        raise SettingsError(
            f"subdividing to max area {max_area:g} in {levels} levels would make {patches:,} patches, and "
            f"{what} of them needs {need / 2**30:,.2f} GiB ({need // patches:,} bytes a patch), over the "
            f"memory budget of {budget_bytes / 2**20:,.0f} MB: raise the budget (Memory Budget, --cache-mb) "
            f"to {-(-need // 2**20):,} MB, or raise the max area or lower the levels")


def subdivide(scene: PatchScene, max_area: float, levels: int, progress=None, *,
              budget_bytes: int | None = None, bytes_per_patch: int = SUBDIVIDE_BYTES_PER_PATCH,
              what: str = "subdividing") -> Hierarchy:
    """Build the hierarchy of ``scene`` (see module docstring).

    ``progress(done, total)`` is called once per round. Before any work the leaf count is
    estimated (``estimate_leaf_count``) and refused above ``MAX_PATCHES``, or, given
    ``budget_bytes``, when the leaves at ``bytes_per_patch`` would not fit in it
    (``check_patch_memory``; ``what`` names the work in the message).
    """
    if levels < 0:
        raise SceneError(f"levels must be 0 or more, got {levels}")
    if levels > 0 and not max_area > 0:
        raise SceneError(f"max area must be positive, got {max_area}")
    expected = estimate_leaf_count(scene.areas, max_area, levels)
    if expected > MAX_PATCHES:
        raise SceneError(
            f"subdividing to max area {max_area:g} in {levels} levels would make {expected:,} patches "
            f"(limit {MAX_PATCHES:,}): raise the max area or lower the levels")
    if budget_bytes is not None:
        check_patch_memory(expected, max_area, levels, budget_bytes, bytes_per_patch, what)
    vertices = [scene.vertices]
    n_vertices = len(scene.vertices)
    edge_mid: dict[int, int] = {}
    tris = scene.triangles.copy()
    source = np.arange(scene.n)
    cluster = np.arange(scene.n)[:, None]       # (m, levels so far)
    central = np.ones((scene.n, 1), dtype=bool)  # leaf on the centre chain of its level-l node
    level_tris = [tris.copy()]
    for r in range(levels):
        threshold = max_area / 2 ** r
        while True:
            verts = np.concatenate(vertices) if len(vertices) > 1 else vertices[0]
            vertices = [verts]
            _, areas = triangle_geometry(verts, tris)
            big = areas > threshold
            if not big.any():
                break
            mids, new_verts = _midpoints(tris[big], edge_mid, n_vertices, verts)
            n_vertices += len(new_verts)
            vertices.append(new_verts)
            children = _children(tris[big], mids)              # (4m, 3), centre first per parent
            keep = ~big
            rep = np.repeat(np.flatnonzero(big), 4)
            tris = np.concatenate([tris[keep], children])
            source = np.concatenate([source[keep], source[rep]])
            cluster = np.concatenate([cluster[keep], cluster[rep]])
            child_central = central[rep] & (np.arange(len(rep)) % 4 == 0)[:, None]
            central = np.concatenate([central[keep], child_central])
        cluster = np.hstack([cluster, np.arange(len(tris))[:, None]])
        central = np.hstack([central, np.ones((len(tris), 1), dtype=bool)])
        level_tris.append(tris.copy())
        if progress:
            progress(r + 1, levels)
    verts = np.concatenate(vertices)
    leaves = PatchScene(
        verts, tris, scene.rho[source], scene.emission[source],
        scene.object_index[source], scene.material_index[source],
        list(scene.object_names), list(scene.material_names))
    representative = [_representatives(cluster[:, l], central[:, l], len(level_tris[l]))
                      for l in range(levels + 1)]
    return Hierarchy(leaves, source, level_tris, [cluster[:, l].copy() for l in range(levels + 1)],
                     representative)


def _midpoints(tris: np.ndarray, edge_mid: dict, n_vertices: int, verts: np.ndarray):
    """Midpoint vertex ids (m, 3) for edges ab, bc, ca; new vertices created for unseen edges."""
    a, b = tris, np.roll(tris, -1, axis=1)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    keys = lo.astype(np.int64) * (1 << 32) + hi
    uniq, inverse = np.unique(keys.ravel(), return_inverse=True)
    ids = np.empty(len(uniq), dtype=np.int64)
    new_pairs = []
    for k, key in enumerate(uniq.tolist()):
        vid = edge_mid.get(key)
        if vid is None:
            vid = n_vertices + len(new_pairs)
            edge_mid[key] = vid
            new_pairs.append((key >> 32, key & 0xFFFFFFFF))
        ids[k] = vid
    pairs = np.array(new_pairs, dtype=np.int64).reshape(-1, 2)
    new_verts = 0.5 * (verts[pairs[:, 0]] + verts[pairs[:, 1]])
    return ids[inverse].reshape(-1, 3), new_verts


def _children(tris: np.ndarray, mids: np.ndarray) -> np.ndarray:
    """Four children per triangle, centre first, all with the parent's orientation."""
    a, b, c = tris.T
    mab, mbc, mca = mids.T
    kids = np.stack([
        np.stack([mab, mbc, mca], axis=1),
        np.stack([a, mab, mca], axis=1),
        np.stack([mab, b, mbc], axis=1),
        np.stack([mca, mbc, c], axis=1),
    ], axis=1)
    return kids.reshape(-1, 3)


def _representatives(cluster: np.ndarray, central: np.ndarray, k: int) -> np.ndarray:
    rep = np.full(k, -1, dtype=np.int64)
    leaves = np.flatnonzero(central)
    rep[cluster[leaves]] = leaves
    return rep
