"""Reflectance from an Image Texture and from a Color Attribute node, per patch."""
import numpy as np

from radtr_addon.blender.pipeline import SolveJob
from radtr_addon.settings import Settings

FAST = dict(method="embree", rays=16, tolerance=1e-2)


def plane_with(bpy, link):
    """A 2 m plane lit by a point light, its Principled Base Color fed by ``link(nodes)``."""
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    plane = bpy.context.active_object
    mat = bpy.data.materials.new("textured")
    nodes = mat.node_tree.nodes
    mat.node_tree.links.new(link(nodes), nodes["Principled BSDF"].inputs["Base Color"])
    plane.data.materials.append(mat)
    light = bpy.data.objects.new("lamp", bpy.data.lights.new("lamp", "POINT"))
    light.location = (0, 0, 2)
    bpy.context.scene.collection.objects.link(light)
    return plane


def job(bpy, max_area):
    ctx = bpy.context
    return SolveJob(ctx.scene, ctx.evaluated_depsgraph_get(), ctx.view_layer,
                    Settings(max_area=max_area, max_reflectance=0.95, **FAST), log=lambda *_: None)


def test_checkerboard_patches_get_the_mean_of_their_texels(blend):
    bpy = blend
    img = bpy.data.images.new("checker", 8, 8, float_buffer=True)
    rows, cols = np.mgrid[0:8, 0:8]
    texels = np.where((rows + cols) % 2 == 0, 0.2, 0.8)
    px = np.ones((8, 8, 4), np.float32)
    px[..., :3] = texels[..., None] * np.array([1.0, 0.75, 0.5])
    img.pixels.foreach_set(px.ravel())

    def texture(nodes):
        tex = nodes.new("ShaderNodeTexImage")
        tex.image = img
        return tex.outputs["Color"]
    plane_with(bpy, texture)
    j = job(bpy, 0.01)                      # patches smaller than a texel (0.0625 m^2) and not aligned
    leaves = j.leaves
    # expected: the mean of the texel function over each patch, on a fine barycentric grid
    m = 64
    a, b = np.meshgrid((np.arange(m) + 0.5) / m, (np.arange(m) + 0.5) / m)
    keep = a + b < 1
    bary = np.stack([1 - a[keep] - b[keep], a[keep], b[keep]], axis=1)
    pts = np.einsum("sk,nkd->nsd", bary, leaves.vertices[leaves.triangles])
    u, v = (pts[..., 0] + 1) / 2, (pts[..., 1] + 1) / 2
    exact = texels[np.minimum((v * 8).astype(int), 7), np.minimum((u * 8).astype(int), 7)].mean(axis=1)
    np.testing.assert_allclose(leaves.rho[:, 0], exact, rtol=0.01)
    np.testing.assert_allclose(leaves.rho[:, 2], 0.5 * exact, rtol=0.01)
    assert leaves.rho[:, 0].min() < 0.3 and leaves.rho[:, 0].max() > 0.7     # the pattern is kept


def test_color_attribute_patches_get_their_corner_mean(blend):
    bpy = blend

    def attribute(nodes):
        node = nodes.new("ShaderNodeVertexColor")
        node.layer_name = "paint"
        return node.outputs["Color"]
    plane = plane_with(bpy, attribute)
    attr = plane.data.color_attributes.new("paint", "FLOAT_COLOR", "POINT")
    colours = np.array([[0.1, 0.2, 0.3, 1], [0.9, 0.2, 0.3, 1], [0.1, 0.8, 0.3, 1], [0.9, 0.8, 0.3, 1]], np.float32)
    attr.data.foreach_set("color", colours.ravel())
    leaves = job(bpy, 0.01).leaves
    co = np.array([v.co[:] for v in plane.data.vertices])
    # the colours are linear in x (red) and y (green) over the plane: so is every patch's mean
    x, y = leaves.centroids[:, 0], leaves.centroids[:, 1]
    fit_r = np.interp(x, [co[:, 0].min(), co[:, 0].max()], [0.1, 0.9])
    fit_g = np.interp(y, [co[:, 1].min(), co[:, 1].max()], [0.2, 0.8])
    np.testing.assert_allclose(leaves.rho[:, 0], fit_r, rtol=1e-5)
    np.testing.assert_allclose(leaves.rho[:, 1], fit_g, rtol=1e-5)


def test_missing_image_falls_back_with_a_warning_naming_it(blend, tmp_path):
    bpy = blend
    img = bpy.data.images.new("lost", 4, 4)
    img.source, img.filepath = "FILE", str(tmp_path / "lost.png")

    def texture(nodes):
        tex = nodes.new("ShaderNodeTexImage")
        tex.image = img
        return tex.outputs["Color"]
    plane_with(bpy, texture)
    j = job(bpy, 0.1)
    assert any("image 'lost'" in w and "material 'textured'" in w for w in j.stats.warnings)
    assert np.all(np.isfinite(j.leaves.rho))


def test_unsupported_nodes_are_named_and_fall_back(blend):
    bpy = blend

    def mix(nodes):
        node = nodes.new("ShaderNodeMix")
        node.data_type = "RGBA"
        node.name = "Blend Colours"
        return node.outputs["Result"]
    plane = plane_with(bpy, mix)
    glossy = bpy.data.materials.new("shiny")
    nodes = glossy.node_tree.nodes
    gloss = nodes.new("ShaderNodeBsdfGlossy")
    glossy.node_tree.links.new(gloss.outputs["BSDF"], nodes["Material Output"].inputs["Surface"])
    glossy.diffuse_color = (0.3, 0.4, 0.5, 1)
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(0, 0, -1))
    bpy.context.active_object.data.materials.append(glossy)
    j = job(bpy, 0.1)
    text = "\n".join(j.stats.warnings)
    assert "material 'textured'" in text and "'Base Color'" in text and "does not evaluate" in text
    assert "material 'shiny'" in text and "Glossy BSDF" in text and "viewport colour" in text
    shiny = j.leaves.material_index == j.leaves.material_names.index("shiny")
    np.testing.assert_allclose(j.leaves.rho[shiny], np.tile([0.3, 0.4, 0.5], (shiny.sum(), 1)), rtol=1e-6)
    assert plane.name in [s.name for s in j.extraction.objects]
