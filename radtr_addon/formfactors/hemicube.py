"""Hemicube form factors drawn offscreen with Blender's ``gpu`` module.

Each patch looks out from its centroid, lifted ``offset`` along its normal so that it does
not see itself, through one full top face and four half side faces of a unit hemicube.
Faces are drawn in ids as ``tiled`` describes. A pixel's delta form factor is

    top face (z = 1):      dF = dA / (pi (x^2 + y^2 + 1)^2)
    side face (x = +-1):   dF = z dA / (pi (y^2 + z^2 + 1)^2)

with dA = (2 / res)^2, normalised so that the pixels of one hemicube sum to 1 (pixel-centre
sums overshoot by about 1e-4 at 64 px). One tile of 3 res x res pixels holds a hemicube:
the top face on the left, the four half faces stacked two by two on the right, so no pixel
is wasted on the empty corners of the side faces.
"""
from __future__ import annotations

import numpy as np

from ..sampling import pixel_centres, rotated_frames, strata, tangent_frames
from .tiled import TiledRenderer, id_shader

_VERTEX = "void main() { v_id = pid; gl_Position = viewProj * vec4(pos, 1.0); }"


def tile_weights(res: int) -> np.ndarray:
    """Delta form factors of one hemicube tile, shape (res, 3 res), rows bottom-up, sum 1."""
    if res < 2 or res % 2:
        raise ValueError(f"hemicube resolution must be even and at least 2, got {res}")
    c = pixel_centres(res)                                   # across a face
    h = strata(res // 2)                                     # heights on a half face
    da = (2.0 / res) ** 2
    top = da / (np.pi * (c[None, :] ** 2 + c[:, None] ** 2 + 1.0) ** 2)
    side = h[:, None] * da / (np.pi * (c[None, :] ** 2 + h[:, None] ** 2 + 1.0) ** 2)
    sides = np.vstack([side, side])
    tile = np.hstack([top, sides, sides])
    return tile / tile.sum()


def _frustum(left, right, bottom, top, near, far):
    return np.array([
        [2 * near / (right - left), 0, (right + left) / (right - left), 0],
        [0, 2 * near / (top - bottom), (top + bottom) / (top - bottom), 0],
        [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)],
        [0, 0, -1, 0],
    ])


def _look(eye, forward, up):
    right = np.cross(forward, up)
    view = np.eye(4)
    view[0, :3], view[1, :3], view[2, :3] = right, up, -forward
    view[:3, 3] = -view[:3, :3] @ eye
    return view


class HemicubeRenderer(TiledRenderer):
    """Rows of form factors for a PatchScene by GPU hemicubes of ``resolution`` pixels.

    ``rotate`` turns each patch's hemicube about its normal by a random angle (fixed by
    ``seed`` and the patch id), so that regular scenes do not alias the same way everywhere.
    Needs a GPU context (``ensure_gpu_context``); shaders are built on first use.
    """

    def __init__(self, scene, resolution: int = 128, rotate: bool = False, seed: int = 0):
        super().__init__(scene, tile_weights(int(resolution)))
        self.res = int(resolution)
        self.rotate, self.seed = rotate, seed
        self._shader = self._batch = None

    def _ensure_gpu_objects(self):
        if self._shader is not None:
            return
        from gpu_extras.batch import batch_for_shader

        def declare(info):
            info.push_constant("MAT4", "viewProj")
            info.vertex_in(0, "VEC3", "pos")
            info.vertex_in(1, "FLOAT", "pid")

        self._shader = id_shader("hemicube", _VERTEX, declare)
        s = self.scene
        pos = (s.vertices[s.triangles.ravel()] - self.center).astype(np.float32)
        pid = np.repeat(np.arange(1, s.n + 1, dtype=np.float32), 3)
        self._batch = batch_for_shader(self._shader, "TRIS", {"pos": pos, "pid": pid})

    def frames(self, ids: np.ndarray):
        """Tangent and bitangent of each hemicube (turned at random when ``rotate``)."""
        normals = self.scene.normals[ids]
        if not self.rotate:
            return tangent_frames(normals)
        angles = np.array([np.random.default_rng((self.seed, int(i))).uniform(0, 2 * np.pi) for i in ids])
        return rotated_frames(normals, angles)

    def _views(self, i: int, t: np.ndarray, b: np.ndarray):
        """(viewport x, y, w, h, view-projection) of the five faces, tile-local pixels."""
        r, h = self.res, self.res // 2
        n = self.scene.normals[i]
        eye = self.eye(i)
        nr, fr = self.near, self.far
        top = _frustum(-nr, nr, -nr, nr, nr, fr) @ _look(eye, n, b)
        half = _frustum(-nr, nr, 0.0, nr, nr, fr)
        sides = [half @ _look(eye, d, n) for d in (t, -t, b, -b)]
        return [(0, 0, r, r, top), (r, 0, r, h, sides[0]), (r, h, r, h, sides[1]),
                (2 * r, 0, r, h, sides[2]), (2 * r, h, r, h, sides[3])]

    def _draw_batch(self, ids, origins):
        import gpu
        from mathutils import Matrix

        self._ensure_gpu_objects()
        tangents, bitangents = self.frames(ids)
        self.bind_ids(self._shader)
        for k, i in enumerate(ids):
            x0, y0 = origins[k]
            for x, y, w, h, m in self._views(int(i), tangents[k], bitangents[k]):
                gpu.state.viewport_set(x0 + x, y0 + y, w, h)
                self._shader.uniform_float("viewProj", Matrix(m.tolist()))
                self._batch.draw(self._shader)
                self.renders += 1
