"""Clear: delete RadTR's results and show the source objects again."""
import bpy

from ..radtr_addon.blender.write import clear_results


class RADTR_OT_clear(bpy.types.Operator):
    """Delete RadTR result objects and show the original meshes again"""

    bl_idname = "radtr.clear"
    bl_label = "Clear Results"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        removed = clear_results(context.scene)
        self.report({"INFO"}, f"RadTR: removed {removed} result objects")
        return {"FINISHED"}
