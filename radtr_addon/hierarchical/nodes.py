"""The node tree of hierarchical radiosity: clusters above the input triangles, elements below.

Clusters (Smits, Arvo and Greenberg 1994) form a binary bounding-volume tree over the input
triangles, split at the median centroid along the widest axis, so that the first link, the
root cluster to itself, refines into O(k log k) links for k input triangles, never k^2.
Its leaves are the input triangles, the roots of the element trees: each element splits
lazily, when a link needs it, into four by its edge midpoints (shared between neighbours,
so the leaves stay one connected mesh with T-vertices where a neighbour did not split).

Nodes live in flat arrays, children contiguous (``first_child``, ``n_children``). A cluster
also keeps, for the ``DIRECTIONS`` table, its projected area A_proj(w) = sum A_i max(0, n_i.w)
over its triangles: what it shows, and so sends and receives, along each direction.
"""
from __future__ import annotations

import numpy as np

from ..sampling import bounding_box
from ..scene import PatchScene


def sphere_directions() -> np.ndarray:
    """42 unit directions about evenly spread: an icosahedron's 12 corners and 30 edge midpoints."""
    t = (1 + 5 ** 0.5) / 2
    corners = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                        [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    corners /= np.linalg.norm(corners, axis=1, keepdims=True)
    d = np.linalg.norm(corners[:, None] - corners[None], axis=-1)
    i, j = np.nonzero(np.triu(np.isclose(d, d[d > 0].min())))
    mids = corners[i] + corners[j]
    out = np.concatenate([corners, mids / np.linalg.norm(mids, axis=1, keepdims=True)])
    return out


DIRECTIONS = sphere_directions()
#: Cell levels whose centroids sample outside light on an element, by its level below its input
#: triangle (64 points on an input triangle, 16 on its children, then 4).
LIGHT_CELLS = np.array([3, 2, 1])


def _faces() -> tuple[np.ndarray, np.ndarray]:
    """The 80 spherical triangles between the table directions, and the inverse (80, 3, 3)
    of each one's corner matrix (columns the corners): its barycentric map."""
    from scipy.spatial import ConvexHull

    faces = ConvexHull(DIRECTIONS).simplices
    return faces, np.linalg.inv(np.transpose(DIRECTIONS[faces], (0, 2, 1)))


DIRECTION_FACES, _FACE_INVERSE = _faces()
#: The faces (42, 6) around each table direction (five round the icosahedron's corners, the
#: first repeated): a unit vector lies in one of the faces round its nearest direction.
_AROUND = np.array([(lambda f: f + f[:6 - len(f)])(np.flatnonzero((DIRECTION_FACES == k).any(axis=1)).tolist())
                    for k in range(len(DIRECTIONS))])


def direction_weights(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The three table directions (m, 3) around each unit vector of ``w`` (m, 3), and weights
    (m, 3) summing to 1 (its gnomonic barycentric coordinates in their face): a quantity
    tabled by direction is read between them, not from the nearest one (up to 18 degrees
    away, where a face seen edge-on shows nothing)."""
    faces = _AROUND[np.argmax(w @ DIRECTIONS.T, axis=1)]                 # (m, 6)
    lam = np.einsum("mfij,mj->mfi", _FACE_INVERSE[faces], w)             # (m, 6, 3)
    pick = np.argmax(lam.min(axis=2), axis=1)
    rows = np.arange(len(w))
    face = faces[rows, pick]
    lam = np.maximum(lam[rows, pick], 0.0)
    return DIRECTION_FACES[face], lam / np.maximum(lam.sum(axis=1, keepdims=True), 1e-300)


class Nodes:
    """Clusters and elements of one scene (see module docstring).

    Per node: ``cluster`` flag, ``parent``, ``first_child`` (-1: none yet), ``n_children``,
    ``center`` and ``radius`` of a bounding sphere, ``lo`` and ``hi`` corners of a bounding
    box, ``area``; per element: its corners
    ``tri`` (3, 3), vertex ids ``vids`` into ``vertices``, ``normal``, the input triangle
    ``root``, ``level`` below it, ``path`` (its child slots from the root, base 4), and
    ``E`` (exitance, own emission plus the reflected light of ``external``), ``H_ext``
    (irradiance from lights outside the solve), ``H_direct`` (the Light objects' part of it,
    which a final gather takes at the points it hits instead) and ``H_spread`` (how much rho
    H_ext varies over the element, where it can split). Elements split at most
    ``max_level`` times below their input triangle, and not below ``min_area`` (m^2).
    """

    def __init__(self, scene: PatchScene, external, max_level: int, min_area: float):
        self.scene, self.external = scene, external
        self.max_level, self.min_area = max_level, min_area
        self.diagonal = bounding_box(scene.vertices)[1] or 1.0
        self.vertices = [scene.vertices]
        self.n_vertices = len(scene.vertices)
        self.midpoint: dict[int, int] = {}
        self.size = 0
        self._arrays = {
            "cluster": (bool, ()), "parent": (np.int64, ()), "first_child": (np.int64, ()),
            "n_children": (np.int64, ()), "center": (float, (3,)), "radius": (float, ()),
            "lo": (float, (3,)), "hi": (float, (3,)),
            "area": (float, ()), "tri": (float, (3, 3)), "vids": (np.int64, (3,)), "normal": (float, (3,)),
            "root": (np.int64, ()), "level": (np.int64, ()), "path": (np.int64, ()), "E": (float, (3,)),
            "H_ext": (float, (3,)), "H_direct": (float, (3,)), "H_spread": (float, ()), "rho": (float, (3,)),
        }
        for name, (dtype, shape) in self._arrays.items():
            setattr(self, name, np.zeros((16, *shape), dtype))
        self._build_clusters()
        self.init_light(self.element_root)

    # -- storage -------------------------------------------------------------------------
    def _add(self, count: int) -> np.ndarray:
        """Ids of ``count`` new nodes (arrays grow by doubling)."""
        need = self.size + count
        cap = len(self.parent)
        if need > cap:
            cap = max(need, 2 * cap)
            for name, (dtype, shape) in self._arrays.items():
                old = getattr(self, name)
                new = np.zeros((cap, *shape), dtype)
                new[:self.size] = old[:self.size]
                setattr(self, name, new)
        ids = np.arange(self.size, need)
        self.size = need
        self.first_child[ids] = -1
        return ids

    # -- clusters ------------------------------------------------------------------------
    def _build_clusters(self):
        """The cluster tree over the input triangles, breadth first (children contiguous)."""
        s = self.scene
        cent = s.centroids
        self.order = np.arange(s.n)          # input triangles in tree order
        root = self._add(1)
        segments = [(int(root[0]), 0, s.n, -1)]
        self.element_root = np.full(s.n, -1, np.int64)
        while segments:
            nxt = []
            for node, lo, hi, parent in segments:
                self.parent[node] = parent
                if hi - lo == 1:
                    self._make_root(node, int(self.order[lo]))
                    continue
                self.cluster[node] = True
                ids = self.order[lo:hi]
                axis = int(np.argmax(np.ptp(cent[ids], axis=0)))
                self.order[lo:hi] = ids[np.argsort(cent[ids, axis], kind="stable")]
                mid = (lo + hi) // 2
                kids = self._add(2)
                self.first_child[node], self.n_children[node] = kids[0], 2
                nxt += [(int(kids[0]), lo, mid, node), (int(kids[1]), mid, hi, node)]
            segments = nxt
        self._cluster_extents()

    def _make_root(self, node: int, t: int):
        s = self.scene
        self.element_root[t] = node
        self.tri[node] = s.vertices[s.triangles[t]]
        self.vids[node] = s.triangles[t]
        self.normal[node], self.area[node] = s.normals[t], s.areas[t]
        self.root[node], self.level[node] = t, 0
        self.rho[node] = s.rho[t]
        self._set_sphere(np.array([node]))

    def _set_sphere(self, ids: np.ndarray):
        tri = self.tri[ids]
        c = tri.mean(axis=1)
        self.center[ids] = c
        self.radius[ids] = np.linalg.norm(tri - c[:, None], axis=-1).max(axis=1)
        self.lo[ids], self.hi[ids] = tri.min(axis=1), tri.max(axis=1)

    def _cluster_extents(self):
        """Bounding spheres, areas, most reflective channel and projected-area tables of clusters."""
        clusters = np.flatnonzero(self.cluster[:self.size])
        self.cluster_row = np.full(self.size, -1, np.int64)
        self.cluster_row[clusters] = np.arange(len(clusters))
        self.clusters = clusters
        s = self.scene
        k = len(clusters)
        lo = np.full((k, 3), np.inf)
        hi = np.full((k, 3), -np.inf)
        self.proj = np.zeros((k, len(DIRECTIONS)))
        self.rho_max = np.zeros(self.size)
        roots = self.element_root
        self.rho_max[roots] = s.rho.max(axis=1)
        root_proj = s.areas[:, None] * np.maximum(s.normals @ DIRECTIONS.T, 0.0)
        tri = s.vertices[s.triangles]
        # walk up from every input triangle: each cluster gathers its members (depth is log k)
        node, t = self.parent[roots].copy(), np.arange(s.n)
        while len(t):
            row = self.cluster_row[node]
            np.minimum.at(lo, row, tri[t].min(axis=1))
            np.maximum.at(hi, row, tri[t].max(axis=1))
            np.add.at(self.proj, row, root_proj[t])
            np.add.at(self.area, node, s.areas[t])
            np.maximum.at(self.rho_max, node, self.rho_max[roots[t]])
            node = self.parent[node]
            keep = node >= 0
            node, t = node[keep], t[keep]
        self.lo[clusters], self.hi[clusters] = lo, hi
        self.center[clusters] = (lo + hi) / 2
        self.radius[clusters] = np.linalg.norm(hi - lo, axis=1) / 2
        self.cluster_depth = np.zeros(k, np.int64)
        for c in clusters[1:] if k else []:         # breadth first: parents come before children
            self.cluster_depth[self.cluster_row[c]] = self.cluster_depth[self.cluster_row[self.parent[c]]] + 1

    # -- elements ------------------------------------------------------------------------
    def can_split(self, n: np.ndarray) -> np.ndarray:
        """Whether nodes ``n`` can have children: clusters, and elements above the last level
        and the least area."""
        return self.cluster[n] | ((self.level[n] < self.max_level) & (self.area[n] > 4 * self.min_area))

    def init_light(self, ids: np.ndarray):
        """E, H_ext, H_direct and H_spread of new elements ``ids``: emission plus the reflected
        external light, its mean over points of each element (and of its Light objects' part),
        and its spread there (and at its corners), the spread from samples drawn alike at
        those points and the mean from samples drawn apart from them (``external``'s
        ``spread``). The points are the
        centroids of the element's cells ``LIGHT_CELLS`` levels down (fewer on small ones), so
        a shadow that misses four points of a large input triangle still splits it. The
        spread only decides splits: elements that cannot split take the mean alone, at a
        half to a quarter of the rays (three in four of the atrium's input triangles)."""
        s = self.scene
        self.E[ids] = s.emission[self.root[ids]]
        if self.external is None or not len(ids):
            return
        from .contacts import cell_centroids, cell_levels

        fit = cell_levels(self.radius[ids], self.diagonal)
        depth = np.clip(np.minimum(LIGHT_CELLS[np.minimum(self.level[ids], len(LIGHT_CELLS) - 1)], fit), 1, None)
        for g in np.unique(depth).astype(int):
            sel = ids[depth == g]
            cells = cell_centroids(g)
            split = self.can_split(sel)
            fixed = sel[~split]
            if len(fixed):
                H, direct = self.external(self.tri[fixed], self.normal[fixed], cells)
                self.H_ext[fixed], self.H_direct[fixed] = H.mean(axis=1), direct.mean(axis=1)
            sel = sel[split]
            if not len(sel):
                continue
            # the corners too: the vertex colours take the light there, so a leaf lit at a
            # corner and dark at its cells is split, not drawn as a long bright wedge
            H, direct, alike = self.external(self.tri[sel], self.normal[sel], np.vstack([cells, np.eye(3)]),
                                             spread=True)
            self.H_ext[sel] = H[:, :len(cells)].mean(axis=1)
            self.H_direct[sel] = direct[:, :len(cells)].mean(axis=1)
            self.H_spread[sel] = (self.rho[sel] * (alike.max(axis=1) - alike.min(axis=1))).max(axis=1)
        self.E[ids] += self.rho[ids] * self.H_ext[ids]

    def split(self, ids: np.ndarray) -> np.ndarray:
        """Give the elements ``ids`` (without children) their four children; returns the new ids."""
        ids = np.unique(ids[self.first_child[ids] < 0])
        if not len(ids):
            return ids
        mids = self._midpoints(self.vids[ids])
        a, b, c = self.vids[ids].T
        mab, mbc, mca = mids.T
        kids_v = np.stack([np.stack([mab, mbc, mca], 1), np.stack([a, mab, mca], 1),
                           np.stack([mab, b, mbc], 1), np.stack([mca, mbc, c], 1)], axis=1).reshape(-1, 3)
        new = self._add(4 * len(ids))
        parent = np.repeat(ids, 4)
        verts = self.all_vertices()
        self.vids[new] = kids_v
        self.tri[new] = verts[kids_v]
        self.parent[new] = parent
        for name in ("normal", "root", "rho"):
            getattr(self, name)[new] = getattr(self, name)[parent]
        self.level[new] = self.level[parent] + 1
        self.path[new] = 4 * self.path[parent] + np.tile(np.arange(4), len(ids))
        self.area[new] = self.area[parent] / 4
        self.first_child[ids], self.n_children[ids] = new[::4], 4
        self._set_sphere(new)
        self.init_light(new)
        return new

    def _midpoints(self, tris: np.ndarray) -> np.ndarray:
        """Midpoint vertex ids (m, 3) of edges ab, bc, ca, shared with neighbours that split before."""
        a, b = tris, np.roll(tris, -1, axis=1)
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        keys = (lo << 32) + hi
        uniq, inverse = np.unique(keys.ravel(), return_inverse=True)
        ids = np.empty(len(uniq), np.int64)
        fresh = []
        for k, key in enumerate(uniq.tolist()):
            vid = self.midpoint.get(key)
            if vid is None:
                vid = self.midpoint[key] = self.n_vertices + len(fresh)
                fresh.append((key >> 32, key & 0xFFFFFFFF))
            ids[k] = vid
        if fresh:
            pairs = np.array(fresh, np.int64)
            verts = self.all_vertices()
            self.vertices = [verts, 0.5 * (verts[pairs[:, 0]] + verts[pairs[:, 1]])]
            self.n_vertices += len(pairs)
        return ids[inverse].reshape(-1, 3)

    def all_vertices(self) -> np.ndarray:
        if len(self.vertices) > 1:
            self.vertices = [np.concatenate(self.vertices)]
        return self.vertices[0]

    def leaves(self) -> np.ndarray:
        """Elements without children, in id order."""
        n = self.size
        return np.flatnonzero(~self.cluster[:n] & (self.first_child[:n] < 0))

    def elements_by_level(self) -> list[np.ndarray]:
        """Element ids grouped by level below their input triangle (0 first)."""
        el = np.flatnonzero(~self.cluster[:self.size])
        lv = self.level[el]
        return [el[lv == k] for k in range(int(lv.max()) + 1)] if len(el) else []
