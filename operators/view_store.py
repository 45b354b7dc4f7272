"""Store View: keep the 3D viewport's viewpoint under a name, in the .blend."""
import bpy

from ..radtr_addon.blender.viewpoints import store_view


class RADTR_OT_view_store(bpy.types.Operator):
    """Save the viewport's viewpoint (target, turn, distance, lens) under a name"""

    bl_idname = "radtr.view_store"
    bl_label = "Store View"
    bl_options = {"REGISTER", "UNDO"}

    name: bpy.props.StringProperty(name="Name", default="View")

    @classmethod
    def poll(cls, context):
        return context.region_data is not None

    def execute(self, context):
        item = store_view(context.scene.radtr, context.region_data, self.name, context.space_data.lens)
        self.report({"INFO"}, f"RadTR: stored view '{item.name}'")
        return {"FINISHED"}
