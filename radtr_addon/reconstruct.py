"""Radiosity at points of the surfaces (mesh vertices) from a solved, patch-constant B.

A vertex shown with the area-weighted mean of the patches around it (what ``write`` stores in
``radtr_radiosity``) is off wherever light changes across a patch: in corners and contact
shadows, the discretisation error that sets how exact a patch solution looks. A final gather
removes most of it: the irradiance at the point itself, H(p) = sum_j F(p -> j) B_j, with
point-to-patch form factors from Embree rays; the reflected exitance is rho(p) H(p).
"""
from __future__ import annotations

import numpy as np

from .formfactors.raycast import EmbreeRays


def gather(scene, B: np.ndarray, points: np.ndarray, normals: np.ndarray, rays: int = 1024,
           seed: int = 0, caster: EmbreeRays | None = None) -> np.ndarray:
    """Irradiance (k, 3) at ``points`` facing ``normals`` from the patches of ``scene`` at radiosity B."""
    caster = caster or EmbreeRays(scene, rays, seed)
    H = np.zeros((len(points), 3))
    for k, row in enumerate(caster.point_rows(np.asarray(points, float), np.asarray(normals, float))):
        H[k] = row.values @ B[row.indices]
    return H
