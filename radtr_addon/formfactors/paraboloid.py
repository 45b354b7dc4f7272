"""Single-view hemisphere form factors (the seed's "paraboloid" method), drawn with ``gpu``.

Projection. A point P seen from the eye along the unit direction d = (x, y, z) in the
patch's tangent frame (z along the normal) lands at (x, y) on the unit disk: the
orthographic projection of the unit hemisphere, Nusselt's analogue. The form factor of any
set of directions is the area of its image on the disk over pi, so every pixel whose centre
lies in the disk weighs the same, 1 / (pixels in the disk): no per-pixel weight table is
needed (unlike the dual-paraboloid map (x, y) / (1 + z), whose pixels would weigh
4 / (pi (1 + x^2 + y^2)^2) dA). Depth is the distance |P - eye|, so nearer surfaces win.

Straight edges. The map is not a perspective projection: a straight edge is an arc on the
disk, but the rasteriser joins projected vertices by chords, which is the method's known
error (darker junctions between walls, worst near the rim). The vertex shader therefore
draws each scene triangle as a barycentric grid of N x N sub-triangles, with one instanced
draw per grid size N (an instance holds max(1, 64 / N^2) parent triangles), the parent
triangle's corners fetched from a texture:

- ``none``: N = 1, the plain projection.
- ``uniform``: the same N for every triangle.
- ``adaptive``: per view, N for each triangle from its edges' sagitta s, the gap on the
  disk between an edge's projected arc and its chord at the arc's midpoint (the gap of a
  sub-edge falls as 1 / N^2): N = sqrt(s / ``split_tolerance``) rounded up to a power of
  two, capped at ``max_split``. Edges in a plane through the normal project straight
  (s = 0) and far or small triangles have tiny s, so only the triangles that need it are
  split. The area a chord cuts off does not shrink with resolution, so the tolerance is in
  disk radii (default 2e-3), not pixels.

Horizon. Triangles wholly below the tangent plane are not drawn at all. Others are
clipped by the GPU at the plane (``gl_ClipDistance`` = height above it), and points below
it are mapped outside the disk (radius 2 - r), so a clipped triangle is cut at the rim
instead of being folded back over the disk.
"""
from __future__ import annotations

import numpy as np

from ..sampling import pixel_centres, tangent_frames
from .methods import DEFAULT_SPLIT_TOLERANCE, SPLIT_MODES
from .tiled import TiledRenderer, frame_texture, id_shader

#: Grid sizes available to adaptive splitting.
ADAPTIVE_LEVELS = (1, 2, 4, 8, 16, 32, 64)

_VERTEX = """
vec4 texel(sampler2D tex, int k) { return texelFetch(tex, ivec2(k % 4096, k / 4096), 0); }
void main() {
  int k = gl_InstanceID * per_instance + int(slot);
  if (k >= count) { gl_Position = vec4(0.0, 0.0, 2.0, 1.0); v_id = 0.0; return; }
  int t = int(texel(order, first + k).r);
  vec3 a = texel(corners, 3 * t).xyz;
  vec3 b = texel(corners, 3 * t + 1).xyz;
  vec3 c = texel(corners, 3 * t + 2).xyz;
  vec3 d = (frame * vec4(a + (b - a) * bary.x + (c - a) * bary.y - eye, 0.0)).xyz;
  float r = length(d);
  d /= max(r, 1e-30);
  vec2 xy = d.xy;
  if (d.z < 0.0) {
    float rho = max(length(xy), 1e-30);
    xy *= (2.0 - rho) / rho;
  }
  gl_ClipDistance[0] = d.z;
  gl_ClipDistance[1] = r - near;
  v_id = float(t + 1);
  gl_Position = vec4(xy, 2.0 * (r - near) / (far - near) - 1.0, 1.0);
}
"""


def disk_weights(res: int) -> np.ndarray:
    """Equal weights on the pixels whose centres lie in the unit disk, shape (res, res), sum 1."""
    if res < 2:
        raise ValueError(f"paraboloid resolution must be at least 2, got {res}")
    c = pixel_centres(res)
    inside = (c[None, :] ** 2 + c[:, None] ** 2) < 1.0
    return inside / inside.sum()


#: Sub-triangles per instance: small grids pack several parent triangles into one instance,
#: since a software rasteriser pays per instance.
TRIANGLES_PER_INSTANCE = 64


def grid_template(n: int):
    """(barycentrics (k, 2), slot (k,), parents per instance) of the instanced grid of size n."""
    per_instance = max(1, TRIANGLES_PER_INSTANCE // (n * n))
    bary = grid_barycentrics(n)
    return (np.tile(bary, (per_instance, 1)),
            np.repeat(np.arange(per_instance, dtype=np.float32), len(bary)), per_instance)


def grid_barycentrics(n: int) -> np.ndarray:
    """(3 n^2, 2) barycentric (u, v) of the sub-triangles of an n x n grid, same winding."""
    out = []
    for i in range(n):
        for j in range(n - i):
            out += [(i, j), (i + 1, j), (i, j + 1)]
            if i + j < n - 1:
                out += [(i + 1, j), (i + 1, j + 1), (i, j + 1)]
    return np.asarray(out, dtype=np.float32) / n


class ParaboloidRenderer(TiledRenderer):
    """Rows of form factors by one hemisphere view per patch, ``resolution`` pixels across.

    ``split`` is one of SPLIT_MODES; ``split_level`` is N for ``uniform``; ``split_tolerance``
    and ``max_split`` steer ``adaptive``.
    """

    #: Depth is linear in distance over near..far (2.5 diagonals): 2^-15 is 7.6e-5 of the
    #: diagonal, under the eye's lift (1e-4, ``EYE_LIFT``); depth interpolated over thin grid triangles
    #: differs between a triangle and its reversed twin by up to about 2^-18.
    back_face_bias = 2.0 ** -15

    def __init__(self, scene, resolution: int = 256, split: str = "adaptive", split_level: int = 4,
                 split_tolerance: float = DEFAULT_SPLIT_TOLERANCE, max_split: int = 32):
        if split not in SPLIT_MODES:
            raise ValueError(f"split mode must be one of {', '.join(SPLIT_MODES)}, got '{split}'")
        super().__init__(scene, disk_weights(int(resolution)))
        self.res = int(resolution)
        self.split, self.split_level, self.max_split = split, max(1, int(split_level)), int(max_split)
        self.split_tolerance = float(split_tolerance)
        self.sub_triangles = 0
        # bounding radius of each triangle about its centroid (vertices within it)
        corners = scene.vertices[scene.triangles]
        self._radii = np.linalg.norm(corners - self.centroids[:, None], axis=2).max(axis=1)
        self._shader = None
        self._grids: dict[int, object] = {}
        self._corners = None

    # -- per-view triangle lists -----------------------------------------------------------
    def levels(self, i: int) -> np.ndarray:
        """Grid size N per scene triangle for the view of patch i; 0 = not drawn (below horizon)."""
        s = self.scene
        n = s.normals[i]
        rel = s.vertices - (self.eye(i) + self.center)
        height = rel @ n
        # zero-area triangles are skipped: the curved map would open collinear points into a triangle
        above = (height[s.triangles] > 0).any(axis=1) & (s.areas > 0)
        above[i] = False
        if self.split == "none":
            return above.astype(np.int64)
        if self.split == "uniform":
            return above * self.split_level
        level = above.astype(np.int64)
        # an edge seen under an angle a has a gap of at most a^2 / 8: only wide ones are measured
        angle = 2 * self._radii / np.maximum(np.linalg.norm(self.centroids - self.center - self.eye(i), axis=1),
                                             1e-300)
        wide = np.flatnonzero(above & (angle ** 2 / 8 > self.split_tolerance))
        sag = self.sagitta(rel, s.triangles[wide], n)
        want = np.ceil(np.sqrt(sag / self.split_tolerance))
        steps = np.array([lv for lv in ADAPTIVE_LEVELS if lv <= self.max_split] or [1])
        level[wide] = steps[np.minimum(np.searchsorted(steps, want), len(steps) - 1)]
        return level

    @staticmethod
    def sagitta(rel: np.ndarray, tris: np.ndarray, n: np.ndarray) -> np.ndarray:
        """Per triangle, the widest gap on the disk between an edge's projected arc and its chord.

        ``rel``: vertices relative to the eye. The gap is measured at the arc's midpoint
        (the projection of the edge's midpoint direction), in units of the disk radius.
        """
        dirs = rel / np.maximum(np.linalg.norm(rel, axis=1), 1e-300)[:, None]
        flat = dirs - np.outer(dirs @ n, n)                      # projection onto the disk plane
        worst = np.zeros(len(tris))
        for a, b in ((0, 1), (1, 2), (2, 0)):
            da, db = dirs[tris[:, a]], dirs[tris[:, b]]
            mid = da + db
            mid /= np.maximum(np.linalg.norm(mid, axis=1), 1e-300)[:, None]
            pa, pb = flat[tris[:, a]], flat[tris[:, b]]
            pm = mid - np.outer(mid @ n, n)
            chord = pb - pa
            length = np.linalg.norm(chord, axis=1)
            gap = np.abs(np.cross(chord, pm - pa) @ n) / np.maximum(length, 1e-300)
            gap = np.where(length > 1e-12, gap, np.linalg.norm(pm - pa, axis=1))
            worst = np.maximum(worst, gap)
        return worst

    def _plan(self, ids: np.ndarray):
        """Triangle order for a batch and, per view, the (N, first, count) instanced draws."""
        chunks, draws, first = [], [], 0
        for i in ids:
            level = self.levels(int(i))
            view = []
            for lv in np.unique(level[level > 0]):
                tris = np.flatnonzero(level == lv)
                chunks.append(tris)
                view.append((int(lv), first, len(tris)))
                first += len(tris)
                self.sub_triangles += len(tris) * int(lv) ** 2
            draws.append(view)
        order = np.concatenate(chunks) if chunks else np.zeros(1, np.int64)
        return order.astype(np.float32)[:, None], draws

    # -- drawing ----------------------------------------------------------------------------
    def _ensure_gpu_objects(self):
        if self._shader is not None:
            return
        def declare(info):
            info.push_constant("MAT4", "frame")
            info.push_constant("VEC3", "eye")
            for name in ("near", "far"):
                info.push_constant("FLOAT", name)
            for name in ("first", "count", "per_instance"):
                info.push_constant("INT", name)
            info.sampler(0, "FLOAT_2D", "corners")
            info.sampler(1, "FLOAT_2D", "order")
            info.vertex_in(0, "VEC2", "bary")
            info.vertex_in(1, "FLOAT", "slot")

        self._shader = id_shader("paraboloid", _VERTEX, declare)
        s = self.scene
        self._corners = frame_texture((s.vertices[s.triangles.reshape(-1)] - self.center).astype(np.float32))

    def _grid(self, n: int):
        """The batch drawing size-n grids and how many parent triangles one instance holds."""
        if n not in self._grids:
            from gpu_extras.batch import batch_for_shader

            bary, slot, per_instance = grid_template(n)
            self._grids[n] = batch_for_shader(self._shader, "TRIS", {"bary": bary, "slot": slot}), per_instance
        return self._grids[n]

    def _draw_batch(self, ids, origins):
        import gpu
        from mathutils import Matrix

        self._ensure_gpu_objects()
        order, draws = self._plan(ids)
        order_tex = frame_texture(order)
        t, b = tangent_frames(self.scene.normals[ids])
        sh = self._shader
        self.bind_ids(sh)
        sh.uniform_sampler("corners", self._corners)
        sh.uniform_sampler("order", order_tex)
        sh.uniform_float("near", self.near)
        sh.uniform_float("far", self.far)
        gpu.state.clip_distances_set(2)
        try:
            for k, i in enumerate(ids):
                frame = np.eye(4)
                # (t, -b) across the disk keeps front faces counter-clockwise on screen
                frame[0, :3], frame[1, :3], frame[2, :3] = t[k], -b[k], self.scene.normals[i]
                x0, y0 = origins[k]
                gpu.state.viewport_set(x0, y0, self.res, self.res)
                sh.uniform_float("frame", Matrix(frame.tolist()))
                sh.uniform_float("eye", tuple(self.eye(int(i))))
                for n, first, count in draws[k]:
                    batch, per_instance = self._grid(n)
                    sh.uniform_int("first", first)
                    sh.uniform_int("count", count)
                    sh.uniform_int("per_instance", per_instance)
                    batch.draw_instanced(sh, instance_start=0, instance_count=-(-count // per_instance))
                self.renders += 1
        finally:
            gpu.state.clip_distances_set(0)
