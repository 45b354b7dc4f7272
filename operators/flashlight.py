"""Flashlight: a spot at the viewport's eye, aimed through the mouse, relit every frame by
the low-rank solve of the last Solve. The event handling lives in ``FlashlightSession``."""
import bpy

from ..radtr_addon.blender.flashlight import FlashlightSession, default_spot, flashlight_for
from ..radtr_addon.blender.scenarios import usable
from ..radtr_addon.errors import RadTRError, user_message
from .session import mouse_ray, running


class RADTR_OT_flashlight(bpy.types.Operator):
    """Relight the solved scene in real time with a flashlight at the eye, aimed by the mouse"""

    bl_idname = "radtr.flashlight"
    bl_label = "Flashlight"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        job = running["last"]
        return (running["job"] is None and job is not None and bool(job.objects)
                and context.area is not None and context.area.type == "VIEW_3D")

    def invoke(self, context, event):
        s = context.scene.radtr
        try:
            light, meshes, warnings, hit = flashlight_for(running["last"], s.lowrank_level, s.lowrank_backend,
                                                          refine_to=s.lowrank_refine, user=s.lowrank_user)
        except RadTRError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        scenarios, skipped = usable(s, running["last"])
        if any(sc.weight > 0 for sc in scenarios):
            light.set_scenarios(scenarios)
        for w in warnings + skipped:
            self.report({"WARNING"}, w)
        self.report({"INFO"}, f"RadTR: low-rank factors {'read from the cache' if hit else 'built'}")
        origin, direction = mouse_ray(context, event)
        self.session = FlashlightSession(light, meshes, default_spot(light.scene, origin, direction))
        self.session.update()
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        ray = mouse_ray(context, event) if event.type == "MOUSEMOVE" else None
        try:
            result = self.session.handle(event.type, event.value, ray)
        except Exception as exc:            # the session restored the colours; end cleanly
            self.report({"ERROR"}, f"RadTR flashlight stopped, colours restored: {user_message(exc)}")
            result = {"CANCELLED"}
        context.area.header_text_set(self.session.header if result == {"RUNNING_MODAL"} else None)
        context.area.tag_redraw()
        return result
