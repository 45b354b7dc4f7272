"""Capture: a picture of the result to PNG, rendered (Cycles, the display material) through the
scene's camera or a saved view, or the viewport as drawn; or every frame of the scene's range
(a camera on a path flies along it)."""
import bpy

from ..radtr_addon.blender.render import render_png
from ..radtr_addon.errors import user_message


class RADTR_OT_capture(bpy.types.Operator):
    """Save a picture (or an animation) of the solved scene to PNG"""

    bl_idname = "radtr.capture"
    bl_label = "Capture"

    filepath: bpy.props.StringProperty(name="File", subtype="FILE_PATH", default="//capture.png",
                                       description="The PNG, or the prefix of the numbered PNGs of an animation")
    kind: bpy.props.EnumProperty(name="Kind", default="RENDER", items=[
        ("RENDER", "Render", "Cycles draws the display material through the camera or a saved view"),
        ("VIEWPORT", "Viewport", "The 3D viewport as it is drawn (Blender's viewport render)")])
    view: bpy.props.StringProperty(name="Camera or View", default="",
                                   description="Render through this camera object or saved view (empty: the scene's)")
    animation: bpy.props.BoolProperty(name="Animation", default=False,
                                      description="Every frame of the scene's frame range")

    def execute(self, context):
        path = bpy.path.abspath(self.filepath)
        try:
            if self.kind == "VIEWPORT":
                if bpy.app.background:
                    self.report({"ERROR"}, "RadTR: a viewport capture needs Blender's window; use Render")
                    return {"CANCELLED"}
                scene = context.scene
                saved = scene.render.filepath
                scene.render.filepath = path
                try:
                    bpy.ops.render.opengl(animation=self.animation, write_still=not self.animation)
                finally:
                    scene.render.filepath = saved
            else:
                render_png(context.scene, path, camera=self.view, animation=self.animation)
        except Exception as exc:
            self.report({"ERROR"}, user_message(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"RadTR: captured {path}")
        return {"FINISHED"}
