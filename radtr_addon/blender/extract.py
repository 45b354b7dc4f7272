"""Read the visible mesh objects of a Blender scene, and their instances, into a PatchScene.

Meshes are taken evaluated (modifiers applied), in world space, triangulated by Blender's
loop triangles. Objects in the result collection are skipped; sources a previous solve hid
are read again, so solving twice gives the same patches. Collection and geometry-nodes
instances of objects come from the evaluated depsgraph, each instance a ``Source`` with its
own patches (and its own result mesh); geometry instanced without an object must be
realised (Realize Instances) to take part.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import SceneError
from ..pipeline import SceneInput
from ..scene import DEGENERATE_AREA_FRACTION, PatchScene
from ..settings import Settings
from .materials import read_material

RESULT_COLLECTION = "RadTR"
#: Custom property set on source objects that a solve hid behind its results.
HIDDEN_SOURCE = "radtr_hidden_source"


@dataclass
class Source:
    """One mesh that takes part: an object, or one instance of an object."""

    name: str
    obj: object                 # the object whose mesh and materials are read
    matrix: np.ndarray          # its world matrix (the instance's, for an instance)
    owner: object               # what a solve hides behind its result: the object, or the instancer
    instance: bool = False


@dataclass
class Extraction(SceneInput):
    """The engine's SceneInput of a Blender scene, and the Sources it was read from."""

    objects: list = field(default_factory=list)     # Sources, indexed by PatchScene.object_index


def result_objects(bl_scene) -> list:
    coll = bpy_collection(bl_scene)
    return list(coll.objects) if coll else []


def bpy_collection(bl_scene):
    import bpy

    coll = bpy.data.collections.get(RESULT_COLLECTION)
    if coll and bl_scene.collection.children.get(coll.name):
        return coll
    return None


def source_objects(bl_scene, view_layer) -> list[Source]:
    """Meshes that take part: visible mesh objects, sources hidden by a previous solve, and the
    object instances of visible instancers (hidden ones are shown for a moment to be read)."""
    results = set(result_objects(bl_scene))
    out = [Source(o.name, o, np.array(o.matrix_world), o) for o in bl_scene.objects
           if o.type == "MESH" and o not in results
           and (o.get(HIDDEN_SOURCE) or o.visible_get(view_layer=view_layer))]
    hidden = [o for o in bl_scene.objects if o.get(HIDDEN_SOURCE) and o.hide_get()]
    for o in hidden:
        o.hide_set(False)
    try:
        view_layer.update()
        counts: dict[str, int] = {}
        for inst in view_layer.depsgraph.object_instances:
            if not inst.is_instance or inst.object.type != "MESH" or inst.parent is None:
                continue
            owner = inst.parent.original
            if owner in results:
                continue
            counts[owner.name] = counts.get(owner.name, 0) + 1
            obj = inst.object.original
            out.append(Source(f"{owner.name}.{obj.name}.{counts[owner.name]:03d}", obj,
                              np.array(inst.matrix_world), owner, True))
    finally:
        for o in hidden:
            o.hide_set(True)
    return out


def extract(depsgraph, objects, max_reflectance: float = Settings.max_reflectance) -> Extraction:
    """PatchScene of ``objects`` evaluated in ``depsgraph``; warnings say what was changed."""
    if not objects:
        raise SceneError("no visible mesh objects to solve")
    warnings: list[str] = []
    materials: dict[str, int] = {}
    mat_props = []
    parts = []
    offset = 0
    for k, src in enumerate(objects):
        slots = [s.material for s in src.obj.evaluated_get(depsgraph).material_slots]
        local = np.zeros(max(len(slots), 1), dtype=np.int64)
        attrs = set()
        for s, mat in enumerate(slots or [None]):
            key = mat.name if mat else "(no material)"
            if key not in materials:
                materials[key] = len(materials)
                mat_props.append(read_material(mat))
            local[s] = materials[key]
            props = mat_props[local[s]]
            if props.texture is not None:
                attrs.add("UV")
            if props.attribute is not None:
                attrs.add(props.attribute)
        verts, tris, uv, colors = _object_triangles(src, depsgraph, attrs, warnings)
        bad = ~np.isfinite(verts).all(axis=1)
        if bad.any():
            raise SceneError(f"object '{src.name}': vertex {int(np.flatnonzero(bad)[0])} has a NaN or infinite "
                             f"coordinate ({int(bad.sum())} vertices in all, after modifiers and transform)")
        if len(tris) == 0:
            warnings.append(f"object '{src.name}' has no faces; skipped")
            continue
        mat_index = local[np.clip(tris[:, 3], 0, len(local) - 1)]
        parts.append((verts, tris[:, :3] + offset, mat_index, k, uv, colors))
        offset += len(verts)
    if not parts:
        raise SceneError("the visible mesh objects have no faces")
    names = list(materials)
    rho = np.array([p.rho for p in mat_props])
    emission = np.array([p.emission for p in mat_props])
    for p in mat_props:
        warnings += p.warnings
    rho = _clamp_reflectance(rho, names, max_reflectance, warnings)
    mat_index = np.concatenate([p[2] for p in parts])
    scene = PatchScene(
        np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]),
        rho[mat_index], emission[mat_index],
        np.concatenate([np.full(len(p[1]), p[3]) for p in parts]), mat_index,
        [o.name for o in objects], names)
    uv = np.concatenate([p[4] for p in parts])
    colors = np.concatenate([p[5] for p in parts])
    keep = scene.areas > DEGENERATE_AREA_FRACTION * scene.areas.mean()
    if not keep.all():
        warnings.append(f"{int((~keep).sum())} zero-area triangles dropped")
        scene, uv, colors = scene.subset(keep), uv[keep], colors[keep]
    textures = {i: p.texture for i, p in enumerate(mat_props) if p.texture is not None}
    attributes = {i: p.attribute for i, p in enumerate(mat_props) if p.attribute is not None}
    two_sided = {i for i, p in enumerate(mat_props) if p.two_sided}
    return Extraction(scene, warnings, uv, colors, textures, attributes, two_sided, objects=list(objects))


def _clamp_reflectance(rho, names, limit, warnings):
    bad = ~np.isfinite(rho).all(axis=1)
    for i in np.flatnonzero(bad):
        warnings.append(f"material '{names[i]}': reflectance is NaN or infinite; using 0.5")
    rho = np.where(bad[:, None], 0.5, rho)
    high = (rho > limit).any(axis=1)
    for i in np.flatnonzero(high):
        warnings.append(f"material '{names[i]}': reflectance {tuple(np.round(rho[i], 3))} "
                        f"clamped to {limit} (a diffuse surface reflecting all light never lets "
                        f"a closed scene converge)")
    return np.clip(rho, 0.0, limit)


def _object_triangles(src, depsgraph, attrs=(), warnings=None):
    """World-space vertices (v, 3), triangles (t, 4: three vertex ids, material slot), and per
    corner UVs (t, 3, 2) and colours (t, 3, 3) when ``attrs`` asks for "UV" or a colour
    attribute name ("" = the active one); NaN where not asked or missing."""
    obj = src.obj
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        mesh.calc_loop_triangles()
        co = np.empty(len(mesh.vertices) * 3)
        mesh.vertices.foreach_get("co", co)
        co = co.reshape(-1, 3)
        m = src.matrix
        world = co @ m[:3, :3].T + m[:3, 3]
        t = len(mesh.loop_triangles)
        tri = np.empty(t * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", tri)
        mat = np.empty(t, dtype=np.int32)
        mesh.loop_triangles.foreach_get("material_index", mat)
        loops = np.empty(t * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("loops", loops)
        uv = np.full((t, 3, 2), np.nan)
        colors = np.full((t, 3, 3), np.nan)
        for name in attrs:
            if name == "UV":
                layer = mesh.uv_layers.active
                if layer is None:
                    warnings.append(f"object '{obj.name}' has a texture but no UV map; using the texture's mean")
                    continue
                data = np.empty(len(mesh.loops) * 2, dtype=np.float32)
                layer.data.foreach_get("uv", data)
                uv = data.reshape(-1, 2)[loops].reshape(t, 3, 2).astype(np.float64)
            else:
                colors = _corner_colors(obj, mesh, name, tri, loops, warnings)
        if np.linalg.det(m[:3, :3]) < 0:                # mirrored: keep normals outward
            tri = tri.reshape(-1, 3)[:, ::-1].ravel()
            uv, colors = uv[:, ::-1], colors[:, ::-1]
        tris = np.column_stack([tri.reshape(-1, 3), mat]).astype(np.int64)
    finally:
        evaluated.to_mesh_clear()
    return world, tris, uv, colors


def _corner_colors(obj, mesh, name, tri, loops, warnings):
    """Corner colours (t, 3, 3) of colour attribute ``name`` (POINT or CORNER domain)."""
    attr = mesh.color_attributes.get(name) if name else mesh.color_attributes.active_color
    t = len(loops) // 3
    if attr is None:
        warnings.append(f"object '{obj.name}': no colour attribute '{name}'; using the material's colour")
        return np.full((t, 3, 3), np.nan)
    data = np.empty(len(attr.data) * 4, dtype=np.float32)
    attr.data.foreach_get("color", data)
    data = data.reshape(-1, 4)[:, :3].astype(np.float64)
    index = tri if attr.domain == "POINT" else loops
    return data[index].reshape(t, 3, 3)
