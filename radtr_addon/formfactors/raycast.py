"""Form factors by ray casting with Embree (``embreex``): no GPU needed.

Row i: ``rays`` cosine-distributed rays leave patch i (stratified on an m x m grid,
m = round(sqrt(rays)), jittered with a generator seeded by ``seed`` and i, so every run
gives the same rows). Origins are spread over the patch (``origins="area"``, estimating
the area-to-area F_ij) or all at its centroid (``"centroid"``, the point-to-area value
the GPU methods compute). Each ray that hits the front of patch j adds 1 / rays to F_ij;
back faces count as ``blocked``, misses as ``escaped``. A ray count of m^2 has a standard
error of at most sqrt(F (1 - F) / m^2) per entry (stratification only lowers it).

``point_to_patch`` is the exact-kernel estimate for refinement: the closed-form
unoccluded form factor from a point to a triangle times the fraction of sample points on
the triangle that the point sees.
"""
from __future__ import annotations

import os
import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .. import compiled
from ..sampling import bounding_box, cosine_directions, grid_side, hit_histogram, jittered, triangle_points
from ..tolerances import RAY_OFFSET
from .closed_form import point_to_polygon
from .rows import Row, histogram_rows, rows_skipping_degenerate

#: Rays cast in one Embree call.
RAYS_PER_CALL = 1 << 20
ORIGINS = ("area", "centroid")
#: Rays per thread at least: fewer go in one call on one core.
THREADED_RAYS = 1 << 16


def _cores() -> int:
    """Cores a batch of rays may use: this process's, but one inside a Dask worker (its
    cluster already runs a process per core)."""
    worker = sys.modules.get("distributed.worker")
    if worker is not None:
        try:
            worker.get_worker()
            return 1
        except ValueError:
            pass
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


class EmbreeRays:
    """Rows of form factors for a PatchScene by stratified cosine-weighted rays."""

    def __init__(self, scene, rays: int = 1024, seed: int = 0, origins: str = "area"):
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        if origins not in ORIGINS:
            raise ValueError(f"ray origins must be one of {', '.join(ORIGINS)}, got '{origins}'")
        self.scene, self.seed, self.origins = scene, seed, origins
        self.side = grid_side(rays)
        self.rays = self.side ** 2
        self.tris = scene.vertices[scene.triangles]
        self._centre, diag = bounding_box(scene.vertices)
        self.epsilon = RAY_OFFSET * (diag or 1.0)
        # Embree sees the scene centred and scaled to a unit diagonal: it misses everything
        # beyond about 1e12 units, and float32 keeps most digits near the origin
        self._unit = 1e6 * self.epsilon
        self._embree = rtcore_scene.EmbreeScene()
        TriangleMesh(self._embree, self._local(self.tris))
        self.cast = 0

    def rows(self, ids) -> list[Row]:
        """Rows for the patch ids given (zero-area patches: all escaped)."""
        return rows_skipping_degenerate(self.scene, ids, self._rows)

    def _rows(self, ids: np.ndarray) -> list[Row]:
        per_call = max(1, RAYS_PER_CALL // self.rays)
        out: list[Row] = []
        for start in range(0, len(ids), per_call):
            out += self._rows_of_batch(ids[start:start + per_call])
        return out

    def row(self, i: int) -> Row:
        return self.rows([i])[0]

    def _samples(self, key):
        """Stratified direction samples (u, v) and origin samples, seeded by ``key``."""
        m = self.side
        rng = np.random.default_rng((self.seed, *np.atleast_1d(key).tolist()))
        u, v = jittered(m, rng)
        perm = rng.permutation(m * m)          # origins stratified independently of directions
        return u, v, u[perm], rng.random(m * m)

    def _rows_of_batch(self, ids: np.ndarray) -> list[Row]:
        s, k, m2 = self.scene, len(ids), self.rays
        samples = [self._samples(int(i)) for i in ids]
        normals = s.normals[ids]
        if self.origins == "area":
            origins = triangle_points(self.tris[ids][:, None], np.stack([x[2] for x in samples]),
                                       np.stack([x[3] for x in samples]))
        else:
            origins = np.broadcast_to(s.centroids[ids][:, None], (k, m2, 3))
        return self._cast(origins, normals, samples)

    def point_rows(self, points: np.ndarray, normals: np.ndarray) -> list[Row]:
        """Point-to-patch form factors from surface points (k, 3) facing ``normals`` (k, 3).

        Used to gather a solved B at mesh vertices (``reconstruct``); rays are seeded by the
        point's index, apart from the patch rows' seeds.
        """
        per_call = max(1, RAYS_PER_CALL // self.rays)
        out: list[Row] = []
        for start in range(0, len(points), per_call):
            p, nrm = points[start:start + per_call], normals[start:start + per_call]
            samples = [self._samples((1, start + q)) for q in range(len(p))]
            out += self._cast(np.broadcast_to(p[:, None], (len(p), self.rays, 3)), nrm, samples)
        return out

    def _cast(self, origins: np.ndarray, normals: np.ndarray, samples) -> list[Row]:
        """Cosine rays from ``origins`` (k, m2, 3) about ``normals`` (k, 3), as rows."""
        s, k, m2 = self.scene, len(normals), self.rays
        dirs = cosine_directions(np.stack([x[0] for x in samples]), np.stack([x[1] for x in samples]), normals)
        origins = origins + self.epsilon * normals[:, None]
        hit = self.hit(origins.reshape(-1, 3), dirs.reshape(-1, 3))
        back = (hit >= 0) & (np.einsum("ij,ij->i", dirs.reshape(-1, 3), s.normals[np.maximum(hit, 0)]) > 0)
        # columns: 0 escaped, 1..n patches, n + 1 blocked
        col = np.where(hit < 0, 0, np.where(back, s.n + 1, hit + 1))
        keys = np.repeat(np.arange(k), m2) * (s.n + 2) + col
        return histogram_rows(hit_histogram(keys, k, s.n + 2) / m2)

    def hit(self, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        """Patch id (k,) each ray from ``origins`` along ``dirs`` (k, 3) hits first, -1 for none."""
        self.cast += len(origins)
        return self._run(self._local(origins), np.asarray(dirs, np.float32)).astype(np.int64)

    def clear_between(self, origins: np.ndarray, targets: np.ndarray, origin_normals=None,
                       target_normals=None) -> np.ndarray:
        """Whether nothing is in the way (k,) between ``origins`` and ``targets`` (k, 3) on
        surfaces: each end is lifted ``epsilon`` off its surface (along its normal, towards
        the other end, where given), the ray leaves ``epsilon`` off its origin and stops
        ``2 epsilon`` before its target, so neither end's own surface counts however near
        the two are (a ceiling 1 mm over a lamp, reached at a grazing angle). The rays are
        made in one compiled pass where numba builds (``clear_rays``, numpy's form)."""
        make = compiled.kernel("clear_rays") if np.ndim(origins) == 2 else None
        return self.reaches(*(make or clear_rays)(origins, targets, origin_normals, target_normals, self.epsilon))

    def first_hit(self, origins: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance (k,) along unit ``dirs`` from ``origins`` to the first surface (inf for
        none) and its patch id (-1 for none)."""
        self.cast += len(origins)
        out = self._run(self._local(origins), np.asarray(dirs, np.float32), output=1)
        t, prim = out["tfar"], out["primID"].astype(np.int64)
        return np.where(prim >= 0, t.astype(float) * self._unit, np.inf), prim

    def _run(self, origins: np.ndarray, dirs: np.ndarray, **options):
        """Embree's ``run`` over every core: it lets go of Python's lock while it casts, so
        chunks of the rays go on threads of their own (1.8x on 2 cores); small batches, and
        one direction for all origins, in one call."""
        n = len(origins)
        k = min(_cores(), n // THREADED_RAYS)
        if k <= 1 or len(dirs) != n:
            return self._embree.run(origins, dirs, **options)
        cuts = np.linspace(0, n, k + 1).astype(np.int64)

        def chunk(a, b):
            return self._embree.run(origins[a:b], dirs[a:b], **{key: v[a:b] if isinstance(v, np.ndarray) else v
                                                                for key, v in options.items()})
        with ThreadPoolExecutor(k) as pool:
            parts = list(pool.map(chunk, cuts[:-1], cuts[1:]))
        if isinstance(parts[0], dict):
            return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
        return np.concatenate(parts)

    def _local(self, points: np.ndarray) -> np.ndarray:
        """``points`` in the frame Embree sees (float32)."""
        return ((np.asarray(points, float) - self._centre) / self._unit).astype(np.float32)

    def reaches(self, origins: np.ndarray, dirs: np.ndarray, dists: np.ndarray | None = None) -> np.ndarray:
        """Whether nothing is in the way (k,) of rays from ``origins`` along unit ``dirs`` for
        ``dists`` (default: to infinity)."""
        self.cast += len(origins)
        dists = np.full(len(origins), 1e30) if dists is None else np.asarray(dists) / self._unit
        blocked = self._run(self._local(origins), np.asarray(dirs, np.float32),
                                   dists=np.asarray(dists, np.float32), query="OCCLUDED")
        return blocked < 0

    def visible_fraction(self, point: np.ndarray, j: int, samples: int = 16) -> float:
        """Fraction of ``samples`` stratified points on patch j with a clear line from ``point``."""
        rng = np.random.default_rng((self.seed, int(j), 1))
        targets = triangle_points(self.tris[j], *jittered(grid_side(samples), rng))
        targets = targets[np.linalg.norm(targets - point, axis=1) > 0]
        if not len(targets):
            return 0.0
        return float(np.mean(self.clear_between(np.broadcast_to(point, targets.shape), targets)))

    def point_to_patch(self, point, normal, j: int, samples: int = 16) -> float:
        """Closed-form form factor from a differential area to patch j, times its visible fraction."""
        point = np.asarray(point, float) + self.epsilon * np.asarray(normal, float)
        unoccluded = point_to_polygon(point, normal, self.tris[j])
        if unoccluded == 0:
            return 0.0
        return unoccluded * self.visible_fraction(point, j, samples)


def clear_rays(origins, targets, origin_normals, target_normals, eps):
    """The rays of ``EmbreeRays.clear_between`` between points (k, 3) on surfaces facing
    ``origin_normals`` and ``target_normals`` (k, 3 or broadcast; None: not lifted): each
    end lifted ``eps`` towards the other, the ray leaving ``eps`` off its origin and stopping
    ``2 eps`` before its target. Origins, unit directions (k, 3) and lengths (k,) (numpy's
    form of the compiled ``clear_rays``)."""
    origins, targets = np.array(origins, float), np.array(targets, float)     # lifted below: copies
    for end, other, n in ((origins, targets, origin_normals), (targets, origins, target_normals)):
        if n is not None:
            n = np.broadcast_to(n, end.shape)
            side = np.where(np.einsum("...c,...c->...", other - end, n) >= 0, 1.0, -1.0)
            end += eps * side[..., None] * n
    d = targets - origins
    dist = np.linalg.norm(d, axis=-1)
    u = d / np.maximum(dist, 1e-300)[..., None]
    return origins + eps * u, u, np.maximum(dist - 3 * eps, 0.0)
