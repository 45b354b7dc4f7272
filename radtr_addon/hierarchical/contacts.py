"""Surfaces with another close in front of part of them: a wall behind a cabinet, the floor
under a table, a ceiling over a lamp hung 1 cm below it.

The light reaching such a part is not what the rest of the surface gets, and a link's few
receiver points on a large element do not see it (ten points on a 5 m wall miss the strip
behind a sofa 5 cm away): many links, each within epsilon, leak light there together. So
for each input triangle the distance h to the first surface along its normal is taken at
the centroids of a grid of cells that are the element tree's own (4^g cells in the order
of ``Nodes.split``'s children, g up to the tree's depth, finer on larger triangles); h is 0
where that surface shows its back (the cell is under a box, however tall), unless it is one
side of a two-sided face (``coincident.twins``: a two-sided lamp under a ceiling shows the
ceiling its upper side; taken for a box's back, it hid the hot ceiling over it). An
element is *mixed* when among the cells it covers some have a surface near in front
(``NEAR_SHARE``) and some do not; every link into a mixed element is refined at the
receiver, down to elements wholly in the gap or wholly out of it (or the deepest level).

As a source, an element sends the light of its open part to the room and that of its
covered part (cells under a surface's back: the floor under a box) only to what covers it:
the floor around a box's footprint lights the box's sides with the floor's open radiosity,
not with a mean that counts the dark floor under the box. Gaps that stay open at their
edges (a ceiling 1 cm over a lamp, a wall behind a sofa) keep their mean: their light
leaks out sideways; a link that sees such a mixed source only in part is refined at the
source (``HierarchicalRadiosity._leaks``), so the hot ceiling over a lamp is not sent past
the lamp's edge as part of its element's mean. ``gap_share`` gives each leaf's share of
covered cells, ``in_gap`` which receivers lie on a source's covered part, ``open_points``
which points of a leaf are open (the final gather takes a floor's light there).
"""
from __future__ import annotations

import numpy as np

from ..formfactors.coincident import twins
from .quadratic import _CHILDREN

#: Grid cells about this fraction of the scene's diagonal across (radius), at most.
CELL_FRACTION = 1 / 200
#: A cell is near a surface in front when that surface is closer than the element's radius
#: and than this share of the farthest any of the element's cells sees (in a room 2.4 m high
#: a floor triangle 2.8 m across has the ceiling "near"; the floor under a box is nearer).
NEAR_SHARE = 0.5
#: Points per side of the grid on which ``open_points`` tests a leaf (16 points).
OPEN_GRID = 4


def cell_levels(radius: np.ndarray, diagonal: float) -> np.ndarray:
    """Cell levels (m,) whose cells, on elements of ``radius``, are about ``CELL_FRACTION`` of
    the scene's ``diagonal`` across (at least level 0)."""
    return np.ceil(np.log2(np.maximum(radius / (CELL_FRACTION * diagonal), 1.0))).astype(int)


def cell_centroids(g: int) -> np.ndarray:
    """Barycentric centroids (4^g, 3) of the level-g cells, cell p's children at 4p .. 4p + 3."""
    corners = np.eye(3)[None]                                  # (cells, 3 corners, 3)
    maps = np.array([np.array(c) for c in _CHILDREN])          # (4, 3, 3) child corners in parent bary
    for _ in range(g):
        corners = np.einsum("sij,pjk->psik", maps, corners).reshape(-1, 3, 3)
    return corners.mean(axis=1)


def near(h: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Which cells (m, c) of elements of ``radius`` (m,) have a surface near in front: closer
    than the radius and than ``NEAR_SHARE`` of the farthest of the element's cells, or
    showing its back (h 0)."""
    return (h == 0) | (h < np.minimum(radius[:, None], NEAR_SHARE * h.max(axis=1, keepdims=True)))


class Proximity:
    """Per input triangle, h at its grid cells; ``mixed(ids)`` for nodes (see module). A
    cluster is mixed when any of its triangles has a cell near a surface: it hands light to
    its triangles by their cosines alone, so the part of a wall behind a panel would get it.
    ``twin``: each input triangle's coincident back-to-back twin (-1 for none)."""

    def __init__(self, nodes, caster, max_level: int):
        s = nodes.scene
        self.nodes, self.caster = nodes, caster
        r0 = nodes.radius[nodes.element_root]
        self.g = np.minimum(cell_levels(r0, nodes.diagonal), max_level)
        self.offset = np.concatenate([[0], np.cumsum(4 ** self.g)])
        self.h = np.empty(self.offset[-1])
        tri = s.vertices[s.triangles]
        self.twin = twins(s.vertices, s.triangles, s.normals)     # the final gather reads it too
        for g in np.unique(self.g):
            ts = np.flatnonzero(self.g == g)
            pts = np.einsum("pk,tkc->tpc", cell_centroids(int(g)), tri[ts])
            n = np.repeat(s.normals[ts], 4 ** g, axis=0)
            h, back = self._normal_hits(pts.reshape(-1, 3), n)
            self.h[(self.offset[ts][:, None] + np.arange(4 ** g)).ravel()] = np.where(back, 0.0, h)
        self.gap = self.h == 0                              # per cell: covered (a surface's back on it)
        self.covered = np.add.reduceat(self.gap, self.offset[:-1]) > 0      # per input triangle
        self.tolerance = 10 * caster.epsilon
        touched = np.zeros(nodes.size, bool)
        for g in np.unique(self.g):
            ts = np.flatnonzero(self.g == g)
            h = self.h[self.offset[ts][:, None] + np.arange(4 ** g)]
            node = nodes.parent[nodes.element_root[ts[near(h, r0[ts]).any(axis=1)]]]
            while len(node):
                touched[node] = True
                node = np.unique(nodes.parent[node])
                node = node[node >= 0]
        self._known = np.where(touched, 2, 0).astype(np.int8)     # per node: 0 unknown, 1 no, 2 mixed

    def _normal_hits(self, points: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance (k,) to the first surface along each normal ``n`` from ``points``, and
        whether it shows its back there (one side of a two-sided face does not: see module)."""
        caster, normals = self.caster, self.nodes.scene.normals
        h, hit = caster.first_hit(points + caster.epsilon * n, n)
        hit_ = np.maximum(hit, 0)
        return h, (hit >= 0) & (np.einsum("kc,kc->k", normals[hit_], n) > 0) & (self.twin[hit_] < 0)

    def open_points(self, leaves: np.ndarray, side: int = OPEN_GRID) -> tuple[np.ndarray, np.ndarray]:
        """Points (m, side^2, 3) stratified on each leaf and whether each is open, not under a
        surface's back (all are on input triangles with no covered cell)."""
        from ..sampling import stratified, triangle_points

        nd = self.nodes
        u, v = stratified(side)
        points = triangle_points(nd.tri[leaves][:, None], u, v)
        is_open = np.ones(points.shape[:2], bool)
        some = np.flatnonzero(self.covered[nd.root[leaves]])
        if len(some):
            n = np.repeat(nd.normal[leaves[some]], side * side, axis=0)
            is_open[some] = ~self._normal_hits(points[some].reshape(-1, 3), n)[1].reshape(len(some), -1)
        return points, is_open

    def gap_share(self, elements: np.ndarray) -> np.ndarray:
        """Share (m,) of each element's cells that are covered (an element finer than the
        cells takes its cell's)."""
        nd = self.nodes
        t, lv = nd.root[elements], nd.level[elements]
        k = self.g[t] - lv
        out = np.empty(len(elements))
        fine = k <= 0
        out[fine] = self.gap[self.offset[t[fine]] + (nd.path[elements[fine]] >> (2 * -k[fine]))]
        for depth in np.unique(k[~fine]):
            sel = np.flatnonzero(k == depth)
            first = self.offset[t[sel]] + nd.path[elements[sel]] * 4 ** depth
            out[sel] = self.gap[first[:, None] + np.arange(4 ** depth)].mean(axis=1)
        return out

    def in_gap(self, src: np.ndarray, rcv: np.ndarray) -> np.ndarray:
        """Whether each receiver's centre lies on its element source's plane where that has
        covered cells (a box's bottom on the floor under it)."""
        nd = self.nodes
        out = self.covered[nd.root[src]]
        i = np.flatnonzero(out)                         # few: only sources with covered cells
        s, r = src[i], rcv[i]
        out[i] = np.einsum("ij,ij->i", nd.center[r] - nd.center[s], nd.normal[s]) <= self.tolerance
        return out

    def mixed(self, ids: np.ndarray) -> np.ndarray:
        """Whether each node of ``ids`` is mixed (an element, or a cluster: see the class)."""
        nd = self.nodes
        if len(self._known) < nd.size:
            self._known = np.concatenate([self._known, np.zeros(nd.size - len(self._known), np.int8)])
        todo = np.unique(ids[self._known[ids] == 0])
        if len(todo):
            out = np.ones(len(todo), np.int8)
            el = ~nd.cluster[todo]
            t, lv = nd.root[todo], nd.level[todo]
            k = np.where(el, self.g[t] - lv, 0)                  # cell levels below the element
            for depth in np.unique(k[k > 0]):
                sel = np.flatnonzero(k == depth)
                e = todo[sel]
                first = self.offset[nd.root[e]] + nd.path[e] * 4 ** depth
                close = near(self.h[first[:, None] + np.arange(4 ** depth)], nd.radius[e])
                out[sel] = np.where(close.any(axis=1) & ~close.all(axis=1), 2, 1)
            self._known[todo] = out
        return self._known[ids] == 2
