"""Lighting scenarios: store the last solve under a name, remove one; their weights (in the
panel) blend them in the result meshes and under the flashlight."""
import bpy

from ..radtr_addon.blender.scenarios import show_blend, store
from .solve import running


class RADTR_OT_scenario_add(bpy.types.Operator):
    """Keep the last solve's light as a lighting scenario, to blend with others by weight"""

    bl_idname = "radtr.scenario_add"
    bl_label = "Store Scenario"
    bl_options = {"REGISTER", "UNDO"}

    name: bpy.props.StringProperty(name="Name", default="")

    @classmethod
    def poll(cls, context):
        job = running["last"]
        return running["job"] is None and job is not None and job.result is not None and bool(job.objects)

    def execute(self, context):
        s = context.scene.radtr
        item = store(s, running["last"], self.name or "Scenario")
        self.report({"INFO"}, f"RadTR: stored lighting scenario '{item.name}' ({running['last'].leaves.n:,} patches)")
        return {"FINISHED"}


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
