"""Store Scenario: keep the last solve's light under a name (weights in the panel blend scenarios)."""
import bpy

from ..radtr_addon.blender.scenarios import store
from .session import running


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
