"""Sky form factors (the seed's F11): how much of each patch each point of a sky dome sees.

Dome points sit every ``alpha`` degrees of azimuth and ``beta`` degrees of altitude, at the
centres of the bands (altitude beta/2, 3 beta/2, ... below 90). From each, a parallel
(orthographic) view towards the scene centre covers the scene's bounding sphere with a
``resolution`` x ``resolution`` grid of parallel rays (Embree; the GPU methods' pixels): a
ray that hits the front of patch i counts one pixel for i, one that hits a back face is
blocked. ``S[p, i] = pixels x pixel area / A_i`` is then cos(theta) x the visible fraction
of patch i seen from direction p. A sky of radiance L(direction) lights patch i with

    H_i = sum_p L(d_p) Omega_p S[p, i],   Omega_p = alpha (sin(top) - sin(bottom)) of p's band,

exact as alpha, beta -> 0 and the pixels shrink: ``bench``-free check, an open horizontal
patch under a uniform sky gets pi L up to the dome's discretisation error (``dome_error``).
Radiance models: uniform, and the CIE overcast sky L(theta) = Lz (1 + 2 cos theta) / 3.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .errors import SettingsError
from .sampling import bounding_sphere, hit_histogram, parallel_rays


@dataclass
class SkyFactors:
    """The dome and its points x patches matrix."""

    directions: np.ndarray      # (p, 3) unit vectors from the scene towards each dome point
    positions: np.ndarray       # (p, 3) the dome points (on a sphere around the scene)
    solid_angles: np.ndarray    # (p,) steradians each point stands for
    S: sp.csr_matrix            # (p, n) cos x visible fraction of patch i from point p

    def irradiance(self, radiance: np.ndarray) -> np.ndarray:
        """H (n, 3) for dome radiances (p, 3) or (p,)."""
        L = np.asarray(radiance, float)
        L = np.repeat(L[:, None], 3, axis=1) if L.ndim == 1 else L
        return np.asarray(self.S.T @ (L * self.solid_angles[:, None]))


def dome_size(alpha: float, beta: float) -> int:
    """How many points ``dome(alpha, beta)`` has."""
    a, b = np.radians(alpha), np.radians(beta)
    return int(np.ceil(np.pi / 2 / b)) * int(round(2 * np.pi / a))


def dome(alpha: float, beta: float) -> tuple[np.ndarray, np.ndarray]:
    """(directions (p, 3), solid angles (p,)) of dome points every alpha x beta degrees."""
    if not (0 < alpha <= 360 and 0 < beta <= 90):
        raise SettingsError(f"sky steps must be 0 < alpha <= 360 and 0 < beta <= 90 degrees, got {alpha}, {beta}")
    a, b = np.radians(alpha), np.radians(beta)
    bands = int(np.ceil(np.pi / 2 / b))
    edges = np.minimum(np.arange(bands + 1) * b, np.pi / 2)
    azimuths = np.arange(int(round(2 * np.pi / a))) * (2 * np.pi / round(2 * np.pi / a))
    dirs, omega = [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        alt = 0.5 * (lo + hi)
        for az in azimuths:
            dirs.append([np.cos(alt) * np.cos(az), np.cos(alt) * np.sin(az), np.sin(alt)])
            omega.append((2 * np.pi / len(azimuths)) * (np.sin(hi) - np.sin(lo)))
    return np.array(dirs), np.array(omega)


def sky_factors(scene, alpha: float = 10.0, beta: float = 10.0, resolution: int = 256,
                scheduler: str = "") -> SkyFactors:
    """Sky form factors of ``scene`` (Embree parallel rays from each dome point; on the Dask
    cluster ``scheduler`` names, when it is not empty)."""
    from .tasks import run

    return run(sky_factor_steps(scene, alpha, beta, resolution, scheduler))


def dome_rows(scene, directions: np.ndarray, resolution: int, caster=None,
              sphere=None) -> list[tuple[np.ndarray, np.ndarray]]:
    """(patch ids, S values) seen from each dome point in ``directions`` (k, 3); ``sphere``:
    the scene's ``bounding_sphere`` when the caller has it."""
    from .formfactors.raycast import EmbreeRays

    caster = caster or EmbreeRays(scene, 1)
    centre, radius = sphere or bounding_sphere(scene.vertices)
    pixel_area = (2 * radius / resolution) ** 2
    out = []
    for d in directions:
        hit = caster.hit(*parallel_rays(centre, radius, d, resolution))
        front = (hit >= 0) & (scene.normals[np.maximum(hit, 0)] @ d > 0)
        counts = hit_histogram(hit[front], 1, scene.n)[0]
        ids = np.flatnonzero(counts)
        out.append((ids, counts[ids] * pixel_area / scene.areas[ids]))
    return out


def sky_factor_steps(scene, alpha: float = 10.0, beta: float = 10.0, resolution: int = 256, scheduler: str = ""):
    """``sky_factors`` as steps (``tasks``): yields the fraction done after each dome point
    (each block of them on a cluster), returns the SkyFactors."""
    from .formfactors.raycast import EmbreeRays

    directions, omega = dome(alpha, beta)
    centre, radius = bounding_sphere(scene.vertices)
    if scheduler:
        from .cluster import dome_row_steps

        per_point = yield from dome_row_steps(scheduler, scene, directions, resolution)
    else:
        caster, per_point = EmbreeRays(scene, 1), []
        for p, d in enumerate(directions):
            per_point += dome_rows(scene, d[None], resolution, caster, (centre, radius))
            yield (p + 1) / len(directions)
    rows = np.repeat(np.arange(len(directions)), [len(ids) for ids, _ in per_point])
    cols = np.concatenate([ids for ids, _ in per_point])
    vals = np.concatenate([v for _, v in per_point])
    S = sp.csr_matrix((vals, (rows, cols)), shape=(len(directions), scene.n))
    return SkyFactors(directions, centre + 2 * radius * directions, omega, S)


def sky_image_steps(scene, sky: SkyFactors, out_dir, resolution: int = 128):
    """One PNG a dome point, ``sky_NNNN.png`` in ``out_dir``: what the point sees, patches in
    their id colour code (the seed saved these views); yields the fraction done, returns the paths."""
    from pathlib import Path

    import matplotlib.image

    from .views import id_colors, sky_view

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for p, d in enumerate(sky.directions):
        paths.append(out_dir / f"sky_{p:04d}.png")
        matplotlib.image.imsave(paths[-1], id_colors(sky_view(scene, d, resolution)))
        yield (p + 1) / len(sky.directions)
    return paths


def uniform_sky(sky: SkyFactors, radiance) -> np.ndarray:
    """Dome radiances (p, 3) of a uniform sky."""
    return np.broadcast_to(np.asarray(radiance, float), (len(sky.directions), 3)).copy()


def cie_overcast(sky: SkyFactors, zenith_radiance) -> np.ndarray:
    """Dome radiances (p, 3) of the CIE overcast sky, L = Lz (1 + 2 cos theta) / 3."""
    cos_theta = sky.directions[:, 2]
    return np.outer((1 + 2 * cos_theta) / 3, np.broadcast_to(np.asarray(zenith_radiance, float), 3))


def dome_error(alpha: float, beta: float) -> float:
    """Relative error of the dome's estimate of pi L on an open horizontal patch (no pixels)."""
    directions, omega = dome(alpha, beta)
    return float(np.sum(omega * directions[:, 2]) / np.pi - 1)
