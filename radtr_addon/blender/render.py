"""Render a picture of a solved scene to PNG, for people to look at.

Cycles draws the result meshes' display material (emission = exposure x B / pi; back faces
see-through) with no bounces, so the picture shows the solved radiosity and nothing Cycles
computed itself; a closed room without a camera is seen from outside as a dollhouse.
The scene's render settings are restored afterwards.
"""
from __future__ import annotations

import numpy as np

_SETTINGS = [
    ("render", "engine"), ("render", "filepath"), ("render", "resolution_percentage"),
    ("render.image_settings", "file_format"), ("view_settings", "view_transform"),
    ("view_settings", "look"), ("cycles", "samples"), ("cycles", "max_bounces"),
    ("cycles", "use_denoising"), ("cycles", "device"),
]


def _owner(scene, path):
    obj = scene
    for part in path.split("."):
        obj = getattr(obj, part)
    return obj


def render_png(bl_scene, path: str, samples: int = 16, camera: str = "", animation: bool = False):
    """Render ``bl_scene`` to ``path`` through the camera object or saved view (``viewpoints``)
    named ``camera``, else the scene's camera, else one framing the scene from the front (the
    walls it sees from behind are see-through: ``write.display_material``). ``animation``: every
    frame of the scene's range, ``path`` the prefix of the numbered PNGs (a camera on a path
    flies along it)."""
    import bpy

    from .viewpoints import SavedView, camera_from_view

    saved = [(p, a, getattr(_owner(bl_scene, p), a)) for p, a in _SETTINGS]
    scene_camera, temp_cam = bl_scene.camera, None
    if camera:
        found = find_camera(bl_scene, camera)
        if isinstance(found, SavedView):
            found = temp_cam = camera_from_view(bl_scene, found)
        bl_scene.camera = found
    if bl_scene.camera is None:
        temp_cam = _frame_camera(bl_scene)
    try:
        r = bl_scene.render
        r.engine = "CYCLES"
        bl_scene.cycles.device = "CPU"
        bl_scene.cycles.samples = samples
        bl_scene.cycles.max_bounces = 0
        bl_scene.cycles.use_denoising = False
        bl_scene.view_settings.view_transform = "Standard"
        bl_scene.view_settings.look = "None"
        r.image_settings.file_format = "PNG"
        r.resolution_percentage = 100
        r.filepath = path
        if animation:
            bpy.ops.render.render(animation=True, scene=bl_scene.name)
        else:
            bpy.ops.render.render(write_still=True, scene=bl_scene.name)
    finally:
        for p, a, v in saved:
            setattr(_owner(bl_scene, p), a, v)
        if temp_cam is not None:
            data = temp_cam.data
            bpy.data.objects.remove(temp_cam)
            bpy.data.cameras.remove(data)
        bl_scene.camera = scene_camera


def find_camera(bl_scene, name: str):
    """The camera object named ``name``, else the saved view of that name (``viewpoints``);
    SceneError listing both when there is neither."""
    from ..errors import SceneError
    from .viewpoints import saved_views

    obj = bl_scene.objects.get(name)
    if obj is not None and obj.type == "CAMERA":
        return obj
    views = saved_views(bl_scene)
    view = next((v for v in views if v.name == name), None)
    if view is None:
        have = ", ".join(o.name for o in bl_scene.objects if o.type == "CAMERA") or "none"
        raise SceneError(f"no camera or saved view '{name}' in scene '{bl_scene.name}' (cameras: {have}; "
                         f"saved views: {', '.join(v.name for v in views) or 'none'})")
    return view


def _frame_camera(bl_scene):
    """A temporary camera looking at the visible objects' bounding box from the front."""
    import bpy
    from mathutils import Vector

    pts = [o.matrix_world @ Vector(c) for o in bl_scene.objects if o.visible_get()
           and o.type == "MESH" for c in o.bound_box]
    arr = np.array([tuple(p) for p in pts]) if pts else np.zeros((1, 3))
    lo, hi = arr.min(axis=0), arr.max(axis=0)
    centre, size = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) or 1.0
    data = bpy.data.cameras.new("RadTR view")
    data.clip_end = 10 * size
    cam = bpy.data.objects.new("RadTR view", data)
    bl_scene.collection.objects.link(cam)
    cam.location = Vector(centre + np.array([0.0, -1.6 * size, 0.35 * size]))
    cam.rotation_euler = (Vector(centre) - cam.location).to_track_quat("-Z", "Y").to_euler()
    bl_scene.camera = cam
    return cam
