"""Shared machinery of the GPU form-factor methods: many views tiled into one framebuffer.

A method draws each patch's view of the scene into one tile of ``weights.shape`` pixels,
every front face in its patch id + 1 (a float in an RGBA32F target, exact up to 2^24), back
faces in n + 1 (``BLOCKED``, so they add up as "blocked"), nothing in 0; only the red
channel is read back. Many tiles share a framebuffer, so one readback and one
``numpy.bincount`` against the method's per-pixel weights (``weights``, summing to 1 per
tile) give many rows. Subclasses set ``weights`` and implement ``_draw_batch``.
"""
from __future__ import annotations

import numpy as np

from ..sampling import bounding_box, hit_histogram
from ..tolerances import EYE_LIFT, NEAR_PLANE
from .rows import Row, histogram_rows, rows_skipping_degenerate

#: Pixels per batch framebuffer (bounds the readback and histogram size).
BATCH_PIXELS = 1 << 21
#: Cells of the per-batch histogram (tiles x patches) before the batch is made smaller.
HISTOGRAM_CELLS = 1 << 23
#: Widest framebuffer used.
MAX_WIDTH = 4096


class TiledRenderer:
    """Rows of form factors for a PatchScene from per-patch views tiled in framebuffers.

    ``back_face_bias`` is the window depth added to back faces, so that a front face at the
    same place wins: a wall modelled as two faces back to back is seen from the room as its
    front face, not as the coincident back of its twin (the smallest bias that gives a closed
    box with doubled walls a white-furnace row sum of 1, measured on Mesa llvmpipe).
    """

    #: A few steps of a 24-bit depth buffer (perspective depth: about 5e-3 w^2 / diagonal
    #: in distance at distance w, near plane 1e-4 of the diagonal).
    back_face_bias = 2.0 ** -21

    def __init__(self, scene, weights: np.ndarray):
        self.scene = scene
        self.weights = weights
        th, tw = weights.shape
        self.center, diag = bounding_box(scene.vertices)
        self.diag = diag or 1.0
        self.centroids = scene.centroids
        self.near = NEAR_PLANE * self.diag
        self.offset = EYE_LIFT * self.diag
        self.far = 2.5 * self.diag
        self.renders = 0
        self._offscreen = None
        self._layouts: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
        tiles_by_pixels = max(1, BATCH_PIXELS // (th * tw))
        tiles_by_hist = max(1, HISTOGRAM_CELLS // (scene.n + 2))
        self.tiles_per_batch = min(tiles_by_pixels, tiles_by_hist)

    def eye(self, i: int) -> np.ndarray:
        """Where patch i looks from, relative to ``center``: its centroid lifted off the surface."""
        return self.centroids[i] - self.center + self.offset * self.scene.normals[i]

    def rows(self, ids) -> list[Row]:
        """Rows for the patch ids given, computed in as few readbacks as fit (zero-area: all escaped)."""
        return rows_skipping_degenerate(self.scene, ids, self._rows)

    def _rows(self, ids: np.ndarray) -> list[Row]:
        out: list[Row] = []
        for start in range(0, len(ids), self.tiles_per_batch):
            out += self._rows_of_batch(ids[start:start + self.tiles_per_batch])
        return out

    def row(self, i: int) -> Row:
        return self.rows([i])[0]

    def _rows_of_batch(self, ids: np.ndarray) -> list[Row]:
        import gpu

        th, tw = self.weights.shape
        cols = max(1, min(len(ids), MAX_WIDTH // tw))
        rows_ = -(-len(ids) // cols)
        width, height = cols * tw, rows_ * th
        origins = [((k % cols) * tw, (k // cols) * th) for k in range(len(ids))]
        offscreen, buffer = self._target(width, height)
        with offscreen.bind():
            fb = gpu.state.active_framebuffer_get()
            gpu.state.scissor_test_set(False)
            gpu.state.viewport_set(0, 0, width, height)
            fb.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
            gpu.state.depth_test_set("LESS_EQUAL")
            gpu.state.depth_mask_set(True)
            gpu.state.face_culling_set("NONE")
            try:
                self._draw_batch(ids, origins)
            finally:
                gpu.state.depth_test_set("NONE")
                gpu.state.depth_mask_set(False)
            fb.read_color(0, 0, width, height, 1, 0, "FLOAT", data=buffer)
        return self._histogram(np.asarray(buffer), len(ids), rows_, cols)

    def _target(self, width: int, height: int):
        """An offscreen framebuffer and readback buffer of this size, kept for the next batch."""
        import gpu

        if self._offscreen is None or self._offscreen[0] != (width, height):
            self.free()
            self._offscreen = ((width, height), gpu.types.GPUOffScreen(width, height, format="RGBA32F"),
                               gpu.types.Buffer("FLOAT", width * height))
        return self._offscreen[1], self._offscreen[2]

    def free(self):
        """Release the GPU framebuffer (also done when the renderer is garbage-collected)."""
        if self._offscreen is not None:
            self._offscreen[1].free()
            self._offscreen = None

    def __del__(self):
        try:
            self.free()
        except Exception:  # interpreter shutdown: the GPU module may be gone already
            pass

    @property
    def blocked_id(self) -> float:
        """The value back faces are drawn in."""
        return float(self.scene.n + 1)

    def bind_ids(self, shader):
        """Bind an ``id_shader`` with this renderer's blocked id and back-face depth bias."""
        shader.bind()
        shader.uniform_float("blocked", self.blocked_id)
        shader.uniform_float("back_bias", self.back_face_bias)

    def _draw_batch(self, ids: np.ndarray, origins: list[tuple[int, int]]):
        """Draw the view of patch ids[k] into the tile whose lower-left pixel is origins[k]."""
        raise NotImplementedError

    def _layout(self, rows_: int, cols: int, count: int):
        """Per framebuffer pixel: histogram cell offset (n + 2) x tile, and weight (0 in unused tiles)."""
        key = (rows_, cols, count)
        if key not in self._layouts:
            th, tw = self.weights.shape
            tile = np.arange(rows_)[:, None] * cols + np.arange(cols)[None, :]
            tile_px = np.kron(tile, np.ones((th, tw), dtype=np.int64)).ravel()
            weights = np.tile(self.weights, (rows_, cols)).ravel()
            weights[tile_px >= count] = 0.0
            if len(self._layouts) >= 4:      # full batches and the last, partial one of each call
                self._layouts.clear()
            self._layouts[key] = (np.minimum(tile_px, count - 1) * (self.scene.n + 2), weights)
        return self._layouts[key]

    def _histogram(self, image: np.ndarray, count: int, rows_: int, cols: int) -> list[Row]:
        base, weights = self._layout(rows_, cols, count)
        return histogram_rows(hit_histogram(base + image.astype(np.int64), count, self.scene.n + 2, weights))


_ID_FRAGMENT = """
void main() {
  FragColor = vec4(gl_FrontFacing ? v_id : blocked, 0.0, 0.0, 1.0);
  gl_FragDepth = gl_FrontFacing ? gl_FragCoord.z : gl_FragCoord.z + back_bias;
}
"""


def id_shader(name: str, vertex_source: str, declare):
    """A shader drawing patch ids: ``declare(info)`` adds the method's inputs; the vertex
    source sets the flat ``v_id``; back faces get the ``blocked`` push constant and lie
    ``back_bias`` deeper, so that they lose depth ties with front faces (``bind_ids``)."""
    import gpu

    info = gpu.types.GPUShaderCreateInfo()
    declare(info)
    info.push_constant("FLOAT", "blocked")
    info.push_constant("FLOAT", "back_bias")
    iface = gpu.types.GPUStageInterfaceInfo(f"radtr_{name}_iface")
    iface.flat("FLOAT", "v_id")
    info.vertex_out(iface)
    info.fragment_out(0, "VEC4", "FragColor")
    info.depth_write("GREATER")
    info.vertex_source(vertex_source)
    info.fragment_source(_ID_FRAGMENT)
    return gpu.shader.create_from_info(info)


def frame_texture(values: np.ndarray):
    """A float RGBA32F texture holding ``values`` (k, <=4) as texels, 4096 per texture row."""
    import gpu

    k = len(values)
    width = min(max(k, 1), MAX_WIDTH)
    height = -(-max(k, 1) // width)
    data = np.zeros((width * height, 4), dtype=np.float32)
    data[:k, :values.shape[1]] = values
    return gpu.types.GPUTexture((width, height), format="RGBA32F",
                                data=gpu.types.Buffer("FLOAT", data.size, data.ravel()))
