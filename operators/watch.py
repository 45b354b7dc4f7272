"""Watch: re-solve and render an emission file each time another program rewrites it; ESC stops
and restores the colours. From a script, ``polls`` > 0 looks that many times and returns."""
import time

import bpy

from ..radtr_addon.blender.sequence import Watcher
from ..radtr_addon.errors import user_message
from .session import last_job


class RADTR_OT_watch(bpy.types.Operator):
    """Watch an emission file: each complete new version is solved, shown and rendered (ESC stops)"""

    bl_idname = "radtr.watch"
    bl_label = "Watch Emission File"

    file: bpy.props.StringProperty(name="File", subtype="FILE_PATH")
    period: bpy.props.FloatProperty(name="Period", default=0.5, min=0.01, description="Seconds between looks")
    out_dir: bpy.props.StringProperty(name="Output Folder", subtype="DIR_PATH", default="//watch")
    out_prefix: bpy.props.StringProperty(name="Output Prefix", default="watch_")
    polls: bpy.props.IntProperty(name="Looks", default=0, min=0,
                                 description="From a script: look this many times, then stop; 0: until ESC")

    def _watcher(self):
        job = last_job(self)
        if job is None:
            return None
        return Watcher(job, bpy.path.abspath(self.file), bpy.path.abspath(self.out_dir), self.out_prefix,
                       log=lambda line: self.report({"INFO"}, line))

    def execute(self, context):
        if self.polls == 0:
            self.report({"ERROR"}, "RadTR: Watch runs until ESC in the viewport; from a script give Looks > 0")
            return {"CANCELLED"}
        watcher = self._watcher()
        if watcher is None:
            return {"CANCELLED"}
        try:
            for _ in range(self.polls):
                watcher.poll(self.period)
                time.sleep(self.period)
        except Exception as exc:
            self.report({"ERROR"}, user_message(exc))
            return {"CANCELLED"}
        finally:
            watcher.close()
        self.report({"INFO"}, f"RadTR: rendered {len(watcher.shown)} version(s)")
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None or self.polls:
            return self.execute(context)
        self._w = self._watcher()
        if self._w is None:
            return {"CANCELLED"}
        wm = context.window_manager
        self._timer = wm.event_timer_add(self.period, window=context.window)
        wm.modal_handler_add(self)
        context.workspace.status_text_set(f"RadTR: watching {self.file}; ESC stops")
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            return self._stop(context, {"FINISHED"})
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            self._w.poll(self.period)
        except Exception as exc:
            self.report({"ERROR"}, user_message(exc))
            return self._stop(context, {"CANCELLED"})
        return {"RUNNING_MODAL"}

    def _stop(self, context, result):
        self._w.close()
        context.window_manager.event_timer_remove(self._timer)
        context.workspace.status_text_set(None)
        self.report({"INFO"}, f"RadTR: watch stopped; {len(self._w.shown)} version(s) rendered")
        return result
