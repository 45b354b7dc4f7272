"""Light objects in Blender scenes: each type over a plane against Cycles, the Cornell box lit
by an area Light against its emissive quad, and bad lights reported."""
import math

import numpy as np
import pytest

from radtr_addon.blender.pipeline import solve
from radtr_addon.settings import Settings

FAST = dict(method="embree", rays=64, tolerance=1e-3)


def add_plane(bpy, size=2.0, rho=(0.8, 0.6, 0.4)):
    """A plane with a pure Diffuse BSDF (a Principled BSDF's specular layer takes about 4% from
    its diffuse lobe in Cycles, which a diffuse bake then misses)."""
    bpy.ops.mesh.primitive_plane_add(size=size)
    plane = bpy.context.active_object
    mat = bpy.data.materials.new("grey")
    nodes = mat.node_tree.nodes
    nodes.remove(nodes["Principled BSDF"])
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (*rho, 1)
    mat.node_tree.links.new(diffuse.outputs["BSDF"], nodes["Material Output"].inputs["Surface"])
    plane.data.materials.append(mat)
    return plane


def add_light(bpy, kind, location, rotation=(0, 0, 0), **props):
    data = bpy.data.lights.new(kind.lower(), kind)
    for k, v in props.items():
        setattr(data, k, v)
    obj = bpy.data.objects.new(kind.lower(), data)
    obj.location, obj.rotation_euler = location, rotation
    bpy.context.scene.collection.objects.link(obj)
    return obj


LIGHTS = {
    "POINT": dict(location=(0.2, -0.1, 1.2), energy=200.0),
    "SPOT": dict(location=(0, 0, 1.5), energy=300.0, spot_size=math.radians(70), spot_blend=0.3),
    "AREA": dict(location=(0, 0, 0.8), energy=150.0, shape="DISK", size=0.6),
    "SUN": dict(location=(0, 0, 3), rotation=(math.radians(25), 0, 0), energy=2.0),
}


def cycles_mean(bpy, obj, samples=256):
    """Area-weighted mean reflected radiance baked by Cycles at the mesh's vertices (direct only)."""
    from test_cycles_bake import vertex_area_mean

    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    cy = scene.cycles
    cy.device, cy.samples, cy.use_denoising, cy.use_adaptive_sampling = "CPU", samples, False, False
    mesh = obj.data
    mesh.color_attributes.active_color = mesh.color_attributes.new("bake", "FLOAT_COLOR", "POINT")
    bpy.ops.object.select_all(action="DESELECT")
    obj.hide_set(False)
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.bake(type="DIFFUSE", pass_filter={"DIRECT", "COLOR"}, target="VERTEX_COLORS")
    return vertex_area_mean(mesh, "bake")


@pytest.mark.parametrize("kind", sorted(LIGHTS))
def test_each_light_over_a_plane_matches_cycles(blend, kind):
    bpy = blend
    plane = add_plane(bpy)
    props = dict(LIGHTS[kind])
    add_light(bpy, kind, props.pop("location"), props.pop("rotation", (0, 0, 0)), **props)
    job = solve(bpy.context, Settings(max_area=0.02, **FAST), log=lambda *_: None)
    leaves = job.leaves
    radtr = (leaves.emission * leaves.areas[:, None]).sum(axis=0) / leaves.areas.sum() / np.pi
    result = bpy.data.objects["Plane_radtr"]
    result.data.materials[0] = plane.data.materials[0]
    cycles = cycles_mean(bpy, result)
    np.testing.assert_allclose(radtr, cycles, rtol=0.03)
    if kind == "SUN":                                    # and the closed form: rho S cos / pi
        np.testing.assert_allclose(radtr, np.array([0.8, 0.6, 0.4]) * 2.0 * math.cos(math.radians(25)) / np.pi,
                                   rtol=1e-6)


def test_cornell_box_lit_by_an_area_light_matches_its_emissive_quad(cornell):
    """The bundled light quad (radiance 17, 12, 4) against an area Light of the same size and power.
    Hemicube rows: with rays, the small quad is hit by few rays per patch and the quad's side is noisy."""
    bpy = cornell
    settings = Settings(max_area=0.004, method="hemicube", resolution=128, solver="direct")
    quad = solve(bpy.context, settings, log=lambda *_: None)
    names = [o.name for o in quad.extraction.objects]
    light = bpy.data.objects["light"]
    co = np.array([light.matrix_world @ v.co for v in light.data.vertices])
    lo, hi = co.min(axis=0), co.max(axis=0)
    size_x, size_y = hi[0] - lo[0], hi[1] - lo[1]
    radiance = np.array([17.0, 12.0, 4.0])
    bpy.data.objects.remove(light)
    add_light(bpy, "AREA", tuple((lo + hi) / 2 - [0, 0, 1e-4]), shape="RECTANGLE", size=size_x, size_y=size_y,
              energy=float(np.pi * radiance[0] * size_x * size_y), color=tuple(radiance / radiance[0]))
    lamp = solve(bpy.context, settings, log=lambda *_: None)
    for k, name in enumerate(names):
        if name == "light":
            continue
        sel_q = quad.leaves.object_index == k
        sel_l = lamp.leaves.object_index == [o.name for o in lamp.extraction.objects].index(name)
        mean_q = (quad.result.B[sel_q] * quad.leaves.areas[sel_q, None]).sum(0) / quad.leaves.areas[sel_q].sum()
        mean_l = (lamp.result.B[sel_l] * lamp.leaves.areas[sel_l, None]).sum(0) / lamp.leaves.areas[sel_l].sum()
        np.testing.assert_allclose(mean_l, mean_q, rtol=0.02, err_msg=name)


def test_bad_lights_are_named_and_skipped(cornell):
    bpy = cornell
    add_light(bpy, "POINT", (0.3, -0.3, 0.3), energy=float("nan")).name = "broken lamp"
    job = solve(bpy.context, Settings(max_area=0.01, **FAST), log=lambda *_: None)
    assert any("'broken lamp'" in w and "skipped" in w for w in job.stats.warnings)
    assert job.result.converged


def set_world(bpy, color=(0.5, 0.5, 0.5), strength=2.0, image=None):
    world = bpy.data.worlds.new("sky")
    bpy.context.scene.world = world
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*color, 1)
    bg.inputs["Strength"].default_value = strength
    if image is not None:
        env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
        env.image = image
        world.node_tree.links.new(env.outputs["Color"], bg.inputs["Color"])
    return world


def test_uniform_world_lights_an_open_plane_like_cycles(blend):
    bpy = blend
    plane = add_plane(bpy)
    set_world(bpy)
    job = solve(bpy.context, Settings(max_area=0.05, **FAST), log=lambda *_: None)
    radtr = (job.leaves.emission * job.leaves.areas[:, None]).sum(axis=0) / job.leaves.areas.sum() / np.pi
    np.testing.assert_allclose(radtr, np.array([0.8, 0.6, 0.4]) * np.pi * 1.0 / np.pi, rtol=1e-6)  # rho pi L / pi
    result = bpy.data.objects["Plane_radtr"]
    result.data.materials[0] = plane.data.materials[0]
    np.testing.assert_allclose(radtr, cycles_mean(bpy, result), rtol=0.03)


def test_environment_image_and_a_missing_one(blend, tmp_path):
    bpy = blend
    add_plane(bpy)
    img = bpy.data.images.new("env", 16, 8, float_buffer=True)
    px = np.zeros((8, 16, 4), np.float32)
    px[4:, :, :3] = 3.0                                  # Blender rows go up: the top half (z > 0) bright
    px[..., 3] = 1
    img.pixels.foreach_set(px.ravel())
    set_world(bpy, strength=1.0, image=img)
    job = solve(bpy.context, Settings(max_area=0.05, **FAST), log=lambda *_: None)
    e = job.leaves.emission
    np.testing.assert_allclose(e, np.broadcast_to(np.array([0.8, 0.6, 0.4]) * np.pi * 3.0, e.shape), rtol=1e-6)
    missing = bpy.data.images.new("nowhere", 4, 4)
    missing.source, missing.filepath = "FILE", str(tmp_path / "nowhere.exr")       # no such file
    set_world(bpy, color=(0.2, 0.2, 0.2), strength=1.0, image=missing)
    job = solve(bpy.context, Settings(max_area=0.05, **FAST), log=lambda *_: None)
    assert any("image 'nowhere'" in w and "Background colour" in w for w in job.stats.warnings)
    e = job.leaves.emission
    np.testing.assert_allclose(e, np.broadcast_to(np.array([0.8, 0.6, 0.4]) * np.pi * 0.2, e.shape), rtol=1e-6)


@pytest.mark.parametrize("two_sided", [True, False])
def test_emitter_back_lights_what_is_behind_it_like_cycles(blend, two_sided):
    """An emitting square facing up, 1 m above a plane: Cycles lights the plane from the
    square's back; RadTR does too unless the material's Backface Culling makes it one-sided."""
    bpy = blend
    plane = add_plane(bpy)
    bpy.ops.mesh.primitive_plane_add(size=0.5, location=(0, 0, 1))
    emitter = bpy.context.active_object
    mat = bpy.data.materials.new("glow")
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0, 0, 0, 1)
    bsdf.inputs["Emission Color"].default_value = (1, 1, 1, 1)
    bsdf.inputs["Emission Strength"].default_value = 5.0
    mat.use_backface_culling = not two_sided
    emitter.data.materials.append(mat)
    job = solve(bpy.context, Settings(max_area=0.05, **FAST), log=lambda *_: None)
    floor = job.leaves.object_index == [s.name for s in job.extraction.objects].index("Plane")
    a = job.leaves.areas[floor, None]
    radtr = (job.leaves.emission[floor] * a).sum(axis=0) / a.sum() / np.pi     # the floor's own light is reflected
    if not two_sided:
        assert np.all(radtr == 0)
        return
    result = bpy.data.objects["Plane_radtr"]
    result.data.materials[0] = plane.data.materials[0]
    np.testing.assert_allclose(radtr, cycles_mean(bpy, result), rtol=0.03)


def test_a_hierarchical_solve_lit_only_by_a_sun(blend):
    """No emitting material, only a Light object: the hierarchical solve takes it (it used to
    refuse the scene as unlit) and the plane gets rho S cos / pi; the summary's emitted power
    is the sun's light reflected once, and says so (a sunlit scene with no emitter "emitted")."""
    bpy = blend
    add_plane(bpy)
    props = dict(LIGHTS["SUN"])
    add_light(bpy, "SUN", props.pop("location"), props.pop("rotation"), **props)
    job = solve(bpy.context, Settings(solver="hierarchical", quality=0.1), log=lambda *_: None)
    B = job.result.B
    np.testing.assert_allclose(B / np.pi, np.broadcast_to(np.array([0.8, 0.6, 0.4]) * 2.0 * math.cos(math.radians(25))
                                                          / np.pi, B.shape), rtol=1e-6)
    assert "W (R, G, B; the Light objects' light counted once reflected): absorbed" in job.summary()


def test_hierarchical_vertex_colours_take_a_sun_at_the_vertex(blend):
    """A black square hides part of a plane from a sun straight above: every written vertex
    colour away from the shadow's edge is rho S (lit) or 0 (in shadow) exactly, the light at
    the vertex itself, not the mean over the leaves around it."""
    bpy = blend
    add_plane(bpy)
    bpy.ops.mesh.primitive_plane_add(size=0.5, location=(0.13, 0.07, 1.0))
    blocker = bpy.context.active_object
    black = bpy.data.materials.new("black")
    black.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0, 0, 0, 1)
    blocker.data.materials.append(black)
    add_light(bpy, "SUN", (0, 0, 3), energy=2.0, angle=0.0)
    solve(bpy.context, Settings(solver="hierarchical", quality=0.03), log=lambda *_: None)
    mesh = bpy.data.objects["Plane_radtr"].data
    co = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    col = np.empty(len(mesh.vertices) * 4, dtype=np.float32)
    mesh.color_attributes["radtr_radiosity"].data.foreach_get("color", col)
    B = col.reshape(-1, 4)[:, :3].astype(float)
    x, y = co[:, 0] - 0.13, co[:, 1] - 0.07
    edge = np.minimum(np.abs(np.abs(x) - 0.25), np.abs(np.abs(y) - 0.25))
    inside = (np.abs(x) < 0.25) & (np.abs(y) < 0.25)
    far = edge > 0.02
    assert inside[far].sum() > 3 and (~inside[far]).sum() > 3
    expected = np.where(inside[:, None], 0.0, np.array([0.8, 0.6, 0.4]) * 2.0)
    np.testing.assert_allclose(B[far], expected[far], rtol=1e-5, atol=1e-6)
