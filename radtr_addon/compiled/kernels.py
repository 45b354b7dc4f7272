"""The numba kernels (see ``compiled``) and, per wrapper, tiny arguments that build and try it."""
from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True)
def _lambert(poly, k, x0, x1, x2, n0, n1, n2):
    """Lambert's contour sum for the first k corners of poly seen from x facing n."""
    total = 0.0
    for i in range(k):
        j = i + 1 if i + 1 < k else 0
        a0, a1, a2 = poly[i, 0] - x0, poly[i, 1] - x1, poly[i, 2] - x2
        b0, b1, b2 = poly[j, 0] - x0, poly[j, 1] - x1, poly[j, 2] - x2
        la = max(np.sqrt(a0 * a0 + a1 * a1 + a2 * a2), 1e-300)
        lb = max(np.sqrt(b0 * b0 + b1 * b1 + b2 * b2), 1e-300)
        a0, a1, a2, b0, b1, b2 = a0 / la, a1 / la, a2 / la, b0 / lb, b1 / lb, b2 / lb
        c0, c1, c2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
        sin = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
        if sin > 1e-15:
            gamma = np.arctan2(sin, a0 * b0 + a1 * b1 + a2 * b2)
            total += gamma * (c0 * n0 + c1 * n1 + c2 * n2) / sin
    return abs(total) / (2 * np.pi)


@njit(cache=True)
def _point_factor(t, x0, x1, x2, n0, n1, n2, poly, h):
    """The form factor from x facing n to the front of triangle t (3, 3), clipped at x's
    horizon (``poly`` (4, 3) and ``h`` (3,): scratch)."""
    e0, e1, e2 = t[1, 0] - t[0, 0], t[1, 1] - t[0, 1], t[1, 2] - t[0, 2]
    f0, f1, f2 = t[2, 0] - t[0, 0], t[2, 1] - t[0, 1], t[2, 2] - t[0, 2]
    nt0, nt1, nt2 = e1 * f2 - e2 * f1, e2 * f0 - e0 * f2, e0 * f1 - e1 * f0
    if (x0 - t[0, 0]) * nt0 + (x1 - t[0, 1]) * nt1 + (x2 - t[0, 2]) * nt2 <= 0:
        return 0.0                                       # the triangle's back faces x
    above = 0
    for k in range(3):
        h[k] = (t[k, 0] - x0) * n0 + (t[k, 1] - x1) * n1 + (t[k, 2] - x2) * n2
        above += h[k] > 0
    if above == 0:
        return 0.0                                       # wholly below x's horizon
    if above == 3:
        return min(_lambert(t, 3, x0, x1, x2, n0, n1, n2), 1.0)
    c = 0                                                # clip at the horizon
    for k in range(3):
        j = k + 1 if k < 2 else 0
        if h[k] >= 0:
            poly[c] = t[k]
            c += 1
        if (h[k] >= 0) != (h[j] >= 0):
            s = h[k] / (h[k] - h[j])
            for q in range(3):
                poly[c, q] = t[k, q] + s * (t[j, q] - t[k, q])
            c += 1
    return min(_lambert(poly, c, x0, x1, x2, n0, n1, n2), 1.0)


@njit(parallel=True, cache=True)
def _polygon_factor(points, normals, tris, out):
    """out[m, p]: the form factor from points[m, p] facing normals[m] to the front of tris[m]."""
    L, P = out.shape
    for m in prange(L):
        poly, h = np.empty((4, 3)), np.empty(3)
        for p in range(P):
            out[m, p] = _point_factor(tris[m], points[m, p, 0], points[m, p, 1], points[m, p, 2],
                                      normals[m, 0], normals[m, 1], normals[m, 2], poly, h)


def polygon_factor(points: np.ndarray, normals: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """``closed_form.polygon_factor``: each (point, triangle) pair clipped and summed in
    registers (the numpy form's temporaries, the clip's six slots and the contour's cross
    products, took most of a large scene's link evaluation)."""
    if not len(points) == len(normals) == len(tris):
        raise ValueError(f"points, normals and triangles of {len(points)}, {len(normals)}, {len(tris)} pairs")
    out = np.empty(points.shape[:2])
    _polygon_factor(_reals(points), _reals(normals), _reals(tris), out)
    return out


@njit(cache=True)
def _triangle_point(tri, u, v, out):
    """``sampling.triangle_points`` for one triangle (3, 3) and uniforms u, v, into out (3,)."""
    r = np.sqrt(u)
    for c in range(3):
        out[c] = tri[0, c] + r * (tri[1, c] - tri[0, c] + v * (tri[2, c] - tri[1, c]))


@njit(cache=True)
def _point_on(e, u0, u1, u2, cluster, span, cum_area, order, node_tri, node_normal, corners, normals, out,
              out_normal):
    """One point of ``points_on`` into out (3,), its normal into out_normal (3,)."""
    if cluster[e]:
        lo, hi = span[e, 0], span[e, 1]
        base = cum_area[lo - 1] if lo > 0 else 0.0
        pick = base + u0 * (cum_area[hi - 1] - base)
        t = order[min(lo + np.searchsorted(cum_area[lo:hi], pick, side="right"), hi - 1)]
        tri, n = corners[t], normals[t]
    else:
        tri, n = node_tri[e], node_normal[e]
    _triangle_point(tri, u1, u2, out)
    out_normal[:] = n


@njit(parallel=True, cache=True)
def _points_on(ends, cluster, span, cum_area, order, node_tri, node_normal, corners, normals, u, out, out_normal):
    for m in prange(len(ends)):
        for k in range(u.shape[1]):
            _point_on(ends[m], u[m, k, 0], u[m, k, 1], u[m, k, 2], cluster, span, cum_area, order, node_tri,
                      node_normal, corners, normals, out[m, k], out_normal[m, k])


def points_on(ends, cluster, span, cum_area, order, node_tri, node_normal, corners, normals, u):
    """``hierarchical.links.Evaluator.points_on``: points (L, m, 3) and their normals on
    the nodes ``ends`` (L,), one per uniform triple u (L, m, 3): on an element's triangle,
    or on the input triangle of a cluster that u[..., 0] picks by area (its members
    ``order[span[e, 0]:span[e, 1]]``, ``cum_area`` their running area), by the square-root
    warp of u[..., 1:] (``sampling.triangle_points``)."""
    if len(ends) != len(u):
        raise ValueError(f"{len(ends)} nodes but uniforms for {len(u)}")
    u = _reals(u)
    out, out_normal = np.empty(u.shape), np.empty(u.shape)
    _points_on(_ints(ends), np.ascontiguousarray(cluster, np.bool_), _ints(span), _reals(cum_area), _ints(order),
               _reals(node_tri), _reals(node_normal), _reals(corners), _reals(normals), u, out, out_normal)
    return out, out_normal


@njit(parallel=True, cache=True)
def _member_shares(lo, count, start, link, order, normals, areas, w, sending, other, cluster, center, node_tri,
                   node_normal, corners, centroids, eps, undo, pos, tri, share):
    for i in prange(len(lo)):
        j = link[i]
        o = other[j]
        poly, h = np.empty((4, 3)), np.empty(3)
        for k in range(count[i]):
            e, t = start[i] + k, order[lo[i] + k]
            pos[e], tri[e] = i, t
            if cluster[o]:
                c = normals[t, 0] * w[j, 0] + normals[t, 1] * w[j, 1] + normals[t, 2] * w[j, 2]
                share[e] = areas[t] * max(c, 0.0) if sending else max(-c, 0.0)
            elif sending:                                # from the element's centre to t
                n0, n1, n2 = node_normal[o, 0], node_normal[o, 1], node_normal[o, 2]
                share[e] = undo[j] * _point_factor(corners[t], center[o, 0] + eps * n0, center[o, 1] + eps * n1,
                                                   center[o, 2] + eps * n2, n0, n1, n2, poly, h)
            else:                                        # from t's centroid to the element
                n0, n1, n2 = normals[t, 0], normals[t, 1], normals[t, 2]
                share[e] = undo[j] * _point_factor(node_tri[o], centroids[t, 0] + eps * n0,
                                                   centroids[t, 1] + eps * n1, centroids[t, 2] + eps * n2,
                                                   n0, n1, n2, poly, h)


def member_shares(lo, count, link, order, normals, areas, w, sending, other, cluster, center, node_tri, node_normal,
                  corners, centroids, eps, undo):
    """``hierarchical.solve._member_shares``: per (link i, member t of its cluster end, the
    input triangles ``order[lo[i]:lo[i] + count[i]]``) the entry's link position, t, and t's
    share of link ``link[i]``'s light along w: A max(0, n.w) sent or max(0, -n.w) taken
    where the link's ``other`` end is a cluster; where it is an element, the closed form
    (sending: from the element's centre, lifted ``eps``, to t; taking: from t's centroid to
    the element) times the link's ``undo``."""
    if not len(lo) == len(count) == len(link):
        raise ValueError(f"{len(lo)} starts, {len(count)} counts and {len(link)} links")
    count = _ints(count)
    start = np.cumsum(count) - count
    n = int(count.sum())
    pos, tri, share = np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n)
    _member_shares(_ints(lo), count, start, _ints(link), _ints(order), _reals(normals), _reals(areas), _reals(w),
                   bool(sending), _ints(other), np.ascontiguousarray(cluster, np.bool_), _reals(center),
                   _reals(node_tri), _reals(node_normal), _reals(corners), _reals(centroids), float(eps),
                   _reals(undo), pos, tri, share)
    return pos, tri, share


@njit(cache=True)
def _splitmix(keys, count, out):
    """``sampling.hashed_uniforms`` of one entry's integer ``keys`` into ``out[:count]``."""
    gold = np.uint64(0x9E3779B97F4A7C15)
    h = np.uint64(0)
    for k in keys:
        h = (h ^ np.uint64(k)) * gold
    for i in range(count):
        h = h + gold
        z = (h ^ (h >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
        out[i] = np.float64(z >> np.uint64(11)) / 9007199254740992.0


#: Entries of ``member_rays`` a thread takes at a time (its scratch made once for them).
MEMBER_RAYS_BLOCK = 4096


@njit(parallel=True, cache=True)
def _member_rays(pos, t, link, end, other, vis, v, cluster, span, cum_area, order, node_tri, node_normal, corners,
                 normals, eps, faced, origin, direction, length):
    for block in prange((len(t) + MEMBER_RAYS_BLOCK - 1) // MEMBER_RAYS_BLOCK):
        u, keys = np.empty(5), np.empty(3, np.int64)
        p, q, nb = np.empty(3), np.empty(3), np.empty(3)
        for m in range(block * MEMBER_RAYS_BLOCK, min((block + 1) * MEMBER_RAYS_BLOCK, len(t))):
            faced[m] = False
            j = link[pos[m]]
            if not (vis[j] > 0 and vis[j] < 1 and v[m] > 0):
                continue
            keys[0], keys[1], keys[2] = end[j], other[j], t[m]
            _splitmix(keys, 5, u)
            na = normals[t[m]]
            _triangle_point(corners[t[m]], u[0], u[1], p)
            _point_on(other[j], u[2], u[3], u[4], cluster, span, cum_area, order, node_tri, node_normal, corners,
                      normals, q, nb)
            d0, d1, d2 = q[0] - p[0], q[1] - p[1], q[2] - p[2]
            faced[m] = (na[0] * d0 + na[1] * d1 + na[2] * d2 > 0) and (nb[0] * d0 + nb[1] * d1 + nb[2] * d2 < 0)
            if faced[m]:
                ray = _ray_between(p[0], p[1], p[2], q[0], q[1], q[2], na[0], na[1], na[2], nb[0], nb[1], nb[2],
                                   eps)
                for c in range(3):
                    origin[m, c], direction[m, c] = ray[c], ray[3 + c]
                length[m] = ray[6]


def member_rays(pos, t, link, end, other, vis, v, cluster, span, cum_area, order, node_tri, node_normal, corners,
                normals, eps):
    """``hierarchical.solve._member_visibility``'s rays: per entry (link ``link[pos]``, input
    triangle t of its cluster ``end``, share v) of a partly visible link (0 < ``vis`` < 1)
    with v > 0, a point on t and one on the link's ``other`` end (by area over a cluster's
    members, ``points_on``) from ``sampling.hashed_uniforms`` of (end, other, t); whether
    the two face each other (False for entries not cast), and where they do the ray of
    ``EmbreeRays.clear_between`` (origins, directions (k, 3), lengths (k,))."""
    if not len(pos) == len(t) == len(v):
        raise ValueError(f"{len(pos)} positions, {len(t)} triangles and {len(v)} shares")
    k = len(t)
    faced = np.empty(k, np.bool_)
    origin, direction, length = np.zeros((k, 3)), np.zeros((k, 3)), np.zeros(k)
    _member_rays(_ints(pos), _ints(t), _ints(link), _ints(end), _ints(other), _reals(vis), _reals(v),
                 np.ascontiguousarray(cluster, np.bool_), _ints(span), _reals(cum_area), _ints(order),
                 _reals(node_tri), _reals(node_normal), _reals(corners), _reals(normals), float(eps), faced, origin,
                 direction, length)
    return faced, origin, direction, length


@njit(cache=True)
def _member(e, k, cluster, span, order, node_tri, node_normal, corners, normals):
    """Triangle k of node e and its normal: a cluster's k-th input triangle, an element's own."""
    if cluster[e]:
        t = order[span[e, 0] + k]
        return corners[t], normals[t]
    return node_tri[e], node_normal[e]


@njit(cache=True)
def _box_ahead(n, p, lo, hi, e):
    """How far the box (lo, hi) of node e reaches ahead of the plane through p facing n: at
    its corner farthest along n, summed as ``_facing`` sums a triangle's corner, so that in
    floating point too no corner inside the box comes out further."""
    x0 = hi[e, 0] if n[0] > 0 else lo[e, 0]
    x1 = hi[e, 1] if n[1] > 0 else lo[e, 1]
    x2 = hi[e, 2] if n[2] > 0 else lo[e, 2]
    return n[0] * (x0 - p[0]) + n[1] * (x1 - p[1]) + n[2] * (x2 - p[2])


@njit(parallel=True, cache=True)
def _facing(src, rcv, cluster, span, order, node_tri, node_normal, corners, normals, lo, hi, tol, out):
    """out[m]: whether some pair of the two ends' triangles has each one's corner ahead of the other's plane."""
    for m in prange(len(src)):
        s, r = src[m], rcv[m]
        a = span[s, 1] - span[s, 0] if cluster[s] else 1
        b = span[r, 1] - span[r, 0] if cluster[r] else 1
        found = False
        for i in range(a):
            ts, ns = _member(s, i, cluster, span, order, node_tri, node_normal, corners, normals)
            if _box_ahead(ns, ts[0], lo, hi, r) <= tol:
                continue                                 # all of R's box behind this one's plane
            for j in range(b):
                tr, nr = _member(r, j, cluster, span, order, node_tri, node_normal, corners, normals)
                ahead_r, ahead_s = -np.inf, -np.inf
                for k in range(3):
                    ahead_r = max(ahead_r, ns[0] * (tr[k, 0] - ts[0, 0]) + ns[1] * (tr[k, 1] - ts[0, 1])
                                  + ns[2] * (tr[k, 2] - ts[0, 2]))
                    ahead_s = max(ahead_s, nr[0] * (ts[k, 0] - tr[0, 0]) + nr[1] * (ts[k, 1] - tr[0, 1])
                                  + nr[2] * (ts[k, 2] - tr[0, 2]))
                if ahead_r > tol and ahead_s > tol:
                    found = True
                    break
            if found:
                break
        out[m] = found


def facing(src, rcv, cluster, span, order, node_tri, node_normal, corners, normals, lo, hi, tol):
    """``hierarchical.links.Evaluator.facing`` for links (src, rcv) of nodes: True where some
    triangle of one end has a corner of some triangle of the other ahead of its plane (more
    than ``tol``) and that one has a corner of it ahead of its own, pair by pair until one
    is found (a cluster's input triangles ``order[span[e, 0]:span[e, 1]]``, an element its
    own ``node_tri``); a triangle of the source with all of the receiver's bounding box
    (``lo``, ``hi``) behind its plane is passed over whole."""
    src, rcv = _ints(src), _ints(rcv)
    if len(src) != len(rcv):
        raise ValueError(f"{len(src)} sources but {len(rcv)} receivers")
    out = np.empty(len(src), np.bool_)
    _facing(src, rcv, np.ascontiguousarray(cluster, np.bool_), _ints(span), _ints(order), _reals(node_tri),
            _reals(node_normal), _reals(corners), _reals(normals), _reals(lo), _reals(hi), float(tol), out)
    return out


@njit(cache=True)
def _ray_between(o0, o1, o2, t0, t1, t2, a0, a1, a2, b0, b1, b2, eps):
    """``formfactors.raycast.clear_rays`` for one pair: origin o facing a, target t facing b
    (a zero normal: not lifted); returns the ray's origin, unit direction and length."""
    side = eps if (t0 - o0) * a0 + (t1 - o1) * a1 + (t2 - o2) * a2 >= 0 else -eps
    o0, o1, o2 = o0 + side * a0, o1 + side * a1, o2 + side * a2
    side = eps if (o0 - t0) * b0 + (o1 - t1) * b1 + (o2 - t2) * b2 >= 0 else -eps
    t0, t1, t2 = t0 + side * b0, t1 + side * b1, t2 + side * b2
    d0, d1, d2 = t0 - o0, t1 - o1, t2 - o2
    dist = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    g = max(dist, 1e-300)
    d0, d1, d2 = d0 / g, d1 / g, d2 / g
    return o0 + eps * d0, o1 + eps * d1, o2 + eps * d2, d0, d1, d2, max(dist - 3 * eps, 0.0)


@njit(parallel=True, cache=True)
def _pair_rays(s, r, us, ur, cluster, span, cum_area, order, node_tri, node_normal, corners, normals, eps,
               origin, direction, length, weight):
    L, m = us.shape[0], us.shape[1]
    for i in prange(L):
        a, na, b, nb = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
        for k in range(m):
            _point_on(s[i], us[i, k, 0], us[i, k, 1], us[i, k, 2], cluster, span, cum_area, order, node_tri,
                      node_normal, corners, normals, a, na)
            _point_on(r[i], ur[i, k, 0], ur[i, k, 1], ur[i, k, 2], cluster, span, cum_area, order, node_tri,
                      node_normal, corners, normals, b, nb)
            d0, d1, d2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
            dist = max(np.sqrt(d0 * d0 + d1 * d1 + d2 * d2), 1e-300)
            d0, d1, d2 = d0 / dist, d1 / dist, d2 / dist
            w = max(na[0] * d0 + na[1] * d1 + na[2] * d2, 0.0) * max(-(nb[0] * d0 + nb[1] * d1 + nb[2] * d2), 0.0)
            w /= dist * dist
            weight[i, k] = w
            if w > 0:
                ray = _ray_between(a[0], a[1], a[2], b[0], b[1], b[2], na[0], na[1], na[2], nb[0], nb[1], nb[2], eps)
                for c in range(3):
                    origin[i, k, c], direction[i, k, c] = ray[c], ray[3 + c]
                length[i, k] = ray[6]


def pair_rays(s, r, us, ur, cluster, span, cum_area, order, node_tri, node_normal, corners, normals, eps):
    """``hierarchical.links.Evaluator._visible_between``'s rays in one pass: for links (s, r)
    of nodes and m uniform triples each at each end (L, m, 3), the points on the ends that
    they place (as ``points_on``), the point-to-point kernel cos cos / d^2 (L, m), and where
    it is positive the ray of ``EmbreeRays.clear_between`` between them (origins, directions
    (L, m, 3), lengths (L, m)). The points, their weights and their rays had been numpy's
    passes over arrays a link's worth of rays deep (a fifth of a large scene's refine)."""
    if not len(s) == len(r) == len(us) == len(ur):
        raise ValueError(f"{len(s)} sources, {len(r)} receivers, uniforms for {len(us)} and {len(ur)}")
    us, ur = _reals(us), _reals(ur)
    origin, direction = np.zeros(us.shape), np.zeros(us.shape)
    length, weight = np.zeros(us.shape[:2]), np.empty(us.shape[:2])
    _pair_rays(_ints(s), _ints(r), us, ur, np.ascontiguousarray(cluster, np.bool_), _ints(span), _reals(cum_area),
               _ints(order), _reals(node_tri), _reals(node_normal), _reals(corners), _reals(normals), float(eps),
               origin, direction, length, weight)
    return origin, direction, length, weight


@njit(parallel=True, cache=True)
def _shadow_rays(x, n_r, tri, n_s, u, v, eps, origin, direction, length, weight):
    K, m = u.shape
    for k in prange(K):
        for j in range(m):
            r, s = np.sqrt(u[k, j]), v[k, j]
            a, b, c = tri[k, 0], tri[k, 1], tri[k, 2]
            t0 = a[0] + r * (b[0] - a[0] + s * (c[0] - b[0]))
            t1 = a[1] + r * (b[1] - a[1] + s * (c[1] - b[1]))
            t2 = a[2] + r * (b[2] - a[2] + s * (c[2] - b[2]))
            d0, d1, d2 = t0 - x[k, 0], t1 - x[k, 1], t2 - x[k, 2]
            dist = max(np.sqrt(d0 * d0 + d1 * d1 + d2 * d2), 1e-300)
            d0, d1, d2 = d0 / dist, d1 / dist, d2 / dist
            w = max(d0 * n_r[k, 0] + d1 * n_r[k, 1] + d2 * n_r[k, 2], 0.0) * \
                max(-(d0 * n_s[k, 0] + d1 * n_s[k, 1] + d2 * n_s[k, 2]), 0.0)
            weight[k, j] = w
            if w > 0:
                ray = _ray_between(x[k, 0], x[k, 1], x[k, 2], t0, t1, t2, 0.0, 0.0, 0.0,
                                   n_s[k, 0], n_s[k, 1], n_s[k, 2], eps)
                for c in range(3):
                    origin[k, j, c], direction[k, j, c] = ray[c], ray[3 + c]
                length[k, j] = ray[6]


def shadow_rays(x, n_r, tri, n_s, u, v, eps):
    """``hierarchical.links.shadow_rays``: for each point x (K, 3) facing ``n_r`` and m
    uniforms (u, v) (K, m), the point on triangle ``tri`` (K, 3, 3) that they place, the
    point-to-point cosines' product (K, m) and, where it is positive, the shadow ray of
    ``EmbreeRays.clear_between`` from x to it (origins, directions (K, m, 3), lengths (K, m))."""
    if not len(x) == len(n_r) == len(tri) == len(n_s) == len(u) == len(v):
        raise ValueError(f"{len(x)} points, {len(tri)} triangles and uniforms for {len(u)}")
    u = _reals(u)
    origin, direction = np.zeros(u.shape + (3,)), np.zeros(u.shape + (3,))
    length, weight = np.zeros(u.shape), np.empty(u.shape)
    _shadow_rays(_reals(x), _reals(n_r), _reals(tri), _reals(n_s), u, _reals(v), float(eps), origin, direction,
                 length, weight)
    return origin, direction, length, weight


@njit(parallel=True, cache=True)
def _cosine_directions(u, v, normals, out):
    K, m = u.shape
    for k in prange(K):
        n0, n1, n2 = normals[k, 0], normals[k, 1], normals[k, 2]
        if abs(n0) < 0.9:                                # t = x cross n, else y cross n
            t0, t1, t2 = 0.0, -n2, n1
        else:
            t0, t1, t2 = n2, 0.0, -n0
        size = np.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        t0, t1, t2 = t0 / size, t1 / size, t2 / size
        b0, b1, b2 = n1 * t2 - n2 * t1, n2 * t0 - n0 * t2, n0 * t1 - n1 * t0
        for j in range(m):
            r, phi = np.sqrt(u[k, j]), 2 * np.pi * v[k, j]
            x, y, z = r * np.cos(phi), r * np.sin(phi), np.sqrt(max(1 - u[k, j], 0.0))
            out[k, j, 0] = x * t0 + y * b0 + z * n0
            out[k, j, 1] = x * t1 + y * b1 + z * n1
            out[k, j, 2] = x * t2 + y * b2 + z * n2


def cosine_directions(u, v, normals):
    """``sampling.cosine_directions`` for u, v (k, m): cosine-weighted unit directions
    (k, m, 3) about ``normals`` (k, 3), in ``sampling.tangent_frames``' frames."""
    if not (np.ndim(u) == 2 and np.shape(u) == np.shape(v) and len(normals) == len(u)):
        raise ValueError(f"samples {np.shape(u)} and {np.shape(v)} for {len(normals)} normals")
    u = _reals(u)
    out = np.empty(u.shape + (3,))
    _cosine_directions(u, _reals(v), _reals(normals), out)
    return out


@njit(parallel=True, cache=True)
def _clear_rays(o, t, a, b, eps, origin, direction, length):
    for k in prange(len(o)):
        ray = _ray_between(o[k, 0], o[k, 1], o[k, 2], t[k, 0], t[k, 1], t[k, 2], a[k, 0], a[k, 1], a[k, 2],
                           b[k, 0], b[k, 1], b[k, 2], eps)
        for c in range(3):
            origin[k, c], direction[k, c] = ray[c], ray[3 + c]
        length[k] = ray[6]


def clear_rays(origins, targets, origin_normals, target_normals, eps):
    """``formfactors.raycast.clear_rays``: the rays of ``EmbreeRays.clear_between`` between
    points (k, 3), each end lifted ``eps`` towards the other along its normal (k, 3 or
    broadcast; None: not lifted); origins, unit directions (k, 3) and lengths (k,)."""
    origins, targets = _reals(origins), _reals(targets)
    if origins.shape != targets.shape:
        raise ValueError(f"{origins.shape} origins but {targets.shape} targets")
    a, b = (np.zeros(origins.shape) if n is None else _reals(np.broadcast_to(n, origins.shape))
            for n in (origin_normals, target_normals))
    origin, direction, length = np.empty(origins.shape), np.empty(origins.shape), np.empty(len(origins))
    _clear_rays(origins, targets, a, b, float(eps), origin, direction, length)
    return origin, direction, length


@njit(parallel=True, cache=True)
def _ray_light(row, x, dirs, dist, tri, H6, light, flat, hot, density, normal, point_normal, rays, shadow, inset,
               mean, shape_max, out):
    """out[k]: the light gather ray k takes from leaf row[k] at x[k] (see ``ray_light``)."""
    for k in prange(len(row)):
        out[k, 0] = out[k, 1] = out[k, 2] = 0.0
        r = row[k]
        if r < 0:
            continue
        a0, a1, a2 = tri[r, 0, 0], tri[r, 0, 1], tri[r, 0, 2]
        e0, e1, e2 = tri[r, 1, 0] - a0, tri[r, 1, 1] - a1, tri[r, 1, 2] - a2
        f0, f1, f2 = tri[r, 2, 0] - a0, tri[r, 2, 1] - a1, tri[r, 2, 2] - a2
        g0, g1, g2 = x[k, 0] - a0, x[k, 1] - a1, x[k, 2] - a2
        d00, d01, d11 = e0 * e0 + e1 * e1 + e2 * e2, e0 * f0 + e1 * f1 + e2 * f2, f0 * f0 + f1 * f1 + f2 * f2
        d20, d21 = g0 * e0 + g1 * e1 + g2 * e2, g0 * f0 + g1 * f1 + g2 * f2
        den = d00 * d11 - d01 * d01
        if den == 0:
            den = 1e-300
        v = (d11 * d20 - d01 * d21) / den
        w = (d00 * d21 - d01 * d20) / den
        q = 1 - inset
        l1, l2, l3 = (1 - v - w - inset / 3) / q, (v - inset / 3) / q, (w - inset / 3) / q
        b0, b1, b2 = l1 * (2 * l1 - 1), l2 * (2 * l2 - 1), l3 * (2 * l3 - 1)
        b3, b4, b5 = 4 * l2 * l3, 4 * l3 * l1, 4 * l1 * l2
        share = 1.0
        if shadow > 0 and hot[r]:
            p = k // rays
            cos_p = dirs[k, 0] * point_normal[p, 0] + dirs[k, 1] * point_normal[p, 1] + dirs[k, 2] * point_normal[p, 2]
            cos_x = abs(dirs[k, 0] * normal[r, 0] + dirs[k, 1] * normal[r, 1] + dirs[k, 2] * normal[r, 2])
            g = cos_p * cos_x
            share = rays * g / max(rays * g + np.pi * shadow * density[r] * dist[k] ** 2, 1e-300)
        for c in range(3):
            s = 1.0
            if not flat[r]:
                m = (mean[0] * H6[r, 0, c] + mean[1] * H6[r, 1, c] + mean[2] * H6[r, 2, c] + mean[3] * H6[r, 3, c]
                     + mean[4] * H6[r, 4, c] + mean[5] * H6[r, 5, c])
                if m > 0:
                    at = (b0 * H6[r, 0, c] + b1 * H6[r, 1, c] + b2 * H6[r, 2, c] + b3 * H6[r, 3, c]
                          + b4 * H6[r, 4, c] + b5 * H6[r, 5, c])
                    s = min(max(at / m, 0.0), shape_max)
            out[k, c] = light[r, c] * s * share


def ray_light(row, x, dirs, dist, tri, H6, light, flat, hot, density, normal, point_normal, rays, shadow, inset,
              mean, shape_max):
    """``hierarchical.solve.ray_light``: the light (k, 3) each final-gather ray takes from the
    leaf ``row`` it hits (-1: none) at ``x``: the leaf's ``light`` times its quadratic ``H6``
    at x over the quadratic's mean (``quadratic.basis`` of the triangle inset by ``inset``,
    clamped to [0, shape_max]; 1 where ``flat`` or the mean is not positive), and of a
    ``hot`` leaf the balance-heuristic share against ``shadow`` shadow rays (``mis_share``)."""
    row = _ints(row)
    out = np.empty((len(row), 3))
    _ray_light(row, _reals(x), _reals(dirs), _reals(dist), _reals(tri), _reals(H6), _reals(light),
               np.ascontiguousarray(flat, np.bool_), np.ascontiguousarray(hot, np.bool_), _reals(density),
               _reals(normal), _reals(point_normal), int(rays), int(shadow), float(inset), _reals(mean),
               float(shape_max), out)
    return out


@njit(parallel=True, cache=True)
def _source_term(src, d, dw, in_gap, cluster, Bgap, Bopen, table, bound, out):
    for m in prange(len(src)):
        s = src[m]
        for c in range(3):
            if not cluster[s]:
                out[m, c] = Bgap[s, c] if in_gap[m] else Bopen[s, c]
            elif bound:
                out[m, c] = max(table[s, d[m, 0], c], table[s, d[m, 1], c], table[s, d[m, 2], c])
            else:
                out[m, c] = dw[m, 0] * table[s, d[m, 0], c] + dw[m, 1] * table[s, d[m, 1], c] \
                    + dw[m, 2] * table[s, d[m, 2], c]


def source_term(src, d, dw, in_gap, cluster, Bgap, Bopen, table, bound):
    """``hierarchical.solve.HierarchicalRadiosity._source_term`` before the cluster maps: per
    link (source ``src``, its three table directions ``d`` and their weights ``dw``) the
    radiosity (L, 3) of an element source, ``Bgap`` where the link is ``in_gap`` else
    ``Bopen``, and of a cluster source its ``table`` read between the directions (their
    largest where ``bound``), in one pass (numpy's gathers and where, once a sweep over a
    large scene's millions of links, took 13 s of its solve)."""
    src = _ints(src)
    out = np.empty((len(src), 3))
    _source_term(src, _ints(d), _reals(dw), np.ascontiguousarray(in_gap, np.bool_),
                 np.ascontiguousarray(cluster, np.bool_), _reals(Bgap), _reals(Bopen), _reals(table), bool(bound), out)
    return out


@njit(parallel=True, cache=True)
def _csr_times(indptr, indices, data, x, out):
    for i in prange(len(indptr) - 1):
        for c in range(x.shape[1]):
            out[i, c] = 0.0
        for j in range(indptr[i], indptr[i + 1]):
            col, a = indices[j], data[j]
            for c in range(x.shape[1]):
                out[i, c] += a * x[col, c]


def csr_times(indptr, indices, data, x):
    """A CSR matrix (``indptr``, ``indices``, ``data``) times x (n, c), its rows shared over
    the cores (scipy's product runs on one: 16 s of a large scene's solve). No bounds are
    checked (``hierarchical.solve.times`` checks the shapes). The index arrays are taken as
    scipy keeps them, int32 or int64: converting tens of millions of indices at every
    product would cost more than the product saves."""
    x = _reals(x)
    if x.ndim != 2:
        raise ValueError(f"x must be (n, c), not {x.shape}")
    out = np.empty((len(indptr) - 1, x.shape[1]))
    _csr_times(_index(indptr), _index(indices), _reals(data), x, out)
    return out


@njit(cache=True)
def _centre(t, out):
    """The centroid of triangle t into ``out``; returns its distance to the farthest corner."""
    for q in range(3):
        out[q] = (t[0, q] + t[1, q] + t[2, q]) / 3
    reach = 0.0
    for k in range(3):
        reach = max(reach, np.sqrt((t[k, 0] - out[0]) ** 2 + (t[k, 1] - out[1]) ** 2 + (t[k, 2] - out[2]) ** 2))
    return reach


@njit(parallel=True, cache=True)
def _pair_sums(src, rcv, first_s, first_r, cluster, span, order, node_tri, node_normal, corners, normals, points,
               far, eps, sent, taken, total):
    for j in prange(len(src)):
        s, r = src[j], rcv[j]
        a = span[s, 1] - span[s, 0] if cluster[s] else 1
        b = span[r, 1] - span[r, 0] if cluster[r] else 1
        poly, h, cr, cs = np.empty((4, 3)), np.empty(3), np.empty(3), np.empty(3)
        for k in range(b):
            tr, nr = _member(r, k, cluster, span, order, node_tri, node_normal, corners, normals)
            e0, e1, e2 = tr[1, 0] - tr[0, 0], tr[1, 1] - tr[0, 1], tr[1, 2] - tr[0, 2]
            f0, f1, f2 = tr[2, 0] - tr[0, 0], tr[2, 1] - tr[0, 1], tr[2, 2] - tr[0, 2]
            c0, c1, c2 = e1 * f2 - e2 * f1, e2 * f0 - e0 * f2, e0 * f1 - e1 * f0
            area = 0.5 * np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
            reach_r = _centre(tr, cr)
            for i in range(a):
                ts, _ = _member(s, i, cluster, span, order, node_tri, node_normal, corners, normals)
                reach = reach_r + _centre(ts, cs)
                if (cs[0] - cr[0]) ** 2 + (cs[1] - cr[1]) ** 2 + (cs[2] - cr[2]) ** 2 > (far * reach) ** 2:
                    f = _point_factor(ts, cr[0] + eps * nr[0], cr[1] + eps * nr[1], cr[2] + eps * nr[2],
                                      nr[0], nr[1], nr[2], poly, h)
                else:
                    f = 0.0
                    for p in range(points.shape[0]):
                        u, v, w = points[p, 0], points[p, 1], points[p, 2]
                        x0 = u * tr[0, 0] + v * tr[1, 0] + w * tr[2, 0] + eps * nr[0]
                        x1 = u * tr[0, 1] + v * tr[1, 1] + w * tr[2, 1] + eps * nr[1]
                        x2 = u * tr[0, 2] + v * tr[1, 2] + w * tr[2, 2] + eps * nr[2]
                        f += _point_factor(ts, x0, x1, x2, nr[0], nr[1], nr[2], poly, h)
                    f /= points.shape[0]
                sent[first_s[j] + i] += area * f
                taken[first_r[j] + k] += f
                total[j] += area * f


def pair_sums(src, rcv, count_s, count_r, cluster, span, order, node_tri, node_normal, corners, normals, points, far,
              eps):
    """``hierarchical.solve._pair_sums``: for the links (src, rcv), whose ends hold ``count_s``
    and ``count_r`` triangles (a cluster's members ``order[span[e, 0]:span[e, 1]]``, an
    element its own), and each pair (s, r) of them, P the mean over barycentric ``points``
    of r (lifted ``eps`` along its normal) of r's form factor to the front of s, or at r's
    centroid alone where the centroids are over ``far`` times the sum of the triangles'
    reaches (centroid to farthest corner) apart; returns
    sent (sum of A_r P per triangle s, link after link), taken (sum of P per triangle r)
    and total (sum of A_r P per link)."""
    src, rcv, count_s, count_r = _ints(src), _ints(rcv), _ints(count_s), _ints(count_r)
    if not len(src) == len(rcv) == len(count_s) == len(count_r):
        raise ValueError(f"{len(src)} sources, {len(rcv)} receivers, {len(count_s)} and {len(count_r)} counts")
    sent, taken, total = np.zeros(int(count_s.sum())), np.zeros(int(count_r.sum())), np.zeros(len(src))
    _pair_sums(src, rcv, np.cumsum(count_s) - count_s, np.cumsum(count_r) - count_r,
               np.ascontiguousarray(cluster, np.bool_), _ints(span), _ints(order), _reals(node_tri),
               _reals(node_normal), _reals(corners), _reals(normals), _reals(points), float(far), float(eps),
               sent, taken, total)
    return sent, taken, total


def _index(a):
    """Contiguous int32 or int64 as given (the two builds of a kernel over scipy's indices)."""
    a = np.asarray(a)
    return np.ascontiguousarray(a, a.dtype if a.dtype in (np.int32, np.int64) else np.int64)


def _ints(a):
    """Contiguous int64, the one type the kernels are built for (no rebuild at a caller's int32)."""
    return np.ascontiguousarray(a, np.int64)


def _reals(a):
    """Contiguous float64, as ``_ints``."""
    return np.ascontiguousarray(a, np.float64)


#: Per wrapper, tiny arguments that build it and try it once.
SMOKE = {
    "polygon_factor": lambda: (np.zeros((1, 1, 3)), np.array([[0.0, 0.0, 1.0]]),
                               np.array([[[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]])),
    "points_on": lambda: (np.array([0, 1]), np.array([True, False]), np.array([[0, 1], [0, 1]]), np.array([0.5]),
                          np.array([0]), np.zeros((2, 3, 3)), np.zeros((2, 3)), np.eye(3)[None], np.eye(3)[:1],
                          np.full((2, 1, 3), 0.5)),
    "shadow_rays": lambda: (np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]),
                            np.array([[[0.0, 0.0, 1.0], [0.0, 1.0, 1.0], [1.0, 0.0, 1.0]]]),
                            np.array([[0.0, 0.0, -1.0]]), np.full((1, 1), 0.5), np.full((1, 1), 0.5), 1e-6),
    "cosine_directions": lambda: (np.full((1, 1), 0.5), np.full((1, 1), 0.5), np.array([[0.0, 0.0, 1.0]])),
    "clear_rays": lambda: (np.zeros((1, 3)), np.ones((1, 3)), np.array([[0.0, 0.0, 1.0]]), None, 1e-6),
    "facing": lambda: (np.array([0]), np.array([1]), np.array([False, False]), np.zeros((2, 2), np.int64),
                       np.array([0]),
                       np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0.0, 0, 1], [0, 1, 1], [1, 0, 1]]]),
                       np.array([[0.0, 0, 1], [0, 0, -1]]), np.zeros((1, 3, 3)), np.eye(3)[:1],
                       np.array([[0.0, 0, 0], [0, 0, 1]]), np.array([[1.0, 1, 0], [1, 1, 1]]), 1e-9),
    "ray_light": lambda: (np.array([0, -1]), np.full((2, 3), 0.25), np.array([[0.0, 0, -1], [0, 0, 1]]), np.ones(2),
                          np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]]), np.ones((1, 6, 3)), np.ones((1, 3)),
                          np.array([False]), np.array([True]), np.ones(1), np.array([[0.0, 0, 1]]),
                          np.array([[0.0, 0, 1]]), 2, 1, 0.05, np.full(6, 1 / 6), 4.0),
    "member_shares": lambda: (np.array([0]), np.array([1]), np.array([0]), np.array([0]), np.eye(3)[:1],
                              np.ones(1), np.eye(3)[:1], True, np.array([0]), np.array([False]), np.zeros((1, 3)),
                              np.array([[[0.0, 0, 1], [1, 0, 1], [0, 1, 1]]]), np.array([[0.0, 0, 1]]),
                              np.array([[[0.0, 0, 1], [1, 0, 1], [0, 1, 1]]]), np.zeros((1, 3)), 1e-6, np.ones(1)),
    "source_term": lambda: (np.array([0, 1]), np.zeros((2, 3), np.int64), np.full((2, 3), 1 / 3),
                            np.array([False, True]), np.array([True, False]), np.ones((2, 3)), np.ones((2, 3)),
                            np.ones((1, 3, 3)), False),
    "pair_rays": lambda: (np.array([0]), np.array([1]), np.full((1, 1, 3), 0.5), np.full((1, 1, 3), 0.5),
                          np.array([True, False]), np.array([[0, 1], [0, 1]]), np.array([0.5]), np.array([0]),
                          np.array([[[0.0, 0, 1], [0, 1, 1], [1, 0, 1]]] * 2), np.array([[0.0, 0, -1]] * 2),
                          np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]]), np.array([[0.0, 0, 1]]), 1e-6),
    "pair_sums": lambda: (np.array([0]), np.array([1]), np.array([1]), np.array([1]), np.array([False, False]),
                          np.zeros((2, 2), np.int64), np.array([0]),
                          np.array([[[0.0, 0, 1], [0, 1, 1], [1, 0, 1]], [[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]]),
                          np.array([[0.0, 0, -1], [0, 0, 1]]), np.zeros((1, 3, 3)), np.eye(3)[:1],
                          np.full((1, 3), 1 / 3), 2.0, 1e-6),
    "csr_times": lambda: (np.array([0, 1, 1], np.int32), np.array([1], np.int32), np.array([2.0]), np.ones((2, 3))),
    "member_rays": lambda: (np.array([0]), np.array([0]), np.array([0]), np.array([1]), np.array([0]),
                            np.array([0.5]), np.array([1.0]), np.array([False, True]),
                            np.array([[0, 1], [0, 1]]), np.array([0.5]), np.array([0]),
                            np.array([[[0.0, 0, 1], [0, 1, 1], [1, 0, 1]]] * 2), np.array([[0.0, 0, -1]] * 2),
                            np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]]), np.array([[0.0, 0, 1]]), 1e-6),
}
