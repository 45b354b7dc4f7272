"""Toggle Patch Emission: click patches to switch their emission and see the light solved again."""
import bpy

from .session import ClickPatches, running


class RADTR_OT_toggle_emission(ClickPatches, bpy.types.Operator):
    """Click patches to switch their emission on or off and see the light solved again (Esc or right click ends)"""

    bl_idname = "radtr.toggle_emission"
    bl_label = "Toggle Patch Emission"
    bl_options = {"REGISTER", "UNDO"}
    hint = "click a patch to switch its emission"

    def start(self, context):
        self.emission = running["last"].leaves.emission.copy()

    def clicked(self, context, origin, direction) -> bool:
        from ..radtr_addon.blender.sequence import toggle_patch

        i, self.emission = toggle_patch(running["last"], origin, direction, self.emission)
        if i >= 0:
            self.report({"INFO"}, f"RadTR: {running['last'].leaves.patch_label(i)} "
                                  f"{'on' if self.emission[i].max() > 0 else 'off'}")
        return False
