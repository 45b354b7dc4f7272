"""Write a solve into Blender: result meshes with colour attributes, display material.

Attributes on every result mesh (B in W/m^2, alpha 1):
- ``radtr_patch`` (FACE, FLOAT_COLOR): each patch's radiosity as solved;
- ``radtr_radiosity`` (POINT, FLOAT_COLOR): radiosity at each vertex, the area-weighted mean of
  the patches around it or, with Vertex Gather rays > 0, a final gather (``reconstruct``);
- ``radtr_patch_index`` (FACE, INT): the patch's index in the solve.

``mode='COPY'`` puts subdivided copies in the "RadTR" collection and hides the sources;
``mode='REPLACE'`` gives the sources the subdivided mesh instead (modifiers applied, removed).
All meshes are built before anything in the scene changes; on an error they are deleted
again, so a failed write leaves the file as it was.
"""
from __future__ import annotations

import math

import numpy as np

from ..reconstruct import MeshPart, VertexRadiosity, mesh_part
from ..scene import check_writable
from .extract import HIDDEN_SOURCE, RESULT_COLLECTION, bpy_collection

DISPLAY_MATERIAL = "RadTR Radiosity"
EMISSION_NODE = "RadTR Emission"


def build_mesh(name: str, vertices: np.ndarray, part: MeshPart, B: np.ndarray, point: np.ndarray,
               emission: np.ndarray | None = None):
    """A new mesh datablock of ``part``'s triangles, with patch radiosity ``B`` (t, 3), vertex
    radiosity ``point`` (v, 3), emission (t, 3) and the patch-id colour code as RadTR's attributes."""
    import bpy

    from ..views import id_colors

    local = part.local
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(len(part.vertex_ids))
    mesh.vertices.foreach_set("co", vertices[part.vertex_ids].astype(np.float32).ravel())
    mesh.loops.add(local.size)
    mesh.loops.foreach_set("vertex_index", local.astype(np.int32).ravel())
    mesh.polygons.add(len(local))
    mesh.polygons.foreach_set("loop_start", np.arange(0, local.size, 3, dtype=np.int32))
    mesh.update(calc_edges=True)
    rgba = np.column_stack([B, np.ones(len(B))]).astype(np.float32)
    mesh.attributes.new("radtr_patch", "FLOAT_COLOR", "FACE").data.foreach_set("color", rgba.ravel())
    mesh.attributes.new("radtr_patch_index", "INT", "FACE").data.foreach_set(
        "value", part.patches.astype(np.int32))
    E = np.zeros_like(B) if emission is None else emission
    for attr, values in (("radtr_emission", E), ("radtr_patch_id", id_colors(part.patches))):
        rgba = np.column_stack([values, np.ones(len(values))]).astype(np.float32)
        mesh.attributes.new(attr, "FLOAT_COLOR", "FACE").data.foreach_set("color", rgba.ravel())
    prgba = np.column_stack([point, np.ones(len(point))]).astype(np.float32)
    attr = mesh.color_attributes.new("radtr_radiosity", "FLOAT_COLOR", "POINT")
    attr.data.foreach_set("color", prgba.ravel())
    mesh.color_attributes.active_color = attr
    mesh.color_attributes.render_color_index = mesh.color_attributes.active_color_index
    return mesh


def display_material(exposure: float = 1.0):
    """The material that shows ``radtr_radiosity`` as radiance B / pi times ``exposure``; a back
    face is see-through to the camera (only: a bake still sees its light), so a closed room seen
    from outside shows its lit inside (a dollhouse view) and a wall seen from behind does not
    hide the room."""
    import bpy

    mat = bpy.data.materials.get(DISPLAY_MATERIAL)
    if mat is None:
        mat = bpy.data.materials.new(DISPLAY_MATERIAL)
        if bpy.app.version < (5, 0, 0):
            mat.use_nodes = True
        nodes, links = mat.node_tree.nodes, mat.node_tree.links
        nodes.clear()
        attr = nodes.new("ShaderNodeAttribute")
        attr.attribute_type = "GEOMETRY"
        attr.attribute_name = "radtr_radiosity"
        emit = nodes.new("ShaderNodeEmission")
        emit.name = EMISSION_NODE
        back, path, both, clear, mix = (nodes.new(kind) for kind in (
            "ShaderNodeNewGeometry", "ShaderNodeLightPath", "ShaderNodeMath", "ShaderNodeBsdfTransparent",
            "ShaderNodeMixShader"))
        both.operation = "MULTIPLY"
        out = nodes.new("ShaderNodeOutputMaterial")
        for node, xy in ((attr, (-400, 0)), (emit, (-150, 0)), (back, (-400, 300)), (path, (-400, 600)),
                         (both, (-150, 300)), (clear, (-150, -150)), (mix, (100, 0)), (out, (300, 0))):
            node.location = xy
        links.new(attr.outputs["Color"], emit.inputs["Color"])
        links.new(back.outputs["Backfacing"], both.inputs[0])
        links.new(path.outputs["Is Camera Ray"], both.inputs[1])
        links.new(both.outputs["Value"], mix.inputs["Fac"])
        links.new(emit.outputs["Emission"], mix.inputs[1])
        links.new(clear.outputs["BSDF"], mix.inputs[2])
        links.new(mix.outputs["Shader"], out.inputs["Surface"])
    set_exposure(exposure)
    return mat


#: Display modes: the attribute the display material shows (F16), and whether exposure applies.
DISPLAYS = {"interpolated": ("radtr_radiosity", True), "flat": ("radtr_patch", True),
            "emission": ("radtr_emission", True), "patch_id": ("radtr_patch_id", False),
            "outlines": ("radtr_radiosity", True)}


def set_exposure(exposure: float, display: str = "interpolated"):
    """Scale every RadTR display (seed F12): displayed radiance = exposure x B / pi; the patch-id
    colour code is shown as it is."""
    import bpy

    mat = bpy.data.materials.get(DISPLAY_MATERIAL)
    if mat and mat.node_tree and EMISSION_NODE in mat.node_tree.nodes:
        scaled = DISPLAYS.get(display, DISPLAYS["interpolated"])[1]
        mat.node_tree.nodes[EMISSION_NODE].inputs["Strength"].default_value = exposure / math.pi if scaled else 1.0


def set_display(bl_scene, display: str, exposure: float):
    """Show ``display`` (see DISPLAYS) on every result mesh: the material's attribute, the
    exposure, and for "outlines" the patch edges drawn over the result objects."""
    import bpy

    mat = bpy.data.materials.get(DISPLAY_MATERIAL)
    if mat is None or mat.node_tree is None:
        return
    attribute = next((n for n in mat.node_tree.nodes if n.type == "ATTRIBUTE"), None)
    if attribute is not None:
        attribute.attribute_name = DISPLAYS[display][0]
    set_exposure(exposure, display)
    coll = bpy_collection(bl_scene)
    for obj in (coll.objects if coll else []):
        obj.show_wire = display == "outlines"


def write_results(bl_scene, extraction, leaves, B, exposure=1.0, mode="COPY", vertex_values=None) -> list:
    """Write radiosity ``B`` of ``leaves`` (a PatchScene) onto the extraction's objects.

    ``vertex_values(part)`` gives the vertex radiosity (default: the area mean of the patches).
    """
    import bpy

    if mode == "REPLACE":
        check_replaceable(extraction.objects)
    check_writable(B, lambda i: f"radiosity of {leaves.patch_label(i)}")
    vertex_values = vertex_values or VertexRadiosity(leaves, B)
    meshes = []
    existing = set(bpy.data.meshes.keys())
    try:
        for k, obj in enumerate(extraction.objects):
            sel = np.flatnonzero(leaves.object_index == k)
            if len(sel) == 0:
                continue
            part = mesh_part(leaves, sel)
            point = vertex_values(part)
            check_writable(point, lambda i: f"radiosity at vertex {i} of object '{obj.name}'")
            mesh = build_mesh(f"{obj.name}_radtr", leaves.vertices, part, B[sel], point, leaves.emission[sel])
            meshes.append((obj, mesh))
            if mode == "REPLACE":
                _to_local(mesh, obj.matrix)
        material = display_material(exposure) if mode == "COPY" else None
    except BaseException:
        for mesh in [m for m in bpy.data.meshes if m.name not in existing]:
            bpy.data.meshes.remove(mesh)
        raise
    clear_results(bl_scene, unhide=False)
    for src, mesh in meshes:                    # names are free now that old results are gone
        mesh.name = f"{src.name}_radtr"
    return _link_copies(bl_scene, meshes, material) if mode == "COPY" else _replace(meshes)


def _link_copies(bl_scene, meshes, material):
    import bpy

    coll = bpy_collection(bl_scene)
    if coll is None:
        coll = bpy.data.collections.get(RESULT_COLLECTION) or bpy.data.collections.new(RESULT_COLLECTION)
        bl_scene.collection.children.link(coll)
    out = []
    for src, mesh in meshes:
        mesh.materials.append(material)
        obj = bpy.data.objects.new(mesh.name, mesh)
        coll.objects.link(obj)
        owner = src.owner
        owner[HIDDEN_SOURCE] = True
        owner.hide_set(True)
        owner.hide_render = True
        out.append(obj)
    return out


def check_replaceable(sources):
    """Raise SceneError when Result: Replace cannot write into a source (an instance, or an
    object whose world matrix flattens an axis, so its mesh has no local coordinates)."""
    from ..errors import SceneError

    for src in sources:
        if src.instance:
            raise SceneError(f"Result: Replace cannot write into instances ('{src.name}'); use Copies")
        axes = np.linalg.norm(src.matrix[:3, :3], axis=0)
        if axes.min() == 0 or abs(np.linalg.det(src.matrix[:3, :3])) < 1e-9 * axes.prod():
            raise SceneError(f"object '{src.name}' has a zero scale along an axis; Result: Replace cannot "
                             f"write its mesh in its own coordinates: fix the scale or use Copies")


def _to_local(mesh, matrix: np.ndarray):
    """Move ``mesh``'s world-space vertices into the coordinates of an object at ``matrix``."""
    inv = np.linalg.inv(matrix)
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3) @ inv[:3, :3].T + inv[:3, 3]
    mesh.vertices.foreach_set("co", co.astype(np.float32).ravel())


def _replace(meshes):
    out = []
    for source, mesh in meshes:
        src = source.owner
        for mat in src.data.materials:
            mesh.materials.append(mat)
        src.modifiers.clear()
        src.data = mesh
        out.append(src)
    return out


def clear_results(bl_scene, unhide: bool = True) -> int:
    """Delete RadTR's result objects; with ``unhide`` show the sources again. Returns count."""
    import bpy

    coll = bpy_collection(bl_scene)
    removed = 0
    if coll is not None:
        for obj in list(coll.objects):
            mesh = obj.data
            bpy.data.objects.remove(obj)
            if mesh.users == 0:
                bpy.data.meshes.remove(mesh)
            removed += 1
        bpy.data.collections.remove(coll)
    if unhide:
        for obj in bl_scene.objects:
            if obj.get(HIDDEN_SOURCE):
                del obj[HIDDEN_SOURCE]
                obj.hide_set(False)
                obj.hide_render = False
    return removed
