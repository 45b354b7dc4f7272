"""Load Patch Vector: a per-patch radiosity or emission from a file onto the last solve's patches."""
import bpy

from .session import last_job


class RADTR_OT_load_vector(bpy.types.Operator):
    """Load a per-patch radiosity (shown as it is) or emission (solved, then shown) from a file
    (.npz, .mat, .dat, .csv) onto the last solve's patches; a file that does not fit changes nothing"""

    bl_idname = "radtr.load_vector"
    bl_label = "Load Patch Vector"
    bl_options = {"REGISTER", "UNDO"}

    filepath: bpy.props.StringProperty(subtype="FILE_PATH")
    kind: bpy.props.EnumProperty(items=[("radiosity", "Radiosity", "Show B as it is"),
                                        ("emission", "Emission", "Solve with this E and show B")])

    def execute(self, context):
        from ..radtr_addon.blender.flashlight import LiveMeshes
        from ..radtr_addon.errors import RadTRError
        from ..radtr_addon.exchange import load_vector

        job = last_job(self)
        if job is None:
            return {"CANCELLED"}
        try:
            v = load_vector(bpy.path.abspath(self.filepath), job.leaves.n)
            B = v if self.kind == "radiosity" else job.with_emission(v)
        except RadTRError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        LiveMeshes(job.objects, job.leaves).write(B)
        self.report({"INFO"}, f"RadTR: {self.kind} of {job.leaves.n:,} patches loaded from {self.filepath}")
        return {"FINISHED"}

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}
