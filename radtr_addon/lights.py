"""Direct light from Blender Light objects at the patches: the first bounce, before any solve.

Units follow Cycles. A point or spot light of power P (W) and colour C has radiant intensity
I = P C / (4 pi) W/sr (a spot is a point light masked by its cone, not focused), so a patch
at distance d with cosine cos gets H = I cos / d^2. An area light of power P and area A
emits radiance L = P C / (pi A) from its front (-Z) side, so H = pi L F(p -> light) =
(P C / A) F, with F the closed-form point-to-polygon form factor (disks and ellipses as
32-gons). A sun of strength S (W/m^2) gives H = S C cos. Lights with a size (point radius,
area shape, sun angle) are sampled with ``samples`` deterministic shadow rays per patch, so
shadows are soft; all visibility is by Embree. The patch's first-bounce exitance is then
E_i = rho_i H_i, and any solver carries it further.

The World: a distant sky of radiance L(direction), uniform (a World colour) or from an
equirectangular environment image, gives H = integral of L cos over the directions in which
nothing blocks the sky: ``sky_irradiance`` estimates it with cosine-weighted Embree rays,
H = pi x mean(L over the rays that escape).

Two-sided emitters: a mesh emits from its front (its patches); where its material is
two-sided, the back of each emitting input triangle is added as a polygon area light
(``Light.back_of``), so its light reaches what lies behind as first-bounce light.

Culling: a light is not traced at a patch where its unoccluded irradiance is below
``cull`` times that of the brightest light there; the light so left out is reported as
``culled`` power (W per channel).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .formfactors.closed_form import point_to_triangles
from .sampling import cone_directions, cosine_directions, grid_side, sphere_points, stratified, triangle_points
from .tolerances import CULL

KINDS = ("POINT", "SPOT", "AREA", "SUN")
SHAPES = ("SQUARE", "RECTANGLE", "DISK", "ELLIPSE")
#: Sides of the polygon standing for a disk or ellipse area light.
ROUND_SIDES = 32


@dataclass
class Light:
    """A Blender light in world space (``matrix``: its world matrix; it shines along -Z)."""

    name: str
    kind: str
    color: np.ndarray
    power: float                     # W; for a sun, strength in W/m^2
    matrix: np.ndarray = field(default_factory=lambda: np.eye(4))
    radius: float = 0.0              # point/spot soft size (m); for a sun, its angle (rad)
    spot_size: float = np.pi / 4     # full cone angle
    spot_blend: float = 0.15
    shape: str = "SQUARE"
    size_x: float = 1.0
    size_y: float = 1.0
    outline: np.ndarray | None = None  # an area light of any polygon (world space), e.g. an emitter's back

    @classmethod
    def polygon_light(cls, name: str, polygon: np.ndarray, exitance: np.ndarray) -> "Light":
        """An area light of ``polygon`` (counter-clockwise seen from the side it lights) with
        exitance E (W/m^2): an emitting patch, or the back of one."""
        area = _areas(_fan(polygon)).sum()
        peak = float(exitance.max())
        return cls(name, "AREA", exitance / peak, peak * area, outline=np.array(polygon, float))

    @classmethod
    def back_of(cls, name: str, triangle: np.ndarray, exitance: np.ndarray) -> "Light":
        """The back side of a two-sided emitting triangle (exitance E, W/m^2) as an area light."""
        return cls.polygon_light(name, triangle[::-1], exitance)

    @property
    def position(self) -> np.ndarray:
        return self.matrix[:3, 3]

    @property
    def axis(self) -> np.ndarray:
        """The direction the light shines in (world -Z of the light)."""
        z = self.matrix[:3, 2]
        return -z / np.linalg.norm(z)

    def polygon(self) -> np.ndarray:
        """An area light's outline in world space, counter-clockwise seen from its front."""
        if self.outline is not None:
            return self.outline
        if self.shape in ("DISK", "ELLIPSE"):
            t = -np.linspace(0, 2 * np.pi, ROUND_SIDES, endpoint=False)
            # equal-area polygon: scale so the polygon's area is the ellipse's
            scale = np.sqrt(np.pi / (0.5 * ROUND_SIDES * np.sin(2 * np.pi / ROUND_SIDES)))
            local = np.stack([np.cos(t) * scale, np.sin(t) * scale], 1) * 0.5
        else:
            local = np.array([[0.5, 0.5], [0.5, -0.5], [-0.5, -0.5], [-0.5, 0.5]])
        sy = self.size_y if self.shape in ("RECTANGLE", "ELLIPSE") else self.size_x
        pts = np.column_stack([local[:, 0] * self.size_x, local[:, 1] * sy, np.zeros(len(local)), np.ones(len(local))])
        return (pts @ self.matrix.T)[:, :3]

    def area(self) -> float:
        if self.outline is not None:
            return float(_areas(_fan(self.outline)).sum())
        sy = self.size_y if self.shape in ("RECTANGLE", "ELLIPSE") else self.size_x
        world = np.linalg.norm(self.matrix[:3, 0]) * np.linalg.norm(self.matrix[:3, 1])
        factor = np.pi / 4 if self.shape in ("DISK", "ELLIPSE") else 1.0
        return factor * self.size_x * sy * world


#: The golden ratio's fraction: a sequence (0.5 + k GOLDEN) mod 1 spreads evenly whatever its length.
GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0


def _fan(poly: np.ndarray) -> np.ndarray:
    return np.stack([np.broadcast_to(poly[0], (len(poly) - 2, 3)), poly[1:-1], poly[2:]], axis=1)


def _areas(tris: np.ndarray) -> np.ndarray:
    """Areas (k,) of triangles (k, 3, 3)."""
    return 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)


def _sample_points(light: Light, count: int) -> np.ndarray:
    """Deterministic points on the light's emitting surface (its centre when it has none):
    grid cells on a triangle of an area light's fan, the triangle picked by the golden-ratio
    sequence (by the cells' order, as before, the cells near one fan triangle's apex went to
    it and the far ones to the next: a 0.6 m square's points centred 4 cm off its centre)."""
    u, v = stratified(grid_side(count))
    return _light_points(light, u, v, (0.5 + np.arange(len(u)) * GOLDEN) % 1.0)


def _light_points(light: Light, u: np.ndarray, v: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Points (k, 3) on the light's emitting surface from uniforms u, v (k,) (w (k,): which
    triangle of an area light's fan, by area); its centre for each when it has none."""
    if light.kind == "AREA":
        tris = _fan(light.polygon())
        areas = _areas(tris)
        pick = np.minimum(np.searchsorted(np.cumsum(areas) / areas.sum(), w), len(tris) - 1)
        return triangle_points(tris[pick], u, v)
    if light.radius > 0 and light.kind in ("POINT", "SPOT"):
        return sphere_points(light.position, light.radius, u, v)
    return np.repeat(light.position[None], len(u), axis=0)


def spot_mask(light: Light, to_point: np.ndarray) -> np.ndarray:
    """Cycles' spot cone with blend: 0 outside, smoothstep over the blend band inside the edge."""
    cos_half = np.cos(light.spot_size / 2)
    c = to_point @ light.axis
    smooth = (1 - cos_half) * light.spot_blend
    t = np.clip((c - cos_half) / smooth, 0.0, 1.0) if smooth > 0 else (c > cos_half).astype(float)
    return np.where(c > cos_half, t * t * (3 - 2 * t), 0.0)


def unoccluded(light: Light, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Irradiance (k,) per unit colour from ``light`` at points facing ``normals``, no shadows."""
    if light.kind == "SUN":
        return light.power * np.maximum(normals @ -light.axis, 0.0)
    if light.kind == "AREA":
        F = point_to_triangles(points, normals, _fan(light.polygon())).sum(axis=1)
        return light.power / max(light.area(), 1e-300) * F
    d = light.position - points
    dist = np.linalg.norm(d, axis=1)
    u = d / np.maximum(dist, 1e-300)[:, None]
    H = light.power / (4 * np.pi) * np.maximum(np.einsum("ij,ij->i", u, normals), 0.0) / np.maximum(dist, 1e-300) ** 2
    return H * spot_mask(light, -u) if light.kind == "SPOT" else H


def visibility(light: Light, points: np.ndarray, normals: np.ndarray, caster, samples: int,
               uniforms: np.ndarray | None = None) -> np.ndarray:
    """Fraction (k,) of shadow rays from each point that reach the light, among the rays above
    the point's horizon (the part of a light below it is already clipped from its form factor):
    ``samples`` rays a point to the same points of the light, or with ``uniforms`` (k, 3) one
    ray a point, to the point of the light that its own uniforms place (a ray below the
    horizon counts as reaching it)."""
    k = len(points)
    if light.kind == "SUN":
        if uniforms is None:
            u, v = stratified(grid_side(samples if light.radius > 0 else 1))
            dirs = cone_directions(-light.axis, light.radius / 2, u, v)
            d = np.tile(dirs, (k, 1))
        else:
            d = cone_directions(-light.axis, light.radius / 2, uniforms[:, 0], uniforms[:, 1])
        origins = np.repeat(points, len(d) // k, axis=0)
        clear = caster.reaches(origins + caster.epsilon * d, d)
    else:
        if uniforms is None:
            targets = np.tile(_sample_points(light, samples), (k, 1))
        else:
            targets = _light_points(light, *uniforms.T)
        origins = np.repeat(points, len(targets) // k, axis=0)
        d = targets - origins
        d = d / np.maximum(np.linalg.norm(d, axis=-1), 1e-300)[:, None]
        normal = None
        if light.kind == "AREA":
            t = _fan(light.polygon())[0]
            normal = np.cross(t[1] - t[0], t[2] - t[0])
            normal = normal / np.linalg.norm(normal)
        clear = caster.clear_between(origins, targets, target_normals=normal)
    above = (np.einsum("ij,ij->i", d, np.repeat(normals, len(d) // k, axis=0)) > 0)
    if uniforms is not None:
        return (clear | ~above).astype(float)
    seen = (clear & above).reshape(k, -1).sum(axis=1)
    return seen / np.maximum(above.reshape(k, -1).sum(axis=1), 1)


#: Where a patch's irradiance is taken: the centroids of its four midpoint children
#: (barycentric), averaged, so light that changes across a patch is integrated, not point-sampled.
PATCH_POINTS = np.array([[4, 1, 1], [1, 4, 1], [1, 1, 4], [2, 2, 2]]) / 6.0


def irradiance_at(points: np.ndarray, normals: np.ndarray, lights: list[Light], caster, *, samples: int = 16,
                  cull: float = CULL, rng: np.random.Generator | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(H (k, 3), culled (k, 3)): the light of ``lights`` at points (already lifted off their
    surface) facing unit ``normals``, and the unoccluded irradiance of the lights culled there.
    With ``rng``: one shadow ray a point to each light, to a point of it drawn afresh for each
    (``visibility``'s ``uniforms``): many such points average a light's penumbra."""
    H = np.zeros((len(points), 3))
    culled = np.zeros((len(points), 3))
    if not len(lights):
        return H, culled
    bounds = np.array([unoccluded(light, points, normals) * light.color.max() for light in lights])
    brightest = bounds.max(axis=0)
    for light, bound in zip(lights, bounds):
        raw = bound / max(light.color.max(), 1e-300)
        keep = (bound > 0) & (bound >= cull * brightest)
        skipped = (bound > 0) & ~keep
        culled[skipped] += np.outer(raw[skipped], light.color)
        ids = np.flatnonzero(keep)
        if len(ids):
            drawn = None if rng is None else rng.random((len(ids), 3))
            vis = visibility(light, points[ids], normals[ids], caster, samples, drawn)
            H[ids] += np.outer(raw[ids] * vis, light.color)
    return H, culled


def direct_irradiance(scene, lights: list[Light], *, samples: int = 16, cull: float = CULL, caster=None):
    """(H (n, 3), culled power (3,) W): the light of ``lights`` on the patches of ``scene``,
    the mean over ``PATCH_POINTS`` of each patch."""
    from .formfactors.raycast import EmbreeRays

    if not len(lights):
        return np.zeros((scene.n, 3)), np.zeros(3)
    caster = caster or EmbreeRays(scene, 1)
    k = len(PATCH_POINTS)
    normals = np.repeat(scene.normals, k, axis=0)
    points = np.einsum("pc,ncd->npd", PATCH_POINTS, scene.vertices[scene.triangles]).reshape(-1, 3)
    H, culled = irradiance_at(points + caster.epsilon * normals, normals, lights, caster, samples=samples, cull=cull)
    area = np.repeat(scene.areas / k, k)
    return H.reshape(scene.n, k, 3).mean(axis=1), (culled * area[:, None]).sum(axis=0)

def equirect_lookup(image: np.ndarray):
    """Radiance by direction from an equirectangular image (h, w, 3), as Cycles maps it:
    u = 1/2 - atan2(y, x) / (2 pi), v = 1/2 + asin(z) / pi (v up), nearest texel."""
    h, w = image.shape[:2]

    def radiance(dirs: np.ndarray) -> np.ndarray:
        u = 0.5 - np.arctan2(dirs[:, 1], dirs[:, 0]) / (2 * np.pi)
        v = 0.5 + np.arcsin(np.clip(dirs[:, 2], -1, 1)) / np.pi
        col = np.minimum((u % 1.0) * w, w - 1).astype(np.int64)
        row = np.minimum((1 - v) * h, h - 1).astype(np.int64)        # image row 0 is the top
        return image[row, col, :3]
    return radiance


def sky_irradiance(scene, radiance, rays: int = 64, seed: int = 0, caster=None, shared: int = 1) -> np.ndarray:
    """Irradiance (n, 3) at the patches from a distant sky of ``radiance(dirs) -> (k, 3)``
    (W/m^2/sr): pi x the mean radiance over cosine-weighted rays that leave the scene.
    Each run of ``shared`` consecutive patches draws the same jittered directions (common
    random numbers): where they face one way (points of one element), their differences are
    how the sky's visibility changes between them, not the rays' noise. Drawn apart, the
    noise of 64 rays at a window's edge passed the split threshold and split elements down
    to their last level (a furnished room's window: 37,800 splits where the World was the
    cause, 3,900 with 256 rays a point)."""
    from .formfactors.raycast import RAYS_PER_CALL, EmbreeRays

    caster = caster or EmbreeRays(scene, rays, seed)
    m2 = caster.rays
    H = np.zeros((scene.n, 3))
    per_call = max(1, RAYS_PER_CALL // (m2 * shared)) * shared
    for start in range(0, scene.n, per_call):
        ids = np.arange(start, min(start + per_call, scene.n))
        groups = -(-len(ids) // shared)
        u, v = stratified(caster.side)
        rng = np.random.default_rng((seed, 2, start))
        ju = np.repeat(rng.random((groups, m2)), shared, axis=0)[:len(ids)]
        jv = np.repeat(rng.random((groups, m2)), shared, axis=0)[:len(ids)]
        u = (u[None] + (ju - 0.5) / caster.side) % 1.0
        v = (v[None] + (jv - 0.5) / caster.side) % 1.0
        n = scene.normals[ids]
        dirs = cosine_directions(u, v, n).reshape(-1, 3)
        origins = np.repeat(scene.centroids[ids] + caster.epsilon * n, m2, axis=0)
        L = radiance(dirs) * caster.reaches(origins, dirs)[:, None]
        H[ids] = np.pi / m2 * (np.ones(m2) @ L.reshape(len(ids), m2, 3))      # the mean (numpy's: 4x slower)
    return H
