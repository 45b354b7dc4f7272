"""Hemicube form factors drawn offscreen with Blender's ``gpu`` module.

Each patch looks out from its centroid, lifted ``offset`` along its normal so that it does
not see itself, through one full top face and four half side faces of a unit hemicube.
Every front face is drawn in its patch id (a float in an RGBA32F target, exact up to 2^24),
back faces in minus their id, nothing in 0. A pixel's delta form factor is

    top face (z = 1):      dF = dA / (pi (x^2 + y^2 + 1)^2)
    side face (x = +-1):   dF = z dA / (pi (y^2 + z^2 + 1)^2)

with dA = (2 / res)^2, normalised so that the pixels of one hemicube sum to 1 (pixel-centre
sums overshoot by about 1e-4 at 64 px). One tile of 3 res x res pixels holds a hemicube:
the top face on the left, the four half faces stacked two by two on the right. Many tiles
share one framebuffer, so one readback and one ``numpy.bincount`` give many rows.
"""
from __future__ import annotations

import numpy as np

from .rows import Row

#: Pixels per batch framebuffer (bounds the readback and histogram size).
BATCH_PIXELS = 1 << 21
#: Cells of the per-batch histogram (tiles x patches) before the batch is made smaller.
HISTOGRAM_CELLS = 1 << 23

_VERTEX = "void main() { v_id = pid; gl_Position = viewProj * vec4(pos, 1.0); }"
_FRAGMENT = "void main() { FragColor = vec4(gl_FrontFacing ? v_id : -v_id, 0.0, 0.0, 1.0); }"


def tile_weights(res: int) -> np.ndarray:
    """Delta form factors of one hemicube tile, shape (res, 3 res), rows bottom-up, sum 1."""
    if res < 2 or res % 2:
        raise ValueError(f"hemicube resolution must be even and at least 2, got {res}")
    c = -1.0 + (np.arange(res) + 0.5) * 2.0 / res           # pixel centres across a face
    h = (np.arange(res // 2) + 0.5) * 2.0 / res              # heights on a half face
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


def tangent_frames(normals: np.ndarray):
    """Unit tangents t and bitangents b with (t, b, n) right-handed, per normal."""
    helper = np.where(np.abs(normals[:, [0]]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    t = np.cross(helper, normals)
    t /= np.linalg.norm(t, axis=1)[:, None]
    return t, np.cross(normals, t)


class HemicubeRenderer:
    """Rows of form factors for a PatchScene by GPU hemicubes of ``resolution`` pixels.

    Needs a GPU context (``ensure_gpu_context``); shaders are built on first use.
    """

    def __init__(self, scene, resolution: int = 128):
        self.scene = scene
        self.res = int(resolution)
        self.weights = tile_weights(self.res)
        lo, hi = scene.vertices.min(axis=0), scene.vertices.max(axis=0)
        self.center = 0.5 * (lo + hi)
        self.centroids = scene.centroids
        self.diag = float(np.linalg.norm(hi - lo)) or 1.0
        self.near = 1e-4 * self.diag
        self.offset = 1e-4 * self.diag
        self.far = 2.5 * self.diag
        self._shader = self._batch = None
        self._layouts: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
        self.renders = 0
        tiles_by_pixels = max(1, BATCH_PIXELS // (3 * self.res * self.res))
        tiles_by_hist = max(1, HISTOGRAM_CELLS // (scene.n + 2))
        self.tiles_per_batch = min(tiles_by_pixels, tiles_by_hist)

    def rows(self, ids: np.ndarray) -> list[Row]:
        """Rows for the patch ids given, computed in as few readbacks as fit."""
        ids = np.asarray(ids, dtype=np.int64)
        out: list[Row] = []
        for start in range(0, len(ids), self.tiles_per_batch):
            out += self._batch_rows(ids[start:start + self.tiles_per_batch])
        return out

    # -- drawing -----------------------------------------------------------------------
    def _ensure_gpu_objects(self):
        if self._shader is not None:
            return
        import gpu
        from gpu_extras.batch import batch_for_shader

        info = gpu.types.GPUShaderCreateInfo()
        info.push_constant("MAT4", "viewProj")
        info.vertex_in(0, "VEC3", "pos")
        info.vertex_in(1, "FLOAT", "pid")
        iface = gpu.types.GPUStageInterfaceInfo("radtr_hemicube_iface")
        iface.flat("FLOAT", "v_id")
        info.vertex_out(iface)
        info.fragment_out(0, "VEC4", "FragColor")
        info.vertex_source(_VERTEX)
        info.fragment_source(_FRAGMENT)
        self._shader = gpu.shader.create_from_info(info)
        s = self.scene
        pos = (s.vertices[s.triangles.ravel()] - self.center).astype(np.float32)
        pid = np.repeat(np.arange(1, s.n + 1, dtype=np.float32), 3)
        self._batch = batch_for_shader(self._shader, "TRIS", {"pos": pos, "pid": pid})

    def _views(self, i: int, t: np.ndarray, b: np.ndarray):
        """(viewport x, y, w, h, view-projection) of the five faces, tile-local pixels."""
        s, r, h = self.scene, self.res, self.res // 2
        n = s.normals[i]
        eye = self.centroids[i] - self.center + self.offset * n
        nr, fr = self.near, self.far
        top = _frustum(-nr, nr, -nr, nr, nr, fr) @ _look(eye, n, b)
        half = _frustum(-nr, nr, 0.0, nr, nr, fr)
        sides = [half @ _look(eye, d, n) for d in (t, -t, b, -b)]
        return [(0, 0, r, r, top), (r, 0, r, h, sides[0]), (r, h, r, h, sides[1]),
                (2 * r, 0, r, h, sides[2]), (2 * r, h, r, h, sides[3])]

    def _batch_rows(self, ids: np.ndarray) -> list[Row]:
        import gpu
        from mathutils import Matrix

        self._ensure_gpu_objects()
        s = self.scene
        cols = max(1, min(len(ids), 4096 // (3 * self.res)))
        rows_ = -(-len(ids) // cols)
        width, height = cols * 3 * self.res, rows_ * self.res
        tangents, bitangents = tangent_frames(s.normals[ids])
        offscreen = gpu.types.GPUOffScreen(width, height, format="RGBA32F")
        buffer = gpu.types.Buffer("FLOAT", width * height * 4)
        try:
            with offscreen.bind():
                fb = gpu.state.active_framebuffer_get()
                gpu.state.scissor_test_set(False)
                gpu.state.viewport_set(0, 0, width, height)
                fb.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
                gpu.state.depth_test_set("LESS_EQUAL")
                gpu.state.depth_mask_set(True)
                gpu.state.face_culling_set("NONE")
                self._shader.bind()
                for k, i in enumerate(ids):
                    x0, y0 = (k % cols) * 3 * self.res, (k // cols) * self.res
                    for x, y, w, h, m in self._views(int(i), tangents[k], bitangents[k]):
                        gpu.state.viewport_set(x0 + x, y0 + y, w, h)
                        self._shader.uniform_float("viewProj", Matrix(m.tolist()))
                        self._batch.draw(self._shader)
                        self.renders += 1
                fb.read_color(0, 0, width, height, 4, 0, "FLOAT", data=buffer)
                gpu.state.depth_test_set("NONE")
                gpu.state.depth_mask_set(False)
        finally:
            offscreen.free()
        image = np.asarray(buffer).reshape(height, width, 4)[:, :, 0]
        return self._histogram(image, len(ids), cols)

    def _layout(self, rows_: int, cols: int):
        """Tile index and delta form factor of every framebuffer pixel (cached per grid)."""
        key = (rows_, cols)
        if key not in self._layouts:
            r = self.res
            tile = np.arange(rows_)[:, None] * cols + np.arange(cols)[None, :]
            self._layouts[key] = (np.kron(tile, np.ones((r, 3 * r), dtype=np.int64)),
                                  np.tile(self.weights, (rows_, cols)))
        return self._layouts[key]

    def _histogram(self, image: np.ndarray, count: int, cols: int) -> list[Row]:
        n, r = self.scene.n, self.res
        rows_ = image.shape[0] // r
        ids = np.rint(image).astype(np.int64)
        ids = np.where(ids < 0, n + 1, ids)
        tile_px, weights = self._layout(rows_, cols)
        used = tile_px < count
        keys = tile_px[used] * (n + 2) + ids[used]
        hist = np.bincount(keys, weights[used], minlength=count * (n + 2)).reshape(count, n + 2)
        out = []
        for row in hist:
            idx = np.flatnonzero(row[1:n + 1])
            out.append(Row(idx, row[1:n + 1][idx], float(row[0]), float(row[n + 1])))
        return out
