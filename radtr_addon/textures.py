"""Reflectance that varies over a surface: image textures and colour attributes, per patch.

A leaf patch lies inside one input triangle (``Hierarchy.source``); its corners' barycentric
coordinates there carry the input triangle's UVs or corner colours down to the patch.
An image texture gives the patch the mean of the texture over its UV triangle, sampled on an
m x m stratified grid with m^2 about ``SAMPLES_PER_TEXEL`` times the texels it covers (at
least 16, at most 4,096 samples; nearest texel, repeating). A colour attribute gives the
mean of the three corner colours (the mean of the linear interpolation over the patch).
"""
from __future__ import annotations

import numpy as np

from .sampling import stratified, triangle_points

SAMPLES_PER_TEXEL = 64
MIN_SAMPLES, MAX_SAMPLES = 16, 4096


def barycentric(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Barycentric coordinates (k, 3) of points (k, 3) in triangles (k, 3, 3), least squares."""
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    v0, v1, v2 = b - a, c - a, points - a
    d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
    d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
    den = np.where(d00 * d11 - d01 * d01 == 0, 1e-300, d00 * d11 - d01 * d01)
    v = (d11 * d20 - d01 * d21) / den
    w = (d00 * d21 - d01 * d20) / den
    return np.stack([1 - v - w, v, w], axis=1)


def carry(base, leaves, ids: np.ndarray, source: np.ndarray, corner_values: np.ndarray) -> np.ndarray:
    """Per-corner values (t, 3, c) of the input triangles of ``base``, interpolated to the
    corners of leaves ``ids`` (k, 3, c); ``source`` maps every leaf to its input triangle."""
    src = source[ids]
    src_tris = base.vertices[base.triangles[src]]                              # (k, 3, 3)
    out = np.empty((len(ids), 3, corner_values.shape[2]))
    for k in range(3):
        bary = barycentric(leaves.vertices[leaves.triangles[ids, k]], src_tris)
        out[:, k] = np.einsum("nj,njc->nc", bary, corner_values[src])
    return out


def varying_reflectance(extraction, hierarchy, limit: float) -> tuple[np.ndarray, list[str]]:
    """Leaf reflectances (n, 3) with textures and colour attributes applied, clamped to ``limit``."""
    base, leaves, source = extraction.scene, hierarchy.leaves, hierarchy.source
    rho = leaves.rho.copy()
    warnings = []
    names = leaves.material_names
    for m, image in extraction.textures.items():
        ids = np.flatnonzero((leaves.material_index == m) & ~np.isnan(extraction.uv[source, 0, 0]))
        if len(ids):
            rho[ids] = texel_mean(image, carry(base, leaves, ids, source, extraction.uv))
    for m in extraction.attributes:
        ids = np.flatnonzero((leaves.material_index == m) & ~np.isnan(extraction.corner_color[source, 0, 0]))
        if len(ids):
            rho[ids] = carry(base, leaves, ids, source, extraction.corner_color).mean(axis=1)
    high = (rho > limit).any(axis=1)
    for m in np.unique(leaves.material_index[high]):
        count = int((high & (leaves.material_index == m)).sum())
        warnings.append(f"material '{names[m]}': {count} patches with texture or attribute reflectance "
                        f"above {limit} clamped")
    return np.clip(rho, 0.0, limit), warnings


def texel_mean(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Mean colour (k, 3) of ``image`` (h, w, 3; row 0 at the bottom, as Blender stores it)
    over UV triangles (k, 3, 2)."""
    h, w = image.shape[:2]
    out = np.empty((len(uv), 3))
    area = 0.5 * np.abs(np.cross(uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]))
    counts = np.clip(area * w * h * SAMPLES_PER_TEXEL, MIN_SAMPLES, MAX_SAMPLES)
    sides = np.ceil(np.sqrt(counts)).astype(int)
    for m in np.unique(sides):
        sel = np.flatnonzero(sides == m)
        p = triangle_points(uv[sel][:, None], *stratified(m))                              # (k, m^2, 2)
        col = np.floor((p[..., 0] % 1.0) * w).astype(np.int64) % w
        row = np.floor((p[..., 1] % 1.0) * h).astype(np.int64) % h
        out[sel] = image[row, col].mean(axis=1)
    return out
