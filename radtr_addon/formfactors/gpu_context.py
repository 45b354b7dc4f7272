"""A GPU drawing context for offscreen form-factor renders, also in background mode.

``blender -b`` and the PyPI ``bpy`` module start without one: ``GPUOffScreen`` raises
"GPU functions for drawing are not available in background mode" until something has
rendered. One 8x8 Workbench render of a throw-away scene creates it (about 1 s on Mesa
llvmpipe); the user's scenes and render settings are not touched.
"""
from __future__ import annotations

from ..errors import GPUUnavailable

_ready = False


def ensure_gpu_context():
    """Make ``gpu`` drawing usable; raise GPUUnavailable with the reason when it cannot be."""
    global _ready
    if _ready:
        return
    import bpy
    import gpu

    try:
        gpu.types.GPUOffScreen(4, 4).free()
    except Exception:
        _render_tiny_frame(bpy)
        try:
            gpu.types.GPUOffScreen(4, 4).free()
        except Exception as exc:
            raise GPUUnavailable(f"no GPU drawing context for form factors: {exc}") from exc
    _ready = True


def _render_tiny_frame(bpy):
    scene = bpy.data.scenes.new("RadTR GPU init")
    cam_data = bpy.data.cameras.new("RadTR GPU init")
    cam = bpy.data.objects.new("RadTR GPU init", cam_data)
    try:
        scene.collection.objects.link(cam)
        scene.camera = cam
        scene.render.engine = "BLENDER_WORKBENCH"
        scene.render.resolution_x = scene.render.resolution_y = 8
        bpy.ops.render.render(scene=scene.name)
    finally:
        bpy.data.objects.remove(cam)
        bpy.data.cameras.remove(cam_data)
        bpy.data.scenes.remove(scene)
