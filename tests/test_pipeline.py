"""The engine pipeline end to end without Blender: a room made of arrays, lit by a ceiling
emitter and a point light, solved in an interpreter where ``bpy`` cannot be imported, gives the
same patches and B as the same room built in Blender and solved through ``SolveJob``."""
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT

#: A 2 m room (inward faces; float32-exact coordinates, so Blender's meshes store them as they
#: are), its ceiling the emitter (material 1), a point light off-centre. Writes B and the
#: leaves' centroids, with and without the lamp.
ENGINE = """
import sys
for name in ("bpy", "gpu", "mathutils", "bmesh"):
    sys.modules[name] = None
import numpy as np
import pytest
from radtr_addon.lights import Light
from radtr_addon.pipeline import SceneInput, solve
from radtr_addon.scene import PatchScene
from radtr_addon.settings import Settings

v = 2.0 * np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
tris = np.array([[a, b, c] for a, b, c, d in quads] + [[a, c, d] for a, b, c, d in quads])
ceiling = (v[tris][:, :, 2] == 2).all(axis=1)
rho = np.where(ceiling[:, None], [0.25, 0.25, 0.25], [0.75, 0.5, 0.25])
E = np.where(ceiling[:, None], 2 * np.pi, 0.0) * np.ones(3)
scene = PatchScene(v, tris, rho, E, 0, ceiling.astype(int), ["room"], ["wall", "panel"])
lamp = Light("lamp", "POINT", np.array([1.0, 0.5, 0.25]), 40.0, np.eye(4))
lamp.matrix[:3, 3] = (0.5, 1.5, 0.75)
settings = Settings(method="embree", rays=256, max_area=0.25, solver="direct", tolerance=1e-9)
out = {}
for label, lights in (("lit", [lamp]), ("dark", [])):
    s = solve(SceneInput(scene, lights=lights), settings, log=lambda *_: None)
    out[label] = s.B
out["centroids"] = s.leaves.centroids
out["blocked"] = np.array(sys.modules["bpy"] is None)
np.savez(sys.argv[1], **out)
"""


def blender_room(bpy):
    """The same room as ``ENGINE``'s, as a Blender mesh with two materials and a point light."""
    from scenes._common import material

    v = 2.0 * np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    faces = [(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads]
    mesh = bpy.data.meshes.new("room")
    mesh.from_pydata(v.tolist(), [], faces)
    mesh.materials.append(material(bpy, "wall", (0.75, 0.5, 0.25)))
    mesh.materials.append(material(bpy, "panel", (0.25, 0.25, 0.25), strength=2.0))
    for poly in mesh.polygons:
        poly.material_index = int(all(v[i][2] == 2 for i in poly.vertices))
    room = bpy.data.objects.new("room", mesh)
    data = bpy.data.lights.new("lamp", "POINT")
    data.energy, data.color, data.shadow_soft_size = 40.0, (1.0, 0.5, 0.25), 0.0
    lamp = bpy.data.objects.new("lamp", data)
    lamp.location = (0.5, 1.5, 0.75)
    for obj in (room, lamp):
        bpy.context.scene.collection.objects.link(obj)


def test_engine_solve_without_blender_equals_the_blender_path(blend, tmp_path):
    from radtr_addon.blender.pipeline import SolveJob
    from radtr_addon.settings import Settings

    out = tmp_path / "engine.npz"
    run = subprocess.run([sys.executable, "-c", ENGINE, str(out)], capture_output=True, text=True, cwd=ROOT,
                         timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    engine = np.load(out)
    assert engine["blocked"]
    lamp_share = (engine["lit"] - engine["dark"]).sum() / engine["lit"].sum()
    assert lamp_share > 0.1                      # the lamp lights the room: it takes part in the check

    blender_room(blend)
    ctx = blend.context
    job = SolveJob(ctx.scene, ctx.evaluated_depsgraph_get(), ctx.view_layer,
                   Settings(method="embree", rays=256, max_area=0.25, solver="direct", tolerance=1e-9),
                   log=lambda *_: None)
    job.run().finish()
    np.testing.assert_array_equal(job.leaves.centroids, engine["centroids"])
    np.testing.assert_allclose(job.B, engine["lit"], rtol=1e-9, atol=1e-12)


def test_eta_extrapolates_the_residual_fall_to_the_tolerance():
    """A residual falling as exp(-t/2) reaches the tolerance 1e-3 at t = 2 ln 1000: the ETA at
    t = 4 is that minus 4; before three slices there is none; the readout says it."""
    from geometry import cube

    from radtr_addon.pipeline import SceneInput, Solve
    from radtr_addon.settings import Settings

    s = Solve(SceneInput(cube()), Settings(method="embree", rays=16, tolerance=1e-3), log=lambda *_: None)
    assert s.eta is None
    s._trace = [(t, np.exp(-t / 2)) for t in (1.0, 2.0, 3.0, 4.0)]
    assert s.eta == pytest.approx(2 * np.log(1000) - 4, rel=1e-9)
    assert f"about {2 * np.log(1000) - 4:,.0f} s left" in s.readout
    s._trace = [(t, 0.5) for t in (1.0, 2.0, 3.0)]             # no fall: no estimate
    assert s.eta is None


def test_a_sky_that_reaches_nothing_is_said():
    """A closed box lit from inside: the research sky sees only back faces; the solve says so."""
    from geometry import cube

    from radtr_addon.pipeline import SceneInput, Solve
    from radtr_addon.scene import PatchScene
    from radtr_addon.settings import Settings

    s = Solve(SceneInput(cube()), Settings(method="embree", rays=16, sky="uniform", sky_step=45, sky_resolution=32),
              log=lambda *_: None)
    assert s.sky.S.nnz == 0
    assert any("the sky (uniform) reaches no patch" in w for w in s.stats.warnings)
    box = cube()
    outside = PatchScene(box.vertices, box.triangles[:, ::-1], 0.5, 1.0, 0, 0)      # the same box, faces out
    s = Solve(SceneInput(outside), Settings(method="embree", rays=16, sky="uniform", sky_step=45,
                                            sky_resolution=32), log=lambda *_: None)
    assert s.sky.S.nnz > 0 and not any("reaches no patch" in w for w in s.stats.warnings)
