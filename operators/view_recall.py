"""Recall View: put the 3D viewport at a saved viewpoint."""
import bpy

from ..radtr_addon.blender.viewpoints import recall_view


class RADTR_OT_view_recall(bpy.types.Operator):
    """Move the viewport to this saved view"""

    bl_idname = "radtr.view_recall"
    bl_label = "Recall View"

    index: bpy.props.IntProperty(name="Index", default=0, min=0)

    @classmethod
    def poll(cls, context):
        return context.region_data is not None

    def execute(self, context):
        views = context.scene.radtr.views
        if self.index >= len(views):
            self.report({"ERROR"}, f"RadTR: no saved view {self.index}")
            return {"CANCELLED"}
        recall_view(views[self.index], context.region_data)
        context.space_data.lens = views[self.index].lens
        return {"FINISHED"}
