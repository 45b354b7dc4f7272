"""``bench formfactors``: speed and accuracy of every form-factor method on the Cornell box.

For 3,584 and 51,200 triangles (``--quick``: 3,584 only), each method and setting computes
the same sample of rows; a row's error is measured against a converged reference for the
same quantity, the point-to-area form factor from the patch centroid: Embree rays from the
centroid (262,144 per row; its own noise, about sqrt(F / 262144) per entry, is the floor
of the table). Columns: ms per row and rows per second (the sample's wall time, GPU
drawing, readback and histogram included), RMS error over all entries of the sample rows,
max |error| of an entry, and the mean |error of the row sum| (the box is open at the
front, so sums are not 1). A PNG plots RMS error against ms per row: the speed/accuracy frontier.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..formfactors.methods import FormFactorSettings, make_method

SIZES = (3584, 51200)
SAMPLE_ROWS = 48
REFERENCE_RAYS = 1 << 18

SETTINGS = [
    FormFactorSettings("hemicube", 64), FormFactorSettings("hemicube", 128),
    FormFactorSettings("hemicube", 128, rotate=True), FormFactorSettings("hemicube", 256),
    FormFactorSettings("hemicube", 512),
    FormFactorSettings("paraboloid", 128, split="none"), FormFactorSettings("paraboloid", 256, split="none"),
    FormFactorSettings("paraboloid", 256, split="uniform", split_level=4),
    FormFactorSettings("paraboloid", 128), FormFactorSettings("paraboloid", 256),
    FormFactorSettings("paraboloid", 512),
    FormFactorSettings("embree", rays=256, origins="centroid"),
    FormFactorSettings("embree", rays=1024, origins="centroid"),
    FormFactorSettings("embree", rays=4096, origins="centroid"),
]


def cornell_patches(target: int):
    """The bundled Cornell box subdivided to about ``target`` triangles."""
    import bpy

    from ..blender.extract import extract, source_objects
    from ..blender.scenes import load_bundled
    from ..hierarchy import subdivide
    from .skeleton import max_area_for

    bpy.ops.wm.read_homefile(use_empty=True)
    load_bundled("cornell_box").build(bpy)
    ctx = bpy.context
    base = extract(ctx.evaluated_depsgraph_get(), source_objects(ctx.scene, ctx.view_layer)).scene
    return subdivide(base, max_area_for(base.areas, target), 1).leaves


def dense(rows, n: int) -> np.ndarray:
    out = np.zeros((len(rows), n))
    for k, r in enumerate(rows):
        out[k, r.indices] = r.values
    return out


def measure(scene, settings: FormFactorSettings, ids: np.ndarray, reference: np.ndarray) -> dict:
    method = make_method(scene, settings)
    method.rows(ids[:2])                                 # shaders, textures, first framebuffer
    t0 = time.perf_counter()
    rows = method.rows(ids)
    seconds = time.perf_counter() - t0
    err = dense(rows, scene.n) - reference
    return {
        "patches": scene.n, "method": settings.label(), "ms_per_row": 1e3 * seconds / len(ids),
        "rows_per_s": len(ids) / seconds, "rms_error": float(np.sqrt(np.mean(err ** 2))),
        "max_error": float(np.abs(err).max()),
        "row_sum_error": float(np.mean(np.abs(err.sum(axis=1)))),
    }


def plot(results: list[dict], path: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len({r["patches"] for r in results}), figsize=(13, 5), squeeze=False)
    for ax, n in zip(axes[0], sorted({r["patches"] for r in results})):
        for family, marker in (("hemicube", "o"), ("paraboloid", "s"), ("embree", "^")):
            pts = [r for r in results if r["patches"] == n and r["method"].startswith(family)]
            ax.scatter([p["ms_per_row"] for p in pts], [p["rms_error"] for p in pts], marker=marker, label=family)
            for p in pts:
                ax.annotate(p["method"].replace(family, "").strip(), (p["ms_per_row"], p["rms_error"]),
                            fontsize=7, xytext=(3, 3), textcoords="offset points")
        ax.set(xscale="log", yscale="log", xlabel="ms per row", ylabel="RMS error per entry",
               title=f"Cornell box, {n:,} patches")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def run(quick: bool = False, out_dir: str = "out") -> list[dict]:
    from ..formfactors.gpu_context import ensure_gpu_context
    from ..formfactors.raycast import EmbreeRays

    ensure_gpu_context()
    results = []
    for target in SIZES[:1] if quick else SIZES:
        scene = cornell_patches(target)
        ids = np.linspace(0, scene.n - 1, SAMPLE_ROWS).astype(np.int64)
        reference = dense(EmbreeRays(scene, REFERENCE_RAYS, seed=99, origins="centroid").rows(ids), scene.n)
        for settings in SETTINGS:
            if quick and settings.resolution >= 512 and settings.method != "embree":
                continue
            results.append(measure(scene, settings, ids, reference))
            print(f"  {results[-1]['patches']} {results[-1]['method']}: {results[-1]['ms_per_row']:.2f} ms/row",
                  flush=True)
    Path(out_dir).mkdir(exist_ok=True)
    png = Path(out_dir) / "formfactors.png"
    plot(results, png)
    print(f"RadTR: wrote {png}")
    return results
