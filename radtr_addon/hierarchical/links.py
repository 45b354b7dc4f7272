"""Links between nodes: how much light each carries, how wrong that may be, and refinement.

A link S -> R says: R gathers the light of S at this level of both trees. Its transfer:

- element to element: the irradiance of R per unit radiosity of S, a quadratic over R
  (``quadratic``) through F(x -> S) V(x, S) at its six nodes x: the closed-form (Lambert contour)
  form factor from the point to the polygon S, clipped at the point's horizon, times the
  fraction of ``VISIBILITY_RAYS`` shadow rays from x to stratified, seeded points on S that
  arrive. Exact for the source's extent however near it is, so near-field links need refine
  only for how the light varies over R. The unoccluded quadratic is the least-squares fit
  to F at those ten points and at a 12-point degree-6 rule's (``quadratic.fitted``), with
  the rule's mean over R: through the six nodes alone it could not follow a steep rise of
  F towards R's edge (the perpendicular walls of an empty room took 6-18% too little of
  each other's light), and scaled to the rule's mean it was right on R but not on R's
  parts, where a coarse receiver's many links summed their errors (a closed room's leaves
  gathered 0.93-1.03 of its light at the 1st and 99th percentiles, 0.97-1.04 fitted).
- with a cluster at either end: between the ends' centres along w, at distance d, the source
  sending its projected area A_proj(w) times its radiosity, the receiver taking cos per
  element (a cluster receiver hands the light to its triangles, ``solve``), through the
  point-to-disc kernel 1 / (pi d^2 + A_proj(w)): a point's form factor to a disc of that
  area facing it, where 1 / (pi d^2) would count a source of the receiver's size at twice its
  radius 25% too bright (and such links, each within epsilon, are many: a closed room lost
  or gained 3-4% of its light through them); visibility by rays between random points of
  the two ends' triangles, weighted by the point-to-point kernel cos cos / d^2, cast
  afresh once the link is kept.

Error estimate of a link (W/m^2 at R, worst channel), against epsilon x the scene's mean
emitted exitance: element pairs rho_R (B_S e + (B_S max - B_S min) F), e the miss of the
quadratic at R's check points (or a quarter of F's spread over R, or how far its mean was
from the degree-6 rule's, if more; or the unoccluded F where any shadow ray was blocked: a
shadow boundary may cross R); cluster links rho_R B_S (F x the ends' angular size seen
across the link + the unoccluded F where any ray was blocked; with the visibility first
cast, ``Links.judged``); near cluster links (the ends' spheres overlap, or one straddles
an element's plane: the kernel does not hold) all the light S could bring, rho_R sum(B A) over S /
(pi gap^2), ``Evaluator.gap``. A link from a source with a surface close in front of part
of it that is seen only in part (``vis`` below 1) is refined at the source where the
spread of its B matters (``solve``). A link over the bound is replaced by the links of the children of its larger
end; a link whose ends cannot split further is kept.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import compiled
from ..formfactors.closed_form import polygon_factor
from ..formfactors.raycast import clear_rays
from ..sampling import strata, triangle_points
from . import quadratic
from .nodes import DIRECTIONS, Nodes, direction_weights

#: Barycentric points on a receiving element where its form factor is evaluated (``quadratic``).
RECEIVER_POINTS = quadratic.POINTS
#: Share of F's spread over the receiver counted as error even where the quadratic fits the
#: check points (a peak near an edge falls between them).
SPREAD_SHARE = 0.25
#: Shadow rays per receiver point (element links) and per cluster link.
VISIBILITY_RAYS = 4
#: Relative error of a cluster end's projected area read between the three table directions
#: around the link's (faces about 30 degrees wide), counted in every cluster link's error estimate.
DIRECTION_ERROR = 1.0
#: Point pairs per link with a cluster end (visibility between random points of the ends).
CLUSTER_RAYS = 16
#: Links evaluated per numpy batch (bounds the temporary memory).
BATCH = 20_000
#: Links whose ends hold at most this many triangle pairs are first tested pair by pair for
#: whether any two of their triangles face each other (``Evaluator.facing``), alike in the
#: compiled form (which stops at the first facing pair) and numpy's, so that both keep the
#: same links.
FACING_PAIRS = 4096
#: Triangle pairs numpy's form of ``facing`` holds at once (about 300 bytes each).
FACING_CHUNK = 250_000


@dataclass
class Links:
    """Accepted links (arrays of equal length): ends, transfer coefficient and what the error needs."""

    src: np.ndarray
    rcv: np.ndarray
    coef: np.ndarray       # (L, 6) transfer per unit source term at the receiver's nodes
    spread: np.ndarray     # element pairs: the quadratic's miss (``Evaluator._elements``); cluster links: angular size
    occluded: np.ndarray   # unoccluded mean transfer where visibility is not complete, else 0
    d: np.ndarray          # (L, 3) table directions around the direction of travel S -> R
    dw: np.ndarray         # (L, 3) their weights (``nodes.direction_weights``)
    vis: np.ndarray        # visible share of the transfer (F-weighted over R's points; cluster links: V)
    near: np.ndarray       # a cluster link between ends too close for its kernel: spread is 1 / (pi gap^2)
    judged: np.ndarray     # the visible share its error is estimated with: a kept cluster link's
    #                        ``vis`` is cast afresh (``Evaluator.see``), so what carries its light
    #                        is not what chose to keep it

    FIELDS = ("src", "rcv", "coef", "spread", "occluded", "d", "dw", "vis", "near", "judged")

    @classmethod
    def empty(cls) -> "Links":
        z = np.zeros(0)
        return cls(z.astype(np.int64), z.astype(np.int64), np.zeros((0, 6)), z, z, np.zeros((0, 3), np.int64),
                   np.zeros((0, 3)), z, z.astype(bool), z)

    def unoccluded(self, i: np.ndarray) -> np.ndarray:
        """The unoccluded transfer of cluster links ``i`` (the coefficient without visibility)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.judged[i] < 1, self.occluded[i],
                            np.where(self.vis[i] > 0, self.coef[i, 0] / self.vis[i], 0.0))

    @property
    def mean(self) -> np.ndarray:
        """The transfer averaged over the receiver."""
        return self.coef @ quadratic.MEAN

    def __len__(self):
        return len(self.src)

    def take(self, keep: np.ndarray) -> "Links":
        return Links(*(getattr(self, f)[keep] for f in Links.FIELDS))

    @staticmethod
    def concat(parts: list["Links"]) -> "Links":
        parts = [p for p in parts if len(p)] or [Links.empty()]
        return Links(*(np.concatenate([getattr(p, f) for p in parts]) for f in Links.FIELDS))


class Evaluator:
    """Evaluates candidate links of one ``Nodes`` tree with an Embree ``caster`` for visibility."""

    def __init__(self, nodes: Nodes, caster, seed: int = 0):
        self.nodes, self.caster = nodes, caster
        self.rng = np.random.default_rng(seed)
        s = nodes.scene
        self.cum_area = np.cumsum(s.areas[nodes.order])    # members by area, in cluster-tree order
        self.centroids = s.centroids
        self.corners = s.vertices[s.triangles]             # (n, 3, 3) input triangles' corners
        self.span = self._spans()

    def _spans(self) -> np.ndarray:
        """(nodes, 2) range of each cluster-tree node's triangles in ``nodes.order``."""
        nd = self.nodes
        pos = np.empty(nd.scene.n, np.int64)
        pos[nd.order] = np.arange(nd.scene.n)
        span = np.zeros((nd.size, 2), np.int64)
        span[:, 0] = np.iinfo(np.int64).max
        node, t = nd.parent[nd.element_root].copy(), np.arange(nd.scene.n)
        span[nd.element_root, 0], span[nd.element_root, 1] = pos, pos + 1
        while len(t):
            np.minimum.at(span[:, 0], node, pos[t])
            np.maximum.at(span[:, 1], node, pos[t] + 1)
            node = nd.parent[node]
            keep = node >= 0
            node, t = node[keep], t[keep]
        return span

    def evaluate(self, src: np.ndarray, rcv: np.ndarray) -> Links:
        """Links for the pairs (src, rcv) that carry any light (the rest are dropped)."""
        out = []
        for lo in range(0, len(src), BATCH):
            s, r = src[lo:lo + BATCH], rcv[lo:lo + BATCH]
            keep = self.facing(s, r)
            s, r = s[keep], r[keep]
            both = ~self.nodes.cluster[s] & ~self.nodes.cluster[r]
            out.append(self._elements(s[both], r[both]))
            out.append(self._clusters(s[~both], r[~both]))
        return Links.concat(out)

    def size(self, ends: np.ndarray) -> np.ndarray:
        """Input triangles (L,) under each end (1 for an element)."""
        out = np.ones(len(ends), np.int64)
        cl = self.nodes.cluster[ends]
        out[cl] = np.diff(self.span[ends[cl]], axis=1)[:, 0]
        return out

    def _members(self, ends: np.ndarray, count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each end's ``count`` (``size``) triangles, end after end: corners (m, 3, 3) and
        normals (m, 3); an element is its own triangle, a cluster its input triangles."""
        nd, sc = self.nodes, self.nodes.scene
        cl = nd.cluster[ends]
        lo = np.zeros(len(ends), np.int64)
        lo[cl] = self.span[ends[cl], 0]
        pos, at = ranges(lo, count)
        c = cl[pos]
        tri, normal = nd.tri[ends[pos]], nd.normal[ends[pos]]
        t = nd.order[at[c]]
        tri[c], normal[c] = self.corners[t], sc.normals[t]
        return tri, normal

    def facing(self, s: np.ndarray, r: np.ndarray) -> np.ndarray:
        """False for links that carry no light for certain: every pair of their triangles has
        one wholly behind (or in) the other's plane (neighbours on a floor, round a column,
        on the two faces of a slab; about four in five of the atrium's triangle pairs whose
        bounding spheres overlap). Tested only where the ends hold at most ``FACING_PAIRS``
        triangle pairs (a fifth of the atrium's near cluster links of 17-4,096 pairs turned
        out to face away, and each such link had been split down to 16 pairs first); True
        for the rest."""
        out = np.ones(len(s), bool)
        cs, cr = self.size(s), self.size(r)
        nd, tol = self.nodes, self.caster.epsilon
        small = np.flatnonzero(cs * cr <= FACING_PAIRS)
        kernel = compiled.kernel("facing")
        if kernel is not None and len(small):
            out[small] = kernel(s[small], r[small], nd.cluster, self.span, nd.order, nd.tri, nd.normal,
                                self.corners, nd.scene.normals, nd.lo, nd.hi, tol)
            return out
        for first, last in batches(cs[small] * cr[small], FACING_CHUNK):
            part = small[first:last]
            out[part] = self._facing_pairs(s[part], r[part], cs[part], cr[part])
        return out

    def _facing_pairs(self, s: np.ndarray, r: np.ndarray, cs: np.ndarray, cr: np.ndarray) -> np.ndarray:
        """Numpy's form of ``compiled.kernels.facing`` for links (s, r) whose ends hold cs and cr
        triangles: every pair of their triangles at once."""
        tol = self.caster.epsilon
        ts, ns = self._members(s, cs)
        tr, nr = self._members(r, cr)
        link, k = ranges(np.zeros(len(s), np.int64), cs * cr)
        i = (np.cumsum(cs) - cs)[link] + k // cr[link]
        j = (np.cumsum(cr) - cr)[link] + k % cr[link]
        a = np.einsum("mc,mkc->mk", ns[i], tr[j] - ts[i, :1]).max(axis=1) > tol
        b = np.einsum("mc,mkc->mk", nr[j], ts[i] - tr[j, :1]).max(axis=1) > tol
        return np.bincount(link, weights=a & b, minlength=len(s)) > 0

    def _elements(self, s: np.ndarray, r: np.ndarray) -> Links:
        nd = self.nodes
        keep = s != r
        s, r = s[keep], r[keep]
        if not len(s):
            return Links.empty()
        tri_s, tri_r, n_r = nd.tri[s], nd.tri[r], nd.normal[r]
        points = np.vstack([RECEIVER_POINTS, quadratic.RULE_POINTS])
        x = np.einsum("pk,lkc->lpc", points, tri_r) + self.caster.epsilon * n_r[:, None]
        F0 = polygon_factor(x, n_r, tri_s)                                  # (L, P) unoccluded
        # the quadratic nearest F at all the points, with the mean over R by a degree-6 rule;
        # its worst miss there refines the link. Where the rule's points see nothing of S (a
        # sliver of R in front of it) the six nodes' values are kept and the difference
        # from the rule's mean refines the link
        k = len(RECEIVER_POINTS)
        mean_q = F0[:, k:] @ quadratic.RULE_WEIGHTS
        fit = quadratic.fitted(F0, mean_q)
        resid = np.abs(F0 - fit @ quadratic.AT_FIT.T).max(axis=1)
        x, exact = x[:, :k], F0[:, :k]
        seen = exact > 0
        mean0 = exact[:, :6] @ quadratic.MEAN
        some = mean_q > 0
        F0 = exact.copy()
        F0[some, :6] = fit[some]
        V = self._visible_from_points(x, n_r, tri_s, nd.normal[s], seen)
        F = F0 * V
        miss = np.abs(F[:, 6:] - F[:, :6] @ quadratic.AT_CHECK.T).max(axis=1)
        miss = np.maximum(miss, SPREAD_SHARE * (F.max(axis=1) - F.min(axis=1)))
        miss = np.maximum(miss, np.where(some, resid, np.abs(mean0 - mean_q)))
        # a shadow boundary may cross R (or every ray was blocked and the samples missed where
        # S shows): the unoccluded F bounds the light at stake
        occluded = np.where(((V < 1) & seen).any(axis=1), F0[:, :6] @ quadratic.MEAN, 0.0)
        vis = (exact * V).sum(axis=1) / np.maximum(exact.sum(axis=1), 1e-300)
        links = Links(s, r, F[:, :6], miss, occluded, *self._direction(s, r), vis, np.zeros(len(s), bool), vis)
        return links.take(seen.any(axis=1))

    def _visible_from_points(self, x: np.ndarray, n_r: np.ndarray, tri_s: np.ndarray, n_s: np.ndarray,
                             need: np.ndarray) -> np.ndarray:
        """Visible fraction (L, P) of S from points x (L, P, 3) facing ``n_r``: shadow rays to
        random points on S, each weighted by the cosines at both ends, so the part of S
        behind x's horizon (already clipped from F) does not count as shadow."""
        L, P = need.shape
        V = np.zeros((L, P))
        li, pi = np.nonzero(need)
        if not len(li):
            return V
        m = VISIBILITY_RAYS
        u = strata(m, self.rng.random((len(li), m)))                         # stratified in u
        v = self.rng.random((len(li), m))
        kernel = compiled.kernel("shadow_rays") or shadow_rays
        origin, direction, length, w = kernel(x[li, pi], n_r[li], tri_s[li], n_s[li], u, v, self.caster.epsilon)
        ki, mi = np.nonzero(w > 0)
        ok = np.zeros(w.shape)
        ok[ki, mi] = self.caster.reaches(origin[ki, mi], direction[ki, mi], length[ki, mi])
        total = w.sum(axis=1)
        V[li, pi] = np.where(total > 0, (w * ok).sum(axis=1) / np.maximum(total, 1e-300), 1.0)
        return V

    def _direction(self, s, r) -> tuple[np.ndarray, np.ndarray]:
        w = self.nodes.center[r] - self.nodes.center[s]
        return direction_weights(w / np.maximum(np.linalg.norm(w, axis=1, keepdims=True), 1e-300))

    def _clusters(self, s: np.ndarray, r: np.ndarray) -> Links:
        nd = self.nodes
        if not len(s):
            return Links.empty()
        w = nd.center[r] - nd.center[s]
        dist = np.linalg.norm(w, axis=1)
        w = w / np.maximum(dist, 1e-300)[:, None]
        reach = nd.radius[s] + nd.radius[r]
        geo = np.ones(len(s))
        es, er = ~nd.cluster[s], ~nd.cluster[r]
        geo[es] *= nd.area[s[es]] * np.maximum(np.einsum("ij,ij->i", nd.normal[s[es]], w[es]), 0.0)
        geo[er] *= np.maximum(-np.einsum("ij,ij->i", nd.normal[r[er]], w[er]), 0.0)
        # where an element end is: the other end's sphere wholly behind its plane (nothing
        # passes), wholly in front (the centre-to-centre cosine holds), or across it (refine)
        side_s = np.where(es, np.einsum("ij,ij->i", nd.center[r] - nd.tri[s, 0], nd.normal[s]), np.inf)
        side_r = np.where(er, np.einsum("ij,ij->i", nd.center[s] - nd.tri[r, 0], nd.normal[r]), np.inf)
        behind = (side_s < -nd.radius[r]) | (side_r < -nd.radius[s])
        clear = (side_s > nd.radius[r]) & (side_r > nd.radius[s])
        far = (dist > reach) & clear
        s, r, w, dist, geo, far = (a[~behind] for a in (s, r, w, dist, geo, far))
        V = np.ones(len(s))                       # near or across: cast only if kept (``see``)
        V[far] = self._visible_between(s[far], r[far])
        d, dw = direction_weights(w)
        free = geo / (np.pi * np.maximum(dist ** 2, 1e-300) + self._shown_area(s, w, d, dw))
        with np.errstate(divide="ignore"):
            bound = 1.0 / (np.pi * self.gap(s, r) ** 2)                   # inf where the boxes touch
        spread = np.where(far, (nd.radius[s] + nd.radius[r]) / np.maximum(dist, 1e-300) + DIRECTION_ERROR, bound)
        return Links(s, r, np.repeat((V * free)[:, None], 6, axis=1), spread, np.where(V < 1, free, 0.0),
                     d, dw, V, ~far, V)

    def gap(self, s: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Distance (L,) between the ends' bounding boxes (0 where they overlap): no point of
        one is nearer the other, so 1 / (pi gap^2) bounds the irradiance a point of R gets per
        unit power / pi that S sends, however S and R lie (``HierarchicalRadiosity.errors``)."""
        nd = self.nodes
        apart = np.maximum(np.maximum(nd.lo[r] - nd.hi[s], nd.lo[s] - nd.hi[r]), 0.0)
        return np.linalg.norm(apart, axis=1)

    def see(self, L: Links, which: np.ndarray):
        """Cast the visibility of the kept cluster links ``which`` of L afresh, in place (its
        transfer's ``vis``; ``judged`` stays). Near links cast none when evaluated (most are
        refined, and their rays would be thrown away); a far link's own rays decide whether
        it is kept (its error grows with V), so with those rays carrying its light too the
        kept links were those whose rays happened to be blocked, and those whose rays all
        were (V = 0) were dropped with their light: a stack of slats lit on its lowest gave
        the floor below 15-20% too little."""
        i = np.flatnonzero(which)
        if len(i):
            V = self._visible_between(L.src[i], L.rcv[i])
            L.coef[i] = (V * L.unoccluded(i))[:, None]
            L.vis[i] = V

    def _shown_area(self, s: np.ndarray, w: np.ndarray, d: np.ndarray, dw: np.ndarray) -> np.ndarray:
        """The area each source shows along w (A max(0, n.w); a cluster's read from its table)."""
        nd = self.nodes
        out = nd.area[s] * np.maximum(np.einsum("ij,ij->i", nd.normal[s], w), 0.0)
        cs = np.flatnonzero(nd.cluster[s])
        out[cs] = np.einsum("cj,cj->c", dw[cs], nd.proj[nd.cluster_row[s[cs]][:, None], d[cs]])
        return out

    def points_on(self, nodes_: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points (L, m, 3) on each node's triangles and their normals, from uniforms u
        (L, m, 3): u[..., 0] picks a cluster's member by area, the rest place the point on
        the triangle (compiled where numba builds: the numpy form's gathers of each point's
        triangle took a sixth of a large scene's solve)."""
        nd, s = self.nodes, self.nodes.scene
        kernel = compiled.kernel("points_on")
        if kernel is not None:
            return kernel(nodes_, nd.cluster, self.span, self.cum_area, nd.order, nd.tri, nd.normal,
                          self.corners, s.normals, u)
        out, normal = np.empty(u.shape), np.empty(u.shape)
        el = ~nd.cluster[nodes_]
        out[el] = triangle_points(nd.tri[nodes_[el]][:, None], u[el, :, 1], u[el, :, 2])
        normal[el] = nd.normal[nodes_[el]][:, None]
        cl = np.flatnonzero(~el)
        if len(cl):
            t = self.member_by_area(nodes_[cl, None], u[cl, :, 0])
            out[cl] = triangle_points(self.corners[t], u[cl, :, 1], u[cl, :, 2])
            normal[cl] = s.normals[t]
        return out, normal

    def member_by_area(self, clusters: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The input triangle of each cluster (any shape) that the uniform ``u`` (same shape)
        picks, each member with the chance of its share of the cluster's area."""
        lo, hi = self.span[clusters, 0], self.span[clusters, 1]
        base = np.where(lo > 0, self.cum_area[np.maximum(lo - 1, 0)], 0.0)
        pick = base + u * (self.cum_area[hi - 1] - base)
        return self.nodes.order[np.minimum(np.searchsorted(self.cum_area, pick, side="right"), hi - 1)]

    def _visible_between(self, s: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Visible fraction (L,) between the two ends: rays between random points of their
        triangles, each pair weighted by the point-to-point kernel cos cos / d^2, so that it
        is the share of the form factor that arrives, as the per-triangle shares of
        ``solve.ClusterMaps`` are (a cluster's faces turned away are accounted for by its
        cosines, not by its own shadow). Weighted by cos cos alone, the parts of a cluster
        nearest the receiver counted too little: a stack of slats lit on its lowest, whose
        upper slats' edges nearest the floor peek past it, gave the floor 6% too little."""
        m, nd = CLUSTER_RAYS, self.nodes
        us, ur = self.rng.random((len(s), m, 3)), self.rng.random((len(r), m, 3))
        kernel = compiled.kernel("pair_rays")
        if kernel is not None:
            origin, direction, length, w = kernel(s, r, us, ur, nd.cluster, self.span, self.cum_area, nd.order,
                                                  nd.tri, nd.normal, self.corners, nd.scene.normals,
                                                  self.caster.epsilon)
        else:
            origin, direction, length, w = self._pair_rays(s, r, us, ur)
        li, mi = np.nonzero(w > 0)
        ok = np.zeros(w.shape)
        ok[li, mi] = self.caster.reaches(origin[li, mi], direction[li, mi], length[li, mi])
        total = w.sum(axis=1)
        return np.where(total > 0, (w * ok).sum(axis=1) / np.maximum(total, 1e-300), 0.0)

    def _pair_rays(self, s: np.ndarray, r: np.ndarray, us: np.ndarray, ur: np.ndarray):
        """Numpy's form of ``compiled.kernels.pair_rays``: the points that uniforms ``us``, ``ur``
        (L, m, 3) place on the ends, their kernel cos cos / d^2 (L, m), and where it is
        positive the ray between them (origins, directions (L, m, 3), lengths (L, m))."""
        a, na = self.points_on(s, us)
        b, nb = self.points_on(r, ur)
        d = b - a
        dist = np.maximum(np.linalg.norm(d, axis=-1), 1e-300)
        d = d / dist[..., None]
        w = np.maximum(np.einsum("lmc,lmc->lm", na, d), 0) * np.maximum(-np.einsum("lmc,lmc->lm", nb, d), 0)
        w /= dist ** 2
        origin, direction, length = np.zeros(a.shape), np.zeros(a.shape), np.zeros(w.shape)
        li, mi = np.nonzero(w > 0)
        origin[li, mi], direction[li, mi], length[li, mi] = clear_rays(a[li, mi], b[li, mi], na[li, mi],
                                                                       nb[li, mi], self.caster.epsilon)
        return origin, direction, length, w


def shadow_rays(x, n_r, tri, n_s, u, v, eps):
    """For each point x (K, 3) facing ``n_r`` and m uniforms (u, v) (K, m): the point on
    triangle ``tri`` (K, 3, 3) facing ``n_s`` that they place (``triangle_points``), the
    product of the cosines at both ends (K, m; 0 where either faces away) and, where it is
    positive, the shadow ray ``EmbreeRays.clear_between`` casts from x to it (``clear_rays``,
    the target lifted towards x): origins, directions (K, m, 3) and lengths (K, m) (numpy's
    form of the compiled ``shadow_rays``)."""
    targets = triangle_points(tri[:, None], u, v)
    d = targets - x[:, None]
    dist = np.linalg.norm(d, axis=-1)
    d = d / np.maximum(dist, 1e-300)[..., None]
    w = np.maximum(np.einsum("kmc,kc->km", d, n_r), 0) * np.maximum(-np.einsum("kmc,kc->km", d, n_s), 0)
    origin, direction, length = np.zeros(targets.shape), np.zeros(targets.shape), np.zeros(w.shape)
    ki, mi = np.nonzero(w > 0)
    origin[ki, mi], direction[ki, mi], length[ki, mi] = clear_rays(x[ki], targets[ki, mi], None, n_s[ki], eps)
    return origin, direction, length, w


def batches(count: np.ndarray, limit: int):
    """(first, last) of runs of consecutive items whose ``count`` sums to at most ``limit``
    (one item alone where its own is more): batches bounding a pass's temporary memory."""
    total = np.cumsum(count)
    first = 0
    while first < len(total):
        base = total[first - 1] if first else 0
        last = max(first + 1, int(np.searchsorted(total, base + limit, side="right")))
        yield first, last
        first = last


def ranges(first: np.ndarray, count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(position, index) pairs for the index ranges first[i] .. first[i] + count[i] - 1."""
    pos = np.repeat(np.arange(len(first)), count)
    offset = np.arange(len(pos)) - np.repeat(np.cumsum(count) - count, count)
    return pos, np.repeat(first, count) + offset


def children(nodes: Nodes, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(parent position, child id) pairs for nodes ``n`` that have children."""
    return ranges(nodes.first_child[n], nodes.n_children[n])


def expand(nodes: Nodes, src: np.ndarray, rcv: np.ndarray, split_src: np.ndarray):
    """The child links replacing links (src, rcv): the children of src where ``split_src``,
    else of rcv; a cluster linked to itself becomes every pair of its children."""
    self_link = src == rcv
    out_s, out_r = [], []
    a = np.flatnonzero(self_link)
    if len(a):
        pos, kid = children(nodes, src[a])
        # all ordered pairs of children of the same parent
        i, j = np.nonzero(pos[:, None] == pos[None, :]) if len(pos) < 4096 else _pairs(pos)
        out_s.append(kid[i])
        out_r.append(kid[j])
    b = np.flatnonzero(~self_link & split_src)
    if len(b):
        pos, kid = children(nodes, src[b])
        out_s.append(kid)
        out_r.append(rcv[b][pos])
    c = np.flatnonzero(~self_link & ~split_src)
    if len(c):
        pos, kid = children(nodes, rcv[c])
        out_s.append(src[c][pos])
        out_r.append(kid)
    if not out_s:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(out_s), np.concatenate(out_r)


def _pairs(pos: np.ndarray):
    """Index pairs (i, j) with pos[i] == pos[j], for sorted groups of ``pos``."""
    starts = np.flatnonzero(np.r_[True, pos[1:] != pos[:-1]])
    sizes = np.diff(np.r_[starts, len(pos)])
    i = np.concatenate([np.repeat(np.arange(st, st + k), k) for st, k in zip(starts, sizes)])
    j = np.concatenate([np.tile(np.arange(st, st + k), k) for st, k in zip(starts, sizes)])
    return i, j


def direction_cosines(normals: np.ndarray) -> np.ndarray:
    """max(0, -n . w_d) (m, directions): how much light travelling along each table direction
    an element facing ``normals`` receives, per unit irradiance normal to that direction."""
    return np.maximum(-normals @ DIRECTIONS.T, 0.0)
