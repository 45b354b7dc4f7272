"""Results out as glTF 2.0 through Blender's own exporter, for game engines and viewers.

Each result mesh carries, per vertex: ``COLOR_0``, the radiance RadTR shows (exposure x B / pi,
linear, clipped to the [0, 1] that glTF colours hold, with a warning counting what was clipped),
and ``_RADTR_RADIOSITY``, B itself in W/m^2 (a float VEC3 glTF custom attribute); its material
is unlit (``KHR_materials_unlit``: a viewer or game engine shows COLOR_0 as it is, the light
baked in, and adds none of its own). The attributes and the material made for the export are
removed again and the materials and selection restored, so the file is as it was.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputFileError, SceneError

#: Attribute names: what glTF's COLOR_0 shows, and the exact radiosity (custom attributes start with "_").
DISPLAY, EXACT = "radtr_display", "_RADTR_RADIOSITY"
UNLIT = "RadTR glTF Unlit"


def unlit_material():
    """A Background shader fed by the ``DISPLAY`` colour: Blender's exporter writes it as
    ``KHR_materials_unlit`` with COLOR_0."""
    import bpy

    mat = bpy.data.materials.new(UNLIT)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    colour, shader, out = (nodes.new(k) for k in ("ShaderNodeVertexColor", "ShaderNodeBackground",
                                                  "ShaderNodeOutputMaterial"))
    colour.layer_name = DISPLAY
    links.new(colour.outputs["Color"], shader.inputs["Color"])
    links.new(shader.outputs["Background"], out.inputs["Surface"])
    return mat


def vertex_radiosity(mesh) -> np.ndarray:
    """B (v, 3) at the vertices of a result mesh (its ``radtr_radiosity`` attribute)."""
    col = np.empty(len(mesh.vertices) * 4, dtype=np.float32)
    mesh.color_attributes["radtr_radiosity"].data.foreach_get("color", col)
    return col.reshape(-1, 4)[:, :3]


def export_gltf(bl_scene, objects, path, exposure: float = 1.0) -> list[str]:
    """Write ``objects`` (result meshes of a solve) to ``path`` (.glb or .gltf); returns warnings."""
    import addon_utils
    import bpy

    path = Path(path)
    if path.suffix.lower() not in (".glb", ".gltf"):
        raise InputFileError(f"{path}: a glTF file ends in .glb or .gltf")
    objects = [o for o in objects if o.type == "MESH" and "radtr_radiosity" in o.data.color_attributes]
    if not objects:
        raise SceneError("no RadTR result meshes to export: solve the scene first")
    if not addon_utils.check("io_scene_gltf2")[1]:
        addon_utils.enable("io_scene_gltf2", default_set=False)
    selected = [o for o in bl_scene.objects if o.select_get()]
    materials = {o: list(o.data.materials) for o in objects}
    unlit = unlit_material()
    clipped = total = 0
    try:
        for o in objects:
            B = vertex_radiosity(o.data)
            shown = exposure * B / np.pi
            clipped += int((shown > 1).any(axis=1).sum())
            total += len(B)
            rgba = np.ones((len(B), 4), dtype=np.float32)
            rgba[:, :3] = np.clip(shown, 0, 1)
            o.data.color_attributes.new(DISPLAY, "FLOAT_COLOR", "POINT").data.foreach_set("color", rgba.ravel())
            o.data.attributes.new(EXACT, "FLOAT_VECTOR", "POINT").data.foreach_set("vector", B.ravel())
            for k in range(len(o.data.materials)):
                o.data.materials[k] = unlit
            if not len(o.data.materials):
                o.data.materials.append(unlit)
        for o in bl_scene.objects:
            o.select_set(o in objects)
        bpy.ops.export_scene.gltf(filepath=str(path.resolve()), use_selection=True, export_vertex_color="NAME",
                                  export_vertex_color_name=DISPLAY, export_all_vertex_colors=False,
                                  export_attributes=True, export_materials="EXPORT",
                                  export_format="GLB" if path.suffix.lower() == ".glb" else "GLTF_SEPARATE")
    finally:
        for o in objects:
            for name in (DISPLAY, EXACT):
                if name in o.data.attributes:
                    o.data.attributes.remove(o.data.attributes[name])
            o.data.materials.clear()
            for m in materials[o]:
                o.data.materials.append(m)
        bpy.data.materials.remove(unlit)
        for o in bl_scene.objects:
            o.select_set(o in selected)
    if clipped:
        return [f"{clipped:,} of {total:,} vertices are brighter than glTF colours hold at exposure {exposure:g} "
                f"(COLOR_0 clipped to 1; _RADTR_RADIOSITY keeps B): lower the exposure to keep them"]
    return []
