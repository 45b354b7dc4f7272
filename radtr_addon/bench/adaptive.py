"""``bench adaptive``: uniform patches against hierarchical radiosity, both against Cycles.

For the bundled ``cornell_box``, ``furnished_room`` and, without ``--quick``, the large
``atrium`` (``LARGE``: hierarchical only, at one Quality) and each configuration (uniform
Embree patches with Jacobi at two patch counts; hierarchical at several Quality values, each
with its default final gather, ``settings.auto_gather_rays``):
a solve as a user runs it (``pipeline.solve``, result meshes written), then Cycles baked at
the vertices of those result meshes (emitters left out) as the reference, each object at
the samples its mean needs (``reference_bake``; at least ``REFERENCE_SPP``, 256 with
``--quick``). Table ``adaptive``: leaves, links (and n^2, the uniform matrix), seconds, the
RMS relative error of reflected radiance (what a user sees: the written ``radtr_radiosity``
colours / pi) over the vertices and weighted by each vertex's area (``area_``), both less
the reference's own noise (``solvers.rel_rms``: its variance, measured between two halves
of its samples, had been added to every squared error, RadTR's and Cycles'; its per-vertex
size is ``reference_noise``), the worst object's mean error, and for each error the samples
and seconds Cycles needs for it on the same vertices (``solvers.crossing``: a log-log line
through the bakes at the first two ``CURVE_SPP``) with the ratio; table ``stages``: seconds
by stage. Per vertex, the strips refined along contact lines weigh as much as the open
walls: in the Cornell box at Quality 0.1 the floor vertices within 1 mm of the blocks'
footprints (156 of 1,843, under a block or beside it) carried 35% of the squared error.
Both errors are relative to the reference's RMS, so bright vertices weigh most: in the
furnished room the ceiling over the lamp (0.32% of its area) holds 97% of the reference's
square. The plot ``out/adaptive.png``: both errors against seconds per scene, uniform,
hierarchical, Cycles.
"""
from __future__ import annotations

import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from .solvers import REFERENCE_SEED, crossing, cycles_bakes, rel_rms

REFERENCE_SPP = 1024
CURVE_SPP = (16, 64, 256)
QUALITIES = (0.1, 0.03, 0.01)
UNIFORM_PATCHES = (2000, 8000)
#: The large scene: its 65,474 input triangles are a patch each at least, so no uniform
#: solve (its matrix: 4.3e9 form factors); one Quality (at 1.0 and 0.3 its solve is much the
#: same, its time its links: README); its reference at fewer samples, their noise taken out
#: of the errors all the same (its 102,780 result vertices take 27 s a 16-sample bake).
LARGE = {"scene": "atrium", "qualities": (1.0,), "reference_spp": 64}


class ResultVertices:
    """The written vertex colours of a job's result meshes, emitters left out, in one order;
    ``parts`` is what ``solvers.cycles_bakes`` bakes."""

    def __init__(self, job):
        from ..reconstruct import mesh_part

        leaves, base = job.leaves, job.extraction.scene
        self.leaves = leaves
        emits = {k for k in range(len(base.object_names)) if base.emission[base.object_index == k].max() > 0}
        self.parts, self.objects = [], []
        for k, obj in enumerate(job.extraction.objects):
            sel = np.flatnonzero(leaves.object_index == k)
            if k not in emits and len(sel):
                self.parts.append((obj.name, mesh_part(leaves, sel)))

    def radiance(self) -> tuple[np.ndarray, np.ndarray]:
        """Reflected radiance (v, 3) from the written colours, and each vertex's part index."""
        import bpy

        values, which = [], []
        for k, (name, part) in enumerate(self.parts):
            mesh = bpy.data.objects[f"{name}_radtr"].data
            col = np.empty(len(mesh.vertices) * 4, dtype=np.float32)
            mesh.color_attributes["radtr_radiosity"].data.foreach_get("color", col)
            values.append(col.reshape(-1, 4)[:, :3])
            which.append(np.full(len(mesh.vertices), k))
        return np.concatenate(values).astype(np.float64) / np.pi, np.concatenate(which)

    def areas(self) -> np.ndarray:
        """Each vertex's share of its mesh's area (a third of each triangle at it), in the order
        of ``radiance``: weighted so, vertex values average to the mean over the surface of
        the colours shown (interpolated across each triangle)."""
        return np.concatenate([np.bincount(part.local.ravel(), minlength=len(part.vertex_ids),
                                           weights=np.repeat(self.leaves.areas[part.patches] / 3, 3))
                               for _, part in self.parts])


def worst_object(values, reference, which, weights) -> float:
    """Largest relative error (any channel) of an object's mean reflected radiance over its
    surface: vertex values weighted by ``ResultVertices.areas``, as a plain mean over
    vertices counts the strips refined along contacts and corners, where the light changes
    fast, many times over."""
    worst = 0.0
    for k in np.unique(which):
        m = which == k
        ref, val = (np.average(x[m], axis=0, weights=weights[m]) for x in (reference, values))
        worst = max(worst, float(np.max(np.abs(val - ref) / np.maximum(ref, 1e-12))))
    return worst


def bake_samples(which, weights, noise: float = 0.005, least: int = 32, most: int = 1024) -> np.ndarray:
    """Cycles samples per object (a power of two, ``least`` to ``most``) that bring the noise
    of its area-weighted mean near ``noise``: a vertex's bake strays about 1.15 / sqrt(samples)
    of its value (a table of 77 vertices' worth of area moved +-1.5% between 64-sample bakes),
    so the mean over n_eff = (sum w)^2 / sum w^2 vertices needs n_eff x samples >= (1.15 /
    noise)^2, 53,000 at 0.5%. One sample count for every object left an east wall whose mean
    rests on 181 vertices' worth of area +2.6% off at 32 samples, +0.3% at 1,024."""
    n_eff = np.array([weights[which == k].sum() ** 2 / (weights[which == k] ** 2).sum()
                      for k in range(which.max() + 1)])
    return np.clip(2 ** np.ceil(np.log2((1.15 / noise) ** 2 / n_eff)), least, most).astype(int)


def reference_bake(job, vertices: ResultVertices, which, weights, least: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """Cycles' reflected radiance at the result vertices, in the order of ``radiance``, each
    object baked at its ``bake_samples`` (at least ``least``), and the variance (v, 3) of
    that noisy value: each sample count is baked in two halves by seeds of their own, the
    mean taken, the variance from their difference (((a - b) / 2)^2: unbiased, but of one
    degree of freedom per entry, so only its sums over many vertices mean anything). Seeds
    of its own: a curve's bake by the reference's seed is the start of it, and measured
    closer to it than it is to the light (the Cornell box's result vertices at Quality 0.1:
    7.1% and 3.2% at 16 and 64 samples against a 256-sample bake by their seed; 7.3% and
    3.6% against two 256-sample bakes by others)."""
    spp = bake_samples(which, weights, least=least)
    out, noise = np.empty((len(which), 3)), np.empty((len(which), 3))
    for s in map(int, np.unique(spp)):
        ks = np.flatnonzero(spp == s)
        group = SimpleNamespace(parts=[vertices.parts[k] for k in ks])
        a, b = (cycles_bakes(job, group, (s // 2,), seed=REFERENCE_SEED + k)[s // 2][0] for k in (0, 1))
        at = np.isin(which, ks)
        out[at], noise[at] = (a + b) / 2, ((a - b) / 2) ** 2
    return out, noise


def configurations(quick: bool, scene: str) -> list[tuple[str, dict]]:
    """Uniform patch counts and hierarchical Qualities to solve; ``--quick`` takes fewer (the
    furnished room at Quality 0.1 only: at 0.03 its bakes alone pass half an hour)."""
    qualities = QUALITIES[:1 if scene == "furnished_room" else 2] if quick else QUALITIES
    uniform = [(f"uniform {n:,}", {"solver": "jacobi", "method": "embree", "rays": 1024, "max_area": 0.0,
                                   "tolerance": 1e-4, "patches": n}) for n in UNIFORM_PATCHES[:1 if quick else 2]]
    if scene == LARGE["scene"]:
        qualities, uniform = LARGE["qualities"], []
    hier = [(f"hierarchical {q:g}", {"solver": "hierarchical", "quality": q, "tolerance": 1e-4})
            for q in qualities]
    return uniform + hier


def solve_scene(scene: str, label: str, options: dict):
    """Open a bundled scene fresh and solve it as the CLI does; returns the job and its seconds."""
    import bpy

    from ..blender.extract import extract, source_objects
    from ..blender.pipeline import solve
    from ..blender.scenes import open_scene
    from ..settings import Settings, auto_max_area

    open_scene(scene)
    options = dict(options)
    patches = options.pop("patches", None)
    if patches:
        ctx = bpy.context
        base = extract(ctx.evaluated_depsgraph_get(), source_objects(ctx.scene, ctx.view_layer)).scene
        options["max_area"] = auto_max_area(base.areas.sum(), 1, patches)
    t0 = time.perf_counter()
    job = solve(bpy.context, Settings(**options), log=lambda *_: None)
    return job, time.perf_counter() - t0


def scene_rows(scene: str, quick: bool) -> tuple[list[dict], list[dict]]:
    rows, curves = [], []
    spp_ref = LARGE["reference_spp"] if scene == LARGE["scene"] else 256 if quick else REFERENCE_SPP
    curve_spp = CURVE_SPP[:2]
    for label, options in configurations(quick, scene):
        job, seconds = solve_scene(scene, label, options)
        vertices = ResultVertices(job)
        values, which = vertices.radiance()
        areas = vertices.areas()
        bakes = cycles_bakes(job, vertices, curve_spp)
        reference, noise = reference_bake(job, vertices, which, areas, least=spp_ref)
        cy_s = [bakes[s][1] for s in curve_spp]
        n = job.adaptive.leaf_count if options["solver"] == "hierarchical" else job.leaves.n
        links = job.adaptive.links if options["solver"] == "hierarchical" else n * n
        stages = {k: round(v, 2) for k, v in job.stats.seconds.items() if v >= 0.005}
        row = {"scene": scene, "config": label, "leaves": n, "links": links, "n^2": n * n,
               "seconds": round(seconds, 2),
               "reference_noise": round(float(np.sqrt(noise.sum() / (reference ** 2).sum())), 4)}
        curve = {"scene": scene, "config": label, "seconds": seconds}
        for key, weights in (("error", None), ("area_error", areas)):
            error = rel_rms(values, reference, weights, noise)
            cy_err = [rel_rms(bakes[s][0], reference, weights, noise) for s in curve_spp]
            spp, cycles_s = crossing(list(curve_spp), cy_err, cy_s, error)
            tag = "" if weights is None else "area_"
            row.update({key: round(error, 4), f"{tag}cycles_spp": float(np.round(spp)),
                        f"{tag}cycles_s": round(cycles_s, 2), f"{tag}ratio": round(cycles_s / seconds, 2)})
            curve.update({key: error, f"{tag}cycles": list(zip(cy_s, cy_err))})
        row.update({"worst_object": round(worst_object(values, reference, which, areas), 4), "stages": stages})
        rows.append(row)
        curves.append(curve)
        print(f"  {scene} {label}: {n:,} leaves, {seconds:.1f} s, error {row['error']:.3f} per vertex "
              f"(Cycles {row['cycles_s']:.1f} s), {row['area_error']:.3f} by area "
              f"(Cycles {row['area_cycles_s']:.1f} s)", flush=True)
    return rows, curves


def plot(curves: list[dict], path: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter, NullFormatter

    scenes = list(dict.fromkeys(c["scene"] for c in curves))
    fig, axes = plt.subplots(2, len(scenes), figsize=(6 * len(scenes), 9), squeeze=False)
    for row, (key, cycles, what) in enumerate((("error", "cycles", "per-vertex"),
                                               ("area_error", "area_cycles", "area-weighted"))):
        for ax, scene in zip(axes[row], scenes):
            mine = [c for c in curves if c["scene"] == scene]
            for kind, marker in (("uniform", "s-"), ("hierarchical", "o-")):
                pts = [(c["seconds"], c[key], c["config"]) for c in mine if c["config"].startswith(kind)]
                if pts:
                    ax.loglog([p[0] for p in pts], [p[1] for p in pts], marker, label=f"RadTR {kind}")
                    for t, e, name in pts:
                        ax.annotate(name.split()[-1], (t, e), textcoords="offset points", xytext=(4, 4), fontsize=8)
            cy = mine[-1][cycles]
            ax.loglog([c[0] for c in cy], [c[1] for c in cy], "k^--", label="Cycles bake (last mesh)")
            ax.set(title=f"{scene}: {what}", xlabel="seconds", ylabel=f"{what} RMS error vs Cycles reference")
            ax.grid(True, which="both", alpha=0.3)
            ax.xaxis.set_minor_formatter(NullFormatter())
            percent = FuncFormatter(lambda v, _: f"{100 * v:.3g}%")    # a span within one decade has no major tick
            ax.yaxis.set_major_formatter(percent)
            ax.yaxis.set_minor_formatter(percent)
            ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(quick: bool = False, out_dir: str = "out") -> dict[str, list[dict]]:
    scenes = ("cornell_box", "furnished_room") + (() if quick else (LARGE["scene"],))
    rows, curves = [], []
    for scene in scenes:
        r, c = scene_rows(scene, quick)
        rows += r
        curves += c
    path = Path(out_dir) / "adaptive.png"
    plot(curves, path)
    print(f"plot: {path}")
    stages = [{"scene": r["scene"], "config": r["config"], **r.pop("stages")} for r in rows]
    return {"adaptive": rows, "stages": stages}
