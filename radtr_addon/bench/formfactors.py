"""``bench formfactors``: speed and accuracy of every form-factor method and of every paraboloid split mode.

Two tables, ``methods`` and ``split modes``.

``methods``, on the Cornell box: for 3,584 and 51,200 triangles (``--quick``: 3,584 only),
each method and setting computes the same sample of rows; a row's error is measured against
a converged reference for the same quantity, the point-to-area form factor from the patch
centroid: Embree rays from the centroid (262,144 per row; its own noise, about
sqrt(F / 262144) per entry, is the floor of the table). Columns: ms per row and rows per
second (the sample's wall time, GPU drawing, readback and histogram included), RMS error
over all entries of the sample rows, max |error| of an entry, and the mean |error of the row
sum| (the box is open at the front, so sums are not 1). A PNG plots RMS error against ms
per row: the speed/accuracy frontier.

``split modes``: the seed's split-mode timings (report 6.2, Tables 5 and 6: Sponza Atrium,
68,430 triangles, 10,000 shooting iterations, and the Cornell box, 3,200 triangles, 1,000
iterations; paraboloid with the split in a geometry or tessellation shader) against ours on
the bundled Sponza-class ``atrium`` (65,474 triangles as built, not subdivided: its floor is
one quad of 400 m^2, so big near triangles are everywhere), paraboloid 256 at split level 4
(the seed's tessellation used 4 divisions, 16 sub-triangles), 96 sample rows (``--quick``:
48) spread over the triangle list, against the same kind of Embree reference. One seed
iteration is one row (a shot), so the seed's seconds compare with our ms per row through
the ratio to ``none`` (``x_none`` against ``seed_x_none``): the machines differ. Columns:
our mode and the seed's name for it, mean sub-triangles drawn per view, ms per row and its
ratio to ``none``, the seed's Sponza seconds and their ratio to ``none``, the seed's Cornell
ratio, then the errors as above (the court is open to the sky, so sums are not 1) and the
mean fraction of a view drawn as back faces (``blocked``: the backs of surfaces seen through
the gaps chords leave, and sub-triangles folded over on the disk).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..formfactors.methods import FormFactorSettings, make_method

SIZES = (3584, 51200)
SAMPLE_ROWS = 48
REFERENCE_RAYS = 1 << 18

#: The split-mode table: scene, paraboloid resolution and split level, sample rows (``--quick``: fewer).
SPLIT_SCENE, SPLIT_RESOLUTION, SPLIT_LEVEL = "atrium", 256, 4
SPLIT_ROWS, SPLIT_ROWS_QUICK = 96, 48
#: Our split mode: (the seed's name for it, seconds for Sponza at 10,000 iterations, for the
#: Cornell box at 1,000), report 6.2, Tables 5 and 6.
SEED_SPLITS = {
    "none": ("none", 286, 8.7), "triangle": ("triangle", 1622, 16.6), "centre": ("centre", 324, 9.4),
    "uniform": ("homogeneous", 544, 11.3), "diagonal": ("diagonal", 1400, 13.6),
    "adaptive": ("tessellation 4", 417, 8.9),
}

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


def bundled_patches(name: str):
    """The triangles of bundled scene ``name``, built in a fresh file, as a PatchScene."""
    import bpy

    from ..blender.extract import extract, source_objects
    from ..blender.scenes import load_bundled

    bpy.ops.wm.read_homefile(use_empty=True)
    load_bundled(name).build(bpy)
    ctx = bpy.context
    return extract(ctx.evaluated_depsgraph_get(), source_objects(ctx.scene, ctx.view_layer)).scene


def cornell_patches(target: int):
    """The bundled Cornell box subdivided to about ``target`` triangles."""
    from ..hierarchy import subdivide
    from .skeleton import max_area_for

    base = bundled_patches("cornell_box")
    return subdivide(base, max_area_for(base.areas, target), 1).leaves


def dense(rows, n: int) -> np.ndarray:
    out = np.zeros((len(rows), n))
    for k, r in enumerate(rows):
        out[k, r.indices] = r.values
    return out


def timed_rows(scene, settings: FormFactorSettings, ids: np.ndarray):
    """(method, rows, seconds): the rows of ``ids``, timed after a warm-up."""
    method = make_method(scene, settings)
    method.rows(ids[:2])                                 # shaders, textures, first framebuffer
    if hasattr(method, "sub_triangles"):
        method.sub_triangles = 0
    t0 = time.perf_counter()
    rows = method.rows(ids)
    return method, rows, time.perf_counter() - t0


def errors(rows, n: int, reference: np.ndarray) -> dict:
    err = dense(rows, n) - reference
    return {"rms_error": float(np.sqrt(np.mean(err ** 2))), "max_error": float(np.abs(err).max()),
            "row_sum_error": float(np.mean(np.abs(err.sum(axis=1))))}


def measure(scene, settings: FormFactorSettings, ids: np.ndarray, reference: np.ndarray) -> dict:
    _, rows, seconds = timed_rows(scene, settings, ids)
    return {"patches": scene.n, "method": settings.label(), "ms_per_row": 1e3 * seconds / len(ids),
            "rows_per_s": len(ids) / seconds, **errors(rows, scene.n, reference)}


def split_modes(quick: bool = False) -> list[dict]:
    """The split-mode table (module docstring): every paraboloid split mode on the atrium."""
    from ..formfactors.methods import SPLIT_MODES
    from ..formfactors.raycast import EmbreeRays

    scene = bundled_patches(SPLIT_SCENE)
    ids = np.linspace(0, scene.n - 1, SPLIT_ROWS_QUICK if quick else SPLIT_ROWS).astype(np.int64)
    reference = dense(EmbreeRays(scene, REFERENCE_RAYS, seed=99, origins="centroid").rows(ids), scene.n)
    out = []
    for mode in SPLIT_MODES:
        settings = FormFactorSettings("paraboloid", SPLIT_RESOLUTION, split=mode, split_level=SPLIT_LEVEL)
        method, rows, seconds = timed_rows(scene, settings, ids)
        seed_name, seed_s, seed_cornell_s = SEED_SPLITS[mode]
        ms = 1e3 * seconds / len(ids)
        none = out[0] if out else {"ms_per_row": ms}
        out.append({
            "patches": scene.n, "mode": mode, "seed_mode": seed_name,
            "sub_tris": round(method.sub_triangles / len(ids)), "ms_per_row": ms,
            "x_none": ms / none["ms_per_row"], "seed_s": seed_s, "seed_x_none": seed_s / SEED_SPLITS["none"][1],
            "seed_cornell_x": seed_cornell_s / SEED_SPLITS["none"][2], **errors(rows, scene.n, reference),
            "blocked": float(np.mean([r.blocked for r in rows])),
        })
        print(f"  {scene.n} {settings.label()}: {ms:.2f} ms/row", flush=True)
    return out


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


def run(quick: bool = False, out_dir: str = "out") -> dict[str, list[dict]]:
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
    return {"methods": results, "split modes": split_modes(quick)}
