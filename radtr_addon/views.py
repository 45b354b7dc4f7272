"""What a patch sees, as pictures (the seed's F16/F17 debug views), and where to put the eye.

``patch_view`` casts one Embree ray per pixel from a patch's centroid and returns the patch id
each pixel sees (-1 nothing, -2 a back face; ``"sky"``: the parallel view a sky form factor
counts, from the dome point along the patch's normal): ``"paraboloid"`` is the orthographic
hemisphere (Nusselt) map the paraboloid method draws, where every pixel in the disk weighs
the same, so a patch's share of the disk is its form factor; ``"hemicube"`` is the unfolded
hemicube, the full top face in the middle of a 2 res x 2 res cross and the four half faces
around it. ``id_colors`` turns ids into the seed's colour code. ``view_from_patch`` gives
the eye position and rotation that look out of a patch along its normal.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .sampling import bounding_box, bounding_sphere, parallel_rays, pixel_centres, tangent_frames

VIEWS = ("paraboloid", "hemicube", "sky")


def _directions(kind: str, res: int):
    """Per-pixel local directions (h, w, 3) (x: tangent, y: bitangent, z: normal), NaN off the view."""
    if kind == "paraboloid":
        g = pixel_centres(res)
        x, y = np.meshgrid(g, g[::-1])
        r2 = x * x + y * y
        d = np.stack([x, y, np.sqrt(np.maximum(1 - r2, 0))], axis=-1)
        d[r2 > 1] = np.nan
        return d
    if kind != "hemicube":
        raise ValueError(f"view must be one of {', '.join(VIEWS)}, got '{kind}'")
    n = 2 * res
    g = pixel_centres(n)                                       # -1 .. 1 across the cross, top face in |.| < 0.5
    x, y = np.meshgrid(g * 2, (g * 2)[::-1])                   # top face: -1..1
    d = np.full((n, n, 3), np.nan)
    top = (np.abs(x) <= 1) & (np.abs(y) <= 1)
    d[top] = np.stack([x[top], y[top], np.ones(top.sum())], axis=-1)
    for axis, sign in ((0, 1), (0, -1), (1, 1), (1, -1)):
        along = x if axis == 0 else y
        other = y if axis == 0 else x
        side = (sign * along > 1) & (np.abs(other) <= 1)
        h = 2 - sign * along[side]                             # height above the horizon: 1 at the top edge
        v = np.zeros((side.sum(), 3))
        v[:, axis] = sign
        v[:, 1 - axis] = other[side]
        v[:, 2] = h
        d[side] = v
    return d


def sky_view(scene, direction, res: int = 128, caster=None) -> np.ndarray:
    """Patch ids (res, res) of the parallel view from the sky point in ``direction`` (the view a
    sky form factor counts, ``sky``): -1 sky seen through, -2 a back face."""
    from .formfactors.raycast import EmbreeRays

    caster = caster or EmbreeRays(scene, 1)
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    hit = caster.hit(*parallel_rays(*bounding_sphere(scene.vertices), d, res, top_down=True))
    back = (hit >= 0) & (scene.normals[np.maximum(hit, 0)] @ d < 0)
    return np.where(back, -2, hit).reshape(res, res)


def patch_view(scene, i: int, kind: str = "paraboloid", res: int = 128, caster=None) -> np.ndarray:
    """Patch ids (h, w) seen from patch ``i``'s centroid: -1 nothing, -2 back face, NaN pixels -3.
    ``"sky"``: the sky's parallel view from the dome point along the patch's normal (the zenith
    when the normal points down)."""
    from .formfactors.raycast import EmbreeRays

    caster = caster or EmbreeRays(scene, 1)
    if kind == "sky":
        n = scene.normals[i]
        return sky_view(scene, n if n[2] > 0 else [0.0, 0.0, 1.0], res, caster)
    local = _directions(kind, res)
    ok = ~np.isnan(local[..., 0])
    n = scene.normals[i]
    t, b = tangent_frames(n[None])
    d = local[ok] @ np.stack([t[0], b[0], n])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    origin = scene.centroids[i] + caster.epsilon * n
    hit = caster.hit(np.broadcast_to(origin, d.shape), d)
    back = (hit >= 0) & (np.einsum("ij,ij->i", d, scene.normals[np.maximum(hit, 0)]) > 0)
    out = np.full(ok.shape, -3)
    out[ok] = np.where(back, -2, hit)
    return out


def id_colors(ids: np.ndarray) -> np.ndarray:
    """RGB (h, w, 3) in [0, 1]: patch i as the bytes of i + 1 (the seed's code); nothing black,
    back faces dark red, outside the view grey."""
    code = ids + 1
    rgb = np.stack([code & 255, (code >> 8) & 255, (code >> 16) & 255], axis=-1) / 255.0
    rgb[ids == -1] = 0.0
    rgb[ids == -2] = (0.3, 0.0, 0.0)
    rgb[ids == -3] = 0.5
    return rgb


def view_from_patch(scene, i: int, lift: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """(eye position, rotation quaternion w, x, y, z) looking out of patch ``i`` along its normal
    (a Blender view looks along its -Z)."""
    n = scene.normals[i]
    z = -n                                                     # the view's +Z points back into the patch
    t, _ = tangent_frames(n[None])
    x = t[0]
    y = np.cross(z, x)
    m = np.stack([x, y, z], axis=1)                            # columns: the view's axes in world space
    qx, qy, qz, qw = Rotation.from_matrix(m).as_quat()
    q = np.array([qw, qx, qy, qz])
    return scene.centroids[i] + lift * bounding_box(scene.vertices)[1] * n, q / np.linalg.norm(q)


def pick_patch(scene, origin, direction, caster=None) -> int:
    """The patch a ray from ``origin`` along ``direction`` hits first, or -1 (a viewport click)."""
    from .formfactors.raycast import EmbreeRays

    caster = caster or EmbreeRays(scene, 1)
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    return int(caster.hit(np.asarray([origin], float), d[None])[0])


def toggle_emission(E: np.ndarray, i: int) -> np.ndarray:
    """E with patch i switched off if it emits, else on at the scene's brightest emission (F17)."""
    out = E.copy()
    out[i] = 0.0 if E[i].max() > 0 else E[E.max(axis=1).argmax()]
    return out
