"""Pick View: click a patch of the last solve to look out of it (View from Patch by clicking)."""
import bpy

from ..radtr_addon.views import pick_patch
from .session import ClickPatches, running


class RADTR_OT_pick_view(ClickPatches, bpy.types.Operator):
    """Click a patch to put the eye on it, looking out along its normal (Esc or right click ends)"""

    bl_idname = "radtr.pick_view"
    bl_label = "Pick Patch View"
    hint = "click a patch to look out of it"

    def clicked(self, context, origin, direction) -> bool:
        i = pick_patch(running["last"].leaves, origin, direction)
        if i < 0:
            return False
        context.scene.radtr.view_patch = i
        bpy.ops.radtr.view_from_patch()
        return True
