"""``bench skeleton``: seconds per stage of one Cornell box solve at 3,584 patches.

Stages: extract (Blender meshes to PatchScene), subdivide, form_factor_init (GPU
context), form_factors (hemicube rows), solve (shooting arithmetic), write (colour
attributes). ``--quick``: 896 patches.
"""
from __future__ import annotations

import numpy as np

from ..hierarchy import estimate_leaf_count


def max_area_for(areas: np.ndarray, target: int, levels: int = 1) -> float:
    """The max area whose subdivision gives the leaf count nearest ``target``."""
    lo, hi = float(areas.max()) * 1e-6, float(areas.max()) * 2
    for _ in range(60):
        mid = np.sqrt(lo * hi)
        if estimate_leaf_count(areas, mid, levels) > target:
            lo = mid
        else:
            hi = mid
    return min((lo, hi), key=lambda a: abs(estimate_leaf_count(areas, a, levels) - target))


def cornell_job(target: int, levels: int = 1, **settings):
    """A SolveJob (set up, not solved) of the bundled Cornell box in a fresh file at about
    ``target`` leaf patches after ``levels`` rounds; ``settings``: other ``Settings`` fields."""
    import bpy

    from ..blender.extract import extract, source_objects
    from ..blender.pipeline import SolveJob
    from ..blender.scenes import load_bundled
    from ..settings import Settings

    bpy.ops.wm.read_homefile(use_empty=True)
    load_bundled("cornell_box").build(bpy)
    ctx = bpy.context
    base = extract(ctx.evaluated_depsgraph_get(), source_objects(ctx.scene, ctx.view_layer)).scene
    s = Settings(max_area=max_area_for(base.areas, target, levels), levels=levels, **settings)
    return SolveJob(ctx.scene, ctx.evaluated_depsgraph_get(), ctx.view_layer, s, log=lambda *_: None)


def run(quick: bool = False) -> list[dict]:
    rows = []
    for target in ([896] if quick else [896, 3584]):
        job = cornell_job(target)
        job.run()
        job.finish()
        s = job.stats.seconds
        rows.append({
            "patches": job.leaves.n, "shots": job.result.iterations,
            "rows": job.rows.computed, **{k: round(v, 3) for k, v in s.items()},
            "total": round(sum(s.values()), 3),
        })
    return rows
