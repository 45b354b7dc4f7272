"""Pick View: click a patch of the last solve to look out of it (View from Patch by clicking)."""
import bpy

from ..radtr_addon.views import pick_patch
from .session import mouse_ray, running


class RADTR_OT_pick_view(bpy.types.Operator):
    """Click a patch to put the eye on it, looking out along its normal (Esc or right click ends)"""

    bl_idname = "radtr.pick_view"
    bl_label = "Pick Patch View"

    @classmethod
    def poll(cls, context):
        return running["last"] is not None and context.area is not None and context.area.type == "VIEW_3D"

    def invoke(self, context, event):
        context.window_manager.modal_handler_add(self)
        context.area.header_text_set("RadTR: click a patch to look out of it; Esc or right click ends")
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type in ("ESC", "RIGHTMOUSE"):
            context.area.header_text_set(None)
            return {"FINISHED"}
        if event.type != "LEFTMOUSE" or event.value != "PRESS":
            return {"PASS_THROUGH"}
        i = pick_patch(running["last"].leaves, *mouse_ray(context, event))
        if i >= 0:
            context.scene.radtr.view_patch = i
            context.area.header_text_set(None)
            bpy.ops.radtr.view_from_patch()
            return {"FINISHED"}
        return {"RUNNING_MODAL"}
