"""``bench solvers``: the seed's timing table, time to accuracy against Cycles, and precision.

Tables (``--quick``: smaller sizes, fewer samples):

- ``seed``: the Cornell box solved by shooting, 3,584 and 51,200 triangles (the nearest
  subdivision: 3,872 and 55,808) x 1,000 and 20,000 shots (tolerance 0, so every shot is
  made), per form-factor method, in seconds here (form factors + shots) next to the
  seed's (Table 3, paraboloid column). GPU rows at 51,200 x 20,000 need 20,000 renders of
  13-47 ms on llvmpipe; they are left out (``skipped``).
- ``accuracy``: the Cornell box at 3,584 triangles, Embree form factors. Each solver runs
  from scratch with its own form factors (their time included) and, at checkpoints, the
  RMS error of B against the direct solution and the per-vertex RMS error of reflected
  radiance against a Cycles bake at ``REFERENCE_SAMPLES``; Cycles bakes the same meshes at
  16..1024 samples. RadTR's error against Cycles flattens at its discretisation error (the
  floor); the table gives the floor, the Cycles samples and seconds that reach it
  (log-log interpolation) and the ratio of seconds.
- ``floor``: the direct solve's error against the same reference for a coarser patch size
  (compared at the vertices it shares with the reference mesh) and other form-factor methods.
- ``precision``: shooting and Jacobi in float32 and float64: seconds and error.

The plot (out/solvers.png): error against seconds, one curve per solver and Cycles.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..formfactors.methods import FormFactors, FormFactorSettings
from ..solvers import SOLVERS, make_solver
from .formfactors import cornell_patches

SEED_SECONDS = {(3584, 1000): 7.5, (3584, 20000): 146.0, (51200, 1000): 9.8, (51200, 20000): 190.0}
SEED_METHODS = [FormFactorSettings("paraboloid", 128, split="none"), FormFactorSettings("hemicube", 64),
                FormFactorSettings("embree", rays=256)]
ACCURACY_FF = FormFactorSettings("embree", rays=1024)
CYCLES_SAMPLES = (16, 64, 256, 1024)
REFERENCE_SAMPLES = 4096
GATHER_RAYS = (64, 256, 1024)


def cornell_job(target: int, settings: FormFactorSettings, solver: str = "direct"):
    """A SolveJob of the Cornell box at about ``target`` triangles with these form factors."""
    from .skeleton import cornell_job as job

    knobs = ("method", "resolution", "rotate", "split", "split_level", "rays")
    return job(target, **{k: getattr(settings, k) for k in knobs}, solver=solver, tolerance=1e-9)


# -- the seed's table --------------------------------------------------------------------------
def seed_table(quick: bool) -> list[dict]:
    sizes = (896,) if quick else (3584, 51200)
    shots = (1000,) if quick else (1000, 20000)
    out = []
    for size in sizes:
        leaves = cornell_patches(size)
        for settings in SEED_METHODS:
            for count in shots:
                row = {"triangles": leaves.n, "shots": count, "form_factors": settings.label()}
                gpu = settings.method != "embree"
                if gpu and size > 10_000 and count > 1000:
                    out.append({**row, "rows": 0, "ff_s": "skipped", "shots_s": "", "total_s": "", "seed_s": "",
                                "target_s": ""})
                    continue
                rows = FormFactors(leaves, settings)
                solver = make_solver("shooting", leaves, rows, tol=0.0, max_iterations=count)
                while not solver.step(256):
                    pass
                ff = rows.seconds
                out.append({**row, "rows": rows.computed, "ff_s": round(ff, 2),
                            "shots_s": round(solver.seconds - ff, 2), "total_s": round(solver.seconds, 2),
                            "seed_s": SEED_SECONDS.get((size, count), ""),
                            "target_s": {(3584, 1000): 2.0, (51200, 1000): 5.0}.get((size, count), "")})
    return out


# -- time to accuracy --------------------------------------------------------------------------
class VertexMap:
    """Per-vertex values on the result meshes (light excluded), concatenated in object order."""

    def __init__(self, job, skip=("light",)):
        from ..reconstruct import mesh_part

        leaves = job.leaves
        self.leaves = leaves
        self.parts = []
        for k, obj in enumerate(job.extraction.objects):
            sel = np.flatnonzero(leaves.object_index == k)
            if obj.name not in skip and len(sel):
                self.parts.append((obj.name, mesh_part(leaves, sel)))

    def __call__(self, values: np.ndarray) -> np.ndarray:
        """Area means at the vertices of per-patch ``values``."""
        from ..reconstruct import VertexRadiosity

        mean = VertexRadiosity(self.leaves, values)
        return np.concatenate([mean(part) for _, part in self.parts])

    def gathered(self, B, rays: int) -> np.ndarray:
        """Reflected radiance at the vertices by a final gather of B."""
        from ..reconstruct import VertexRadiosity

        vertex = VertexRadiosity(self.leaves, B, rays)
        exitance = np.concatenate([vertex(part) for _, part in self.parts])
        return (exitance - self(self.leaves.emission)) / np.pi

    @property
    def positions(self) -> list[tuple[str, np.ndarray]]:
        return [(name, self.leaves.vertices[part.vertex_ids]) for name, part in self.parts]


def reflected(B, leaves) -> np.ndarray:
    """Reflected radiance per patch, (B - E) / pi: what a Cycles DIFFUSE bake gives."""
    return (B - leaves.emission) / np.pi


def _row_sums(a) -> np.ndarray:
    """Sum over each row's channels (a row of a 1-D array is its own entry)."""
    a = np.asarray(a, float)
    return a.reshape(len(a), -1).sum(axis=1)


def rel_rms(x, ref, weights=None, noise=None) -> float:
    """RMS of x - ref over the RMS of ref, over rows (vertices, patches) weighted alike, or
    by ``weights`` (each row's area: the error over the surface, as a picture shows it).
    ``noise``: the variance of ref's own noise per entry (``adaptive.reference_bake``),
    taken out of both sums, so that the error is against the light itself: ref's noise adds
    its variance to every error squared, Cycles' own at a few samples as RadTR's."""
    x, ref = np.asarray(x, float), np.asarray(ref, float)
    err, size = _row_sums((x - ref) ** 2), _row_sums(ref ** 2)
    if noise is not None:
        err, size = err - _row_sums(noise), size - _row_sums(noise)
    return float(np.sqrt(max(np.average(err, weights=weights), 0.0) / np.average(size, weights=weights)))


#: Cycles' seed for reference bakes, apart from the curves' (``cycles_bakes``).
REFERENCE_SEED = 2


def cycles_bakes(job, vmap: VertexMap, samples, seed: int = 1) -> dict[int, tuple[np.ndarray, float]]:
    """Cycles vertex bakes of reflected radiance on the result meshes: samples -> (values,
    seconds). Bakes of one ``seed`` share their first samples (a 16-sample bake is the start
    of a 256-sample one), so a reference to measure others by needs a seed of its own."""
    import bpy

    scene = job.bl_scene
    scene.render.engine = "CYCLES"
    cy = scene.cycles
    cy.device, cy.use_denoising, cy.seed = "CPU", False, seed
    cy.use_adaptive_sampling = False           # every vertex gets the samples asked for
    cy.max_bounces = cy.diffuse_bounces = 64
    cy.sample_clamp_direct = cy.sample_clamp_indirect = 0.0
    targets = []
    for src in job.extraction.objects:
        res = bpy.data.objects[f"{src.name}_radtr"]
        res.data.materials[0] = src.obj.data.materials[0]
        res.select_set(src.name in [name for name, _ in vmap.parts])
        if res.select_get():
            attr = (res.data.color_attributes.get("bake")      # a second "bake" would be "bake.001"
                    or res.data.color_attributes.new("bake", "FLOAT_COLOR", "POINT"))
            res.data.color_attributes.active_color = attr
            targets.append(res)
    bpy.context.view_layer.objects.active = targets[0]
    out = {}
    for spp in samples:
        cy.samples = spp
        t0 = time.perf_counter()
        bpy.ops.object.bake(type="DIFFUSE", pass_filter={"DIRECT", "INDIRECT", "COLOR"}, target="VERTEX_COLORS")
        seconds = time.perf_counter() - t0
        values = []
        for obj in targets:
            col = np.empty(len(obj.data.vertices) * 4, dtype=np.float32)
            obj.data.color_attributes["bake"].data.foreach_get("color", col)
            values.append(col.reshape(-1, 4)[:, :3])
        out[spp] = (np.concatenate(values).astype(np.float64), seconds)
    return out


def solver_curve(method: str, leaves, exact, vmap, reference, checkpoints: int = 40) -> dict:
    """Seconds, error against the direct solution and against Cycles, at checkpoints of one solve."""
    t0 = time.perf_counter()
    rows = FormFactors(leaves, ACCURACY_FF)
    solver = make_solver(method, leaves, rows, tol=1e-7, max_iterations=200_000)
    setup = time.perf_counter() - t0
    unit = max(leaves.n // 8, 1) if method == "shooting" else 1
    seconds, vs_direct, vs_cycles = [], [], []
    while True:
        done = solver.step(unit)
        B = solver.result().B
        seconds.append(setup + solver.seconds)
        vs_direct.append(rel_rms(B, exact))
        vs_cycles.append(rel_rms(vmap(reflected(B, leaves)), reference))
        if done or len(seconds) > 4 * checkpoints:
            break
    return {"solver": method, "seconds": seconds, "vs_direct": vs_direct, "vs_cycles": vs_cycles}


def reach_seconds(curve) -> float:
    """Seconds a curve takes to come within 5% of its final error against Cycles."""
    final = curve["vs_cycles"][-1]
    return next(t for t, e in zip(curve["seconds"], curve["vs_cycles"]) if e <= 1.05 * final)


def fast_path(leaves, vmap, reference) -> dict:
    """End to end with cheap settings: Embree 256-ray rows, Jacobi to 1e-3, vertex gather 256."""
    from ..solvers import solve

    t0 = time.perf_counter()
    B = solve("jacobi", leaves, FormFactors(leaves, FormFactorSettings("embree", rays=256)), tol=1e-3).B
    values = vmap.gathered(B, 256)
    return {"solver": "embree 256 + jacobi 1e-3 + vertex gather 256", "seconds": [time.perf_counter() - t0],
            "vs_direct": [np.nan], "vs_cycles": [rel_rms(values, reference)]}


def crossing(samples, errors, seconds, target: float):
    """Cycles samples and seconds where its error falls to ``target`` (log-log line through
    its bakes; beyond them, seconds in proportion to samples). NaN where an error is not
    positive (within the reference's noise: not resolved)."""
    if target <= 0 or min(errors) <= 0:
        return float("nan"), float("nan")
    ls, le, lt = np.log(samples), np.log(errors), np.log(seconds)
    slope, icpt = np.polyfit(ls, le, 1)                      # error ~ samples^slope (about -1/2)
    s = (np.log(target) - icpt) / slope
    t = np.interp(s, ls, lt)
    if s > ls[-1]:
        t = lt[-1] + (s - ls[-1])
    elif s < ls[0]:
        t = lt[0] + (s - ls[0])
    return float(np.exp(s)), float(np.exp(t))


def accuracy(quick: bool, out_dir: Path):
    size = 896 if quick else 3584
    samples = CYCLES_SAMPLES[:2] if quick else CYCLES_SAMPLES
    reference_spp = 256 if quick else REFERENCE_SAMPLES
    job = cornell_job(size, ACCURACY_FF)
    job.run()
    job.finish()
    leaves, exact = job.leaves, job.result.B
    vmap = VertexMap(job)
    bakes = cycles_bakes(job, vmap, samples)
    reference = cycles_bakes(job, vmap, (reference_spp,), seed=REFERENCE_SEED)[reference_spp][0]
    curves = [solver_curve(m, leaves, exact, vmap, reference) for m in SOLVERS]
    fastest = min(curves, key=lambda c: reach_seconds(c))
    for rays in GATHER_RAYS:
        t0 = time.perf_counter()
        values = vmap.gathered(exact, rays)
        seconds = reach_seconds(fastest) + time.perf_counter() - t0
        curves.append({"solver": f"{fastest['solver']} + vertex gather {rays}", "seconds": [seconds],
                       "vs_direct": [np.nan], "vs_cycles": [rel_rms(values, reference)]})
    curves.append(fast_path(leaves, vmap, reference))
    cycles = {"samples": list(samples), "seconds": [bakes[s][1] for s in samples],
              "vs_cycles": [rel_rms(bakes[s][0], reference) for s in samples]}
    rows = []
    for c in curves:
        floor, reach = c["vs_cycles"][-1], reach_seconds(c)
        spp, cy_s = crossing(cycles["samples"], cycles["vs_cycles"], cycles["seconds"], floor)
        rows.append({"triangles": leaves.n, "solver": c["solver"], "floor": round(floor, 4),
                     "radtr_s": round(reach, 2),
                     "final_vs_direct": "" if np.isnan(c["vs_direct"][-1]) else c["vs_direct"][-1],
                     "cycles_spp": int(round(spp)), "cycles_s": round(cy_s, 2), "ratio": round(cy_s / reach, 1)})
    for spp, t, e in zip(cycles["samples"], cycles["seconds"], cycles["vs_cycles"]):
        rows.append({"triangles": leaves.n, "solver": f"cycles {spp} spp", "floor": round(e, 4),
                     "radtr_s": "", "final_vs_direct": "", "cycles_spp": spp, "cycles_s": round(t, 2), "ratio": ""})
    plot(curves, cycles, out_dir / "solvers.png", leaves.n, reference_spp)
    positions = {name: pos for name, pos in vmap.positions}
    return rows, job, reference, positions


def floor_table(quick: bool, reference, positions) -> list[dict]:
    """Direct-solve error against the reference at its vertices, for other patch sizes and methods."""
    from scipy.spatial import cKDTree

    sizes = (224, 896) if quick else (968, 3584)
    methods = [ACCURACY_FF, FormFactorSettings("embree", rays=4096), FormFactorSettings("hemicube", 64),
               FormFactorSettings("hemicube", 256)]
    offsets, start = {}, 0
    for name, pos in positions.items():
        offsets[name] = (start, cKDTree(pos), _single(pos))
        start += len(pos)
    out = []
    for size in sizes:
        for settings in methods if size == sizes[-1] else methods[:1]:
            job = cornell_job(size, settings)
            job.run()
            vmap = VertexMap(job)
            values = vmap(reflected(job.solver.result().B, job.leaves))
            got, want, k = [], [], 0
            for name, pos in vmap.positions:
                first, tree, single = offsets[name]
                dist, idx = tree.query(pos)
                hit = (dist < 1e-6) & single[idx] & _single(pos)
                got.append(values[k:k + len(pos)][hit])
                want.append(reference[first + idx[hit]])
                k += len(pos)
            got, want = np.concatenate(got), np.concatenate(want)
            out.append({"triangles": job.leaves.n, "form_factors": settings.label(), "vertices": len(got),
                        "error_vs_cycles": round(rel_rms(got, want), 4)})
    return out


def _single(pos: np.ndarray) -> np.ndarray:
    """Vertices whose position no other vertex of the mesh shares (corners of separate faces do)."""
    _, inverse, counts = np.unique(np.round(pos, 9), axis=0, return_inverse=True, return_counts=True)
    return counts[inverse.ravel()] == 1


def precision_table(job) -> list[dict]:
    leaves, exact = job.leaves, job.result.B
    rows = FormFactors(leaves, ACCURACY_FF)
    rows.rows(np.arange(leaves.n))                 # every row cached: the solves alone are timed
    out = []
    for method in ("shooting", "jacobi"):
        for dtype in (np.float64, np.float32):
            solver = make_solver(method, leaves, rows, tol=1e-6, max_iterations=200_000, dtype=dtype)
            while not solver.step(256):
                pass
            r = solver.result()
            out.append({"solver": method, "precision": np.dtype(dtype).name, "iterations": r.iterations,
                        "seconds": round(solver.seconds, 3), "error_vs_direct": rel_rms(r.B, exact)})
    return out


def plot(curves, cycles, path: Path, n: int, reference_spp: int):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.8))
    for c in curves:
        if len(c["seconds"]) > 1:
            a.loglog(c["seconds"], np.maximum(c["vs_direct"], 1e-12), label=c["solver"])
            b.loglog(c["seconds"], c["vs_cycles"], label=f"RadTR {c['solver']}")
        else:
            b.loglog(c["seconds"], c["vs_cycles"], "s", label=f"RadTR {c['solver']}")
    b.loglog(cycles["seconds"], cycles["vs_cycles"], "ko--", label="Cycles bake")
    for spp, t, e in zip(cycles["samples"], cycles["seconds"], cycles["vs_cycles"]):
        b.annotate(f"{spp}", (t, e), textcoords="offset points", xytext=(4, 4), fontsize=8)
    a.set(title=f"Cornell box, {n:,} patches: RMS error of B vs direct", xlabel="seconds (form factors included)",
          ylabel="relative RMS error")
    b.set(title=f"per-vertex reflected radiance vs Cycles {reference_spp} spp", xlabel="seconds",
          ylabel="relative RMS error")
    for ax in (a, b):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(quick: bool = False, out_dir: str = "out") -> dict[str, list[dict]]:
    out = Path(out_dir)
    acc, job, reference, positions = accuracy(quick, out)
    tables = {"seed": seed_table(quick), "accuracy": acc}
    tables["precision"] = precision_table(job)
    tables["floor"] = floor_table(quick, reference, positions)
    print(f"plot: {out / 'solvers.png'}")
    return tables
