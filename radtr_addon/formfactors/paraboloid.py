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
draws each scene triangle as a template of sub-triangles given in barycentric coordinates,
with one instanced draw per template (an instance holds max(1, 64 / sub-triangles) parent
triangles), the parent triangle's corners fetched from a texture. The split modes are the
seed's six (report 4.5.1, 5.4.3 and Anexo J "Shaders de división de triángulos en
paraboloide"), each drawn as such a template; ``split_level`` N sets the depth (see
``split_barycentrics``):

- ``none`` (seed "Sin división"): the plain projection, 1 triangle.
- ``triangle`` (seed "División de triángulos", longest-edge bisection): 4^ceil(log2 N)
  sub-triangles, every edge cut in 2^ceil(log2 N).
- ``centre`` (seed "División desde el centro del triángulo"): a fan of 3 N triangles from the
  centroid, every edge cut in N.
- ``uniform`` (seed "División homogénea"): the N x N barycentric grid, N^2 sub-triangles.
- ``diagonal`` (seed "División diagonal"): a zigzag strip of 3 N - 2 triangles, every edge
  cut in N.
- ``adaptive`` (ours, standing in for the seed's "División con teselado", whose tessellation
  shader picks the split count on the GPU): per view, the grid size N of each triangle from
  its edges' sagitta s, the gap on the disk between an edge's projected arc and its chord at
  the arc's midpoint (the gap of a sub-edge falls as 1 / N^2): N = sqrt(s /
  ``split_tolerance``) rounded up to a power of two, capped at ``max_split``. Edges in a
  plane through the normal project straight (s = 0) and far or small triangles have tiny s,
  so only the triangles that need it are split. The area a chord cuts off does not shrink
  with resolution, so the tolerance is in disk radii (default 2e-3), not pixels.

The seed's geometry shaders split each triangle until its edges were shorter on screen than
a threshold; here the depth is one N for every drawn triangle (``adaptive`` apart). Every
fixed-depth template cuts each parent edge into the same points, so two neighbours with the
same template meet without cracks, and sub-triangles keep the parent's winding.

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
  vec2 o = texel(order, first + k).rg;
  int t = int(o.r);
  int turn = int(o.g);
  vec3 a = texel(corners, 3 * t + turn).xyz;
  vec3 b = texel(corners, 3 * t + (turn + 1) % 3).xyz;
  vec3 c = texel(corners, 3 * t + (turn + 2) % 3).xyz;
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


def split_template(mode: str, n: int):
    """(barycentrics (k, 2), slot (k,), parents per instance) of the instanced template of
    ``mode`` at level n (``split_barycentrics``)."""
    bary = split_barycentrics(mode, n)
    per_instance = max(1, TRIANGLES_PER_INSTANCE // (len(bary) // 3))
    return (np.tile(bary, (per_instance, 1)),
            np.repeat(np.arange(per_instance, dtype=np.float32), len(bary)), per_instance)


def split_barycentrics(mode: str, n: int) -> np.ndarray:
    """(3 k, 2) barycentric (u, v) of the k sub-triangles that split mode ``mode`` draws at level n.

    A point (u, v) is a + u (b - a) + v (c - a) for the parent's corners a, b, c; every
    sub-triangle has the parent's winding and together they tile the parent. ``none`` is the
    parent, ``uniform`` and ``adaptive`` the n x n grid (``grid_barycentrics``), the others
    ``bisection_barycentrics``, ``centre_barycentrics`` and ``diagonal_barycentrics``.
    """
    n = max(1, int(n))
    if mode == "none":
        return grid_barycentrics(1)
    if mode in ("uniform", "adaptive"):
        return grid_barycentrics(n)
    if mode == "triangle":
        return bisection_barycentrics(n)
    if mode == "centre":
        return centre_barycentrics(n)
    if mode == "diagonal":
        return diagonal_barycentrics(n)
    raise ValueError(f"split mode must be one of {', '.join(SPLIT_MODES)}, got '{mode}'")


def sub_triangle_count(mode: str, n: int) -> int:
    """How many sub-triangles ``split_barycentrics(mode, n)`` has."""
    n = max(1, int(n))
    k = (n - 1).bit_length()
    return {"none": 1, "triangle": 4 ** k, "centre": 3 * n, "diagonal": 3 * n - 2}.get(mode, n * n)


def grid_barycentrics(n: int) -> np.ndarray:
    """(3 n^2, 2) barycentric (u, v) of the sub-triangles of an n x n grid, same winding.

    The seed's "División homogénea" (Anexo J): the split the scene's own subdivision makes,
    sub-triangles of the parent's proportions.
    """
    out = []
    for i in range(n):
        for j in range(n - i):
            out += [(i, j), (i + 1, j), (i, j + 1)]
            if i + j < n - 1:
                out += [(i + 1, j), (i + 1, j + 1), (i, j + 1)]
    return np.asarray(out, dtype=np.float32) / n


def bisection_barycentrics(n: int) -> np.ndarray:
    """(3 4^k, 2), k = ceil(log2 n): 2 k rounds of bisection, every edge cut in 2^k >= n.

    The seed's "División de triángulos" (Anexo J; "División Triángulo" in the tools list):
    repeatedly split the triangle whose edge is longest on screen at that edge's midpoint,
    also splitting the neighbour across an interior edge so that no hanging vertex opens a
    hole, until every edge is under a threshold. As a fixed template: the parent's corners
    are turned per view so that its longest edge on the disk is b-c
    (``ParaboloidRenderer.first_split``), round 1 halves it, and each later round halves
    every sub-triangle at the edge facing its newest vertex (newest-vertex bisection, the
    conforming form of longest-edge bisection: no hanging vertices). Two rounds halve every
    edge, so each parent edge is cut in 2^k equal pieces.
    """
    rounds = 2 * (max(1, int(n)) - 1).bit_length()
    tris = [((0, 0), (1, 0), (0, 1))]           # (newest vertex, then the edge it faces)
    for _ in range(rounds):
        nxt = []
        for apex, p, q in tris:
            m = ((p[0] + q[0]) / 2, (p[1] + q[1]) / 2)
            nxt += [(m, apex, p), (m, q, apex)]
        tris = nxt
    return np.asarray(tris, dtype=np.float32).reshape(-1, 2)


def centre_barycentrics(n: int) -> np.ndarray:
    """(9 n, 2): 3 n triangles fanned from the centroid to each parent edge cut in n pieces.

    The seed's "División desde el centro del triángulo" (Anexo J): first 3 triangles from
    the centre to the corners, then each one's outer edge divided until its pieces are short
    enough, with a triangle from the centre to each piece. Outer edges get a bounded length
    and meet the neighbours' without cracks; the triangles are long and thin, and the three
    edges from the centre stay chords (the seed's "cubo rojo cortado").
    """
    n = max(1, int(n))
    corners = np.array([(0, 0), (3 * n, 0), (0, 3 * n)])   # in units of 1 / (3 n): the centroid is (n, n)
    out = []
    for a in range(3):
        p, q = corners[a], corners[(a + 1) % 3]
        for k in range(n):
            out += [(n, n), tuple(p + (q - p) * k // n), tuple(p + (q - p) * (k + 1) // n)]
    return np.asarray(out, dtype=np.float32) / (3 * n)


def diagonal_barycentrics(n: int) -> np.ndarray:
    """(3 (3 n - 2), 2): a zigzag strip of 3 n - 2 triangles, every parent edge cut in n.

    The seed's "División diagonal" (Anexo J): "divides the edges generating triangles in
    zigzag; with few triangles it divides the edges well but makes triangles too long". The
    report's figure is not in its text, so the layout is our reading: one strip between the
    two boundary chains from corner a to corner b, P (a to b, n pieces) and Q (a to c to b,
    2 n pieces), its rungs running diagonally across the parent, two steps along Q for each
    along P. Every vertex is on the boundary: the edges are followed with the fewest
    triangles any split cutting them in n can have, and the inside is left to long chords.
    """
    n = max(1, int(n))
    if n == 1:
        return grid_barycentrics(1)

    def p(i):
        return (i, 0)

    def q(j):
        return (0, j) if j <= n else (j - n, 2 * n - j)

    out = [(0, 0), p(1), q(1)]
    i, j = 1, 1
    while (i, j) != (n - 1, 2 * n - 1):
        if i < n - 1 and (j == 2 * n - 1 or 2 * (i + 1) <= j + 1):
            out += [p(i), p(i + 1), q(j)]
            i += 1
        else:
            out += [p(i), q(j + 1), q(j)]
            j += 1
    out += [p(n - 1), p(n), q(2 * n - 1)]
    return np.asarray(out, dtype=np.float32) / n


class ParaboloidRenderer(TiledRenderer):
    """Rows of form factors by one hemisphere view per patch, ``resolution`` pixels across.

    ``split`` is one of SPLIT_MODES; ``split_level`` is the level N of ``uniform``, ``triangle``,
    ``centre`` and ``diagonal`` (``split_barycentrics``); ``split_tolerance`` and ``max_split``
    steer ``adaptive``.
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
        self._templates: dict[int, object] = {}
        self._corners = None

    # -- per-view triangle lists -----------------------------------------------------------
    def relative(self, i: int) -> np.ndarray:
        """The scene's vertices relative to the eye of patch i."""
        return self.scene.vertices - (self.eye(i) + self.center)

    def levels(self, i: int, rel: np.ndarray | None = None) -> np.ndarray:
        """Split level N per scene triangle for the view of patch i; 0 = not drawn (below horizon).

        ``rel``: ``relative(i)``, when the caller has it."""
        s = self.scene
        n = s.normals[i]
        rel = self.relative(i) if rel is None else rel
        height = rel @ n
        # zero-area triangles are skipped: the curved map would open collinear points into a triangle
        above = (height[s.triangles] > 0).any(axis=1) & (s.areas > 0)
        above[i] = False
        if self.split == "none":
            return above.astype(np.int64)
        if self.split != "adaptive":
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

    def first_split(self, i: int, tris: np.ndarray, rel: np.ndarray | None = None) -> np.ndarray:
        """Per triangle of ``tris``, the turn 0..2 of its corners the view of patch i draws it with.

        The corners are fetched as (t, t + 1, t + 2) mod 3 from turn t, which keeps the
        winding. ``triangle`` turns the triangle's longest edge on the disk (the seed's
        "visually longest") to b-c, the edge the bisection halves first; ``diagonal`` turns it
        to a-b, the edge its strip runs along, so that a back-to-back twin (the same corners in
        the other order) is split into the same sub-triangles. Other modes: 0. ``rel``:
        ``relative(i)``, when the caller has it.
        """
        if self.split not in ("triangle", "diagonal") or not len(tris):
            return np.zeros(len(tris), np.int64)
        s = self.scene
        rel = self.relative(i) if rel is None else rel
        t, b = tangent_frames(s.normals[i][None])
        scale = 1.0 / np.maximum(np.sqrt(np.einsum("ij,ij->i", rel, rel)), 1e-300)
        x, y = (rel @ t[0]) * scale, (rel @ b[0]) * scale                # the vertices on the disk
        corner = s.triangles[tris].T
        xs, ys = [x[k] for k in corner], [y[k] for k in corner]
        # squared length of the edge facing corner 0, 1, 2 (the same for a twin's reversed edge)
        facing = np.stack([(xs[p] - xs[q]) ** 2 + (ys[p] - ys[q]) ** 2 for p, q in ((1, 2), (2, 0), (0, 1))], axis=1)
        longest = np.argmax(facing, axis=1)
        return longest if self.split == "triangle" else (longest + 1) % 3

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
        """(triangle, turn) order for a batch and, per view, the (N, first, count) instanced draws."""
        chunks, draws, first = [], [], 0
        for i in ids:
            rel = self.relative(int(i))
            level = self.levels(int(i), rel)
            turn = np.zeros(len(level), np.int64)
            drawn = np.flatnonzero(level > 0)
            turn[drawn] = self.first_split(int(i), drawn, rel)
            view = []
            for lv in np.unique(level[drawn]):
                tris = np.flatnonzero(level == lv)
                chunks.append(np.column_stack([tris, turn[tris]]))
                view.append((int(lv), first, len(tris)))
                first += len(tris)
                self.sub_triangles += len(tris) * sub_triangle_count(self.split, int(lv))
            draws.append(view)
        order = np.concatenate(chunks) if chunks else np.zeros((1, 2), np.int64)
        return order.astype(np.float32), draws

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

    def _template(self, n: int):
        """The batch drawing this mode's level-n template and how many parent triangles one instance holds."""
        if n not in self._templates:
            from gpu_extras.batch import batch_for_shader

            bary, slot, per_instance = split_template(self.split, n)
            self._templates[n] = batch_for_shader(self._shader, "TRIS", {"bary": bary, "slot": slot}), per_instance
        return self._templates[n]

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
                    batch, per_instance = self._template(n)
                    sh.uniform_int("first", first)
                    sh.uniform_int("count", count)
                    sh.uniform_int("per_instance", per_instance)
                    batch.draw_instanced(sh, instance_start=0, instance_count=-(-count // per_instance))
                self.renders += 1
        finally:
            gpu.state.clip_distances_set(0)
