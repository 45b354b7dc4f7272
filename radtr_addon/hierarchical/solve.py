"""Refine-solve rounds of hierarchical radiosity, push-pull gathering and the result.

One round: refine every link whose error estimate (``links``) is over epsilon x the emitted
power, with the radiosity of the last solve (E at first), and every link into a receiver with
another surface close in front of part of it (``contacts``); refine the elements over which an
outside light (Light objects, the World) varies by more than that too; then solve by Jacobi
sweeps over the links with push-pull: pull the radiosity up the trees (an element's is the
area mean of its leaves, a cluster's the light it sends along each table direction), gather
along every link into its receiver, push the irradiance down to the leaves (to a cluster's
elements by their cosine to each direction) and set B = E + rho H there. Rounds end when no
link needs refining.

Bound: every link kept carries at most epsilon x emitted power of error (or cannot split any
more), and each element's gathered light goes through its own links once per bounce, so the
error of the light reflected once is at most (links into an element) x epsilon; over all
bounces the power-weighted error of B is at most epsilon x emitted x links / (1 - rho_max).
In practice the estimate is loose by orders: tests measure the error against a fine uniform
direct solve (``tests/test_hierarchical.py``).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .. import compiled
from ..errors import Cancelled, SceneError
from ..formfactors.closed_form import polygon_factor
from ..reconstruct import INSET
from ..scene import PatchScene, triangle_geometry
from ..solvers.result import SolveResult
from ..textures import barycentric
from . import quadratic
from .contacts import Proximity, cell_centroids
from .links import Evaluator, Links, batches, direction_cosines, expand, ranges
from .nodes import DIRECTIONS, Nodes

#: Links held at most (about 100 bytes each), refused beyond with advice.
MAX_LINKS = 20_000_000
#: Clusters of at most this many input triangles send and take light by each triangle's own
#: cosine to a link's direction (``ClusterMaps``); larger ones by the direction table.
EXACT_CLUSTER = 256
#: (link, triangle) entries of ``ClusterMaps`` made per batch (bounds the temporary memory).
MAP_BATCH = 1_000_000
#: Links between two clusters holding at most this many triangle pairs share their light by
#: each pair's closed form (``_paired_shares``), not by one direction and distance for all.
PAIRED = 256
#: The same for links with an element end (a cluster of at most this many triangles; larger
#: ones take each triangle's closed form at one point, ``_member_shares``).
PAIRED_ELEMENT = 64
#: Barycentric points where a pair's closed form is taken on its receiving triangle (the
#: centroids of its cells two levels down)...
PAIR_POINTS = cell_centroids(2)
#: ... or at its centroid alone, where the two triangles' centroids are over this many times
#: the sum of their reaches (centroid to farthest corner) apart.
PAIR_FAR = 2.0
#: Triangle pairs numpy's form of ``_pair_sums`` takes at a time (bounds its memory).
PAIR_BATCH = 100_000
#: Fraction of the way from a result vertex to its leaves' centroids where its light is taken.
#: On a box's side at the floor the gather point sees the floor's leaves along the footprint
#: (``_open_light``) over a span that grows with the inset: at 1% (0.1 mm up) a few leaves'
#: noise came through as thin spikes up the side. Concave room edges pay for a large one,
#: their points moved into the brighter inside (Cycles bakes the edge itself): on the Cornell
#: box at Quality 0.1 the ceiling's area mean was +5.2% at 10%, +2.7% at 3%, +1.8% at 1%; the
#: furnished room's box sides within 2 cm of the floor 7-16% RMS at 10%, 7-17% at 3%.
CORNER_INSET = 0.03
#: Epsilons (at most ``reconstruct.INSET`` of the way) towards its leaf's centre that a final
#: gather's hit point moves before its shadow rays to the Light objects: off a seam, where a
#: ray lifted off the floor could start behind the wall it meets.
SEAM_STEP = 4.0
#: Most a gather ray's light may stand over its leaf's mean by the leaf's quadratic (``light_shape``).
SHAPE_MAX = 4.0
#: Cosine rays per leaf that ``_open_light`` casts on a floor a box rests on (4 a point).
CONTACT_RAYS = 64
#: Shadow rays per (result vertex, emitting triangle): a stratified grid on the emitter.
CORNER_RAYS = 16
#: Rays of the final gather cast per batch (``_gather_steps``): bounds its memory to a few
#: hundred MB whatever the rays per vertex (4,096 vertices a batch at 256 rays).
GATHER_BATCH_RAYS = 1 << 20
#: From this many final-gather rays a vertex on, a pilot of ``GATHER_PILOT`` rays a vertex
#: measures each vertex's noise and the rest of the rays go where it is (``gather_sides``).
GATHER_ADAPTIVE = 128
GATHER_PILOT = 16
#: Least and most rays a vertex gets in an adaptive final gather, as multiples of the mean. A
#: pilot may see no spread where a few rays would (17% of the points of a furnished test room):
#: with a quarter the least, the worst 1% of its lit corners were 12% off (6.7% gathered
#: evenly), with a half 10%; on the Cornell box the errors are the same either way.
GATHER_SPREAD = (0.5, 16.0)
#: Leaves whose reflected radiosity is over this many times the area mean are hot (the ceiling
#: over a lamp hung just under it: 4,600 leaves, 0.75 m^2, 60% of a furnished room's reflected
#: power): the final gather samples them as lights too (``_hot_light``), as well as by its
#: cosine rays, which find them seldom and then as specks (that room's worst tenth of corners
#: at 256 rays: over 43% off a 4,096-ray gather with cosine rays alone, over 26% with both).
HOT_FACTOR = 10.0
#: Shadow rays to hot leaves per result vertex, for each gather ray so many.
HOT_SHARE = 1 / 8
#: Least reflectance a link's error is weighed by: an error of the light a receiver takes
#: changes its B by rho times it, and the power books (absorbed) by the rest, so a black
#: receiver's links are held to the bound too (an up-facing lamp 30 cm under a ceiling: 15%
#: of the emitted light was in no book, its hot ceiling's coarse links into the lamp unrefined).
BOOKS_RHO = 0.1
#: Share of epsilon that a partly seen source's spread may bring its link (``_leaks``).
LEAK_SHARE = 0.1
#: Candidate links evaluated per slice of a refine (``refine``).
REFINE_CHUNK = 500_000
#: Elements split (and their outside light sampled) per slice of ``refine_lights``.
LIGHT_CHUNK = 20_000


@dataclass
class HierarchicalSettings:
    """The knobs: ``epsilon`` (Quality) trades time for error; the rest bound the work."""

    epsilon: float = 0.1           # link error bound / the scene's mean emitted exitance
    max_level: int = 8             # element splits below an input triangle
    min_area: float = 1e-6         # smallest element, as a fraction of the scene's area
    tolerance: float = 1e-4        # Jacobi stop: residual power / emitted
    max_rounds: int = 8
    max_sweeps: int = 400          # Jacobi sweeps per round (Max Iterations)
    gather_rays: int = 0           # final gather at the result vertices once solved (0: leaf quadratics)
    seed: int = 0


@dataclass
class ClusterMaps:
    """Links with a small cluster end (at most ``EXACT_CLUSTER`` input triangles), summed over
    its triangles instead of read from the direction table: a table read between directions
    18 degrees apart sees a face head-on as cos 18 = 0.95 of itself, once at each end, and a
    closed room lost 4% of its light through cluster links. ``S`` (sending links x input
    triangles): A max(0, n.w) along each link ``send``; ``R`` (input triangles x taking
    links, held transposed): max(0, -n.w), how much of each link ``take`` a triangle of its
    receiver gets.
    Between a small cluster and an element, each triangle goes by its own closed form
    (``closed_form.polygon_factor``: from the element's centre to the triangle, or from the
    triangle's centroid to the element), scaled to undo the link's one-disc kernel: as one
    disc at the centres' distance, the boxes of a closed room sent 5.8% of their light
    nowhere (3.3% so; 0.5% with element links alone). A partly visible link's entries are
    shared out by a shadow ray each (``_member_visibility``)."""

    links: Links
    blocks: list           # per round's new links: (send, S, take, RT); -1 for a link since refined

    @classmethod
    def of(cls, evaluator, L: Links) -> "ClusterMaps":
        nodes = evaluator.nodes
        w = nodes.center[L.rcv] - nodes.center[L.src]
        dist = np.linalg.norm(w, axis=1)
        w /= np.maximum(dist, 1e-300)[:, None]
        n = nodes.scene.n
        # the link's kernel is V geo / (pi d^2 + A_proj): an entry by a closed form undoes it
        geo = np.maximum(-np.einsum("ij,ij->i", nodes.normal[L.rcv], w), 0.0)
        disc = np.pi * dist ** 2 + evaluator._shown_area(L.src, w, L.d, L.dw)
        sent, taken = _paired_shares(evaluator, L)
        send, (link, t, v) = _member_entries(evaluator, L, w, True, disc / np.maximum(geo, 1e-300) * (geo > 0),
                                             sent)
        S = _by_rows(link, t, v, (len(send), n))
        shown = nodes.area[L.src] * np.maximum(np.einsum("ij,ij->i", nodes.normal[L.src], w), 0.0)
        take, (link, t, v) = _member_entries(evaluator, L, w, False,
                                             (np.pi * dist ** 2 + shown) / np.maximum(shown, 1e-300) * (shown > 0),
                                             taken)
        RT = _by_rows(link, t, v, (len(take), n))
        return cls(L, [(send, S, take, RT)])

    def extended(self, evaluator, keep: np.ndarray, new: Links, links: Links) -> "ClusterMaps":
        """The maps of ``links`` = the links of these maps where ``keep``, then ``new``: the
        kept rows stay where they are, their links renumbered (a large scene's later rounds
        refine a few links of millions, and restacking its maps took 13 s a round); a block
        is compacted once most of its rows are of links since refined."""
        at = np.where(keep, np.cumsum(keep) - 1, -1)               # where a kept link lands
        blocks = []
        for send, S, take, RT in self.blocks:
            send, take = np.where(send >= 0, at[send], -1), np.where(take >= 0, at[take], -1)
            if 2 * (send >= 0).sum() < len(send) or 2 * (take >= 0).sum() < len(take):
                ks, kt = send >= 0, take >= 0
                send, S, take, RT = send[ks], S[ks], take[kt], RT[kt]
            blocks.append((send, S, take, RT))
        send, S, take, RT = ClusterMaps.of(evaluator, new).blocks[0]
        held = int(keep.sum())
        return ClusterMaps(links, blocks + [(send + held, S, take + held, RT)])

    def sent(self, B_roots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(links, term): what each sending small cluster's link carries, from its input
        triangles' radiosity ``B_roots`` (input triangles, 3)."""
        out = [(times(S, B_roots)[send >= 0], send[send >= 0]) for send, S, _, _ in self.blocks]
        return np.concatenate([o[1] for o in out]), np.concatenate([o[0] for o in out])

    def taking(self) -> np.ndarray:
        """The links whose receiver is a small cluster."""
        return np.concatenate([take[take >= 0] for _, _, take, _ in self.blocks])

    def taken(self, per_link: np.ndarray) -> np.ndarray:
        """Irradiance (input triangles, 3) the taking links bring, each carrying ``per_link``."""
        return sum(RT.T @ (per_link[take] * (take >= 0)[:, None]) for _, _, take, RT in self.blocks)

    def joined(self) -> tuple:
        """(send, S, take, RT) of the held links in one block."""
        from scipy.sparse import vstack

        parts = [(send[send >= 0], S[send >= 0], take[take >= 0], RT[take >= 0])
                 for send, S, take, RT in self.blocks]
        return (np.concatenate([p[0] for p in parts]), vstack([p[1] for p in parts], format="csr"),
                np.concatenate([p[2] for p in parts]), vstack([p[3] for p in parts], format="csr"))


def times(A, x: np.ndarray) -> np.ndarray:
    """CSR matrix ``A`` times x (n, c): on every core where numba builds
    (``compiled.kernels.csr_times``, which checks no bounds: the shapes are checked here),
    else scipy's."""
    if A.format != "csr" or A.shape[1] != len(x):
        raise ValueError(f"a CSR matrix times x: got {A.format} {A.shape} times {np.shape(x)}")
    kernel = compiled.kernel("csr_times")
    return kernel(A.indptr, A.indices, A.data, x) if kernel is not None else np.asarray(A @ x)


def _by_rows(row: np.ndarray, col: np.ndarray, val: np.ndarray, shape: tuple):
    """CSR matrix of entries already in row order (``_member_entries`` makes them link after
    link, no two alike), without scipy's sort and sum of a COO matrix (a large scene's 70
    million entries: 12 s)."""
    from scipy.sparse import csr_matrix

    if np.any(row[1:] < row[:-1]):
        raise ValueError("cluster map entries out of row order")
    indptr = np.concatenate([[0], np.cumsum(np.bincount(row, minlength=shape[0]))])
    return csr_matrix((val, col, indptr), shape=shape)


def _paired_shares(evaluator, L: Links) -> tuple:
    """For the links of L with a cluster end and at most ``PAIRED`` triangle pairs
    (``PAIRED_ELEMENT`` with an element end), their shares by each pair's closed form
    P[r, s] (``_pair_sums``: the mean over points of receiving triangle r of its form
    factor to the front of sending triangle s), as two (first, values) for
    ``_member_entries``, of the sending and the taking ends: first[j] where link j's
    values start (-1: not paired), one value per triangle of its end in cluster order.
    Sent: s's power into R per unit B_s, sum_r A_r P[r, s], over the link's unoccluded
    transfer; taken: r's irradiance from all of S at unit B, sum_s P[r, s], over all of
    S's power into R (an element end's share folded into the other's). From an even B over
    S, r then gets V B sum_s P[r, s], and each s sends R its own power V B_s sum_r A_r
    P[r, s]. With one direction and distance for all pairs, the links between
    small clusters round a closed room's corners (2-7 triangles) sent 19% more light than
    the closed forms, and those of over 64 pairs in another closed room 10% more; those
    from small clusters to elements, each triangle's closed form taken at the element's
    centre alone, 2-4.5% more."""
    nd = evaluator.nodes
    cs, cr = evaluator.size(L.src), evaluator.size(L.rcv)
    both = nd.cluster[L.src] & nd.cluster[L.rcv]
    limit = np.where(both, PAIRED, PAIRED_ELEMENT)
    j = np.flatnonzero((nd.cluster[L.src] | nd.cluster[L.rcv]) & (cs * cr <= limit))
    out = []
    for count in (cs, cr):
        first = np.full(len(L), -1, np.int64)
        first[j] = np.cumsum(count[j]) - count[j]
        out.append([first, np.zeros(int(count[j].sum()))])
    if not len(j):
        return tuple(out)
    kernel = compiled.kernel("pair_sums")
    if kernel is not None:
        sent, taken, total = kernel(L.src[j], L.rcv[j], cs[j], cr[j], nd.cluster, evaluator.span, nd.order, nd.tri,
                                    nd.normal, evaluator.corners, nd.scene.normals, PAIR_POINTS, PAIR_FAR,
                                    evaluator.caster.epsilon)
    else:
        sent, taken, total = _pair_sums(evaluator, L.src[j], L.rcv[j], cs[j], cr[j])
    free = L.unoccluded(j)
    sent /= np.repeat(np.where(free > 0, free, np.inf), cs[j])
    taken /= np.repeat(np.where(total > 0, total, np.inf), cr[j])
    one_s, one_r = ~nd.cluster[L.src[j]], ~nd.cluster[L.rcv[j]]      # an element end has no entries
    out[0][1] = sent * np.repeat(np.where(one_r, taken[out[1][0][j]], 1.0), cs[j])
    out[1][1] = taken * np.repeat(np.where(one_s, sent[out[0][0][j]], 1.0), cr[j])
    return tuple(out)


def _pair_sums(evaluator, src: np.ndarray, rcv: np.ndarray, cs: np.ndarray, cr: np.ndarray) -> tuple:
    """Numpy's form of ``compiled.kernels.pair_sums``: for links (src, rcv) whose ends hold
    ``cs`` and ``cr`` triangles, and each pair (s, r) of them, P the mean over ``PAIR_POINTS``
    of r of its form factor to s (at r's centroid alone beyond ``PAIR_FAR``): per triangle s
    the sum of A_r P, per triangle r the sum of P (link after link, in cluster order), per
    link the sum of A_r P. In batches of about ``PAIR_BATCH`` pairs."""
    out = [_pair_batch(evaluator, src[first:last], rcv[first:last], cs[first:last], cr[first:last])
           for first, last in batches(cs * cr, PAIR_BATCH)]
    return tuple(np.concatenate([o[k] for o in out]) for k in range(3)) if out else (np.zeros(0),) * 3


def _pair_batch(evaluator, src, rcv, cs, cr) -> tuple:
    """``_pair_sums`` of one batch of links."""
    link, k = ranges(np.zeros(len(src), np.int64), cs * cr)
    ks, kr = k // cr[link], k % cr[link]
    tri_s, _ = evaluator._members(src, cs)
    tri_r, n_r = evaluator._members(rcv, cr)
    at_s, at_r = (np.cumsum(cs) - cs)[link] + ks, (np.cumsum(cr) - cr)[link] + kr
    area_r = 0.5 * np.linalg.norm(np.cross(tri_r[:, 1] - tri_r[:, 0], tri_r[:, 2] - tri_r[:, 0]), axis=1)
    c_s, c_r = tri_s.mean(axis=1), tri_r.mean(axis=1)
    reach_s = np.linalg.norm(tri_s - c_s[:, None], axis=2).max(axis=1)
    reach_r = np.linalg.norm(tri_r - c_r[:, None], axis=2).max(axis=1)
    eps = evaluator.caster.epsilon
    close = np.sum((c_s[at_s] - c_r[at_r]) ** 2, axis=1) <= (PAIR_FAR * (reach_s[at_s] + reach_r[at_r])) ** 2
    P = np.empty(len(at_r))
    i, j = np.flatnonzero(close), np.flatnonzero(~close)
    x = np.einsum("pk,lkc->lpc", PAIR_POINTS, tri_r[at_r[i]]) + eps * n_r[at_r[i]][:, None]
    P[i] = polygon_factor(x, n_r[at_r[i]], tri_s[at_s[i]]).mean(axis=1)
    P[j] = polygon_factor((c_r + eps * n_r)[at_r[j], None], n_r[at_r[j]], tri_s[at_s[j]])[:, 0]
    power = area_r[at_r] * P
    return (np.bincount(at_s, weights=power, minlength=int(cs.sum())),
            np.bincount(at_r, weights=P, minlength=int(cr.sum())),
            np.bincount(link, weights=power, minlength=len(src)))


def _member_entries(evaluator, L: Links, w: np.ndarray, sending: bool, undo: np.ndarray,
                    paired: tuple | None = None):
    """The links of L whose sending (or taking) end is a small cluster, and per (link, input
    triangle of that end) the share of the link's light: A max(0, n.w) sent, max(0, -n.w)
    taken; where the other end is an element, the triangle's closed form to it (sending:
    from the element's centre to the triangle; taking: from the triangle's centroid to the
    element) times ``undo``, the link's kernel over its cosine; where ``paired``
    (``_paired_shares``: that end's), its values. In batches of ``MAP_BATCH`` entries (a
    large scene has tens of millions)."""
    nodes, span = evaluator.nodes, evaluator.span
    ends, other = (L.src, L.rcv) if sending else (L.rcv, L.src)
    links = np.flatnonzero(nodes.cluster[ends])                 # clusters are the first nodes: in span
    lo, hi = span[ends[links]].T
    small = hi - lo <= EXACT_CLUSTER
    links, lo, count = links[small], lo[small], (hi - lo)[small]
    rows, tris, vals = [], [], []
    for first, last in batches(count, MAP_BATCH):
        pos, t, v = _member_shares(evaluator, lo[first:last], count[first:last], links[first:last], w, sending,
                                   other, undo)
        start = paired[0][links[first:last]] if paired is not None else np.full(last - first, -1)
        if (start >= 0).any():
            e = np.flatnonzero(start[pos] >= 0)
            k = e - (np.cumsum(count[first:last]) - count[first:last])[pos[e]]
            v[e] = paired[1][start[pos[e]] + k]
        _member_visibility(evaluator, pos, t, links[first:last], ends, other, L.vis, v)
        rows.append(pos + first)
        tris.append(t)
        vals.append(v)
    if not rows:
        return links, (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
    return links, (np.concatenate(rows), np.concatenate(tris), np.concatenate(vals))


def _member_shares(evaluator, lo, count, links, w, sending, other, undo):
    """(entry's link position, input triangle t, t's share of its link's light) for the
    members ``order[lo:lo + count]`` of each link's cluster end: A max(0, n.w) sent or
    max(0, -n.w) taken along w where the link's ``other`` end is a cluster; where it is an
    element, t's closed form to it (sending: from the element's centre to t; taking: from
    t's centroid to the element) times the link's ``undo``. Compiled where numba builds (a
    large scene has tens of millions of entries; numpy's gathers of their points and
    triangles took 30 s of the atrium's solve)."""
    nodes, sc, eps = evaluator.nodes, evaluator.nodes.scene, evaluator.caster.epsilon
    kernel = compiled.kernel("member_shares")
    if kernel is not None:
        return kernel(lo, count, links, nodes.order, sc.normals, sc.areas, w, sending, other, nodes.cluster,
                      nodes.center, nodes.tri, nodes.normal, evaluator.corners, evaluator.centroids, eps, undo)
    pos, at = ranges(lo, count)
    t, j = nodes.order[at], links[pos]
    cos = np.einsum("ij,ij->i", sc.normals[t], w[j])
    v = sc.areas[t] * np.maximum(cos, 0.0) if sending else np.maximum(-cos, 0.0)
    el = np.flatnonzero(~nodes.cluster[other[j]])
    if len(el):
        e, te = other[j[el]], t[el]
        if sending:
            x, normal = nodes.center[e] + eps * nodes.normal[e], nodes.normal[e]
            poly = evaluator.corners[te]
        else:
            x, normal, poly = evaluator.centroids[te] + eps * sc.normals[te], sc.normals[te], nodes.tri[e]
        v[el] = polygon_factor(x[:, None], normal, poly)[:, 0] * undo[j[el]]
    return pos, t, v


def _member_visibility(evaluator, pos: np.ndarray, t: np.ndarray, link: np.ndarray, end: np.ndarray,
                       other: np.ndarray, vis: np.ndarray, v: np.ndarray):
    """Scale, in place, the shares v of entries (link position ``pos``, triangle t of its
    small cluster end; the links ``link``, their ``end`` and ``other`` ends and ``vis``) of
    partly visible links, to hand each link's light to the triangles that see its other
    end: one shadow ray from a point of t to a point of ``other`` (both drawn from a hash of
    the entry, so maps carried over rounds equal maps made afresh), the entries of each link
    then scaled so that their sum (the link's visibility, from its own rays) is kept. A
    cluster's visibility shared by all its triangles lets the light of its lit, exposed
    parts go out as if from its hidden ones too. Entries of links that see their other end
    whole or not at all stay, and so do a link's entries where every ray was blocked or
    those that arrive carry under 1e-9 of its shares (rescaled, they would be a billion
    times their own). The rays are made in one compiled pass where numba builds
    (``member_rays``)."""
    nd, caster = evaluator.nodes, evaluator.caster
    if not ((vis[link] > 0) & (vis[link] < 1)).any():
        return
    kernel = compiled.kernel("member_rays")
    if kernel is not None:
        faced, origin, direction, length = kernel(pos, t, link, end, other, vis, v, nd.cluster, evaluator.span,
                                                  evaluator.cum_area, nd.order, nd.tri, nd.normal,
                                                  evaluator.corners, nd.scene.normals, caster.epsilon)
        cast = np.flatnonzero(faced)
        seen = caster.reaches(origin[cast], direction[cast], length[cast])
    else:
        from ..sampling import hashed_uniforms, triangle_points

        j = link[pos]
        cast = np.flatnonzero((vis[j] > 0) & (vis[j] < 1) & (v > 0))
        u = hashed_uniforms((end[j[cast]], other[j[cast]], t[cast]), 5)
        tc, oc = t[cast], other[j[cast]]
        a, na = triangle_points(evaluator.corners[tc], u[0], u[1]), nd.scene.normals[tc]
        b, nb = evaluator.points_on(oc, u[2:].T[:, None])               # by area where oc is a cluster
        b, nb = b[:, 0], nb[:, 0]
        d = b - a
        faced = (np.einsum("ij,ij->i", na, d) > 0) & (np.einsum("ij,ij->i", nb, d) < 0)
        cast = cast[faced]
        seen = caster.clear_between(a[faced], b[faced], na[faced], nb[faced])
    blocked = cast[~seen]
    if not len(blocked):
        return
    # per link: keep the entries' sum, so the link's own visibility stands
    total = np.bincount(pos, weights=v, minlength=len(link))
    kept = total - np.bincount(pos[blocked], weights=v[blocked], minlength=len(link))
    some = kept > 1e-9 * total
    v[blocked[some[pos[blocked]]]] = 0.0
    v *= np.where(some, total / np.where(some, kept, 1.0), 1.0)[pos]


@dataclass
class HierarchicalResult:
    """The adaptive leaves (triangulated where a neighbour split: no T-vertices), their
    radiosity, and how the solve went."""

    leaves: PatchScene             # output triangles, each with its leaf's rho, E, B, H
    result: SolveResult
    leaf: np.ndarray               # (t,) the element each output triangle belongs to
    corner_B: np.ndarray           # (t, 3 corners, 3) radiosity at each output triangle's corners
    links: int
    elements: int
    rounds: list = field(default_factory=list)   # per round: links, leaves, seconds

    @property
    def leaf_count(self) -> int:
        return len(np.unique(self.leaf))

    def mesh_vertex_values(self, part) -> np.ndarray:
        """Radiosity (v, 3) at a result mesh's vertices (``reconstruct.MeshPart``): the area
        mean of its triangles' own corner values there (the leaves' quadratics and the outside
        lights at the vertex); the triangles meet vertex to vertex, so colours have no cracks,
        and at a crease each side is its own."""
        w = np.repeat(self.leaves.areas[part.patches], 3)
        idx = part.local.ravel()
        n = len(part.vertex_ids)
        total = np.bincount(idx, weights=w, minlength=n)
        corner = self.corner_B[part.patches].reshape(-1, 3)
        return np.stack([np.bincount(idx, weights=w * corner[:, c], minlength=n)
                         for c in range(3)], axis=1) / np.maximum(total, 1e-300)[:, None]


def conforming(tris: np.ndarray, midpoint: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Leaves (t, 3 vertex ids) cut where a neighbour's split left a vertex inside one of their
    edges (``midpoint``: edge (lo << 32 | hi) -> its midpoint): a fan from the opposite corner
    when one edge has such vertices, from the centroid (a new vertex, -1 here) when more do.
    Returns the triangles (k, 3), the leaf row of each, and whether a corner is the centroid."""
    def inside(a: int, b: int) -> list[int]:
        m = midpoint.get((min(a, b) << 32) + max(a, b))
        return [] if m is None else inside(a, m) + [m] + inside(m, b)

    out, rows = [], []
    for row, (a, b, c) in enumerate(tris.tolist()):
        edges = [inside(a, b), inside(b, c), inside(c, a)]
        full = [n for n, e in enumerate(edges) if e]
        if not full:
            out.append((a, b, c))
            rows.append(row)
            continue
        loop = [a, *edges[0], b, *edges[1], c, *edges[2]]
        if len(full) == 1:
            k = full[0]
            corner = (c, a, b)[k]                       # opposite the cut edge
            line = [(a, b, c)[k], *edges[k], (a, b, c)[(k + 1) % 3]]
            out += [(corner, p, q) for p, q in zip(line[:-1], line[1:])]
        else:
            out += [(-1, p, q) for p, q in zip(loop, loop[1:] + loop[:1])]
        rows += [row] * (len(out) - len(rows))
    out = np.array(out, np.int64).reshape(-1, 3)
    return out, np.array(rows, np.int64), out < 0


def mis_share(cos_p: np.ndarray, cos_x: np.ndarray, density: np.ndarray, r: np.ndarray, rays: int,
              samples: int) -> np.ndarray:
    """Balance-heuristic share of a final-gather sample that reaches a hot leaf's point x, r
    from the vertex, at cosines ``cos_p`` (vertex) and ``cos_x`` (leaf): ``rays`` cosine rays
    (pdf cos_p / pi per steradian) and ``samples`` shadow rays by power (``density`` per unit
    area, so density r^2 / cos_x per steradian) can both draw it. A cosine ray takes ``rays``
    x share of the leaf's B, a shadow ray share x B (summed, not averaged): the shadow rays
    carry a small hot leaf far off, the cosine rays the back of a lamp a centimetre away."""
    g = cos_p * cos_x
    return g / np.maximum(rays * g + np.pi * samples * density * r ** 2, 1e-300)


def gather_sides(rays: int, noise: np.ndarray, area: np.ndarray) -> np.ndarray:
    """Grid sides (k,) of the final gather's cosine rays at k points, ``rays`` a point on
    average, each point's count in proportion to (sqrt(area) x noise)^(1/3) within
    ``GATHER_SPREAD`` x ``rays`` (fewer on average where nearly every point has no noise and the
    most cannot make up the mean): ``noise`` the variance of a pilot gather's estimate there,
    ``area`` the point's share of the result mesh. A stratified gather's variance falls about
    as rays^-2 (on the Cornell box from 64 to 256 rays 14x, median of its points), and the
    counts n that make sum w v0 (n0 / n)^2 least for a given sum n go as (w v0)^(1/3). Weights
    w = sqrt(area) sit between per vertex (1) and per area (area, where a few large vertices
    on open walls take most rays and the thin strips along contacts starve): on that box,
    from the pilot's noise, variance per vertex 0.99x and by area 0.17x an even share's."""
    drive = np.cbrt(np.sqrt(area) * np.maximum(noise, 0.0))
    least, most = GATHER_SPREAD[0] * rays, GATHER_SPREAD[1] * rays
    if not drive.any():
        counts = np.full(len(drive), float(rays))
    else:
        lo, hi = least / drive.max(), most / max(float(drive[drive > 0].min()), 1e-300)
        for _ in range(60):                                # the scale whose clipped counts average rays
            scale = np.sqrt(lo * hi)
            lo, hi = (scale, hi) if np.clip(scale * drive, least, most).mean() < rays else (lo, scale)
        counts = np.clip(np.sqrt(lo * hi) * drive, least, most)
    return np.maximum(1, np.rint(np.sqrt(counts))).astype(int)


@dataclass
class GatherTargets:
    """What a final gather's rays take their light from: the leaves (``caster``, by row of
    ``leaf_ids``), the reflected ``light`` each sends (``_open_light``) less, where ``at_hit``,
    the Light objects' part, which the ray takes at the point it hits instead
    (``direct_at``), which are ``hot``, at what ``density`` per unit area the shadow rays
    draw them, which are ``flat`` (``light_shape``), and each input triangle's two-sided
    ``twin``."""

    caster: object
    light: np.ndarray
    hot: np.ndarray
    density: np.ndarray
    twin: np.ndarray
    flat: np.ndarray
    tri: np.ndarray        # (leaves, 3, 3) corners
    centre: np.ndarray     # (leaves, 3) centroids
    normal: np.ndarray     # (leaves, 3)
    H6: np.ndarray         # (leaves, 6, 3) irradiance quadratics (``light_shape``)
    at_hit: np.ndarray     # (leaves,) whose Light objects' light is made at each hit point
    direct_at: object      # ``pipeline`` external's ``direct_at``, or None


def ray_stats(got: np.ndarray, paired: bool) -> tuple[np.ndarray, np.ndarray]:
    """The mean (k, 3) of each point's rays ``got`` (k, rays, 3) and its variance (k, 3): by
    pairs of rays next to each other (``paired``, for an even count: the strata collapsed in
    twos), else by the rays' spread. By matrix products, not numpy's reductions over the middle axis, which
    took 4-14x as long (6 s of a large scene's final gather)."""
    rays = got.shape[1]
    H = np.ones(rays) @ got / rays
    if paired:
        d = got[:, 0::2] - got[:, 1::2]
        return H, np.einsum("kpc,kpc->kc", d, d) / rays ** 2
    d = got - H[:, None]
    return H, np.einsum("krc,krc->kc", d, d) / (max(rays - 1, 1) * rays)


def ray_light(seen: GatherTargets, row: np.ndarray, x: np.ndarray, dirs: np.ndarray, dist: np.ndarray,
              normals: np.ndarray, rays: int, shadow: int) -> np.ndarray:
    """The light (k, 3) each of k final-gather rays takes (``_gather_batch``): the ray from
    point k // ``rays`` (facing ``normals``) along ``dirs`` hits leaf ``row`` (-1: none) at
    ``x``, ``dist`` away; it takes ``seen.light`` there (``light_shape``), and of a hot leaf its
    balance-heuristic share against ``shadow`` shadow rays (``mis_share``). Compiled where
    numba builds (``compiled.kernels.ray_light``; the numpy temporaries of barycentric
    coordinates and quadratics were 40% of the Cornell box's gather)."""
    kernel = compiled.kernel("ray_light")
    if kernel is not None:
        return kernel(row, x, dirs, dist, seen.tri, seen.H6, seen.light, seen.flat, seen.hot, seen.density,
                      seen.normal, normals, rays, shadow, quadratic.INSET, quadratic.MEAN, SHAPE_MAX)
    got = np.zeros((len(row), 3))
    h = np.flatnonzero(row >= 0)
    r = row[h]
    got[h] = seen.light[r] * light_shape(seen.H6[r], barycentric(x[h], seen.tri[r]), seen.flat[r])
    if shadow:
        k = h[seen.hot[r]]
        cos_p = np.einsum("kc,kc->k", dirs[k], normals[k // rays])
        cos_x = np.abs(np.einsum("kc,kc->k", dirs[k], seen.normal[row[k]]))
        got[k] *= rays * mis_share(cos_p, cos_x, seen.density[row[k]], dist[k], rays, shadow)[:, None]
    return got


def light_shape(H6: np.ndarray, lam: np.ndarray, flat: np.ndarray) -> np.ndarray:
    """(m, 3) how the reflected light of leaves with irradiance quadratics ``H6`` (m, 6, 3) at
    barycentric ``lam`` in them stands to their mean: the quadratic there over its mean,
    clamped to [0, ``SHAPE_MAX``]; 1 where ``flat`` (a floor a box rests on, whose quadratic
    counts the dark footprint: its open light is made apart, ``_open_light``)."""
    at = np.einsum("mi,mic->mc", quadratic.basis(lam), H6)
    mean = np.einsum("i,mic->mc", quadratic.MEAN, H6)
    out = np.clip(at / np.maximum(mean, 1e-300), 0.0, SHAPE_MAX)
    out[(mean <= 0) | flat[:, None]] = 1.0
    return out


class HierarchicalRadiosity:
    """Hierarchical radiosity over a PatchScene of input triangles.

    ``external(tris (m, 3, 3), normals (m, 3), bary (points, 3), spread=False) -> (H,
    direct)`` (m, points, 3) gives the irradiance of lights outside the solve at barycentric
    points of each element and the Light objects' part of it (with ``spread``, a third: H
    with its samples drawn alike at an element's points, whose spread decides a split), and
    ``external.direct_at`` that part at points a final gather's rays hit
    (``pipeline.Solve._external_light``);
    ``shown`` (n,) marks the input triangles whose leaves are output (emitter backs are
    solved, not shown).
    """

    def __init__(self, scene: PatchScene, settings: HierarchicalSettings | None = None, *, external=None,
                 shown: np.ndarray | None = None, caster=None):
        from ..formfactors.raycast import EmbreeRays

        self.settings = s = settings or HierarchicalSettings()
        if not s.epsilon > 0:
            raise SceneError(f"quality epsilon must be positive, got {s.epsilon}")
        t0 = time.perf_counter()
        self.scene = scene
        self.shown = np.ones(scene.n, bool) if shown is None else np.asarray(shown, bool)
        self.nodes = nd = Nodes(scene, external, s.max_level, s.min_area * float(scene.areas.sum()))
        self.caster = caster or EmbreeRays(scene, 1)
        self.evaluator = Evaluator(nd, self.caster, s.seed)
        self.contacts = Proximity(nd, self.caster, s.max_level)
        self.size0 = nd.size                                     # cluster tree nodes
        self.proj_root = scene.areas[:, None] * np.maximum(scene.normals @ DIRECTIONS.T, 0.0)
        self.cos_root = direction_cosines(scene.normals)
        rows = nd.cluster_row
        depth = np.full(self.size0, -1)
        depth[nd.clusters] = nd.cluster_depth
        self.by_depth = [nd.clusters[nd.cluster_depth == k] for k in range(int(depth.max()) + 1)] \
            if len(nd.clusters) else []
        self.proj = np.zeros((self.size0, len(DIRECTIONS)))
        self.proj[nd.clusters] = nd.proj[rows[nd.clusters]]
        self.proj[nd.element_root] = self.proj_root
        self.power = float((nd.E[nd.element_root] * scene.areas[:, None]).sum(axis=0).max())
        if not self.power > 0:
            raise SceneError("nothing emits light: give a material emission or add a light that reaches a surface")
        self.eps = s.epsilon * self.power / float(scene.areas.sum())     # W/m^2
        self.Bn = nd.E[:nd.size].copy()
        self.Bopen, self.Bgap = self.Bn.copy(), self.Bn.copy()     # of the open part and of the gap (contacts)
        self.Brange = np.zeros(nd.size)
        self._pull(nd.element_root, nd.element_root[:, None], self.Bn[nd.element_root],
                   self.contacts.gap_share(nd.element_root))
        self.links = Links.empty()
        self.sweeps, self.history, self.times = 0, [], []
        self.rounds: list[dict] = []
        self.stage_seconds = {"clusters": time.perf_counter() - t0, "refine": 0.0, "solve": 0.0}
        self.done = False
        self._round = None                # the refine in progress (``_round_steps``)
        self._progress = ""               # what it is doing, for ``phase``
        self._final = None                # the light at the result vertices in progress (``_corner_steps``)
        self.finished = 0.0               # its fraction done
        self._memo: dict = {}             # the result mesh and its corners' light, by the solve they are of
        self._t_start = time.perf_counter()
        self.tol, self.max_iterations = s.tolerance, s.max_rounds

    # -- the interface SolveJob drives (as the other solvers') ---------------------------
    @property
    def iterations(self) -> int:
        return len(self.rounds)

    @property
    def residual(self) -> float:
        return self.history[-1] if self.history else 1.0

    @property
    def refining(self) -> bool:
        """True while a round's refine is under way (between ``step`` slices)."""
        return self._round is not None

    @property
    def finishing(self) -> bool:
        """True while the light at the result vertices is under way (``step``'s last phase)."""
        return self._final is not None

    @property
    def phase(self) -> str:
        if self.refining:
            return f"hierarchical round {len(self.rounds) + 1}, {self._progress}"
        if self.finishing:
            rays = self.settings.gather_rays
            each = "a vertex on average" if rays >= GATHER_ADAPTIVE else "each"
            how = f" (final gather, {rays:,} rays {each})" if rays else ""
            return f"light at the result vertices{how}: {self.finished:.0%}"
        if self.done:
            return f"hierarchical, {len(self.rounds)} rounds, {len(self.links):,} links"
        return f"hierarchical round {len(self.rounds)} solved, {len(self.links):,} links"

    def energy(self) -> dict[str, float]:
        """Fractions of the emitted power absorbed, escaped (left and received by no front
        face), blocked (0: counted in escaped) and unshot (the residual), for the live readout."""
        if not hasattr(self, "B"):
            return {"absorbed": 0.0, "escaped": 0.0, "blocked": 0.0, "unshot": 1.0}
        r = self.result(corners=False).result
        e = max(float(r.emitted.max()), 1e-300)
        return {k: float(getattr(r, k).max()) / e for k in ("absorbed", "escaped", "blocked", "unshot")}

    @property
    def seconds(self) -> float:
        return time.perf_counter() - self._t_start

    # -- state of the trees --------------------------------------------------------------
    def _grow_state(self):
        """New elements start with their parent's radiosity (split after every growth, so
        parents are older)."""
        nd, old = self.nodes, len(self.Bn)
        par = nd.parent[old:nd.size]
        self.Bn = np.concatenate([self.Bn, self.Bn[par]])
        self.Bopen = np.concatenate([self.Bopen, self.Bopen[par]])
        self.Bgap = np.concatenate([self.Bgap, self.Bgap[par]])
        self.Brange = np.concatenate([self.Brange, np.zeros(nd.size - old)])

    def errors(self, L: Links) -> np.ndarray:
        """Error estimate of each link (see ``links``): W/m^2 at its receiver, worst channel."""
        nd = self.nodes
        src, rcv = L.src, L.rcv
        cs, cr = nd.cluster[src], nd.cluster[rcv]
        term = self._source_term(L, bound=True)
        rho = nd.rho[rcv]
        rho[cr] = nd.rho_max[rcv[cr], None]
        rho = np.maximum(rho, BOOKS_RHO)
        err = np.zeros(len(L))
        ee = ~cs & ~cr
        if ee.any():
            g = L.mean[ee]
            f = np.maximum(L.spread[ee], L.occluded[ee])
            e = rho[ee] * (term[ee] * f[:, None] + (self.Brange[src[ee]] * g)[:, None])
            err[ee] = e.max(axis=1)
        o = ~ee & ~L.near
        if o.any():
            # by the visibility it was judged by, not the one that carries its light (``see``)
            f = L.judged[o] * L.unoccluded(o) * L.spread[o] + L.occluded[o]
            err[o] = (rho[o] * term[o] * f[:, None]).max(axis=1)
        o = L.near
        if o.any():
            # ends too close for the kernel: all the light S could bring R (infinite where
            # their boxes touch, whatever S sends)
            with np.errstate(invalid="ignore"):
                e = (rho[o] * self._flux(L.src[o]) * L.spread[o, None]).max(axis=1)
            err[o] = np.where(np.isfinite(L.spread[o]), e, np.inf)
        return err

    def _flux(self, src: np.ndarray) -> np.ndarray:
        """Power / pi (sum of B A over its triangles, W per channel) each source sends, the
        most of its open part and its part in a gap."""
        nd = self.nodes
        out = nd.area[src, None] * np.maximum(self.Bopen[src], self.Bgap[src])
        cs = nd.cluster[src]
        out[cs] = self.flux[src[cs]]
        return out

    def _source_term(self, L: Links, bound: bool = False) -> np.ndarray:
        """B of an element source (of its part in a gap for a receiver in that gap, else of
        its open part: ``contacts``); a cluster source's sum B A max(0, n.w) over its open
        parts along the link's direction: summed over its triangles for the solve's own
        links from a small cluster (``ClusterMaps``), else read between the table's
        directions (``bound``: the largest of them, for the error estimate)."""
        nd = self.nodes
        in_gap = self._element_gather()[0] if L is self.links else self.contacts.in_gap(L.src, L.rcv)
        kernel = compiled.kernel("source_term")
        if kernel is not None:
            term = kernel(L.src, L.d, L.dw, in_gap, nd.cluster, self.Bgap, self.Bopen, self.table, bound)
        else:
            cs = nd.cluster[L.src]
            term = np.where(in_gap[:, None], self.Bgap[L.src], self.Bopen[L.src])
            if cs.any():
                corners = self.table[L.src[cs, None], L.d[cs]]             # (c, 3 directions, 3)
                term[cs] = corners.max(axis=1) if bound else np.einsum("cj,cjk->ck", L.dw[cs], corners)
        if L is self.links and not bound:
            links, sent = self._cluster_maps().sent(self.Bopen[nd.element_root])
            term[links] = sent
        return term

    def _cluster_maps(self) -> "ClusterMaps":
        """``ClusterMaps`` of the current links (rebuilt when the links change)."""
        if getattr(self, "_maps", None) is None or self._maps.links is not self.links:
            self._maps = ClusterMaps.of(self.evaluator, self.links)
        return self._maps

    def _element_gather(self) -> tuple[np.ndarray, np.ndarray, object]:
        """Of the current links, made once a round instead of once a sweep: which take the
        light of their source's part in a gap (``contacts.in_gap``), the links into elements,
        and G (6 x nodes, those links): their coefficients at the receivers' quadratic nodes."""
        from scipy.sparse import csr_matrix

        nd, L = self.nodes, self.links
        made = getattr(self, "_gathering", None)
        if made is None or made[0] is not L or made[1] != nd.size:
            er = np.flatnonzero(~nd.cluster[L.rcv])
            rows = (L.rcv[er, None] * 6 + np.arange(6)).ravel()
            G = csr_matrix((L.coef[er].ravel(), (rows, np.repeat(np.arange(len(er)), 6))),
                           shape=(6 * nd.size, len(er)))
            self._gathering = made = (L, nd.size, self.contacts.in_gap(L.src, L.rcv), er, G)
        return made[2:]

    # -- refinement ----------------------------------------------------------------------
    def _to_refine(self, L: Links) -> tuple[np.ndarray, np.ndarray]:
        """(need, split_src) per link: over the bound (the larger end split), or into a mixed
        receiver (``contacts``: the receiver split), where an end can still split."""
        nd = self.nodes
        cs, cr = self.nodes.can_split(L.src), self.nodes.can_split(L.rcv)
        mixed = self.contacts.mixed(L.rcv) & cr
        leak = self._leaks(L) & cs & ~mixed
        split_src = (cs & ((nd.radius[L.src] >= nd.radius[L.rcv]) | ~cr) & ~mixed) | leak
        need = ((self.errors(L) > self.eps) & (cs | cr)) | mixed | leak
        # a partly visible link with a cluster end read from the direction table shares one
        # visibility over that end's hundreds of triangles: its lit, exposed parts' light
        # goes out as if from its hidden ones too (the atrium's large arch clusters gave
        # the court floor 40% too little); such links go down to ``ClusterMaps`` clusters
        partly = (L.judged < 1) & ~L.near
        big_s = partly & nd.cluster[L.src] & (self.evaluator.size(L.src) > EXACT_CLUSTER)
        big_r = partly & nd.cluster[L.rcv] & (self.evaluator.size(L.rcv) > EXACT_CLUSTER) & ~big_s
        return need | big_s | big_r, (split_src & ~big_r) | big_s

    def _leaks(self, L: Links) -> np.ndarray:
        """Element links from a source with a surface close in front of part of it
        (``contacts``: the ceiling over a lamp) that see it only in part: visibility times
        the source's mean radiosity is then off by up to the spread of its leaves' B (the
        hot ceiling over the lamp seen past the lamp's edge), and its neighbours' links are
        off the same way, so their sum passes epsilon where each does not. Such links are
        refined at the source, down to parts wholly near or wholly clear, where that spread
        times the unoccluded transfer is over ``LEAK_SHARE`` x epsilon."""
        nd = self.nodes
        out = np.zeros(len(L), bool)
        i = np.flatnonzero(~nd.cluster[L.src] & ~nd.cluster[L.rcv] & (L.vis > 0) & (L.vis < 1))
        i = i[self.contacts.mixed(L.src[i])]
        rho = nd.rho[L.rcv[i]].max(axis=1)
        out[i] = rho * self.Brange[L.src[i]] * L.occluded[i] > LEAK_SHARE * self.eps
        return out

    def refine(self, src: np.ndarray, rcv: np.ndarray, held: int = 0):
        """Evaluate candidate links (src, rcv), keep those within the bound, split the rest
        down to their children; a generator that yields after each slice of at most
        ``REFINE_CHUNK`` candidates (a large scene's first round shows progress and can be
        cancelled) and returns the Links kept. ``held``: links kept from before."""
        nd = self.nodes
        kept, queue = [], [(src, rcv)] if len(src) else []
        total = held
        while queue:
            src, rcv = queue.pop()
            if len(src) > REFINE_CHUNK:
                queue.append((src[REFINE_CHUNK:], rcv[REFINE_CHUNK:]))
                src, rcv = src[:REFINE_CHUNK], rcv[:REFINE_CHUNK]
            L = self.evaluator.evaluate(src, rcv)
            need, split_src = self._to_refine(L)
            self.evaluator.see(L, ~need & (nd.cluster[L.src] | nd.cluster[L.rcv]))
            kept.append(L.take(~need & (L.coef.max(axis=1) > 0)))
            total += int((~need).sum())
            if total > MAX_LINKS:
                raise SceneError(f"hierarchical radiosity needs more than {MAX_LINKS:,} links "
                                 f"(about {MAX_LINKS * 100 / 2**30:.1f} GiB) at quality epsilon "
                                 f"{self.settings.epsilon:g}: raise epsilon")
            L, split_src = L.take(need), split_src[need]
            ends = np.where(split_src, L.src, L.rcv)
            nd.split(ends[~nd.cluster[ends]])
            self._grow_state()
            src, rcv = expand(nd, L.src, L.rcv, split_src)
            if len(src):
                queue.append((src, rcv))
            self._progress = (f"refining links: {held + sum(len(k) for k in kept):,} kept, "
                              f"{sum(len(q[0]) for q in queue):,} candidates queued")
            yield
        return Links.concat(kept)

    def refine_lights(self):
        """Split elements over which the reflected outside light varies by more than epsilon;
        a generator that yields before each ``LIGHT_CHUNK`` of splits."""
        nd = self.nodes
        if nd.external is None:
            return
        while True:
            leaves = nd.leaves()
            over = leaves[(nd.H_spread[leaves] > self.eps) & self.nodes.can_split(leaves)]
            if not len(over):
                return
            for lo in range(0, len(over), LIGHT_CHUNK):
                self._progress = (f"splitting elements where the lights and the World vary: "
                                  f"{lo:,} of {len(over):,}")
                yield
                nd.split(over[lo:lo + LIGHT_CHUNK])
                self._grow_state()

    # -- solving -------------------------------------------------------------------------
    def _ancestors(self, leaves: np.ndarray) -> np.ndarray:
        """(leaves, max level + 1) element ancestors of each leaf, itself first, padded with the
        sentinel ``size`` (a zero row)."""
        nd = self.nodes
        depth = int(nd.level[leaves].max()) + 1 if len(leaves) else 1
        anc = np.full((len(leaves), depth), nd.size, np.int64)
        node = leaves.copy()
        live = np.ones(len(leaves), bool)
        for k in range(depth):
            anc[live, k] = node[live]
            up = nd.parent[node]
            live &= (nd.level[node] > 0)
            node = np.where(live, up, node)
        return anc

    def _pull(self, leaves: np.ndarray, anc: np.ndarray, B: np.ndarray, share: np.ndarray):
        """Element radiosity as area means of their leaves (all of them, the open part, the
        part in a gap: ``share`` per leaf, each leaf's light spread evenly over it), and the
        clusters' tables (of the open parts)."""
        nd = self.nodes
        n = nd.size + 1
        w = nd.area[leaves]
        w_open = w * (1.0 - share)
        total, total_open = np.zeros(n), np.zeros(n)
        sums, sums_open = np.zeros((n, 3)), np.zeros((n, 3))
        gapped = share.any()
        for k in range(anc.shape[1]):
            col = anc[:, k]
            total += np.bincount(col, weights=w, minlength=n)
            if gapped:
                total_open += np.bincount(col, weights=w_open, minlength=n)
            for c in range(3):
                sums[:, c] += np.bincount(col, weights=w * B[:, c], minlength=n)
                if gapped:
                    sums_open[:, c] += np.bincount(col, weights=w_open * B[:, c], minlength=n)
        el = np.flatnonzero(total[:-1] > 0)
        self.Bn[el] = sums[el] / total[el, None]
        self.Bopen[el], self.Bgap[el] = self.Bn[el], self.Bn[el]
        if gapped:
            open_, gap = total_open[el], total[el] - total_open[el]
            some = el[open_ > 1e-9 * total[el]]
            self.Bopen[some] = sums_open[some] / total_open[some, None]
            some = el[gap > 1e-9 * total[el]]
            self.Bgap[some] = (sums[some] - sums_open[some]) / (total[some] - total_open[some])[:, None]
        table = np.zeros((self.size0, len(DIRECTIONS), 3))
        roots = nd.element_root
        table[roots] = self.proj_root[:, :, None] * self.Bopen[roots][:, None, :]
        flux = np.zeros((self.size0, 3))
        flux[roots] = nd.area[roots, None] * self.Bopen[roots]
        for level in reversed(self.by_depth):
            first = nd.first_child[level]
            table[level] = table[first] + table[first + 1]
            flux[level] = flux[first] + flux[first + 1]
        self.table, self.flux = table, flux

    def _ranges(self, anc: np.ndarray, B: np.ndarray):
        """``Brange``: the spread of the leaves' largest channel of ``B`` under each element
        (the refine's error estimate reads it; made once a solve, not once a sweep)."""
        n = self.nodes.size + 1
        lo, hi = np.full(n, np.inf), np.full(n, -np.inf)
        bmax = B.max(axis=1)
        for k in range(anc.shape[1]):
            np.minimum.at(lo, anc[:, k], bmax)
            np.maximum.at(hi, anc[:, k], bmax)
        el = np.flatnonzero(np.isfinite(lo[:-1]))
        self.Brange[el] = hi[el] - lo[el]

    def _push_plan(self) -> list:
        """Per element level below the input triangles: (elements, parents, child slots)."""
        nd = self.nodes
        plan = []
        for ids in nd.elements_by_level()[1:]:
            par = nd.parent[ids]
            plan.append((ids, par, ids - nd.first_child[par]))
        return plan

    def _gather(self, leaves: np.ndarray, plan: list) -> np.ndarray:
        """Irradiance (leaves, 6, 3) at the leaves' quadratic nodes, gathered over every link and
        pushed down: from clusters by direction to their triangles, then down each element tree."""
        nd, L = self.nodes, self.links
        term = self._source_term(L)
        _, er, G = self._element_gather()
        H = times(G, term[er]).reshape(nd.size, 6, 3)
        cr = nd.cluster[L.rcv]
        k = len(DIRECTIONS)
        D = np.zeros((self.size0 * k, 3))
        maps = self._cluster_maps()
        taking = maps.taking()
        if len(taking):                                          # small clusters: by each triangle's cosine
            cr = cr.copy()
            cr[taking] = False
            H_root = maps.taken(L.coef[:, :1] * term)
        if cr.any():
            idx = (L.rcv[cr, None] * k + L.d[cr]).ravel()
            val = (L.dw[cr, :, None] * (L.coef[cr, :1] * term[cr])[:, None, :]).reshape(-1, 3)
            D = np.stack([np.bincount(idx, weights=val[:, c], minlength=len(D)) for c in range(3)], axis=1)
        D = D.reshape(self.size0, k, 3).astype(float)
        for level in self.by_depth:                              # down the cluster tree
            first = nd.first_child[level]
            D[first] += D[level]
            D[first + 1] += D[level]
        roots = nd.element_root
        H[roots] += np.einsum("kdc,kd->kc", D[roots], self.cos_root)[:, None, :]
        if len(taking):
            H[roots] += H_root[:, None, :]
        for ids, par, slot in plan:                              # down the element trees
            H[ids] += np.einsum("sij,sjc->sic", quadratic.PUSH[slot], H[par])
        return H[leaves]

    def solve(self, cancel=None):
        """Jacobi sweeps with push-pull until the residual power is below the tolerance. The
        sweep that finds it so keeps the B it gathered from, not the step it makes: that
        gather is then B's own H (``H6``), and the step left the books' ``unshot``, so no
        gather more is needed (one a round, a tenth of a large scene's solve). Where the
        sweeps run out first, the last step is taken and gathered once more."""
        t0 = time.perf_counter()
        nd, s = self.nodes, self.settings
        leaves = nd.leaves()
        anc, plan = self._ancestors(leaves), self._push_plan()
        E, rho, A = nd.E[leaves], nd.rho[leaves], nd.area[leaves]
        B = self.Bn[leaves].copy()
        share = self.contacts.gap_share(leaves)
        self._pull(leaves, anc, B, share)
        sweeps = max(s.max_sweeps, 1)
        for sweep in range(sweeps):
            H6 = self._gather(leaves, plan)
            B_new = E + rho * np.einsum("i,lic->lc", quadratic.MEAN, H6)
            residual = float((A[:, None] * np.abs(B_new - B)).sum(axis=0).max()) / self.power
            self.sweeps += 1
            self.history.append(residual)
            self.times.append(time.perf_counter() - self._t_start)
            if residual <= s.tolerance:
                break
            if cancel is not None and cancel():
                raise Cancelled("solve cancelled; nothing was changed")
            B = B_new
            self._pull(leaves, anc, B, share)
            if sweep == sweeps - 1:
                H6 = self._gather(leaves, plan)
        self.H6 = H6
        self.leaf_ids, self.B = leaves, B
        self._ranges(anc, B)
        self.H = np.einsum("i,lic->lc", quadratic.MEAN, self.H6)
        self.stage_seconds["solve"] += time.perf_counter() - t0

    # -- rounds --------------------------------------------------------------------------
    def _round_steps(self):
        """One round's refine, as a generator of slices (``step`` runs one a call): split where
        outside light varies, then refine the links over the bound (the first round: the root
        cluster to itself). Returns (links, how many were refined)."""
        nd = self.nodes
        self._progress = "starting"
        yield from self.refine_lights()
        if not self.rounds:
            root = np.array([0])
            links = yield from self.refine(root, root)
            return links, len(links)
        need, split_src = self._to_refine(self.links)
        L, split_src = self.links.take(need), split_src[need]
        ends = np.where(split_src, L.src, L.rcv)
        nd.split(ends[~nd.cluster[ends]])
        self._grow_state()
        src, rcv = expand(nd, L.src, L.rcv, split_src)
        unchanged = self.links.take(~need)
        new = yield from self.refine(src, rcv, held=len(unchanged))
        links = Links.concat([unchanged, new])
        if getattr(self, "_maps", None) is not None and self._maps.links is self.links:
            self._maps = self._maps.extended(self.evaluator, ~need, new, links)
        return links, int(need.sum())

    def step(self, count: int = 1, cancel=None) -> bool:
        """One slice of a refine-solve round (whatever ``count``): a slice of the refine
        (``_round_steps``), or, once it is done, the solve; once no link needs refining (or
        the rounds ran out), a slice of the light at the result vertices (``_corner_steps``:
        the final gather if ``gather_rays``). True when done."""
        t0 = time.perf_counter()
        if self._final is not None:
            try:
                self.finished = next(self._final)
                return False
            except StopIteration as stop:
                self._memo["corners", self.settings.gather_rays] = stop.value
                self._final = None
                self.done = True
                return True
            finally:
                self.stage_seconds["vertices"] = self.stage_seconds.get("vertices", 0.0) + time.perf_counter() - t0
        if self._round is None:
            self._round = self._round_steps()
        try:
            next(self._round)
            self.stage_seconds["refine"] += time.perf_counter() - t0
            if cancel is not None and cancel():
                raise Cancelled("solve cancelled; nothing was changed")
            return False
        except StopIteration as stop:
            self.links, refined = stop.value
            self._round = None
        self.stage_seconds["refine"] += time.perf_counter() - t0
        if refined or not self.rounds:
            self.solve(cancel)
        self.rounds.append({"round": len(self.rounds), "links": len(self.links), "refined": refined,
                            "leaves": int(len(self.leaf_ids)), "sweeps": self.sweeps,
                            "seconds": round(time.perf_counter() - self._t_start, 3)})
        self.done = refined == 0 or len(self.rounds) >= self.settings.max_rounds
        if self.done:
            self._final, self.finished, self.done = self._corner_steps(self.settings.gather_rays), 0.0, False
        return self.done

    def leaf_at(self, t: np.ndarray, bary: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The leaf element (m,) holding each point of input triangle ``t`` (m,) at barycentric
        ``bary`` (m, 3), and the point's barycentric coordinates in it."""
        nd = self.nodes
        node = nd.element_root[np.asarray(t)].copy()
        lam = np.array(bary, float)
        while True:
            inner = nd.first_child[node] >= 0
            if not inner.any():
                return node, lam
            i = np.flatnonzero(inner)
            l1, l2, l3 = lam[i].T
            slot = np.where(l1 > 0.5, 1, np.where(l2 > 0.5, 2, np.where(l3 > 0.5, 3, 0)))
            mu = np.stack([1 - 2 * l3, 1 - 2 * l1, 1 - 2 * l2], 1)           # centre child
            twice = 2 * lam[i]
            for k in (1, 2, 3):
                sel = slot == k
                m = twice[sel]
                m[:, k - 1] = 0
                m[:, k - 1] = 1 - m.sum(axis=1)
                mu[sel] = m
            node[i] = nd.first_child[node[i]] + slot
            lam[i] = mu

    def radiosity_at(self, t: np.ndarray, bary: np.ndarray) -> np.ndarray:
        """B (m, 3) at points of input triangles: E + rho H with H the leaf's quadratic there."""
        nd = self.nodes
        leaf, lam = self.leaf_at(t, bary)
        row = np.searchsorted(self.leaf_ids, leaf)
        H = np.einsum("mi,mic->mc", quadratic.basis(lam), self.H6[row])
        return nd.E[leaf] + nd.rho[leaf] * H

    def _gather_of(self, B: np.ndarray) -> np.ndarray:
        """H6 (leaves, 6, 3) that the links gather from the leaves' radiosity ``B`` (pulled up
        the trees in place of the solution's, which is put back)."""
        leaves = self.leaf_ids
        saved = (self.Bn, self.Bopen, self.Bgap, self.table, self.flux)
        self.Bn, self.Bopen, self.Bgap = (a.copy() for a in saved[:3])
        try:
            self._pull(leaves, self._ancestors(leaves), B, self.contacts.gap_share(leaves))
            return self._gather(leaves, self._push_plan())
        finally:
            self.Bn, self.Bopen, self.Bgap, self.table, self.flux = saved

    def _emission_gather(self) -> np.ndarray:
        """H6 (leaves, 6, 3) of the emitters' own light alone, over the same links (the part
        of H6 that ``_emitters_at`` gives exactly at the result's corners)."""
        return self._gather_of(self.scene.emission[self.nodes.root[self.leaf_ids]])

    def delivered(self, sources: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(leaving, delivered): the power (3,) that the leaves ``sources`` (a mask over
        ``leaf_ids``) send at their solved B, and what the links hand every receiver of it.
        In a closed scene the two are equal; where not, that source's light is lost (or made)
        by the links: the books' escaped, source by source."""
        A = self.nodes.area[self.leaf_ids]
        B = np.where(np.asarray(sources, bool)[:, None], self.B, 0.0)
        H = np.einsum("i,lic->lc", quadratic.MEAN, self._gather_of(B))
        return (A[:, None] * B).sum(axis=0), (A[:, None] * H).sum(axis=0)

    def _corner_points(self, tris: np.ndarray, P: np.ndarray, T: np.ndarray, normals: np.ndarray):
        """(points, normals, back): one point per result vertex and side of a crease,
        ``CORNER_INSET`` of the way to its leaves' centroids and lifted off the surface (a
        vertex on a contact line takes the light of its own side), and for each corner of
        ``tris`` (k x 3) its point's row."""
        n = np.repeat(normals, 3, axis=0)
        key = np.column_stack([tris.reshape(-1), np.round(n * 1e6)]).astype(np.int64)
        _, first, back = np.unique(key, axis=0, return_index=True, return_inverse=True)
        back = back.reshape(-1)
        count = np.bincount(back)
        toward = np.stack([np.bincount(back, weights=c) for c in np.repeat(T.mean(axis=1), 3, axis=0).T], 1)
        p = P.reshape(-1, 3)[first]
        p = p + CORNER_INSET * (toward / count[:, None] - p) + self.caster.epsilon * n[first]
        return p, n[first], back

    def _corner_steps(self, rays: int):
        """The light (k x 3 corners, 3) at the corners of the result mesh (``_result_mesh``), in
        slices that yield the fraction done: the leaves' reflected light by a final gather of
        ``rays`` a vertex (``_gather_steps``), or with 0 each leaf's quadratic there (less the
        emitters' share, which comes next); the emitters' light (``_emitters_at``, a batch of
        corner points a slice); the outside lights' (Light objects, the World: ``nodes.external``
        about a small triangle 1% of the way in from each corner, a batch of corners a slice)."""
        from ..tasks import scaled

        nd, sc = self.nodes, self.scene
        at, leaf, _, tris, P, T = self._result_mesh()
        emitters = np.flatnonzero(sc.emission.max(axis=1) > 0)
        # shares of the time, by rays cast per corner point (the outside light's: a guess)
        cost = np.array([rays or 1, CORNER_RAYS * len(emitters), 8 * (nd.external is not None)], float)
        start = np.concatenate([[0.0], np.cumsum(cost / cost.sum())])
        if rays:
            H = yield from scaled(self._gather_steps(rays), start[0], start[1] - start[0])
        else:
            H6 = self.H6[at]
            if len(emitters):
                H6 = H6 - self._emission_gather()[at]
            bary = barycentric(P.reshape(-1, 3), np.repeat(T, 3, axis=0))            # corners in their leaves
            H = np.maximum(np.einsum("kpi,kic->kpc", quadratic.basis(bary).reshape(len(leaf), 3, 6), H6),
                           0.0)                                                     # a quadratic may dip below 0
            yield start[1]
        if len(emitters):
            H = H + (yield from scaled(self._emitters_at(tris, P, T, nd.normal[leaf], emitters),
                                       start[1], start[2] - start[1])).reshape(H.shape)
        if nd.external is not None:
            normals = np.repeat(nd.normal[leaf], 3, axis=0)
            out = np.zeros((len(normals), 3))
            batch = max(1, GATHER_BATCH_RAYS // 64)
            for first in range(0, len(out), batch):
                c = slice(first, first + batch)
                corner = P.reshape(-1, 3)[c]
                small = corner[:, None] + 0.01 * (np.repeat(T, 3, axis=0)[c] - corner[:, None])
                out[c] = nd.external(small, normals[c], np.full((1, 3), 1 / 3))[0][:, 0]
                yield start[2] + (start[3] - start[2]) * min(first + batch, len(out)) / len(out)
            H = H + out.reshape(H.shape)
        return H

    def _gather_steps(self, rays: int):
        """A final gather of the leaves' reflected light at the corners of the result mesh
        (``_result_mesh``), in batches of ``GATHER_BATCH_RAYS``: yields the fraction done,
        returns H (k x 3 corners, 3). ``rays`` stratified cosine rays per vertex on average
        (each vertex's count rounded to a square grid, ``grid_side``; ``_corner_points``), each
        taking the radiosity less emission of the leaf whose front it hits where it hits it
        (``light_shape``: a point on a ceiling by a wall sees the wall's dark top strip at close
        range, and with the wall leaf's mean the Cornell box's ceiling came out +7.5%; the
        hidden backs of two-sided lamps too; a leaf on a floor a box rests on, its open
        part's: ``_open_light``), but the Light objects' light (a sun's) made where the ray
        lands (``direct_at``: the atrium's balusters see, close by, a beam and slab striped by
        sharp shadows that their leaves hold as a mean; 5.7% per vertex against Cycles so,
        3.9% taken where the rays land); the hot leaves' light by shadow rays to them as well
        (``_hot_light``, ``mis_share``). A link hands its receiver the light of a partly seen
        source at the source's mean radiosity; many such links, each within epsilon, brought
        the furniture of a room the hot ceiling over its lamp, hidden but for a 1 cm slot,
        15-60% too bright (2-3% of each object's light). Emitters and the outside lights are
        added at the corners exactly (``_emitters_at``, ``nodes.external``).
        From ``GATHER_ADAPTIVE`` rays on, a pilot of ``GATHER_PILOT`` rays a vertex measures
        each vertex's noise and the rest go where it is (``gather_sides``)."""
        from ..formfactors.raycast import EmbreeRays
        from ..sampling import grid_side
        from ..tasks import scaled

        nd, sc = self.nodes, self.scene
        leaves = self.leaf_ids
        _, leaf, verts, tris, P, T = self._result_mesh()
        caster = EmbreeRays(PatchScene(nd.all_vertices(), nd.vids[leaves], nd.rho[leaves], nd.E[leaves],
                                       sc.object_index[nd.root[leaves]], sc.material_index[nd.root[leaves]]), 1)
        reflected = self.B - sc.emission[nd.root[leaves]]
        glow = reflected.mean(axis=1)
        hot = glow > HOT_FACTOR * np.average(glow, weights=nd.area[leaves])
        density = np.where(hot, glow, 0.0) / max(float((glow * nd.area[leaves])[hot].sum()), 1e-300)
        light, direct = self._open_light(caster, reflected, nd.rho[leaves] * nd.H_direct[leaves])
        direct_at = getattr(nd.external, "direct_at", None)
        at_hit = ~hot & (direct_at is not None)            # a hot leaf's shadow rays take its mean
        light[at_hit] = np.maximum(light[at_hit] - direct[at_hit], 0.0)
        seen = GatherTargets(caster, light, hot, density, self.contacts.twin,
                             self.contacts.covered[nd.root[leaves]], nd.tri[leaves], nd.center[leaves],
                             nd.normal[leaves], self.H6, at_hit, direct_at)
        p, n, back = self._corner_points(tris, P, T, nd.normal[leaf])
        if rays < GATHER_ADAPTIVE:
            H, _ = yield from self._gather_pass(seen, p, n, np.full(len(p), grid_side(rays)), 3)
            return H[back].reshape(len(leaf), 3, 3)
        share = GATHER_PILOT / rays
        _, var = yield from scaled(self._gather_pass(seen, p, n, np.full(len(p), grid_side(GATHER_PILOT)), 5),
                                   0.0, share)
        rho = np.zeros((len(p), 3))
        rho[back] = np.repeat(nd.rho[leaf], 3, axis=0)
        area = np.bincount(back, weights=np.repeat(triangle_geometry(verts, tris)[1] / 3, 3), minlength=len(p))
        sides = gather_sides(rays - GATHER_PILOT, (rho ** 2 * var).sum(axis=1), area)
        H, _ = yield from scaled(self._gather_pass(seen, p, n, sides, 3), share, 1 - share)
        return H[back].reshape(len(leaf), 3, 3)

    def _gather_pass(self, seen: GatherTargets, p: np.ndarray, n: np.ndarray, sides: np.ndarray, tag: int):
        """Gathered light (k, 3) at points ``p`` facing ``n``, by ``sides``^2 stratified cosine
        rays each (``_gather_batch``), and the variance of each point's estimate (k, 3); yields
        the fraction of the rays cast. ``tag`` keeps one pass's random draws apart from another's."""
        H, var = np.zeros((len(p), 3)), np.zeros((len(p), 3))
        total, done = float((sides.astype(float) ** 2).sum()), 0.0
        for m in np.unique(sides):
            at = np.flatnonzero(sides == m)
            batch = max(1, GATHER_BATCH_RAYS // (m * m))
            for first in range(0, len(at), batch):
                i = at[first:first + batch]
                rng = np.random.default_rng((self.settings.seed, tag, int(m), first))
                H[i], var[i] = self._gather_batch(seen, p[i], n[i], int(m), rng)
                done += len(i) * m * m
                yield done / total
        return H, var

    def _gather_batch(self, seen: GatherTargets, p: np.ndarray, n: np.ndarray, m: int, rng):
        """The light (k, 3) an m x m grid of cosine rays (and the hot leaves' shadow rays)
        gathers at each of points ``p`` facing ``n``, and the variance of each estimate (k, 3):
        by pairs of cells next to each other in azimuth (the strata collapsed in twos, which
        overstates a smooth light's), by the rays' spread for odd m, plus the shadow rays'."""
        from ..sampling import cosine_directions, stratified

        nd, sc = self.nodes, self.scene
        leaves, caster, rays = self.leaf_ids, seen.caster, m * m
        shadow = max(1, int(rays * HOT_SHARE)) if seen.hot.any() else 0
        u, v = stratified(m, rng.random((len(p), rays)), rng.random((len(p), rays)))
        dirs = cosine_directions(u, v, n).reshape(-1, 3)
        origins = np.repeat(p, rays, axis=0)
        dist, hit = caster.first_hit(origins, dirs)
        row = hit.copy()                                     # rows of leaf_ids, -1 for none
        h = np.flatnonzero(hit >= 0)
        behind = h[np.einsum("kc,kc->k", dirs[h], caster.scene.normals[hit[h]]) > 0]
        row[behind] = -1
        other = seen.twin[nd.root[leaves[hit[behind]]]]      # the back of a two-sided face: its twin's leaf
        behind, other = behind[other >= 0], other[other >= 0]
        x = origins + dist[:, None] * dirs
        if len(behind):
            leaf_hit, _ = self.leaf_at(other, barycentric(x[behind], sc.vertices[sc.triangles[other]]))
            row[behind] = np.searchsorted(leaves, leaf_hit)
        got = ray_light(seen, row, x, dirs, dist, n, rays, shadow)
        if seen.direct_at is not None:                       # the Light objects' light where it lands
            k = np.flatnonzero(row >= 0)
            k = k[seen.at_hit[row[k]]]
            front = caster.scene.normals[row[k]]             # a two-sided face's back: its twin's front
            inward = seen.centre[row[k]] - x[k]              # a few epsilon off a seam, as ``external``
            reach = np.sqrt(np.einsum("kc,kc->k", inward, inward))
            on = x[k] + np.minimum(INSET, SEAM_STEP * caster.epsilon / np.maximum(reach, 1e-300))[:, None] * inward
            got[k] += caster.scene.rho[row[k]] * seen.direct_at(on, front, rng)
        H, var = ray_stats(got.reshape(len(p), rays, 3), m % 2 == 0)
        if shadow:
            more, more_var = self._hot_light(seen, p, n, rays, shadow, rng)
            H, var = H + more, var + more_var
        return H, var

    def _open_light(self, caster, reflected: np.ndarray, lights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The reflected light (leaves, 3) a gather ray takes from each leaf it hits, and the
        Light objects' part of it (``lights`` made alike): ``reflected``
        but on the leaves of input triangles with covered cells (a floor a box rests on), whose
        light is made again at their open points (``Proximity.open_points``) by ``CONTACT_RAYS``
        cosine rays a leaf, with the direct part (emitters' light by the links, the outside
        light) over the open share. A ray lands on a leaf's open part, but the links gave the
        leaves the footprint's edge crosses a mean that counts the covered part as dark, and
        those beside it too little of the box's side (a furnace: 17% within 1 cm). A leaf with
        no open point takes its nearest ancestor's open mean (``_kin_mean``)."""
        from ..sampling import cosine_directions, grid_side, stratified

        nd, sc = self.nodes, self.scene
        rows = np.flatnonzero(self.contacts.covered[nd.root[self.leaf_ids]])
        if not len(rows):
            return reflected, lights
        ids = self.leaf_ids[rows]
        points, is_open = self.contacts.open_points(ids)
        share = is_open.mean(axis=1)
        m = grid_side(max(1, CONTACT_RAYS // is_open.shape[1]))
        row, _ = np.nonzero(is_open)                               # each open point's row of ids
        points = points[is_open]
        rng = np.random.default_rng((self.settings.seed, 4))
        gathered = np.zeros((len(ids), 3))
        batch = max(1, GATHER_BATCH_RAYS // (m * m))
        for first in range(0, len(row), batch):
            r = row[first:first + batch]
            n = nd.normal[ids[r]]
            u, v = stratified(m, rng.random((len(r), m * m)), rng.random((len(r), m * m)))
            dirs = cosine_directions(u, v, n).reshape(-1, 3)
            _, hit = caster.first_hit(np.repeat(points[first:first + batch] + caster.epsilon * n, m * m, axis=0), dirs)
            front = (hit >= 0) & (np.einsum("kc,kc->k", dirs, caster.scene.normals[np.maximum(hit, 0)]) < 0)
            got = np.where(front[:, None], reflected[np.maximum(hit, 0)], 0.0)
            gathered += np.stack([np.bincount(np.repeat(r, m * m), weights=got[:, c], minlength=len(ids))
                                  for c in range(3)], axis=1)
        some = share > 0
        direct = nd.E[ids] - sc.emission[nd.root[ids]]
        if sc.emission.max() > 0:
            direct = direct + nd.rho[ids] * np.einsum("i,lic->lc", quadratic.MEAN, self._emission_gather()[rows])
        light = np.zeros((len(ids), 6))                  # the light, then the Light objects' part
        light[some, :3] = (direct[some] / share[some, None]
                           + nd.rho[ids[some]] * gathered[some] / (m * m * is_open[some].sum(axis=1))[:, None])
        light[some, 3:] = lights[rows[some]] / share[some, None]
        light, found = self._kin_mean(ids, share * nd.area[ids], light, some)
        out, out_lights = reflected.copy(), lights.copy()
        out[rows[found]], out_lights[rows[found]] = light[found, :3], light[found, 3:]
        return out, out_lights

    def _kin_mean(self, ids: np.ndarray, weight: np.ndarray, values: np.ndarray, known: np.ndarray):
        """``values`` (m, c) of leaves ``ids`` where ``known``, and elsewhere the ``weight``-ed
        mean of the known leaves under the nearest ancestor that has any (found: which have a
        value)."""
        nd = self.nodes
        anc = self._ancestors(ids)
        weight = np.where(known, weight, 0.0)
        found = known.copy()
        for k in range(1, anc.shape[1]):
            if found.all():
                break
            real = anc[:, k] < nd.size
            _, key = np.unique(anc[:, k], return_inverse=True)
            key = key.ravel()
            w = np.where(real, weight, 0.0)
            total = np.bincount(key, weights=w)
            fill = ~found & real & (total[key] > 0)
            for c in range(values.shape[1]):
                values[fill, c] = np.bincount(key, weights=w * values[:, c])[key[fill]] / total[key[fill]]
            found |= fill
        return values, found

    def _hot_light(self, seen: GatherTargets, p: np.ndarray, n: np.ndarray, rays: int, samples: int, rng):
        """Irradiance (len(p), 3) at points ``p`` facing ``n`` from the hot leaves (``seen.hot``)
        sending ``seen.light`` (shaped as the cosine rays take it: ``light_shape``), by ``samples``
        shadow rays per point to points on them drawn by power (leaf by its B x area,
        stratified, then uniform on it: ``seen.density`` per unit area), weighed against the
        ``rays`` cosine rays that may hit them too (``mis_share``); and its variance (len(p), 3)
        by the samples' spread."""
        from ..sampling import strata, triangle_points

        nd, caster, density = self.nodes, seen.caster, seen.density
        hot = np.flatnonzero(seen.hot)
        ids = self.leaf_ids[hot]
        cdf = np.cumsum(density[hot] * nd.area[ids])
        k = np.minimum(np.searchsorted(cdf / cdf[-1], strata(samples, rng.random((len(p), samples)))), len(ids) - 1)
        x = triangle_points(nd.tri[ids[k]], rng.random(k.shape), rng.random(k.shape))        # (points, samples, 3)
        w = x - p[:, None]
        r = np.linalg.norm(w, axis=2)
        w /= np.maximum(r, 1e-300)[..., None]
        cos_p = np.maximum(np.einsum("pc,psc->ps", n, w), 0.0)
        cos_x = np.maximum(-np.einsum("psc,psc->ps", nd.normal[ids[k]], w), 0.0)
        weight = mis_share(cos_p, cos_x, density[hot][k], r, rays, samples)
        shown = np.flatnonzero(weight.ravel() > 0)
        dist, _ = caster.first_hit(np.repeat(p, samples, axis=0)[shown], w.reshape(-1, 3)[shown])
        weight.ravel()[shown] *= dist >= r.ravel()[shown] * (1 - 1e-6) - 10 * caster.epsilon
        lam = barycentric(x.reshape(-1, 3), nd.tri[ids[k]].reshape(-1, 3, 3))
        rows = hot[k].ravel()
        shaped = light_shape(seen.H6[rows], lam, seen.flat[rows]).reshape(*k.shape, 3)
        each = weight[..., None] * seen.light[hot][k] * shaped
        mean, var = ray_stats(each, paired=False)
        return samples * mean, samples ** 2 * var

    def _result_mesh(self):
        """The shown leaves cut at their T-vertices (``conforming``; a leaf with a T-vertex on
        an edge fans from a new centre vertex): (at, leaf, verts, tris, P, T) with ``at`` each
        result triangle's row of ``leaf_ids``/B/H, ``leaf`` its leaf node, ``P`` its corner
        points and ``T`` its leaf's corners (k, 3, 3). Kept while the solve stands, with the
        corners' light made on it (``_memo``)."""
        state = (self.sweeps, len(self.rounds))
        if self._memo.get("state") != state:
            self._memo = {"state": state}
        if "mesh" not in self._memo:
            nd = self.nodes
            shown = np.flatnonzero(self.shown[nd.root[self.leaf_ids]])
            ids = self.leaf_ids[shown]
            verts = nd.all_vertices()
            tris, row, centre = conforming(nd.vids[ids], nd.midpoint)
            fan = np.unique(row[centre.any(axis=1)])
            new_id = np.full(len(ids), -1)
            new_id[fan] = len(verts) + np.arange(len(fan))
            tris = np.where(centre, new_id[row][:, None], tris)
            verts = np.concatenate([verts, nd.tri[ids[fan]].mean(axis=1)])
            self._memo["mesh"] = shown[row], ids[row], verts, tris, verts[tris], nd.tri[ids[row]]
        return self._memo["mesh"]

    def _emitters_at(self, tris: np.ndarray, P: np.ndarray, T: np.ndarray, normals: np.ndarray,
                     emitters: np.ndarray):
        """The emitting triangles' light (k x 3, 3) at the corners of the result triangles
        ``tris`` (k, 3 vertex ids; P their points) of leaves with corners ``T`` facing
        ``normals``: the closed form times shadow rays (``lights.irradiance_at``) at each
        vertex, once per side of a crease, ``CORNER_INSET`` of the way to its leaves'
        centroids (a vertex on a contact line takes the light of its own side). Direct light
        changes fastest where a lamp is near (a wall under it, the ceiling over its back); a
        leaf's quadratic through six nodes has it only to epsilon there. Yields the fraction
        done, a batch of points at a time."""
        from ..lights import Light, irradiance_at

        sc = self.scene
        lights = [Light.polygon_light(f"triangle {t}", sc.vertices[sc.triangles[t]], sc.emission[t]) for t in emitters]
        p, n, back = self._corner_points(tris, P, T, normals)
        H = np.zeros((len(p), 3))
        batch = max(1, GATHER_BATCH_RAYS // (CORNER_RAYS * len(lights)))
        for first in range(0, len(p), batch):
            c = slice(first, first + batch)
            H[c] = irradiance_at(p[c], n[c], lights, self.caster, samples=CORNER_RAYS, cull=0.0)[0]
            yield min(first + batch, len(p)) / len(p)
        return H[back]

    def resume(self, more_rounds: int):
        """Allow ``more_rounds`` refine-solve rounds after the cap."""
        self.settings.max_rounds += more_rounds
        self.max_iterations = self.settings.max_rounds
        self.done = False

    def run(self, cancel=None) -> HierarchicalResult:
        while not self.step(cancel=cancel):
            pass
        return self.result()

    def result(self, corners: bool = True, gather: int | None = None) -> HierarchicalResult:
        """The shown leaves as a PatchScene with their B, H and the books. With ``corners``
        (the written result) the leaves are cut at their T-vertices (``_result_mesh``) and
        each triangle's corners get the leaf's quadratic there and the outside lights (Light
        objects, the World) at the corner itself, not their mean over the leaf, so a sun
        patch's edge is as sharp at the vertices as the leaves allow. With ``gather`` rays
        (None: the settings' ``gather_rays``), the leaves' reflected light reaches each corner
        by a final gather (``_gather_steps``) instead of the quadratic. The corners' light is
        made by ``step``'s last phase (``_corner_steps``), or here when not yet made."""
        from ..tasks import run

        nd, sc = self.nodes, self.scene
        gather = self.settings.gather_rays if gather is None else gather
        leaves = self.leaf_ids
        roots = nd.root[leaves]
        A = nd.area[leaves]
        emitted = (nd.E[leaves] * A[:, None]).sum(axis=0)
        absorbed = ((1 - nd.rho[leaves]) * self.H * A[:, None]).sum(axis=0)
        received = (self.H * A[:, None]).sum(axis=0)
        leaving = (self.B * A[:, None]).sum(axis=0)
        unshot = ((nd.E[leaves] + nd.rho[leaves] * self.H - self.B) * A[:, None]).sum(axis=0)
        if corners:
            at, leaf, verts, tris, P, T = self._result_mesh()
        else:
            at = np.flatnonzero(self.shown[roots])                 # rows of leaf_ids, B, H, H6
            leaf, verts, tris = leaves[at], nd.all_vertices(), nd.vids[leaves[at]]
        patches = PatchScene(verts, tris, nd.rho[leaf], nd.E[leaf], sc.object_index[nd.root[leaf]],
                             sc.material_index[nd.root[leaf]], list(sc.object_names), list(sc.material_names))
        residual = self.history[-1] if self.history else 1.0
        res = SolveResult(self.B[at], self.H[at], self.sweeps, residual <= self.settings.tolerance,
                          list(self.history), list(self.times),
                          dict(self.stage_seconds),
                          "hierarchical", emitted, absorbed, leaving - received, np.zeros(3), unshot)
        if corners:
            if ("corners", gather) not in self._memo:
                t0 = time.perf_counter()
                self._memo["corners", gather] = run(self._corner_steps(gather))
                res.seconds["vertices"] = time.perf_counter() - t0
            H = self._memo["corners", gather]
            E = sc.emission[nd.root[leaf]] if nd.external is not None else nd.E[leaf]
            corner_B = E[:, None] + nd.rho[leaf][:, None] * H
        else:
            corner_B = nd.E[leaf][:, None] + nd.rho[leaf][:, None] * np.einsum(
                "ki,lic->lkc", quadratic.AT_CORNERS, self.H6[at])
        return HierarchicalResult(patches, res, leaf, corner_B, len(self.links),
                                  int((~nd.cluster[:nd.size]).sum()), list(self.rounds))
