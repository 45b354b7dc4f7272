"""Remove View: delete a saved viewpoint."""
import bpy


class RADTR_OT_view_remove(bpy.types.Operator):
    """Delete this saved view"""

    bl_idname = "radtr.view_remove"
    bl_label = "Remove View"
    bl_options = {"REGISTER", "UNDO"}

    index: bpy.props.IntProperty(name="Index", default=0, min=0)

    def execute(self, context):
        views = context.scene.radtr.views
        if self.index >= len(views):
            self.report({"ERROR"}, f"RadTR: no saved view {self.index}")
            return {"CANCELLED"}
        views.remove(self.index)
        return {"FINISHED"}
