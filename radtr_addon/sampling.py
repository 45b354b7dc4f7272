"""Sampling and geometry helpers of the engine: pure functions on numpy arrays.

- frames: orthonormal tangent bases about unit normals;
- warps: unit-square samples (u, v) to points on triangles or a sphere, and to directions
  in a cone or cosine-weighted about a normal;
- grids: one sample per cell of an m x m grid (centred or jittered), pixel centres;
- histograms: ray hits counted into rows;
- parallel rays: a grid of rays along one direction across the scene's bounding sphere.

Samples are drawn by the callers, each from its own seeded generator, so every stream
stays as the callers drew it.
"""
from __future__ import annotations

import numpy as np

from . import compiled
from .tolerances import BOUNDS_FLOOR, BOUNDS_MARGIN


# -- frames ---------------------------------------------------------------------------------
def tangent_frames(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit tangents t (k, 3) and bitangents b (k, 3) with (t, b, n) right-handed, per unit
    normal n (k, 3); t is perpendicular to x (to y where n is near x)."""
    helper = np.where(np.abs(normals[:, [0]]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    t = np.cross(helper, normals)
    t /= np.linalg.norm(t, axis=1)[:, None]
    return t, np.cross(normals, t)


def rotated_frames(normals: np.ndarray, angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``tangent_frames`` (k, 3) turned about each normal (k, 3) by ``angles`` (k,) radians."""
    t, b = tangent_frames(normals)
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    return c * t + s * b, c * b - s * t


# -- warps ----------------------------------------------------------------------------------
def triangle_points(tris: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Uniform points (..., d) on triangles (..., 3, d) from unit-square samples u, v (...),
    by the square-root warp: barycentrics (1 - sqrt u, sqrt u (1 - v), sqrt u v)."""
    a = tris[..., 0, :]
    out = v[..., None] * (tris[..., 2, :] - tris[..., 1, :])         # a + sqrt u (b - a + v (c - b))
    out += tris[..., 1, :] - a
    out = np.sqrt(u)[..., None] * out
    out += a
    return out


def sphere_points(centre: np.ndarray, radius: float, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Uniform points (k, 3) on the sphere (centre (3,), radius) from unit-square samples u, v (k,)."""
    z = 1 - 2 * u
    r = np.sqrt(np.maximum(1 - z * z, 0))
    phi = 2 * np.pi * v
    return centre + radius * np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def cosine_directions(u: np.ndarray, v: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Cosine-weighted unit directions (k, m, 3) about normals (k, 3) from unit-square
    samples u, v (k, m): the disk point (sqrt u, 2 pi v) lifted onto the hemisphere, in
    ``tangent_frames``. Compiled where numba builds (the final gather's and the World's
    tens of millions of rays: numpy's temporaries took 4 of a furnished room's 45 s)."""
    kernel = compiled.kernel("cosine_directions") if np.ndim(u) == 2 else None
    if kernel is not None:
        return kernel(u, v, normals)
    radius, phi = np.sqrt(u), 2 * np.pi * v
    t, b = tangent_frames(normals)
    local = np.stack([radius * np.cos(phi), radius * np.sin(phi), np.sqrt(np.maximum(1 - u, 0))], axis=-1)
    return local[..., :1] * t[:, None] + local[..., 1:2] * b[:, None] + local[..., 2:] * normals[:, None]


def cone_directions(axis: np.ndarray, half_angle: float, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unit directions (k, 3) within ``half_angle`` of the unit ``axis`` (3,) from unit-square
    samples u, v (k,): half_angle sqrt(u) off the axis, 2 pi v round it from -t."""
    t, b = tangent_frames(axis[None])
    theta, phi = half_angle * np.sqrt(u), 2 * np.pi * v
    ring = np.cos(phi)[:, None] * t[0] + np.sin(phi)[:, None] * b[0]
    return np.cos(theta)[:, None] * axis - np.sin(theta)[:, None] * ring


# -- grids ----------------------------------------------------------------------------------
def grid_side(count: int) -> int:
    """Side m (at least 1) of the m x m grid nearest to ``count`` samples."""
    return max(1, int(round(np.sqrt(count))))


def stratified(m: int, u_offsets=0.5, v_offsets=0.5) -> tuple[np.ndarray, np.ndarray]:
    """Samples u, v (..., m^2), one per cell of an m x m grid on the unit square: cell c in
    row c // m (along u) and column c % m (along v), ``u_offsets`` and ``v_offsets``
    (scalars or (..., m^2), in [0, 1)) of the way across it; 0.5: the cell centres."""
    cells = np.arange(m * m)
    return (cells // m + u_offsets) / m, (cells % m + v_offsets) / m


def jittered(m: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``stratified`` samples u, v (m^2,) at uniform random places in their cells; ``rng``
    draws the m^2 u offsets, then the m^2 v offsets."""
    return stratified(m, rng.random(m * m), rng.random(m * m))


def strata(m: int, offsets=0.5) -> np.ndarray:
    """Samples (..., m) in [0, 1), one per m-th, ``offsets`` (scalar or (..., m)) of the way across it."""
    return (np.arange(m) + offsets) / m


def pixel_centres(res: int) -> np.ndarray:
    """Centres (res,) of ``res`` equal pixels across [-1, 1]."""
    return strata(res) * 2 - 1


# -- histograms -----------------------------------------------------------------------------
def hit_histogram(keys: np.ndarray, rows: int, width: int, weights: np.ndarray | None = None) -> np.ndarray:
    """Hits counted per (row, column) cell (rows, width) from flat ``keys`` (k,) =
    row x width + column; with ``weights`` (k,), their sums (float) instead of counts (int)."""
    return np.bincount(keys, weights, minlength=rows * width).reshape(rows, width)


# -- parallel rays --------------------------------------------------------------------------
def bounding_box(vertices: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre (3,) and diagonal length of the axis-aligned box around ``vertices`` (k, 3)."""
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    return 0.5 * (lo + hi), float(np.linalg.norm(hi - lo))


def bounding_sphere(vertices: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre (3,) and radius of a sphere about the box around ``vertices`` (k, 3), a little wider."""
    centre, diagonal = bounding_box(vertices)
    return centre, 0.5 * diagonal * BOUNDS_MARGIN + BOUNDS_FLOOR


def parallel_rays(centre: np.ndarray, radius: float, direction: np.ndarray, res: int,
                  top_down: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Origins and directions (res^2, 3) of a res x res grid of parallel rays along -``direction``
    (unit, (3,)) covering the sphere (centre, radius) from 2 radius out: x along the tangent,
    rows along the bitangent bottom-up (``top_down``: as image rows), one ray per pixel centre."""
    t, b = tangent_frames(direction[None])
    g = pixel_centres(res)
    gx, gy = np.meshgrid(g * radius, (g[::-1] if top_down else g) * radius)
    origins = centre + 2 * radius * direction + gx.reshape(-1, 1) * t[0] + gy.reshape(-1, 1) * b[0]
    return origins, np.broadcast_to(-direction, origins.shape)


def hashed_uniforms(keys: tuple, count: int) -> np.ndarray:
    """``count`` uniforms in [0, 1) (count, m), a fixed function of the integer ``keys`` (a tuple of
    (m,) arrays; splitmix64): the same entry draws the same samples whenever it is made."""
    h = np.zeros(len(keys[0]), np.uint64)
    with np.errstate(over="ignore"):
        for k in keys:
            h = (h ^ np.asarray(k).astype(np.uint64)) * np.uint64(0x9E3779B97F4A7C15)
        out = []
        for _ in range(count):
            h = h + np.uint64(0x9E3779B97F4A7C15)
            z = (h ^ (h >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
            z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
            z = z ^ (z >> np.uint64(31))
            out.append((z >> np.uint64(11)).astype(np.float64) / float(1 << 53))
    return np.array(out)
