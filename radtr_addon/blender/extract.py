"""Read the visible mesh objects of a Blender scene into a PatchScene.

Meshes are taken evaluated (modifiers applied), in world space, triangulated by Blender's
loop triangles. Objects in the result collection are skipped; sources a previous solve hid
are read again, so solving twice gives the same patches.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import SceneError
from ..scene import PatchScene
from .materials import read_material

RESULT_COLLECTION = "RadTR"
#: Custom property set on source objects that a solve hid behind its results.
HIDDEN_SOURCE = "radtr_hidden_source"
#: Reflectances above this are clamped (with a warning naming the material).
MAX_REFLECTANCE = 0.95


@dataclass
class Extraction:
    scene: PatchScene
    objects: list          # bpy Objects, indexed by PatchScene.object_index
    warnings: list[str] = field(default_factory=list)


def result_objects(bl_scene) -> list:
    coll = bpy_collection(bl_scene)
    return list(coll.objects) if coll else []


def bpy_collection(bl_scene):
    import bpy

    coll = bpy.data.collections.get(RESULT_COLLECTION)
    if coll and bl_scene.collection.children.get(coll.name):
        return coll
    return None


def source_objects(bl_scene, view_layer) -> list:
    """Mesh objects that take part: visible ones and sources hidden by a previous solve."""
    results = set(result_objects(bl_scene))
    return [o for o in bl_scene.objects
            if o.type == "MESH" and o not in results
            and (o.get(HIDDEN_SOURCE) or o.visible_get(view_layer=view_layer))]


def extract(depsgraph, objects, max_reflectance: float = MAX_REFLECTANCE) -> Extraction:
    """PatchScene of ``objects`` evaluated in ``depsgraph``; warnings say what was changed."""
    if not objects:
        raise SceneError("no visible mesh objects to solve")
    warnings: list[str] = []
    materials: dict[str, int] = {}
    mat_props = []
    parts = []
    offset = 0
    for k, obj in enumerate(objects):
        verts, tris, slots = _object_triangles(obj, depsgraph)
        if len(tris) == 0:
            warnings.append(f"object '{obj.name}' has no faces; skipped")
            continue
        local = np.zeros(max(len(slots), 1), dtype=np.int64)
        for s, mat in enumerate(slots or [None]):
            key = mat.name if mat else "(no material)"
            if key not in materials:
                materials[key] = len(materials)
                mat_props.append(read_material(mat))
            local[s] = materials[key]
        mat_index = local[np.clip(tris[:, 3], 0, len(local) - 1)]
        parts.append((verts, tris[:, :3] + offset, mat_index, k))
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
    scene, dropped = scene.without_degenerate()
    if dropped:
        warnings.append(f"{dropped} zero-area triangles dropped")
    return Extraction(scene, list(objects), warnings)


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


def _object_triangles(obj, depsgraph):
    """World-space vertices (v, 3) and triangles (t, 4: three vertex ids, material slot)."""
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        mesh.calc_loop_triangles()
        co = np.empty(len(mesh.vertices) * 3)
        mesh.vertices.foreach_get("co", co)
        co = co.reshape(-1, 3)
        m = np.array(evaluated.matrix_world)
        world = co @ m[:3, :3].T + m[:3, 3]
        t = len(mesh.loop_triangles)
        tri = np.empty(t * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", tri)
        mat = np.empty(t, dtype=np.int32)
        mesh.loop_triangles.foreach_get("material_index", mat)
        if np.linalg.det(m[:3, :3]) < 0:                # mirrored: keep normals outward
            tri = tri.reshape(-1, 3)[:, ::-1].ravel()
        tris = np.column_stack([tri.reshape(-1, 3), mat]).astype(np.int64)
        slots = [s.material for s in evaluated.material_slots]
    finally:
        evaluated.to_mesh_clear()
    return world, tris, slots
