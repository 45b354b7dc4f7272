"""Patch View Image: what a patch sees (hemicube or paraboloid, patch ids in colour code) as an Image."""
import bpy
import numpy as np

from ..radtr_addon.views import id_colors, patch_view
from .session import last_job

VIEW_IMAGE = "RadTR Patch View"


class RADTR_OT_patch_view(bpy.types.Operator):
    """Write what a patch sees (hemicube or paraboloid, patch ids in colour code) into an Image"""

    bl_idname = "radtr.patch_view"
    bl_label = "Patch View Image"

    def execute(self, context):
        job = last_job(self)
        if job is None:
            return {"CANCELLED"}
        s = context.scene.radtr
        if not 0 <= s.view_patch < job.leaves.n:
            self.report({"ERROR"}, f"RadTR: patch {s.view_patch} does not exist (0..{job.leaves.n - 1})")
            return {"CANCELLED"}
        ids = patch_view(job.leaves, s.view_patch, s.view_kind, 128)
        rgb = id_colors(ids)[::-1]                       # Blender images start at the bottom row
        h, w = rgb.shape[:2]
        image = bpy.data.images.get(VIEW_IMAGE)
        if image is None or tuple(image.size) != (w, h):
            if image is not None:
                bpy.data.images.remove(image)
            image = bpy.data.images.new(VIEW_IMAGE, w, h, float_buffer=True)
        rgba = np.ones((h, w, 4), dtype=np.float32)
        rgba[..., :3] = rgb
        image.pixels.foreach_set(rgba.ravel())
        image.update()
        self.report({"INFO"}, f"RadTR: {s.view_kind} view of {job.leaves.patch_label(s.view_patch)} in "
                              f"image '{VIEW_IMAGE}'")
        return {"FINISHED"}
