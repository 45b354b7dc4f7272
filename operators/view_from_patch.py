"""View from Patch: the viewport's eye at a patch of the last solve, looking out along its normal."""
import bpy

from ..radtr_addon.views import view_from_patch
from .session import running


class RADTR_OT_view_from_patch(bpy.types.Operator):
    """Put the viewport's eye at a patch, looking out along its normal"""

    bl_idname = "radtr.view_from_patch"
    bl_label = "View from Patch"

    @classmethod
    def poll(cls, context):
        return context.region_data is not None and running["last"] is not None

    def execute(self, context):
        job = running["last"]
        s = context.scene.radtr
        if not 0 <= s.view_patch < job.leaves.n:
            self.report({"ERROR"}, f"RadTR: patch {s.view_patch} does not exist (0..{job.leaves.n - 1})")
            return {"CANCELLED"}
        eye, q = view_from_patch(job.leaves, s.view_patch)
        rv3d = context.region_data
        rv3d.view_perspective = "PERSP"
        rv3d.view_rotation = q
        rv3d.view_distance = 1e-4
        rv3d.view_location = eye
        return {"FINISHED"}
