"""Exact form factors for unoccluded geometry: the references every method is tested against.

- ``point_to_polygon``: differential area at p with normal n to a planar polygon, by
  Lambert's contour integral F = (1 / 2 pi) sum_k gamma_k (n . unit(R_k x R_k+1)), after
  clipping the polygon to the half-space in front of the point.
- ``polygon_factor``: the same for many points and triangles, pair by pair (vectorised,
  clipped at each point's horizon); ``point_to_triangles`` for every point and triangle.
- ``parallel_rectangles`` and ``perpendicular_rectangles``: the catalogue closed forms
  (Howell, configurations C-11 and C-14).
- ``polygon_to_polygon``: area-to-area form factor of two planar polygons by Stokes' double
  contour integral F_12 = (1 / 2 pi A_1) sum_(e in 1) sum_(f in 2) (e^ . f^) int_e int_f ln r
  (Schroeder and Hanrahan derive the inner and outer integrals in closed form; here the inner
  one is closed form and the outer one composite Gauss-Legendre, graded towards the edge ends
  where shared or touching edges make the integrand singular). Each polygon is first clipped
  to the front side of the other's plane, so pairs that partly face away are handled.
  Agrees with the rectangle closed forms to 1e-9 (tests/test_closed_form.py).

Polygons are (k, 3) vertex arrays, counter-clockwise about their normal.
"""
from __future__ import annotations

import numpy as np

from .. import compiled

_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(8)
#: Outer-integral breakpoints on [0, 1]: graded by halving towards both ends.
_BREAKS = np.unique(np.concatenate([[0.0, 1.0], 0.5 ** np.arange(1, 24), 1.0 - 0.5 ** np.arange(1, 24)]))


def polygon_normal_area(poly: np.ndarray):
    """Unit normal (by the right-hand rule) and area of a planar polygon."""
    poly = np.asarray(poly, float)
    cross = np.cross(poly - poly[0], np.roll(poly, -1, axis=0) - poly[0]).sum(axis=0)
    area = 0.5 * np.linalg.norm(cross)
    return (cross / (2 * area) if area > 0 else np.zeros(3)), area


def clip_to_halfspace(poly: np.ndarray, point: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """The part of ``poly`` where (x - point) . normal >= 0 (Sutherland-Hodgman, one plane).

    A polygon with no point strictly in front (coplanar or behind) gives an empty array.
    """
    poly = np.asarray(poly, float)
    d = (poly - point) @ normal
    if not np.any(d > 0):
        return np.zeros((0, 3))
    out = []
    for k in range(len(poly)):
        a, b, da, db = poly[k], poly[(k + 1) % len(poly)], d[k], d[(k + 1) % len(poly)]
        if da >= 0:
            out.append(a)
        if (da >= 0) != (db >= 0) and da != db:
            out.append(a + (b - a) * (da / (da - db)))
    return np.array(out).reshape(-1, 3)


def point_to_polygon(point, normal, poly) -> float:
    """Form factor from a differential area at ``point`` facing ``normal`` to ``poly``."""
    point, normal = np.asarray(point, float), np.asarray(normal, float)
    poly = clip_to_halfspace(poly, point, normal)
    if len(poly) < 3:
        return 0.0
    r = poly - point
    r /= np.linalg.norm(r, axis=1)[:, None]
    r2 = np.roll(r, -1, axis=0)
    cross = np.cross(r, r2)
    sin = np.linalg.norm(cross, axis=1)
    gamma = np.arctan2(sin, np.einsum("ij,ij->i", r, r2))
    ok = sin > 0
    total = np.sum(gamma[ok] * (cross[ok] @ normal) / sin[ok])
    return float(abs(total) / (2 * np.pi))


def parallel_rectangles(a: float, b: float, c: float) -> float:
    """Between directly opposed parallel a x b rectangles a distance c apart."""
    x, y = a / c, b / c
    sx, sy = np.sqrt(1 + x * x), np.sqrt(1 + y * y)
    return float(2 / (np.pi * x * y) * (
        np.log(sx * sy / np.sqrt(1 + x * x + y * y)) + x * sy * np.arctan(x / sy)
        + y * sx * np.arctan(y / sx) - x * np.arctan(x) - y * np.arctan(y)))


def perpendicular_rectangles(length: float, width: float, height: float) -> float:
    """From a length x width rectangle to a length x height one at right angles on their common edge."""
    w, h = width / length, height / length
    s2 = w * w + h * h
    s = np.sqrt(s2)
    log = (np.log((1 + w * w) * (1 + h * h) / (1 + s2))
           + w * w * np.log(w * w * (1 + s2) / ((1 + w * w) * s2))
           + h * h * np.log(h * h * (1 + s2) / ((1 + h * h) * s2)))
    return float((w * np.arctan(1 / w) + h * np.arctan(1 / h) - s * np.arctan(1 / s) + 0.25 * log) / (np.pi * w))


def _segment_log_integral(points: np.ndarray, a: np.ndarray, u: np.ndarray, length: float) -> np.ndarray:
    """int_0^length ln |p - a - t u| dt for each row p of ``points`` (u a unit vector)."""
    rel = points - a
    s0 = rel @ u
    h = np.sqrt(np.maximum(np.einsum("ij,ij->i", rel, rel) - s0 * s0, 0.0))

    def g(tau):
        r2 = h * h + tau * tau
        with np.errstate(divide="ignore", invalid="ignore"):
            log_term = np.where(r2 > 0, 0.5 * tau * np.log(np.where(r2 > 0, r2, 1.0)), 0.0)
        return log_term - tau + h * np.arctan2(tau, h)

    return g(length - s0) - g(-s0)


def polygon_to_polygon(poly1, poly2) -> float:
    """Unoccluded form factor from planar polygon 1 to planar polygon 2 (area-to-area)."""
    p1, p2 = np.asarray(poly1, float), np.asarray(poly2, float)
    n1, area1 = polygon_normal_area(p1)
    n2, area2 = polygon_normal_area(p2)
    if area1 == 0 or area2 == 0:
        return 0.0
    c1 = clip_to_halfspace(p1, p2[0], n2)
    c2 = clip_to_halfspace(p2, p1[0], n1)
    if len(c1) < 3 or len(c2) < 3:
        return 0.0
    nodes = (_BREAKS[:-1, None] + np.outer(np.diff(_BREAKS), (_GAUSS_X + 1) / 2)).ravel()
    weights = np.outer(np.diff(_BREAKS), _GAUSS_W / 2).ravel()
    total = 0.0
    for k in range(len(c1)):
        a, b = c1[k], c1[(k + 1) % len(c1)]
        le = np.linalg.norm(b - a)
        if le == 0:
            continue
        e = (b - a) / le
        pts = a + np.outer(nodes * le, e)
        for m in range(len(c2)):
            c, d = c2[m], c2[(m + 1) % len(c2)]
            lf = np.linalg.norm(d - c)
            if lf == 0:
                continue
            f = (d - c) / lf
            dot = e @ f
            if abs(dot) < 1e-15:
                continue
            total += dot * le * (weights @ _segment_log_integral(pts, c, f, lf))
    return float(abs(total) / (2 * np.pi * area1))


def point_to_triangles(points: np.ndarray, normals: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Unoccluded form factors (P, J) from points facing ``normals`` to the fronts of
    triangles (J, 3, 3): ``polygon_factor`` for every pair."""
    P, J = len(points), len(tris)
    F = polygon_factor(np.repeat(points, J, axis=0)[:, None], np.repeat(normals, J, axis=0), np.tile(tris, (P, 1, 1)))
    return F.reshape(P, J)


def polygon_factor(points: np.ndarray, normals: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Unoccluded form factors (L, P) from points (L, P, 3) facing ``normals`` (L, 3) to the
    fronts of triangles (L, 3, 3), pair by pair: Lambert's contour integral over the part of
    each triangle above the point's tangent plane (clipped, so at most a quadrilateral).
    Compiled (``compiled``: 27x faster on a large scene's links) where numba builds, else by
    ``polygon_factor_numpy``."""
    kernel = compiled.kernel("polygon_factor")
    return polygon_factor_numpy(points, normals, tris) if kernel is None else kernel(points, normals, tris)


def polygon_factor_numpy(points: np.ndarray, normals: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """``polygon_factor`` by numpy: most triangles are wholly above the point's horizon and go
    through the three-corner sum as they are, the rest are clipped first."""
    L, P = points.shape[:2]
    n_t = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    front = np.einsum("lpc,lc->lp", points - tris[:, None, 0], n_t) > 0
    h = np.einsum("lkc,lc->lk", tris, normals)[:, None, :] - np.einsum("lpc,lc->lp", points, normals)[..., None]
    F = np.zeros((L, P))
    whole = front & (h > 0).all(axis=-1)
    li, pi = np.nonzero(whole)
    if len(li):
        F[li, pi] = _lambert(tris[li] - points[li, pi][:, None], normals[li])
    li, pi = np.nonzero(front & ~whole & (h > 0).any(axis=-1))
    if len(li):
        F[li, pi] = _lambert(_clipped(tris[li], h[li, pi]) - points[li, pi][:, None], normals[li])
    return np.minimum(F, 1.0)


def _clipped(v: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Triangles (m, 3, 3) cut to where their height ``h`` (m, 3) above a plane is >= 0, as six
    corners (m, 6, 3) with repeats (a repeated corner adds nothing to Lambert's sum)."""
    h1, v1 = np.roll(h, -1, axis=1), np.roll(v, -1, axis=1)
    inside, crossing = h >= 0, (h >= 0) != (h1 >= 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(crossing, h / (h - h1), 0.0)
    cut = v + t[..., None] * (v1 - v)
    slots = np.stack([v, cut], axis=2).reshape(-1, 6, 3)               # corner, crossing, corner, ...
    valid = np.stack([inside, crossing], axis=2).reshape(-1, 6)
    idx = np.maximum.accumulate(np.where(valid, np.arange(6), -1), axis=1)
    idx = np.where(idx < 0, idx[:, -1:], idx)                          # fill gaps cyclically
    return np.take_along_axis(slots, idx[..., None], axis=1)


def _lambert(poly: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Lambert's contour sum (m,) for polygons (m, k, 3) seen from the origin facing ``normals``
    (components spelled out: ``np.cross`` and ``np.linalg.norm`` took half the time of a
    large scene's link evaluation)."""
    r = poly / np.maximum(np.sqrt(np.einsum("mkc,mkc->mk", poly, poly)), 1e-300)[..., None]
    r2 = r[:, np.r_[1:r.shape[1], 0]]
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    x2, y2, z2 = r2[..., 0], r2[..., 1], r2[..., 2]
    cx, cy, cz = y * z2 - z * y2, z * x2 - x * z2, x * y2 - y * x2
    sin = np.sqrt(cx * cx + cy * cy + cz * cz)
    gamma = np.arctan2(sin, x * x2 + y * y2 + z * z2)
    along = cx * normals[:, None, 0] + cy * normals[:, None, 1] + cz * normals[:, None, 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        terms = np.where(sin > 1e-15, gamma * along / sin, 0.0)
    return np.abs(terms.sum(axis=-1)) / (2 * np.pi)
