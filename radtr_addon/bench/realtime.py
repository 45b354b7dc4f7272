"""``bench realtime``: low-rank precompute and flashlight frames on the Cornell box.

For about 3,584 / 10,000 / 50,000 / 100,000 patches (targets; the subdivision lands on
3,872 / 10,016 / 55,808 / 111,104; ``--quick``: 896 / 3,584, landing on 968 / 3,872) the
hierarchy gets enough levels (each round halves the area limit) for a level near
``CLUSTERS`` nodes, and that level (k clusters) is factored from Embree rows (256 rays).
Table ``precompute``: seconds by stage (hierarchy, form factors of the k representatives,
U, LU) and the memory of U; ``seed``: the seed's set-up and frame rates at its nearest size
(Tables 7 and 10), where it measured one.
Table ``frames``: per back-end, colour and mono, the fewest and most patches a pose lights
(the poses sweep the inside of the box from the camera); ``rays``: shadow rays cast a frame
(each lit group's 4 samples, and every lit patch of a group whose samples disagree or that is
too small to sample: it can exceed the lit patches on small scenes); ``shadow_misses``: the
largest fraction, over every 4th pose, of lit patches whose grouped shadow test differs from
a ray per patch; ms per frame by stage (visibility of the spot, the k-sized coefficients,
the n x k product, write-back into the Blender meshes) and updates per second, over
``FRAMES`` spot poses, one run each (2 busy cores make single figures vary by tens of
percent); ``error``: the back-end's largest error against numpy float64 for the first pose,
over the largest reflected light (float32 rounding; with ``opencl-int8``, what its 8-bit U
adds); ``bound_ms`` is the time a memory-bound float32 product would need: U's bytes over the read
bandwidth of a numpy copy of the same size, measured in the same run (below a few MB, U
stays in cache and this is no bound).
"""
from __future__ import annotations

import time

import numpy as np

from ..lowrank import build
from ..lowrank.backends import BACKENDS, unavailable
from ..lowrank.flashlight import Flashlight, ShadowGroups, Spot, spot_irradiance

SIZES = (3584, 10000, 50000, 100000)
CLUSTERS = 1024
FRAMES = 20
EYE = np.array([0.278, 0.8, 0.273])            # the Cornell camera, in front of the open side
#: The seed's real-time set-up and frame rates (Tables 7 and 10; CPU / GPU).
SEED = {3584: "set-up 50.5 s; colour 75 / 115 FPS, mono 115 / 140",
        9696: "set-up 940 / 422 s; colour 4 / 29 FPS, mono 10 / 58 (LivingLiteColor)"}


def spots(count: int, scene) -> list[Spot]:
    """Spot poses sweeping the inside of the box from the camera position, of the order of
    the box's own light (``default_spot``)."""
    from ..blender.flashlight import default_spot

    angles = np.linspace(-0.4, 0.4, count)
    return [default_spot(scene, EYE, np.array([np.sin(a), -1.0, -0.3 * np.cos(3 * a)])) for a in angles]


def job_for(target: int, levels: int):
    """A SolveJob (not solved) of the Cornell box at about ``target`` patches, with result meshes."""
    from ..blender.write import write_results
    from .skeleton import cornell_job

    job = cornell_job(target, levels, method="embree", rays=256, cache_mb=8192)
    job.objects = write_results(job.bl_scene, job.extraction, job.leaves, job.leaves.emission)
    return job


def read_bound_ms(U: np.ndarray) -> float:
    """ms to read U once at the bandwidth a numpy copy of it reaches (best of 3)."""
    dst = np.empty_like(U)
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        np.copyto(dst, U)
        best = min(best, time.perf_counter() - t0)
    return 1e3 * best / 2                          # a copy reads and writes the same bytes


def shadow_misses(light, poses) -> float:
    """Largest fraction, over ``poses``, of a pose's lit patches whose grouped shadow test
    differs from a ray per patch."""
    worst = 0.0
    for spot in poses:
        grouped = spot_irradiance(light.scene, spot, light._caster, light.groups).any(axis=1)
        single = spot_irradiance(light.scene, spot, light._caster).any(axis=1)
        worst = max(worst, float((grouped != single).sum() / max(single.sum(), 1)))
    return worst


def frames(job, lowrank, backend: str, mono: bool) -> dict:
    from ..blender.flashlight import LiveMeshes

    light = Flashlight(job.leaves, lowrank, backend, groups=ShadowGroups.from_hierarchy(job.hierarchy))
    light.set_mono(mono)
    meshes = LiveMeshes(job.objects, job.leaves)
    poses = spots(FRAMES, job.leaves)
    light.frame(poses[0])                          # warm-up (kernel build, first allocation)
    stages = {"visibility": 0.0, "coefficients": 0.0, "product": 0.0, "write": 0.0}
    light.backend.seconds = {"coefficients": 0.0, "product": 0.0}
    rays = light._caster.cast
    t_all = time.perf_counter()
    for spot in poses:
        B, s = light.frame(spot)
        stages["visibility"] += s["visibility"]
        t0 = time.perf_counter()
        meshes.write(B)
        stages["write"] += time.perf_counter() - t0
    total = time.perf_counter() - t_all
    rays = (light._caster.cast - rays) / FRAMES
    stages.update(light.backend.seconds)
    row = {f"{k}_ms": round(1e3 * v / FRAMES, 2) for k, v in stages.items()}
    E0 = job.leaves.emission.mean(axis=1, keepdims=True) if mono else job.leaves.emission
    lit = [int((light.emission(spot) != E0).any(axis=1).sum()) for spot in poses]
    return {"backend": backend, "mode": "mono" if mono else "colour", "lit_min": min(lit), "lit_max": max(lit),
            "rays": round(rays), "shadow_misses": round(shadow_misses(light, poses[::4]), 4),
            "error": float(f"{backend_error(light, poses[0]):.2e}"), **row, "updates_s": round(FRAMES / total, 1)}


def backend_error(light, spot) -> float:
    """Largest |B - B float64| of the light's back-end for ``spot``, over the largest reflected
    light: float32 rounding, and what a compressed U adds."""
    from ..lowrank.backends import make_backend

    E = light.emission(spot)
    ref = make_backend("numpy", light.backend.lowrank, np.float64).solve(E)
    return float(np.abs(light.backend.solve(E) - ref).max() / np.abs(ref - E).max())


def run(quick: bool = False) -> dict[str, list[dict]]:
    pre, per_frame = [], []
    for target in ((896, 3584) if quick else SIZES):
        t0 = time.perf_counter()
        clusters = min(CLUSTERS, target // 4)
        job = job_for(target, 1 + max(1, round(np.log2(target / clusters))))
        setup = time.perf_counter() - t0
        ks = [len(r) for r in job.hierarchy.representative]
        level = 1 + int(np.argmin([abs(k - clusters) for k in ks[1:]]))
        lowrank = build(job.hierarchy, job.rows, level, dtype=np.float32, budget_bytes=16 << 30)
        s = lowrank.seconds
        pre.append({"patches": job.leaves.n, "level": level, "clusters": lowrank.k,
                    "hierarchy_s": round(job.stats.seconds["subdivide"], 2),
                    "form_factors_s": round(s["form_factors"], 2), "U_s": round(s["U"] + s["V"], 2),
                    "factor_s": round(s["factor"], 2),
                    "total_s": round(sum(s.values()) + job.stats.seconds["subdivide"], 2),
                    "U_MB": round(lowrank.U.nbytes / 2**20, 1), "scene_setup_s": round(setup, 2),
                    "seed": SEED.get(target, "")})
        bound = read_bound_ms(lowrank.U)
        for backend in BACKENDS:
            if unavailable(backend):
                per_frame.append({"patches": job.leaves.n, "backend": backend,
                                  "skipped": f"unavailable: {unavailable(backend)}"})
                continue
            for mono in (False, True):
                per_frame.append({"patches": job.leaves.n, "clusters": lowrank.k,
                                  **frames(job, lowrank, backend, mono), "bound_ms": round(bound, 2)})
    return {"precompute": pre, "frames": per_frame}
