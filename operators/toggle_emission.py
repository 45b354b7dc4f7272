"""Toggle Patch Emission: click patches to switch their emission and see the light solved again."""
import bpy

from ..radtr_addon.errors import user_message
from .session import mouse_ray, running


class RADTR_OT_toggle_emission(bpy.types.Operator):
    """Click patches to switch their emission on or off and see the light solved again (Esc or right click ends)"""

    bl_idname = "radtr.toggle_emission"
    bl_label = "Toggle Patch Emission"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return running["last"] is not None and context.area is not None and context.area.type == "VIEW_3D"

    def invoke(self, context, event):
        self.emission = running["last"].leaves.emission.copy()
        context.window_manager.modal_handler_add(self)
        context.area.header_text_set("RadTR: click a patch to switch its emission; Esc or right click ends")
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        from ..radtr_addon.blender.sequence import toggle_patch

        if event.type in ("ESC", "RIGHTMOUSE"):
            context.area.header_text_set(None)
            return {"FINISHED"}
        if event.type != "LEFTMOUSE" or event.value != "PRESS":
            return {"PASS_THROUGH"}
        origin, direction = mouse_ray(context, event)
        try:
            i, self.emission = toggle_patch(running["last"], origin, direction, self.emission)
        except Exception as exc:                # the meshes keep the last light shown
            context.area.header_text_set(None)
            self.report({"ERROR"}, user_message(exc))
            return {"CANCELLED"}
        if i >= 0:
            self.report({"INFO"}, f"RadTR: {running['last'].leaves.patch_label(i)} "
                                  f"{'on' if self.emission[i].max() > 0 else 'off'}")
        return {"RUNNING_MODAL"}
