"""Results out through glTF: the file Blender's own exporter writes, read back with its own
importer, carries each result vertex's radiosity B (``_RADTR_RADIOSITY``, exact) and the radiance
RadTR shows (COLOR_0: exposure x B / pi, clipped to 1), at the same positions."""
import json
import struct
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT

from radtr_addon.blender.gltf import EXACT, vertex_radiosity
from radtr_addon.blender.pipeline import solve
from radtr_addon.settings import Settings


def by_position(objects) -> dict:
    """{rounded world position: B (3,)} over the vertices of ``objects``."""
    out = {}
    for o in objects:
        co = np.empty(len(o.data.vertices) * 3)
        o.data.vertices.foreach_get("co", co)
        world = co.reshape(-1, 3) @ np.array(o.matrix_world)[:3, :3].T + np.array(o.matrix_world)[:3, 3]
        for p, b in zip(np.round(world, 5), vertex_radiosity(o.data) if "radtr_radiosity" in o.data.color_attributes
                        else read_exact(o.data)):
            out[tuple(p)] = b
    return out


def read_exact(mesh) -> np.ndarray:
    v = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.attributes[EXACT].data.foreach_get("vector", v)
    return v.reshape(-1, 3)


def read_display(mesh) -> np.ndarray:
    """COLOR_0 as Blender's importer reads it (a CORNER byte or float colour), per vertex."""
    attr = mesh.color_attributes[0]
    col = np.empty(len(attr.data) * 4, dtype=np.float32)
    attr.data.foreach_get("color", col)
    corner = np.empty(len(mesh.loops), dtype=np.int64)
    mesh.loops.foreach_get("vertex_index", corner)
    out = np.zeros((len(mesh.vertices), 3))
    out[corner if attr.domain == "CORNER" else slice(None)] = col.reshape(-1, 4)[:, :3]
    return out


@pytest.mark.parametrize("exposure", [1.0, 20.0])
def test_gltf_carries_the_radiosity_of_every_vertex(cornell, tmp_path, exposure):
    from radtr_addon.blender.gltf import export_gltf

    bpy = cornell
    job = solve(bpy.context, Settings(max_area=0.01, method="embree", rays=64, tolerance=1e-2), log=lambda *_: None)
    def state():
        return ({o.name: (o.select_get(), o.data.color_attributes.active_color_name, len(o.data.attributes),
                          [m.name for m in o.data.materials]) for o in job.objects}, len(bpy.data.materials))

    before = state()
    path = tmp_path / "box.glb"
    warnings = export_gltf(bpy.context.scene, job.objects, path, exposure)
    assert state() == before                                                      # the file as it was
    header = json.loads(path.read_bytes()[20:20 + struct.unpack("<I", path.read_bytes()[12:16])[0]])
    assert header["extensionsUsed"] == ["KHR_materials_unlit"]                     # shown as baked, no lighting
    assert all("KHR_materials_unlit" in header["materials"][p["material"]]["extensions"]
               for m in header["meshes"] for p in m["primitives"])
    solved = by_position(job.objects)
    assert bool(warnings) == (exposure * max(b.max() for b in solved.values()) / np.pi > 1)
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=str(path))
    meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    assert len(meshes) == len(job.objects)
    read = by_position(meshes)
    assert read.keys() == solved.keys()
    got, want = np.array([read[k] for k in solved]), np.array(list(solved.values()))
    np.testing.assert_allclose(got, want, rtol=1e-6)
    shown = np.concatenate([read_display(o.data) for o in meshes])
    exact = np.concatenate([read_exact(o.data) for o in meshes])
    # 16-bit in the file, read back into 8-bit sRGB-encoded colours: about 1% of the value
    np.testing.assert_allclose(shown, np.clip(exposure * exact / np.pi, 0, 1), rtol=0.02, atol=2e-3)


def test_cli_writes_gltf_and_refuses_another_suffix(tmp_path):
    run = [sys.executable, "-m", "radtr_addon", "solve", "cornell_box", "--max-area", "0.02", "--method", "embree",
           "--rays", "16", "--tolerance", "0.05"]
    ok = subprocess.run(run + ["--gltf", str(tmp_path / "box.glb")], cwd=ROOT, capture_output=True, text=True,
                        timeout=300)
    assert ok.returncode == 0, ok.stderr[-2000:]
    assert (tmp_path / "box.glb").read_bytes()[:4] == b"glTF"
    bad = subprocess.run(run + ["--gltf", str(tmp_path / "box.png")], cwd=ROOT, capture_output=True, text=True,
                         timeout=300)
    assert bad.returncode == 2 and "a glTF file ends in .glb or .gltf" in bad.stderr
