"""Solve and Continue: radiosity of the visible meshes, written as colour attributes.

Invoked from the UI they run modal (progress bar, live readout, ESC cancels and leaves the
file untouched); called from a script or in background mode they run to the end at once.
Continue takes the last solve of this session further when it stopped at its iteration cap.
"""
import bpy

from ..radtr_addon.blender.pipeline import SolveJob, solve
from ..radtr_addon.errors import user_message

#: The solve running in this session (read by the panel's live readout) and the last one finished.
running = {"job": None, "last": None}


def _report_warnings(op, job):
    for w in job.stats.warnings[:8]:
        op.report({"WARNING"}, w)


class _ModalSolve:
    """Runs a SolveJob from a timer: progress bar, status-bar readout, ESC cancels."""

    def _start(self, context, job):
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
        going_on = False
        try:
            done = job.advance(0.1)
            context.window_manager.progress_update(int(100 * job.fraction))
            context.workspace.status_text_set(f"RadTR: {job.readout}; ESC cancels")
            for area in context.screen.areas:
                if area.type == "VIEW_3D":
                    area.tag_redraw()
            if not done:
                going_on = True
                return {"RUNNING_MODAL"}
            job.finish()
        except Exception as exc:
            self.report({"ERROR"}, user_message(exc))
            return {"CANCELLED"}
        finally:
            if not going_on:
                self._end(context)
        running["last"] = job
        _report_warnings(self, job)
        self.report({"INFO"}, f"RadTR: {job.summary()}")
        return {"FINISHED"}

    def _end(self, context):
        running["job"] = None
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        context.workspace.status_text_set(None)


class RADTR_OT_solve(_ModalSolve, bpy.types.Operator):
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
        _report_warnings(self, job)
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


class RADTR_OT_resume(_ModalSolve, bpy.types.Operator):
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
