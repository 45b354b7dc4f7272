"""Continue: take the last solve of this session further when it stopped at its iteration cap."""
import bpy

from ..radtr_addon.errors import user_message
from .session import ModalSolve, running


class RADTR_OT_resume(ModalSolve, bpy.types.Operator):
    """Continue the last solve, which stopped at its iteration cap, for as many iterations again"""

    bl_idname = "radtr.resume"
    bl_label = "Continue Solve"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        last = running["last"]
        try:
            return (running["job"] is None and last is not None and not last.solver.converged
                    and last.bl_scene == context.scene)
        except ReferenceError:                  # the file it solved was closed
            return False

    def _continued(self, context):
        job = running["last"]
        job.resume(context.scene.radtr.max_iterations)
        return job

    def execute(self, context):
        job = self._continued(context)
        try:
            job.run()
            job.finish()
        except Exception as exc:
            self.report({"ERROR"}, user_message(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"RadTR: {job.summary()}")
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        return self._start(context, self._continued(context))
