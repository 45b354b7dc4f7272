"""Remove Scenario: drop a stored lighting scenario and show the blend of the others."""
import bpy

from ..radtr_addon.blender.scenarios import show_blend
from .session import running


class RADTR_OT_scenario_remove(bpy.types.Operator):
    """Remove this lighting scenario"""

    bl_idname = "radtr.scenario_remove"
    bl_label = "Remove Scenario"
    bl_options = {"REGISTER", "UNDO"}

    index: bpy.props.IntProperty(name="Index", default=0, min=0)

    def execute(self, context):
        s = context.scene.radtr
        if self.index >= len(s.scenarios):
            self.report({"ERROR"}, f"RadTR: no lighting scenario {self.index}")
            return {"CANCELLED"}
        s.scenarios.remove(self.index)
        if running["last"] is not None and running["last"].objects:
            for w in show_blend(s, running["last"]):
                self.report({"WARNING"}, w)
        return {"FINISHED"}
