"""Solve: radiosity of the visible meshes, written as colour attributes.

Invoked from the UI it runs modal (progress bar, live readout, ESC cancels and leaves the
file untouched); called from a script or in background mode it runs to the end at once.
"""
import bpy

from ..radtr_addon.blender.pipeline import SolveJob, solve
from ..radtr_addon.errors import RadTRError

#: The solve running in this session, read by the panel's live readout.
running = {"job": None}


def _summary(job) -> str:
    r = job.result
    return (f"RadTR: {job.leaves.n} patches, {r.iterations} shots, residual "
            f"{r.residual_history[-1] if r.residual_history else 0:.1e}, "
            f"energy balance {r.balance_error():.1e}")


def _report_warnings(op, job):
    for w in job.stats.warnings[:8]:
        op.report({"WARNING"}, w)


class RADTR_OT_solve(bpy.types.Operator):
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
        except RadTRError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        _report_warnings(self, job)
        self.report({"INFO"}, _summary(job))
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        try:
            job = SolveJob(context.scene, context.evaluated_depsgraph_get(), context.view_layer,
                           context.scene.radtr.to_settings())
        except RadTRError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        running["job"] = job
        wm = context.window_manager
        wm.progress_begin(0, 100)
        self._timer = wm.event_timer_add(0.02, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        job = running["job"]
        if event.type == "ESC":
            self._end(context)
            self.report({"WARNING"}, "RadTR: solve cancelled; nothing was changed")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            done = job.advance(0.1)
            context.window_manager.progress_update(int(100 * job.fraction))
            context.workspace.status_text_set(
                f"RadTR: shot {job.solver.iterations}, residual {job.solver.residual:.2e} "
                f"(stop at {job.settings.tolerance:g}); ESC cancels")
            for area in context.screen.areas:
                if area.type == "VIEW_3D":
                    area.tag_redraw()
            if not done:
                return {"RUNNING_MODAL"}
            job.finish()
        except RadTRError as exc:
            self._end(context)
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self._end(context)
        _report_warnings(self, job)
        self.report({"INFO"}, _summary(job))
        return {"FINISHED"}

    def _end(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        context.workspace.status_text_set(None)
        running["job"] = None
