"""What the operators share: the solve running in this session and the last one finished,
the modal runner of Solve and Continue, and the view ray through the mouse."""

from ..radtr_addon.errors import user_message

#: The solve running in this session (read by the panel's live readout) and the last one finished.
running = {"job": None, "last": None}


def last_job(op):
    """The last finished solve, or None after reporting that there is none."""
    job = running["last"]
    if job is None:
        op.report({"ERROR"}, "RadTR: solve first; the tools work on the last solve's patches")
    return job


def report_warnings(op, job):
    for w in job.stats.warnings[:8]:
        op.report({"WARNING"}, w)


def mouse_ray(context, event):
    """(origin, direction) of the view ray through the mouse."""
    from bpy_extras import view3d_utils

    region, rv3d = context.region, context.region_data
    xy = (event.mouse_region_x, event.mouse_region_y)
    return (view3d_utils.region_2d_to_origin_3d(region, rv3d, xy),
            view3d_utils.region_2d_to_vector_3d(region, rv3d, xy))


class _TimerModal:
    """A modal operator on a timer with a progress bar; ``_close`` undoes what ``_begin`` set up."""

    def _begin(self, context):
        wm = context.window_manager
        wm.progress_begin(0, 100)
        self._timer = wm.event_timer_add(0.02, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _close(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        context.workspace.status_text_set(None)


class ModalSolve(_TimerModal):
    """Runs a SolveJob from a timer: progress bar, status-bar readout, ESC cancels."""

    def _start(self, context, job):
        running["job"] = job
        return self._begin(context)

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
        report_warnings(self, job)
        self.report({"INFO"}, f"RadTR: {job.summary()}")
        return {"FINISHED"}

    def _end(self, context):
        running["job"] = None
        self._close(context)


class ModalTask(_TimerModal):
    """Runs a task's steps (``radtr_addon.tasks``) from a timer: progress bar, status text, ESC
    closes the steps (their ``finally`` undoes what is half done). In background mode, or
    called from a script, it runs them to the end at once. Subclasses report in ``finished``."""

    what = "task"

    def _run_steps(self, context, steps):
        import bpy

        from ..radtr_addon.tasks import run

        if bpy.app.background or context.window is None:
            try:
                result = run(steps)
            except Exception as exc:
                self.report({"ERROR"}, user_message(exc))
                return {"CANCELLED"}
            return self.finished(context, result)
        self._steps = steps
        return self._begin(context)

    def modal(self, context, event):
        import time

        if event.type == "ESC":
            self._steps.close()
            self._close(context)
            self.report({"WARNING"}, f"RadTR: {self.what} cancelled")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            end = time.perf_counter() + 0.1
            while time.perf_counter() < end:
                fraction = next(self._steps)
        except StopIteration as done:
            self._close(context)
            return self.finished(context, done.value)
        except Exception as exc:
            self._steps.close()
            self._close(context)
            self.report({"ERROR"}, user_message(exc))
            return {"CANCELLED"}
        context.window_manager.progress_update(int(100 * fraction))
        context.workspace.status_text_set(f"RadTR: {self.what} {fraction:.0%}; ESC cancels")
        return {"RUNNING_MODAL"}

    def finished(self, context, result):
        return {"FINISHED"}


class ClickPatches:
    """A modal operator on the last solve's patches in a 3D view: each left click calls
    ``clicked(context, origin, direction)`` with the view ray (True ends it); Esc or right
    click ends it, an error ends it with the reason; the header shows ``hint`` meanwhile."""

    hint = "click a patch"

    @classmethod
    def poll(cls, context):
        return running["last"] is not None and context.area is not None and context.area.type == "VIEW_3D"

    def invoke(self, context, event):
        self.start(context)
        context.window_manager.modal_handler_add(self)
        context.area.header_text_set(f"RadTR: {self.hint}; Esc or right click ends")
        return {"RUNNING_MODAL"}

    def start(self, context):
        """Set up before the first click."""

    def modal(self, context, event):
        if event.type in ("ESC", "RIGHTMOUSE"):
            context.area.header_text_set(None)
            return {"FINISHED"}
        if event.type != "LEFTMOUSE" or event.value != "PRESS":
            return {"PASS_THROUGH"}
        try:
            done = self.clicked(context, *mouse_ray(context, event))
        except Exception as exc:                # the meshes keep the last light shown
            context.area.header_text_set(None)
            self.report({"ERROR"}, user_message(exc))
            return {"CANCELLED"}
        if done:
            context.area.header_text_set(None)
            return {"FINISHED"}
        return {"RUNNING_MODAL"}
