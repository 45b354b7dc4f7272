"""The bundled furnished room and atrium: each builds in a fresh file with the triangle count
its docstring states, its contacts are exact, its camera sees what it should, its normals face
free space, and its lamps emit."""
import math
import time

import numpy as np
import pytest

from radtr_addon.blender.scenes import load_bundled

EMITTERS = {"furnished_room": {"Lamp"}, "atrium": {"Lamps"}}


def build(bpy, name):
    module = load_bundled(name)
    start = time.perf_counter()
    module.build(bpy)
    seconds = time.perf_counter() - start
    bpy.context.view_layer.update()                              # world matrices
    return module, seconds


def meshes(bpy):
    """name: (world vertices (v, 3) float64, triangles (t, 3)) of every mesh object, evaluated."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    out = {}
    for obj in bpy.context.scene.objects:
        if obj.type != "MESH":
            continue
        mesh = obj.evaluated_get(depsgraph).data
        co = np.empty(3 * len(mesh.vertices), np.float32)
        mesh.vertices.foreach_get("co", co)
        m = np.array(obj.matrix_world)
        mesh.calc_loop_triangles()
        tris = np.empty(3 * len(mesh.loop_triangles), np.int32)
        mesh.loop_triangles.foreach_get("vertices", tris)
        out[obj.name] = (co.reshape(-1, 3).astype(np.float64) @ m[:3, :3].T + m[:3, 3], tris.reshape(-1, 3))
    return out


def triangle_soup(bpy):
    """(t, 3, 3) world triangles, their unit normals and owning object names."""
    parts = meshes(bpy)
    names = np.concatenate([[name] * len(t) for name, (_, t) in parts.items()])
    tri = np.concatenate([v[t] for v, t in parts.values()])
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return tri, n / np.linalg.norm(n, axis=1, keepdims=True), names


def bvh(tri):
    from mathutils.bvhtree import BVHTree

    return BVHTree.FromPolygons(tri.reshape(-1, 3).tolist(), np.arange(tri.size // 3).reshape(-1, 3).tolist(),
                                all_triangles=True)


def sphere_dirs(rng, k):
    d = rng.normal(size=(k, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


# ---- both scenes ----------------------------------------------------------------------------------


@pytest.mark.parametrize("name, lo, hi", [("furnished_room", 1, 400), ("atrium", 50_000, 70_000)])
def test_builds_with_the_triangle_count_its_docstring_states(blend, capfd, name, lo, hi):
    module, seconds = build(blend, name)
    assert capfd.readouterr().out == ""                     # builds silently
    count = sum(len(t) for _, t in meshes(blend).values())
    assert lo <= count <= hi
    assert f"{count:,} input triangles" in " ".join(module.__doc__.split())
    assert seconds < 5.0
    tri, _, names = triangle_soup(blend)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    assert area.min() > 1e-6, f"degenerate triangle in {names[np.argmin(area)]}"
    assert len(blend.data.materials) <= 8


@pytest.mark.parametrize("name", ["furnished_room", "atrium"])
def test_normals_face_free_space(blend, name):
    """Rays leaving the front of a face reach front faces or the sky, never mostly back faces
    (which a face inside a solid would see), and from points in the open only the emitters
    (two-sided) show their backs."""
    module, _ = build(blend, name)
    tri, normal, names = triangle_soup(blend)
    tree, rng = bvh(tri), np.random.default_rng(1)
    picks = np.arange(len(tri)) if len(tri) <= 3000 else rng.choice(len(tri), 3000, replace=False)
    wrong = []
    for i in picks:
        backs = 0
        for _ in range(32):
            r1, r2 = rng.random(2)
            s = math.sqrt(r1)
            p = tri[i, 0] * (1 - s) + tri[i, 1] * s * (1 - r2) + tri[i, 2] * s * r2 + 1e-3 * normal[i]
            d = sphere_dirs(rng, 1)[0]
            d = d if d @ normal[i] > 0 else -d
            hit = tree.ray_cast(p.tolist(), d.tolist())
            backs += hit[2] is not None and d @ normal[hit[2]] > 0 and names[hit[2]] not in EMITTERS[name]
        if backs == 32:
            wrong.append(names[i])
    assert not wrong, f"{len(wrong)} faces facing into solids, in {sorted(set(wrong))}"
    for point in module.FREE_POINTS:
        for d in sphere_dirs(rng, 2000):
            hit = tree.ray_cast(list(point), d.tolist())
            if hit[2] is not None and names[hit[2]] not in EMITTERS[name]:
                assert d @ normal[hit[2]] < 0, f"back of {names[hit[2]]} seen from {point}"


@pytest.mark.parametrize("name, lamp", [("furnished_room", "Lamp"), ("atrium", "Lamps")])
def test_lamps_emit_from_both_sides(blend, name, lamp):
    build(blend, name)
    mat = blend.data.objects[lamp].active_material
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    assert bsdf.inputs["Emission Strength"].default_value > 0
    assert min(bsdf.inputs["Emission Color"].default_value[:3]) > 0
    assert not mat.use_backface_culling                      # emits from its back too
    verts, tris = meshes(blend)[lamp]
    n = np.cross(verts[tris[:, 1]] - verts[tris[:, 0]], verts[tris[:, 2]] - verts[tris[:, 0]])
    assert (n[:, 2] < 0).all() and np.allclose(n[:, :2], 0)   # the emitting front faces down


# ---- the furnished room ---------------------------------------------------------------------------


def test_furnished_room_contacts_are_exact(blend):
    build(blend, "furnished_room")
    v = {name: verts for name, (verts, _) in meshes(blend).items()}
    floor = v["Floor"][:, 2]
    assert floor.min() == floor.max() == 0.0
    for name in ("Table", "Sofa", "Low_Box", "Cabinet"):
        assert abs(v[name][:, 2].min() - floor.max()) <= 1e-9, name
    # The table top rests on its legs and the backrest on the seat: one height each, shared.
    assert len(np.unique(v["Table"][:, 2])) == 3
    assert len(np.unique(v["Sofa"][:, 2])) == 3
    # float32 vertex storage: gaps hold to 1e-6.
    ceiling, lamp = v["Ceiling"][:, 2], v["Lamp"][:, 2]
    assert ceiling.min() == ceiling.max() and lamp.min() == lamp.max()
    assert abs(ceiling.min() - lamp.max() - 0.01) < 1e-6
    north = v["Wall_North"][:, 1]
    assert north.min() == north.max()
    assert abs(north.min() - v["Cabinet"][:, 1].max() - 0.10) < 1e-6
    assert abs(north.min() - v["Sofa"][:, 1].max() - 0.05) < 1e-6
    lo, hi = v["Lamp"].min(axis=0), v["Lamp"].max(axis=0)
    assert np.allclose(hi[:2] - lo[:2], 0.6, atol=1e-6)


def test_furnished_room_is_closed_but_for_the_window_and_the_sun_reaches_the_floor(blend):
    module, _ = build(blend, "furnished_room")
    parts = meshes(blend)
    verts, tris = parts["Wall_East"]
    area = 0.5 * np.linalg.norm(np.cross(verts[tris[:, 1]] - verts[tris[:, 0]],
                                         verts[tris[:, 2]] - verts[tris[:, 0]]), axis=1).sum()
    y0, y1, z0, z1 = module.WINDOW
    assert area == pytest.approx(4.0 * 2.7 - (y1 - y0) * (z1 - z0), rel=1e-6)
    tri, _, _ = triangle_soup(blend)
    tree = bvh(tri)
    centre = np.array(module.ROOM) / 2
    for d in sphere_dirs(np.random.default_rng(2), 4000):
        if tree.ray_cast(centre.tolist(), d.tolist())[2] is None:   # escaped: through the window only
            p = centre + (5.0 - centre[0]) / d[0] * d
            assert d[0] > 0 and y0 <= p[1] <= y1 and z0 <= p[2] <= z1
    sun = blend.data.objects["Sun"]
    d = -np.array(sun.matrix_world)[:3, 2]
    d /= np.linalg.norm(d)
    assert d == pytest.approx(module.sun_direction())
    window = np.array([5.0, (y0 + y1) / 2, (z0 + z1) / 2])
    spot = window + window[2] / -d[2] * d                      # where the window's centre ray lands
    assert 0 < spot[0] < 5 and 0 < spot[1] < 4
    assert tree.ray_cast((spot + [0, 0, 1e-4]).tolist(), (-d).tolist())[2] is None


def test_furnished_room_camera_sees_the_furniture_lamp_and_window(blend):
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    module, _ = build(blend, "furnished_room")
    scene, cam = blend.context.scene, blend.context.scene.camera
    eye = np.array(cam.matrix_world)[:3, 3]
    assert (eye > 0).all() and (eye < np.array(module.ROOM)).all()
    parts = meshes(blend)
    tri, _, names = triangle_soup(blend)
    tree = bvh(tri)
    targets = {name: parts[name][0].mean(axis=0) for name in ("Table", "Sofa", "Low_Box", "Cabinet", "Lamp")}
    targets["Table"] = parts["Table"][0][parts["Table"][0][:, 2] == parts["Table"][0][:, 2].max()].mean(axis=0)
    targets["Low_Box"][2] = parts["Low_Box"][0][:, 2].max()
    y0, y1, z0, z1 = module.WINDOW
    targets["window"] = np.array([5.0, (y0 + y1) / 2, (z0 + z1) / 2])
    for name, p in targets.items():
        x, y, depth = world_to_camera_view(scene, cam, Vector(p.tolist()))
        assert 0.02 < x < 0.98 and 0.02 < y < 0.98 and depth > 0, name
        d = p - eye
        hit = tree.ray_cast(eye.tolist(), (d / np.linalg.norm(d)).tolist())
        if name == "window":
            assert hit[2] is None                              # the sky through the opening
        else:
            assert names[hit[2]] == name


# ---- the atrium -----------------------------------------------------------------------------------


def test_atrium_contacts_open_roof_and_camera(blend):
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    module, _ = build(blend, "atrium")
    v = {name: verts for name, (verts, _) in meshes(blend).items()}
    assert v["Floor"][:, 2].max() == 0.0
    assert v["Columns"][:, 2].min() == 0.0 and v["Walls"][:, 2].min() == 0.0
    assert v["Drapes"][:, 2].max() == np.float32(module.STOREYS[0]["top"])
    top = v["Slabs"][:, 2].max()
    tri, _, names = triangle_soup(blend)
    tree = bvh(tri)
    assert tree.ray_cast([0.0, 0.0, 1.0], [0.0, 0.0, 1.0])[2] is None            # open to the sky
    sun = -np.array(blend.data.objects["Sun"].matrix_world)[:3, 2]
    assert tree.ray_cast([0.0, 0.0, 1e-3], (-sun / np.linalg.norm(sun)).tolist())[2] is None
    scene, cam = blend.context.scene, blend.context.scene.camera
    eye = np.array(cam.matrix_world)[:3, 3]
    assert (np.abs(eye[:2]) < [module.CX, module.CY]).all() and 0 < eye[2] < top
    seen = {}
    frame = [np.array(c) for c in cam.data.view_frame(scene=scene)]   # camera-space corners
    for fx in np.linspace(0.02, 0.98, 32):
        for fy in np.linspace(0.02, 0.98, 18):
            local = frame[2] + fx * (frame[1] - frame[2]) + fy * (frame[3] - frame[2])
            d = np.array(cam.matrix_world.to_3x3()) @ local
            hit = tree.ray_cast(eye.tolist(), (d / np.linalg.norm(d)).tolist())
            key = "sky" if hit[2] is None else names[hit[2]]
            seen[key] = seen.get(key, 0) + 1
    total = sum(seen.values())
    for key in ("Columns", "Arches", "Floor", "sky"):
        assert seen.get(key, 0) > 0.04 * total, seen
    assert seen.get("Drapes", 0) > 0 and seen.get("Balustrades", 0) > 0, seen
    x, y, depth = world_to_camera_view(scene, cam, Vector((module.CX, 0.0, 3.0)))
    assert 0 < x < 1 and 0 < y < 1 and depth > 0                  # the far end of the court
