"""Solve: radiosity of the visible meshes, written as colour attributes.

Invoked from the UI it runs modal (progress bar, live readout, ESC cancels and leaves the
file untouched); called from a script or in background mode it runs to the end at once.
"""
import bpy

from ..radtr_addon.blender.pipeline import SolveJob, solve
from ..radtr_addon.errors import user_message
from .session import ModalSolve, report_warnings, running


class RADTR_OT_solve(ModalSolve, bpy.types.Operator):
    """Solve radiosity for the visible mesh objects and write it to colour attributes"""

    bl_idname = "radtr.solve"
    bl_label = "Solve Radiosity"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return context.scene is not None and running["job"] is None

    def execute(self, context):
        try:
            job = solve(context, context.scene.radtr.to_settings())
        except Exception as exc:
            self.report({"ERROR"}, user_message(exc))
            return {"CANCELLED"}
        running["last"] = job
        report_warnings(self, job)
        self.report({"INFO"}, f"RadTR: {job.summary()}")
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        try:
            job = SolveJob(context.scene, context.evaluated_depsgraph_get(), context.view_layer,
                           context.scene.radtr.to_settings())
        except Exception as exc:
            self.report({"ERROR"}, user_message(exc))
            return {"CANCELLED"}
        return self._start(context, job)
